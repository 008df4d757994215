#version 460
#extension GL_GOOGLE_include_directive : require
// Tone mapping: the frame's linear radiance (what the viewing pass leaves) times the exposure -> the
// sRGB pixels a PNG carries. A pass of its own, so an exposure edit re-tone-maps the resident linear
// frame instead of tracing eye rays again.
#include "transport.h"
#include "tone_map.glsl"
layout(local_size_x = TRANSPORT_GROUP_SIZE) in;
#include "linear_id.glsl"

layout(std140, binding = TRANSPORT_BINDING_PARAMS) readonly buffer Params { TransportParams params; };
layout(std430, binding = TRANSPORT_BINDING_HDR) readonly buffer Hdr { vec4 hdr[]; };
layout(std430, binding = TRANSPORT_BINDING_LDR) writeonly buffer Ldr { uint ldr[]; };

void main() {
    uint index = linear_invocation();
    if (index >= params.image.x * params.image.y) return;
    ldr[index] = srgb8(hdr[index].rgb, params.tone.x);
}
