#version 460
#extension GL_GOOGLE_include_directive : require
// The paper's data-parallel octree: a min/max pyramid of n and, per voxel, the level of the leaf that
// covers it (the coarsest node whose n range is below epsilon; level 0 where none is). A node's range
// spans the 3x3x3 neighbourhood of each of its voxels, so that trilinear interpolation anywhere inside
// a leaf stays within its range. The pyramid starts at level 1: a voxel is level 0 exactly when its
// level-1 node is not a leaf, so per-voxel ranges are never needed, nor per-voxel levels.
#include "volume_build.h"
// The workgroup size comes before linear_id.glsl: gl_WorkGroupSize used ahead of the declaration folds
// to 1, which breaks every dispatch folded past 65535 groups.
layout(local_size_x = VOLUME_GROUP_SIZE) in;
#include "linear_id.glsl"

layout(binding = OCTREE_BINDING_INDEX_FIELD, rgba32f) uniform readonly image3D index_field;
layout(std430, binding = OCTREE_BINDING_PYRAMID) buffer Pyramid { vec2 pyramid[]; };
layout(std430, binding = OCTREE_BINDING_LEVELS) writeonly buffer Levels { uint levels[]; };
layout(push_constant) uniform Push { OctreePush push; };

uint level_offset(uint level) { return level < 4u ? push.offsets0[level] : push.offsets1[level - 4u]; }

uvec3 level_dims(uint level) { return (push.dims.xyz + (1u << level) - 1u) >> level; }

// A node's place within its level, x fastest; the level map is laid out as level 1 is.
uint node_in_level(uint level, uvec3 node) {
    uvec3 d = level_dims(level);
    return (node.z * d.y + node.y) * d.x + node.x;
}

uint node_index(uint level, uvec3 node) { return level_offset(level) + node_in_level(level, node); }

// The node of the box being written (OctreePush::first, extent) that invocation i writes; false past
// the box. A full build's box is the whole level; an edit's, the nodes its changed voxels reach.
bool box_node(uint i, out uvec3 node) {
    uvec3 e = push.extent.xyz;
    node = push.first.xyz + uvec3(i % e.x, (i / e.x) % e.y, i / (e.x * e.y));
    return i < e.x * e.y * e.z;
}

// Level 1 straight from the index field: a level-1 node's range covers the 3x3x3 neighbourhoods of its
// 2x2x2 voxels, the 4x4x4 voxels from 2 node - 1 to 2 node + 2 (clamped: a repeated edge voxel changes
// no minimum or maximum, and covers the last node of an odd side, which has one voxel along it).
// Eight loads per voxel; a level of per-voxel ranges would take 27 and write as many ranges as voxels.
void level1_range(uvec3 node) {
    ivec3 first = 2 * ivec3(node) - 1;
    ivec3 last = ivec3(push.dims.xyz) - 1;
    float lo = 1e30, hi = -1e30;
    for (int z = 0; z < 4; ++z)
        for (int y = 0; y < 4; ++y)
            for (int x = 0; x < 4; ++x) {
                float n = imageLoad(index_field, clamp(first + ivec3(x, y, z), ivec3(0), last)).r;
                lo = min(lo, n);
                hi = max(hi, n);
            }
    pyramid[node_index(1u, node)] = vec2(lo, hi);
}

void reduce(uvec3 node) {
    uint level = push.dims.w;
    uvec3 child_dims = level_dims(level - 1u);
    vec2 range = vec2(1e30, -1e30);
    for (uint c = 0u; c < 8u; ++c) {
        uvec3 child = 2u * node + uvec3(c & 1u, (c >> 1u) & 1u, c >> 2u);
        if (any(greaterThanEqual(child, child_dims))) continue;
        vec2 r = pyramid[node_index(level - 1u, child)];
        range = vec2(min(range.x, r.x), max(range.y, r.y));
    }
    pyramid[node_index(level, node)] = range;
}

// The level map has one entry per level-1 node: its 2x2x2 voxels have the same ancestors, so the same
// leaf level, and one entry for eight voxels makes this job 8x smaller.
void level_map(uvec3 c) {
    uint level = 0u;
    for (uint l = 1u; l <= push.offsets1.z; ++l) {
        vec2 r = pyramid[node_index(l, c >> (l - 1u))];
        if (r.y - r.x >= push.epsilon) break;
        level = l;
    }
    levels[node_in_level(1u, c)] = level;
}

void main() {
    uvec3 node;
    if (!box_node(linear_invocation(), node)) return;
    if (kMode == OCTREE_MODE_LEVEL1_RANGE) {
        level1_range(node);
    } else if (kMode == OCTREE_MODE_REDUCE) {
        reduce(node);
    } else {
        level_map(node);
    }
}
