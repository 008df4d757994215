#version 460
#extension GL_GOOGLE_include_directive : require
// An interactive frame at the viewer's size from a frame traced smaller (mixed resolution, as real-time
// renderers draw fog at a fraction of the screen's size): one thread per pixel of the viewer's image.
// What the traced eye rays gathered along the way (fog, glass, the volumes) and the transmittance to
// their ends change smoothly and are interpolated between the traced pixels; the end itself, the floor
// (its checker, the lit disc's rim, the floor map) or the sky, is found again for each pixel along its
// own straight ray, at the viewer's size. Where the traced rays bent (the object) their transmittance
// to a straight end is 0, and the pixel is their light, interpolated.
#include "transport_common.glsl"
#include "environment.glsl"
#include "tone_map.glsl"

layout(local_size_x = VIEW_GROUP_SIZE, local_size_y = VIEW_GROUP_SIZE) in;
layout(binding = TRANSPORT_BINDING_FLOOR_MAP) uniform sampler3D floor_map;
layout(std430, binding = TRANSPORT_BINDING_VIEW_ENDS) readonly buffer Ends { vec4 ends[]; };
layout(std430, binding = TRANSPORT_BINDING_VIEWER_HDR) writeonly buffer ViewerHdr { vec4 viewer_hdr[]; };
layout(std430, binding = TRANSPORT_BINDING_VIEWER_LDR) writeonly buffer ViewerLdr { uint viewer_ldr[]; };
layout(push_constant) uniform Push { UpscalePush push; };
#include "eye_ray_ends.glsl"

void main() {
    load_params();
    uvec2 pixel = gl_GlobalInvocationID.xy;
    uint width = push.viewer.x, height = push.viewer.y;
    if (pixel.x >= width || pixel.y >= height) return;
    // The pixel's ray, as the viewing pass makes one for an image of this size (at the pixel's centre).
    vec2 ndc = image_plane_point(vec2(pixel) + 0.5, width, height);
    vec3 d = eye_direction(ndc);
    float tan_half = params.camera_position.w;
    vec3 eye = params.camera_position.xyz;
    bool sees_floor = floor_enabled() && d.y < 0.0 && eye.y > params.floor_plane.x;
    vec3 end = vec3(0.0);
    if (sees_floor) {
        vec3 floor_point = eye + d * ((eye.y - params.floor_plane.x) / -d.y);
        end = floor_radiance(floor_point, d, length(floor_point - eye), float(height));
    } else {
        end = sky(d);
    }

    // Where that direction falls among the traced pixels' samples (their sub-pixel offset included): the
    // traced frame's aspect rounds differently from the viewer's, so by direction, not by pixel ratio.
    uint traced_w = params.image.x, traced_h = params.image.y;
    float traced_aspect = float(traced_w) / float(traced_h);
    vec2 at = vec2((ndc.x / (tan_half * traced_aspect) + 1.0) * 0.5 * float(traced_w),
                   (1.0 - ndc.y / tan_half) * 0.5 * float(traced_h)) - 0.5 - params.refinement.zw;
    at = clamp(at, vec2(0.0), vec2(traced_w - 1u, traced_h - 1u));
    uvec2 lo = uvec2(at);
    uvec2 hi = min(lo + 1u, uvec2(traced_w, traced_h) - 1u);
    vec2 f = at - vec2(lo);
    uint corner[4] = uint[4](lo.y * traced_w + lo.x, lo.y * traced_w + hi.x, hi.y * traced_w + lo.x, hi.y * traced_w + hi.x);
    float weight[4] = float[4]((1.0 - f.x) * (1.0 - f.y), f.x * (1.0 - f.y), (1.0 - f.x) * f.y, f.x * f.y);
    vec3 gathered = vec3(0.0), transmittance = vec3(0.0);
    for (int k = 0; k < 4; ++k) {
        gathered += weight[k] * ends[2u * corner[k]].rgb;
        transmittance += weight[k] * ends[2u * corner[k] + 1u].rgb;
    }
    vec3 radiance = gathered + transmittance * end;
    uint index = pixel.y * width + pixel.x;
    viewer_hdr[index] = vec4(radiance, 0.0);  // no inverse depth: nothing reprojects a viewer's frame
    viewer_ldr[index] = srgb8(radiance, params.tone.x);
}
