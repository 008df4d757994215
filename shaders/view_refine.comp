#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_ballot : require
// Between the two rounds of an interactive frame (transport.h, VIEW_PIXELS_*): every pixel the coarse
// round did not trace sits between two or four traced ones (even x and y). Where those agree to within
// VIEW_REFINE_LEVELS on screen, the pixel takes their mean; where they do not, it is listed for the
// second round, and the list's header counts the groups of that indirect dispatch.
#include "transport.h"
#include "tone_map.glsl"
#include "view_tiles.glsl"
layout(local_size_x = VIEW_REFINE_GROUP_SIZE) in;

layout(std140, binding = TRANSPORT_BINDING_PARAMS) readonly buffer Params { TransportParams params; };
layout(std430, binding = TRANSPORT_BINDING_HDR) buffer Hdr { vec4 hdr[]; };
layout(std430, binding = TRANSPORT_BINDING_REFINE) buffer Refine {
    WorkListHeader refine;
    uint refine_pixels[];
};
layout(std430, binding = TRANSPORT_BINDING_VIEW_ENDS) buffer Ends { ViewEnd ends[]; };
layout(push_constant) uniform Push { uint write_ends; };  // 1: the frame's eye rays' ends are interpolated too

uvec3 bytes_of(uint rgba) { return uvec3(rgba, rgba >> 8u, rgba >> 16u) & 0xffu; }

void main() {
    // One group per tile, walked as the viewing pass walks it, so the pixels a subgroup lists are
    // neighbours and the second round traces them side by side.
    uint width = params.image.x, height = params.image.y;
    uvec2 pixel = tile_pixel(gl_WorkGroupID.xy, gl_LocalInvocationID.x);
    bool inside = pixel.x < width && pixel.y < height;
    bool traced = (pixel.x & 1u) == 0u && (pixel.y & 1u) == 0u;
    // Traced neighbours: the pixel itself along an even axis, the two beside it along an odd one.
    uvec2 odd = pixel & 1u;
    uvec2 lo = pixel - odd, hi = min(pixel + odd, uvec2(width, height) - 1u);
    bool bounded = all(lessThan(pixel + odd, uvec2(width, height)));  // the far neighbour exists
    uint corner[4] = uint[4](lo.y * width + lo.x, lo.y * width + hi.x, hi.y * width + lo.x, hi.y * width + hi.x);
    uvec3 least = uvec3(255u), most = uvec3(0u);
    vec4 sum = vec4(0.0);
    for (int k = 0; k < 4; ++k) {
        uint c = inside ? corner[k] : 0u;
        vec4 radiance = hdr[c];  // w: inverse depth, averaged alike
        uvec3 b = bytes_of(srgb8(radiance.rgb, params.tone.x));
        least = min(least, b);
        most = max(most, b);
        sum += radiance;
    }
    bool agree = bounded && all(lessThanEqual(most - least, uvec3(VIEW_REFINE_LEVELS)));
    uint index = pixel.y * width + pixel.x;
    if (inside && !traced && agree) {
        hdr[index] = 0.25 * sum;
        if (write_ends != 0u) {
            // Ends of one kind (and bent legs that start near each other, the upscale's rule)
            // are interpolated; a pixel between different ends takes the interpolated light, all gathered.
            ViewEnd end = ViewEnd(vec3(0.0), ends[corner[0]].kind, vec3(0.0), 0u, vec4(0.0));
            vec3 leg = vec3(0.0), starts[4];
            for (int k = 0; k < 4; ++k) {
                ViewEnd e = ends[corner[k]];
                end.gathered += 0.25 * e.gathered;
                end.through += 0.25 * e.through;
                starts[k] = e.leg_start.xyz;
                end.leg_start.xyz += 0.25 * starts[k];
                leg += unpack_direction(e.leg_direction);
                if (e.kind != end.kind) end.kind = VIEW_END_GATHERED;
            }
            end.leg_direction = pack_direction(normalize(leg));
            float reach = leg_reach(end.leg_start.xyz, params.camera_position, height);
            for (int k = 0; k < 4; ++k) {
                vec3 apart = starts[k] - end.leg_start.xyz;
                if (end.kind == VIEW_END_BENT && dot(apart, apart) > reach * reach)
                    end.kind = VIEW_END_GATHERED;
            }
            if (end.kind == VIEW_END_GATHERED)
                end = ViewEnd(0.25 * sum.rgb, VIEW_END_GATHERED, vec3(0.0), 0u, vec4(0.0));
            ends[index] = end;
        }
    }
    bool listed = inside && !traced && !agree;
    uvec4 ballot = subgroupBallot(listed);
    uint count = subgroupBallotBitCount(ballot);
    uint first = 0u;
    if (subgroupElect() && count > 0u) {
        first = atomicAdd(refine.count, count);
        uint groups = work_list_groups_begun(first, first + count, VIEW_GROUP_SIZE * VIEW_GROUP_SIZE);
        if (groups > 0u) atomicAdd(refine.groups_x, groups);
    }
    first = subgroupBroadcastFirst(first);
    if (listed) refine_pixels[first + subgroupBallotExclusiveBitCount(ballot)] = index;
}
