#version 460
#extension GL_GOOGLE_include_directive : require
// Vulkan self-test: integer arithmetic round trip and trilinear interpolation of a 3D image read texel by
// texel, as the transport passes read their grids (trilinear.glsl).
#include "selftest.h"
#include "trilinear.glsl"

layout(local_size_x = SELFTEST_GROUP_SIZE) in;
layout(std430, binding = SELFTEST_BINDING_INPUT) readonly buffer Input { uint values_in[]; };
layout(std430, binding = SELFTEST_BINDING_OUTPUT) writeonly buffer Output { uint values_out[]; };
layout(binding = SELFTEST_BINDING_IMAGE, r32f) readonly uniform image3D volume;
layout(std430, binding = SELFTEST_BINDING_SAMPLES) buffer Samples { vec4 samples[]; };
layout(push_constant) uniform Push { SelftestPush push; };

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= push.count) return;
    if (push.mode == 0u) {
        values_out[i] = values_in[i] * push.multiplier + i;
    } else {
        // samples[i].xyz holds a normalized coordinate; write back the interpolated value in .w
        TrilinearCell cell = trilinear_cell(samples[i].xyz, imageSize(volume));
        samples[i].w = TRILINEAR_AT(volume, cell).r;
    }
}
