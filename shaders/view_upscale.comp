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
layout(std430, binding = TRANSPORT_BINDING_FLOOR_MAP) readonly buffer FloorMap { uvec2 floor_map[]; };
layout(std430, binding = TRANSPORT_BINDING_HDR) readonly buffer Hdr { vec4 hdr[]; };  // the traced frame
layout(std430, binding = TRANSPORT_BINDING_VIEW_ENDS) readonly buffer Ends { ViewEnd ends[]; };
layout(std430, binding = TRANSPORT_BINDING_VIEWER_HDR) writeonly buffer ViewerHdr { vec4 viewer_hdr[]; };
layout(std430, binding = TRANSPORT_BINDING_VIEWER_LDR) writeonly buffer ViewerLdr { uint viewer_ldr[]; };
layout(std430, binding = TRANSPORT_BINDING_STILL_ENDS) readonly buffer StillEnds { ViewEnd still_ends[]; };
layout(push_constant) uniform Push { UpscalePush push; };
// How many of the traced pixels a subgroup's viewer pixels fall between each lane loads and hands to the
// others (upscale_shared_loads in transport.h): one or two loads a lane instead of four, where loads are
// most of the pass (lavapipe loads a lane at a time); 0: each lane loads its own four.
layout(constant_id = UPSCALE_CONSTANT_SHARED_LOADS) const uint kSharedLoads = 0u;
// A light drag's frames: each viewer pixel's own eye ray is the still frame's before it
// (TRANSPORT_BINDING_STILL_ENDS), and the traced pixels give only the light gathered before its end.
layout(constant_id = UPSCALE_CONSTANT_STILL_ENDS) const bool kStillEnds = false;
// The frame has one light (most scenes): the floor's light reads it by a constant index.
layout(constant_id = UPSCALE_CONSTANT_ONE_LIGHT) const bool kOneLight = false;
#define EYE_RAY_ENDS_ONE_LIGHT
#include "eye_ray_ends.glsl"

// One edge of a bent leg's footprint on the floor: how its landing moves when its start moves by `change`
// and its direction turns by `turn` (to first order), `scale` of that, at most `longest` long.
vec3 leg_edge(vec3 change, vec3 turn, vec3 toward, float to_plane, float scale, float longest) {
    float change_to_plane = (change.y + to_plane * turn.y) / -toward.y;
    vec3 e = scale * (change + to_plane * turn + change_to_plane * toward);
    return e * min(1.0, longest / max(length(e), 1e-30));
}

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
            // Unpacked once a lane, not a corner; the still's ends have their own legs.
            vec3 loaded_direction = kStillEnds ? vec3(0.0) : unpack_direction(loaded.leg_direction);
            for (int k = 0; k < 4; ++k) {
                uint entry = (at_corner[k].y - origin.y) * columns + (at_corner[k].x - origin.x);
                uint lane = entry % gl_SubgroupSize;
                // With the still's ends, only what was gathered before the end and how it ended.
                vec3 through = kStillEnds ? vec3(0.0) : subgroupShuffle(loaded.through, lane);
                vec3 leg_start = kStillEnds ? vec3(0.0) : subgroupShuffle(loaded.leg_start.xyz, lane);
                vec3 gathered = subgroupShuffle(loaded.gathered, lane);
                uint kind = subgroupShuffle(loaded.kind, lane);
                ViewEnd handed = ViewEnd(gathered, kind, through, 0u, vec4(leg_start, 0.0));
                vec3 handed_light = subgroupShuffle(loaded_light, lane);
                vec3 handed_direction = kStillEnds ? vec3(0.0) : subgroupShuffle(loaded_direction, lane);
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
            directions[k] = kStillEnds ? vec3(0.0) : unpack_direction(corners[k].leg_direction);
        }
    }
    // The bent legs around the pixel took one way through the glass when all four are bent and start
    // within reach of their interpolation: the pixel's own leg is then their interpolation, and it meets
    // the floor or the sky as its own (so the horizon seen through the glass is the viewer's pixels', too).
    // Their directions may differ as much as they do: near the rim of a ball lens neighbouring legs turn
    // fast, and following them there came closer to the still than the traced light (docs/interactive.md).
    // With the still's ends (kStillEnds) the pixel's own end is the still's instead, where one of the
    // traced pixels around it ended as it did: its own ray or last leg, and the transmittance to it, so
    // the object's outline and what the glass shows are the still's, at the viewer's size; the traced
    // pixels that ended alike give the light gathered before it.
    uint index = pixel.y * width + pixel.x;
    vec3 from = eye, toward = d;
    bool follows_leg = false, own_end = false;
    vec3 start = vec3(0.0), leg = vec3(0.0);
    ViewEnd own;
    vec3 own_gathered = vec3(0.0);
    float own_weight = 0.0;
    if (kStillEnds) {
        own = still_ends[index];
        for (int k = 0; k < 4; ++k) {
            bool alike = corners[k].kind == own.kind;
            own_gathered += alike ? weight[k] * corners[k].gathered : vec3(0.0);
            own_weight += alike ? weight[k] : 0.0;
        }
        own_end = own.kind != VIEW_END_GATHERED && own_weight > 0.0;
        follows_leg = own_end && own.kind == VIEW_END_BENT;
        start = own.leg_start.xyz;
        leg = unpack_direction(own.leg_direction);
    } else {
        bool all_bent = true;
        for (int k = 0; k < 4; ++k) {
            all_bent = all_bent && corners[k].kind == VIEW_END_BENT;
            start += weight[k] * corners[k].leg_start.xyz;
            leg += weight[k] * directions[k];
        }
        leg = normalize(leg);
        float reach = leg_reach(start, params.camera_position, traced_h);
        follows_leg = all_bent;
        for (int k = 0; k < 4; ++k) {
            vec3 apart = corners[k].leg_start.xyz - start;
            follows_leg = follows_leg && dot(apart, apart) <= reach * reach;
        }
    }
    if (follows_leg) {
        from = start;
        toward = leg;
    }

    // The end the pixel sees, its own straight ray's or its bent leg's: one floor lookup either way. A
    // leg's footprint on the floor is the change of its landing across the traced pixels (to first order
    // in the four legs' starts and directions), scaled to the viewer's pixel, or across the still's
    // pixels beside it that took the same way through the glass, each edge at most 16 cones long (as the
    // viewing pass bounds a bent ray's).
    bool sees_floor = floor_enabled() && toward.y < 0.0 && from.y > params.floor_plane.x;
    float to_plane = (from.y - params.floor_plane.x) / -toward.y;
    vec3 floor_point = from + toward * to_plane;
    float distance_to_floor = length(floor_point - eye);
    vec3 along, across;
    vec2 checker_width;
    cone_footprint(normalize(floor_point - eye), distance_to_floor, float(height), along, across,
                   checker_width);
    if (follows_leg && sees_floor) {
        float longest = 16.0 * length(along);
        vec3 edge[2];
        if (kStillEnds) {
            uvec2 next = min(pixel + 1u, uvec2(width, height) - 1u);
            ViewEnd beside[2] =
                ViewEnd[2](still_ends[pixel.y * width + next.x], still_ends[next.y * width + pixel.x]);
            bool apart_pixels[2] = bool[2](next.x > pixel.x, next.y > pixel.y);
            float reach = leg_reach(start, params.camera_position, height);
            edge = vec3[2](along, across);
            for (int axis = 0; axis < 2; ++axis) {
                vec3 apart = beside[axis].leg_start.xyz - start;
                bool alike = apart_pixels[axis] && beside[axis].kind == VIEW_END_BENT;
                vec3 turn = unpack_direction(beside[axis].leg_direction) - leg;
                if (alike && dot(apart, apart) <= reach * reach)
                    edge[axis] = leg_edge(apart, turn, toward, to_plane, 1.0, longest);
            }
        } else {
            float scale = float(traced_w) / float(width);
            vec3 s0 = corners[0].leg_start.xyz, s1 = corners[1].leg_start.xyz, s2 = corners[2].leg_start.xyz,
                 s3 = corners[3].leg_start.xyz;
            vec3 changes[2] = vec3[2](0.5 * (s1 - s0 + s3 - s2), 0.5 * (s2 - s0 + s3 - s1));
            vec3 turns[2] = vec3[2](0.5 * (directions[1] - directions[0] + directions[3] - directions[2]),
                                    0.5 * (directions[2] - directions[0] + directions[3] - directions[1]));
            for (int axis = 0; axis < 2; ++axis)
                edge[axis] = leg_edge(changes[axis], turns[axis], toward, to_plane, scale, longest);
            edge[0] = hi.x > lo.x ? edge[0] : along;
            edge[1] = hi.y > lo.y ? edge[1] : across;
        }
        along = edge[0];
        across = edge[1];
        checker_width = sqrt(along.xz * along.xz + across.xz * across.xz) / params.floor_plane.y;
    }
    vec3 end = sees_floor ? floor_radiance_over(floor_point, along, across, checker_width) : sky(toward);

    vec3 radiance = vec3(0.0);
    if (kStillEnds) {
        if (own_end) radiance = own_gathered / own_weight + own.through * end;
        else for (int k = 0; k < 4; ++k) radiance += weight[k] * traced[k];
    } else {
        for (int k = 0; k < 4; ++k) {
            bool ends_as_viewer = corners[k].kind == VIEW_END_STRAIGHT || follows_leg;
            vec3 seen = corners[k].gathered + corners[k].through * end;
            radiance += weight[k] * (ends_as_viewer ? seen : traced[k]);
        }
    }
    if (!inside) return;
    viewer_hdr[index] = vec4(radiance, 0.0);  // no inverse depth: nothing reprojects a viewer's frame
    viewer_ldr[index] = srgb8(radiance, params.tone.x);
}
