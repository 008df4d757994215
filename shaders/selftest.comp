#version 460
#extension GL_GOOGLE_include_directive : require
// Vulkan self-test: integer arithmetic round trip and trilinear sampling of a 3D image.
#include "selftest.h"

layout(local_size_x = SELFTEST_GROUP_SIZE) in;
layout(std430, binding = SELFTEST_BINDING_INPUT) readonly buffer Input { uint values_in[]; };
layout(std430, binding = SELFTEST_BINDING_OUTPUT) writeonly buffer Output { uint values_out[]; };
layout(binding = SELFTEST_BINDING_IMAGE) uniform sampler3D volume;
layout(std430, binding = SELFTEST_BINDING_SAMPLES) buffer Samples { vec4 samples[]; };
layout(push_constant) uniform Push { SelftestPush push; };

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= push.count) return;
    if (push.mode == 0u) {
        values_out[i] = values_in[i] * push.multiplier + i;
    } else {
        // samples[i].xyz holds a normalized coordinate; write back the filtered value in .w
        samples[i].w = textureLod(volume, samples[i].xyz, 0.0).r;
    }
}
