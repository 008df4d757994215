#version 460
#extension GL_GOOGLE_include_directive : require
// Before temporal reuse (temporal_reuse.comp), one thread per sample of an interactive frame: the mean
// and standard deviation of the radiance of the sample's 3x3 neighbourhood, the statistics of what is
// there now, against which the reprojected history is clipped. Per sample rather than per history
// pixel: a ninth of the reads where the history has several pixels per sample, and interpolated
// bilinearly there, so the box changes smoothly from pixel to pixel.
#include "temporal.h"
layout(local_size_x = TEMPORAL_GROUP_SIZE, local_size_y = TEMPORAL_GROUP_SIZE) in;

layout(std430, binding = TEMPORAL_BINDING_PARAMS) readonly buffer Params { TemporalParams params; };
layout(std430, binding = TEMPORAL_BINDING_SAMPLES) readonly buffer Samples { vec4 samples[]; };
layout(std430, binding = TEMPORAL_BINDING_NEIGHBOURHOOD) writeonly buffer Neighbourhood { vec4 neighbourhood[]; };

void main() {
    ivec2 size = ivec2(params.sizes.zw);
    ivec2 s = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(s, size))) return;
    vec3 sum = vec3(0.0), squares = vec3(0.0);
    for (int k = 0; k < 9; ++k) {
        ivec2 t = clamp(s + ivec2(k % 3 - 1, k / 3 - 1), ivec2(0), size - 1);
        vec3 c = samples[t.y * size.x + t.x].rgb;
        sum += c;
        squares += c * c;
    }
    vec3 mean = sum * (1.0 / 9.0);
    uint index = uint(s.y * size.x + s.x);
    neighbourhood[2u * index] = vec4(mean, 0.0);
    neighbourhood[2u * index + 1u] = vec4(sqrt(max(squares * (1.0 / 9.0) - mean * mean, vec3(0.0))), 0.0);
}
