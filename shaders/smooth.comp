#version 460
#extension GL_GOOGLE_include_directive : require
// One axis of the separable Gaussian that smooths coverage (Ihrke et al.: sigma of about one voxel keeps
// the refracting shell 2-3 voxels wide without halos). Edges clamp: an object that volume.bounds cuts
// continues past the grid instead of gaining a false interface there.
#include "volume_build.h"
// The workgroup size comes before linear_id.glsl: gl_WorkGroupSize used ahead of the declaration folds
// to 1, which breaks every dispatch folded past 65535 groups.
layout(local_size_x = VOLUME_GROUP_SIZE) in;
#include "linear_id.glsl"

layout(std430, binding = SMOOTH_BINDING_SOURCE) readonly buffer Source { float source[]; };
layout(std430, binding = SMOOTH_BINDING_TARGET) writeonly buffer Target { float target[]; };
layout(push_constant) uniform Push { SmoothPush push; };

void main() {
    uvec3 dims = push.dims.xyz;
    uint i = linear_invocation();
    if (i >= dims.x * dims.y * dims.z) return;
    uvec3 v = uvec3(i % dims.x, (i / dims.x) % dims.y, i / (dims.x * dims.y));
    uint axis = push.dims.w;
    uint stride = axis == 0u ? 1u : (axis == 1u ? dims.x : dims.x * dims.y);
    int position = int(v[axis]);
    int last = int(dims[axis]) - 1;
    // Divided by the weights' sum as added here, so a fully covered neighbourhood gives exactly 1.
    float sum = 0.0, weights = 0.0;
    for (int o = -push.radius; o <= push.radius; ++o) {
        int p = clamp(position + o, 0, last);
        float w = push.weights[abs(o)];
        sum += w * source[int(i) + (p - position) * int(stride)];
        weights += w;
    }
    target[i] = sum / weights;
}
