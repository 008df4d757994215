#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#extension GL_KHR_shader_subgroup_shuffle : require
// An interactive frame at the viewer's size from a frame traced smaller (mixed resolution, as real-time
// renderers draw fog at a fraction of the screen's size): one thread per pixel of the viewer's image.
// What the traced eye rays gathered along the way (fog, glass, the volumes) and the transmittance to
// their ends change smoothly and are interpolated between the traced pixels; the end itself, the floor
// (its checker, the lit disc's rim, the floor map) or the sky, is found again for each pixel along its
// own straight ray, at the viewer's size. Where the traced rays bent (the object), what they see through
// it is found again along their last legs, interpolated as rays where the four around the pixel took one
// way through the glass: the checker and the horizon seen through the glass are as sharp as past it.
#include "transport_common.glsl"
#include "environment.glsl"
#include "tone_map.glsl"

layout(local_size_x = VIEW_GROUP_SIZE, local_size_y = VIEW_GROUP_SIZE) in;
layout(binding = TRANSPORT_BINDING_FLOOR_MAP) uniform sampler3D floor_map;
layout(std430, binding = TRANSPORT_BINDING_HDR) readonly buffer Hdr { vec4 hdr[]; };  // the traced frame
layout(std430, binding = TRANSPORT_BINDING_VIEW_ENDS) readonly buffer Ends { ViewEnd ends[]; };
layout(std430, binding = TRANSPORT_BINDING_VIEWER_HDR) writeonly buffer ViewerHdr { vec4 viewer_hdr[]; };
layout(std430, binding = TRANSPORT_BINDING_VIEWER_LDR) writeonly buffer ViewerLdr { uint viewer_ldr[]; };
layout(push_constant) uniform Push { UpscalePush push; };
// How many of the traced pixels a subgroup's viewer pixels fall between each lane loads and hands to the
// others (upscale_shared_loads in transport.h): one or two loads a lane instead of four, where loads are
// most of the pass (lavapipe loads a lane at a time); 0: each lane loads its own four.
layout(constant_id = UPSCALE_CONSTANT_SHARED_LOADS) const uint kSharedLoads = 0u;
#include "eye_ray_ends.glsl"

void main() {
    load_params();
    uint width = push.viewer.x, height = push.viewer.y;
    // Lanes past the image's edge stay, to hand on what they load.
    bool inside = gl_GlobalInvocationID.x < width && gl_GlobalInvocationID.y < height;
    uvec2 pixel = min(gl_GlobalInvocationID.xy, uvec2(width, height) - 1u);
    // The pixel's ray, as the viewing pass makes one for an image of this size (at the pixel's centre).
    vec2 ndc = image_plane_point(vec2(pixel) + 0.5, width, height);
    vec3 d = eye_direction(ndc);
    float tan_half = params.camera_position.w;
    vec3 eye = params.camera_position.xyz;
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
    ViewEnd corners[4];
    vec3 traced[4], directions[4];  // the traced light, and the legs' directions unpacked
    if (kSharedLoads > 0u && gl_SubgroupSize >= 8u) {
        // The subgroup's traced pixels, a rectangle of them: lane i loads its i-th, row by row, and the
        // subgroup's size on from it.
        uvec2 origin = uvec2(subgroupMin(lo.x), subgroupMin(lo.y));
        uint columns = subgroupMax(hi.x) - origin.x + 1u;
        uvec2 at_corner[4] = uvec2[4](lo, uvec2(hi.x, lo.y), uvec2(lo.x, hi.y), hi);
        for (uint load = 0u; load < kSharedLoads; ++load) {
            uint i = load * gl_SubgroupSize + gl_SubgroupInvocationID;
            uvec2 mine = min(origin + uvec2(i % columns, i / columns), uvec2(traced_w, traced_h) - 1u);
            ViewEnd loaded = ends[mine.y * traced_w + mine.x];
            vec3 loaded_light = hdr[mine.y * traced_w + mine.x].rgb;
            vec3 loaded_direction = unpack_direction(loaded.leg_direction);  // once a lane, not a corner
            for (int k = 0; k < 4; ++k) {
                uint entry = (at_corner[k].y - origin.y) * columns + (at_corner[k].x - origin.x);
                uint lane = entry % gl_SubgroupSize;
                ViewEnd handed = ViewEnd(subgroupShuffle(loaded.gathered, lane),
                                         subgroupShuffle(loaded.kind, lane),
                                         subgroupShuffle(loaded.through, lane), 0u,
                                         vec4(subgroupShuffle(loaded.leg_start.xyz, lane), 0.0));
                vec3 handed_light = subgroupShuffle(loaded_light, lane);
                vec3 handed_direction = subgroupShuffle(loaded_direction, lane);
                if (entry / gl_SubgroupSize == load) {
                    corners[k] = handed;
                    traced[k] = handed_light;
                    directions[k] = handed_direction;
                }
            }
        }
    } else {
        for (int k = 0; k < 4; ++k) {
            corners[k] = ends[corner[k]];
            traced[k] = hdr[corner[k]].rgb;
            directions[k] = unpack_direction(corners[k].leg_direction);
        }
    }
    // The bent legs around the pixel took one way through the glass when all four are bent and start
    // within reach of their interpolation: the pixel's own leg is then their interpolation, and it meets
    // the floor or the sky as its own (so the horizon seen through the glass is the viewer's pixels', too).
    // Their directions may differ as much as they do: near the rim of a ball lens neighbouring legs turn
    // fast, and following them there came closer to the still than the traced light (docs/interactive.md).
    bool all_bent = true;
    vec3 start = vec3(0.0), leg = vec3(0.0);
    for (int k = 0; k < 4; ++k) {
        all_bent = all_bent && corners[k].kind == VIEW_END_BENT;
        start += weight[k] * corners[k].leg_start.xyz;
        leg += weight[k] * directions[k];
    }
    leg = normalize(leg);
    float reach = leg_reach(start, params.camera_position, traced_h);
    bool follows_leg = all_bent;
    for (int k = 0; k < 4; ++k) {
        vec3 apart = corners[k].leg_start.xyz - start;
        follows_leg = follows_leg && dot(apart, apart) <= reach * reach;
    }

    // The end the pixel sees, its own straight ray's or its bent leg's: one floor lookup either way. A
    // leg's footprint on the floor is the change of its landing across the traced pixels (to first order
    // in the four legs' starts and directions), scaled to the viewer's pixel, each edge at most 16 cones
    // long (as the viewing pass bounds a bent ray's).
    vec3 from = follows_leg ? start : eye, toward = follows_leg ? leg : d;
    bool sees_floor = floor_enabled() && toward.y < 0.0 && from.y > params.floor_plane.x;
    float to_plane = (from.y - params.floor_plane.x) / -toward.y;
    vec3 floor_point = from + toward * to_plane;
    float distance_to_floor = length(floor_point - eye);
    vec3 along, across;
    vec2 checker_width;
    cone_footprint(normalize(floor_point - eye), distance_to_floor, float(height), along, across,
                   checker_width);
    if (follows_leg && sees_floor) {
        float scale = float(traced_w) / float(width);
        vec3 s0 = corners[0].leg_start.xyz, s1 = corners[1].leg_start.xyz, s2 = corners[2].leg_start.xyz,
             s3 = corners[3].leg_start.xyz;
        vec3 changes[2] = vec3[2](0.5 * (s1 - s0 + s3 - s2), 0.5 * (s2 - s0 + s3 - s1));
        vec3 turns[2] = vec3[2](0.5 * (directions[1] - directions[0] + directions[3] - directions[2]),
                                0.5 * (directions[2] - directions[0] + directions[3] - directions[1]));
        float longest = 16.0 * length(along);
        vec3 edge[2];
        for (int axis = 0; axis < 2; ++axis) {
            float change_to_plane = (changes[axis].y + to_plane * turns[axis].y) / -toward.y;
            vec3 e = scale * (changes[axis] + to_plane * turns[axis] + change_to_plane * toward);
            edge[axis] = e * min(1.0, longest / max(length(e), 1e-30));
        }
        along = hi.x > lo.x ? edge[0] : along;
        across = hi.y > lo.y ? edge[1] : across;
        checker_width = sqrt(along.xz * along.xz + across.xz * across.xz) / params.floor_plane.y;
    }
    vec3 end = sees_floor ? floor_radiance_over(floor_point, along, across, checker_width) : sky(toward);

    vec3 radiance = vec3(0.0);
    for (int k = 0; k < 4; ++k) {
        bool own_end = corners[k].kind == VIEW_END_STRAIGHT || follows_leg;
        radiance += weight[k] * (own_end ? corners[k].gathered + corners[k].through * end : traced[k]);
    }
    uint index = pixel.y * width + pixel.x;
    if (!inside) return;
    viewer_hdr[index] = vec4(radiance, 0.0);  // no inverse depth: nothing reprojects a viewer's frame
    viewer_ldr[index] = srgb8(radiance, params.tone.x);
}
