#version 460
#extension GL_GOOGLE_include_directive : require
// The paper's data-parallel octree: a min/max pyramid of n and, per voxel, the level of the leaf that
// covers it (the coarsest node whose n range is below epsilon). Level-0 ranges span each voxel's 3x3x3
// neighbourhood so that trilinear interpolation anywhere inside a leaf stays within its range.
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

uint node_index(uint level, uvec3 node) {
    uvec3 d = level_dims(level);
    return level_offset(level) + (node.z * d.y + node.y) * d.x + node.x;
}

void leaf_range(uint i) {
    uvec3 dims = push.dims.xyz;
    ivec3 v = ivec3(i % dims.x, (i / dims.x) % dims.y, i / (dims.x * dims.y));
    float lo = 1e30, hi = -1e30;
    for (int z = -1; z <= 1; ++z)
        for (int y = -1; y <= 1; ++y)
            for (int x = -1; x <= 1; ++x) {
                float n = imageLoad(index_field, clamp(v + ivec3(x, y, z), ivec3(0), ivec3(dims) - 1)).r;
                lo = min(lo, n);
                hi = max(hi, n);
            }
    pyramid[i] = vec2(lo, hi);
}

void reduce(uint i) {
    uint level = push.level_dims.w;
    uvec3 d = push.level_dims.xyz;
    if (i >= d.x * d.y * d.z) return;
    uvec3 node = uvec3(i % d.x, (i / d.x) % d.y, i / (d.x * d.y));
    uvec3 child_dims = level_dims(level - 1u);
    vec2 range = vec2(1e30, -1e30);
    for (uint c = 0u; c < 8u; ++c) {
        uvec3 child = 2u * node + uvec3(c & 1u, (c >> 1u) & 1u, c >> 2u);
        if (any(greaterThanEqual(child, child_dims))) continue;
        vec2 r = pyramid[node_index(level - 1u, child)];
        range = vec2(min(range.x, r.x), max(range.y, r.y));
    }
    pyramid[level_offset(level) + i] = range;
}

void level_map(uint i) {
    uvec3 dims = push.dims.xyz;
    uvec3 v = uvec3(i % dims.x, (i / dims.x) % dims.y, i / (dims.x * dims.y));
    uint level = 0u;
    for (uint l = 1u; l <= push.offsets1.z; ++l) {
        vec2 r = pyramid[node_index(l, v >> l)];
        if (r.y - r.x >= push.epsilon) break;
        level = l;
    }
    levels[i] = level;
}

void main() {
    uint i = linear_invocation();
    uint voxels = push.dims.x * push.dims.y * push.dims.z;
    if (kMode == OCTREE_MODE_LEAF_RANGE) {
        if (i < voxels) leaf_range(i);
    } else if (kMode == OCTREE_MODE_REDUCE) {
        reduce(i);
    } else if (i < voxels) {
        level_map(i);
    }
}
