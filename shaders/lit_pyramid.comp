#version 460
#extension GL_GOOGLE_include_directive : require
// The lit pyramid (transport.h): which cells of LIT_BLOCK^3 index-field voxels, and of 2^k times that
// many, any photon light reaches, so that eye rays cross the others without gathering. One dispatch
// finds level 0 from the radiance grid; one per level above merges each 2^3 cells of the level below;
// a last one turns level 0 into unlit-level counts (transport.h). Every cell is written by one
// invocation reading a fixed footprint: cheaper on lavapipe than having every lit voxel mark the cells
// it touches, which ran a store loop per level for every voxel.
#include "transport.h"
layout(local_size_x = TRANSPORT_GROUP_SIZE) in;
#include "linear_id.glsl"

layout(constant_id = LIT_CONSTANT_MODE) const uint kMode = LIT_MODE_BASE;
layout(std140, binding = TRANSPORT_BINDING_PARAMS) readonly buffer Params { TransportParams params; };
layout(binding = TRANSPORT_BINDING_FLUX, rgba32f) uniform readonly image3D flux;
layout(std430, binding = TRANSPORT_BINDING_LIT_BLOCKS) buffer LitBlocks { uint lit_blocks[]; };
layout(push_constant) uniform Push { LitPyramidPush push; };

uint cell_index(uint level, uvec3 c) {
    uvec3 cells = lit_cells(params.lit_grid.xyz, level);
    return params.lit_offsets[level] + (c.z * cells.y + c.y) * cells.x + c.x;
}

// Whether light reaches level-0 block b: whether a radiance voxel with fluence lies within one radiance
// voxel of it, so that trilinear fetches in the block can see it. A radiance voxel v spans lattice
// voxels [f v, f (v + 1)); with its neighbours, [f (v - 1), f (v + 2)). That meets the block's voxels
// [B b, B b + B - 1] (B = LIT_BLOCK lit_grid.w) for v from ceil((B b + 1) / f) - 2 to
// floor((B b + B - 1) / f) + 1.
bool block_lit(uvec3 b) {
    ivec3 f = ivec3(params.radiance_grid.w);
    int side = int(LIT_BLOCK * params.lit_grid.w);
    ivec3 first = max((side * ivec3(b) + f) / f - 2, ivec3(0));
    ivec3 last = min((side * ivec3(b) + side - 1) / f + 1, ivec3(params.radiance_grid.xyz) - 1);
    bool lit = false;
    for (int z = first.z; z <= last.z; ++z)
        for (int y = first.y; y <= last.y; ++y)
            for (int x = first.x; x <= last.x; ++x) lit = lit || imageLoad(flux, ivec3(x, y, z)).w > 0.0;
    return lit;
}

// Whether any of the (up to) 8 cells below cell c of `level` is lit.
bool children_lit(uint level, uvec3 c) {
    uvec3 below = lit_cells(params.lit_grid.xyz, level - 1u) - 1u;
    uint lit = 0u;
    for (uint k = 0u; k < 8u; ++k)  // a child past the grid's edge repeats the last one: harmless in an OR
        lit |= lit_blocks[cell_index(level - 1u, min(2u * c + uvec3(k & 1u, (k >> 1u) & 1u, k >> 2u), below))];
    return lit != 0u;
}

// How many levels are unlit at level-0 block b. A lit cell's parents are lit, so these are the finest.
uint unlit_levels(uvec3 b) {
    uint unlit = 0u;
    for (uint level = 0u; level < LIT_LEVELS; ++level) unlit += lit_blocks[cell_index(level, b >> level)] == 0u ? 1u : 0u;
    return unlit;
}

void main() {
    uint level = kMode == LIT_MODE_MERGE ? push.level : 0u;
    uvec3 cells = lit_cells(params.lit_grid.xyz, level);
    uint i = linear_invocation();
    if (i >= cells.x * cells.y * cells.z) return;
    uvec3 c = uvec3(i % cells.x, (i / cells.x) % cells.y, i / (cells.x * cells.y));
    uint value;
    if (kMode == LIT_MODE_BASE) value = block_lit(c) ? 1u : 0u;
    else if (kMode == LIT_MODE_MERGE) value = children_lit(level, c) ? 1u : 0u;
    else value = unlit_levels(c);  // reads only this block's own level-0 entry, so rewriting it is safe
    lit_blocks[cell_index(level, c)] = value;
}
