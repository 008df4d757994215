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
layout(constant_id = SMOOTH_CONSTANT_RADIUS) const int kRadius = 1;

// Each invocation smooths SMOOTH_RUN consecutive voxels along the axis, so the taps they share are
// loaded once: SMOOTH_RUN + 2 radius loads instead of SMOOTH_RUN (2 radius + 1) (storage-buffer loads
// run lane by lane on lavapipe). Every voxel still adds its taps in order from -radius to +radius.
void main() {
    uvec3 dims = push.dims.xyz;
    uint axis = push.dims.w;
    uvec3 runs_dims = dims;
    runs_dims[axis] = (dims[axis] + SMOOTH_RUN - 1u) / SMOOTH_RUN;
    uint i = linear_invocation();
    if (i >= runs_dims.x * runs_dims.y * runs_dims.z) return;
    uvec3 v = uvec3(i % runs_dims.x, (i / runs_dims.x) % runs_dims.y, i / (runs_dims.x * runs_dims.y));
    v[axis] *= SMOOTH_RUN;
    uint stride = axis == 0u ? 1u : (axis == 1u ? dims.x : dims.x * dims.y);
    uint first = (v.z * dims.y + v.y) * dims.x + v.x - v[axis] * stride;  // the line's voxel at 0
    int start = int(v[axis]), last = int(dims[axis]) - 1;
    float sum[SMOOTH_RUN], weights = 0.0;
    for (int j = 0; j < SMOOTH_RUN; ++j) sum[j] = 0.0;
    for (int o = -kRadius; o <= kRadius; ++o) weights += push.weights[abs(o)];
    // Tap k lies at start - kRadius + k: offset o = k - kRadius - j from voxel start + j.
    for (int k = 0; k < SMOOTH_RUN + 2 * kRadius; ++k) {
        float value = source[first + uint(clamp(start - kRadius + k, 0, last)) * stride];
        for (int j = 0; j < SMOOTH_RUN; ++j) {
            int o = k - kRadius - j;
            if (abs(o) <= kRadius) sum[j] += push.weights[abs(o)] * value;
        }
    }
    for (int j = 0; j < SMOOTH_RUN; ++j)
        if (start + j <= last) target[first + uint(start + j) * stride] = sum[j] / weights;
}
