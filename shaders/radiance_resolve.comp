#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
// Turns the photon pass's fixed-point sums into physical units for the viewing pass:
// fluence rate (W/m^2) = sum(flux x path length) / voxel volume, the net flux vector the same way from
// the direction-weighted sums (its length over the fluence is how much the light has one direction),
// and floor irradiance (W/m^2) = sum(flux) / texel area. Independent of photon count and grid resolution.
#include "transport.h"
layout(local_size_x = TRANSPORT_GROUP_SIZE) in;
#include "linear_id.glsl"

layout(std140, binding = TRANSPORT_BINDING_PARAMS) readonly buffer Params { TransportParams params; };
#include "radiance_sums.glsl"
layout(std430, binding = TRANSPORT_BINDING_ACCUM_FLOOR) readonly buffer AccumFloor { uint accum_floor[]; };
layout(binding = TRANSPORT_BINDING_RADIANCE, rgba32f) uniform image3D radiance;
layout(binding = TRANSPORT_BINDING_FLUX, rgba32f) uniform image3D flux;
layout(std430, binding = TRANSPORT_BINDING_FLOOR_MAP) buffer FloorMap { uvec2 floor_map[]; };

// A refinement batch joins the running mean of the batches before it (refinement.x = 1/batches); the
// first replaces whatever the images held. Each light after the first adds its share of the batch.
vec4 batch_mean(vec4 before, vec4 batch) {
    float weight = params.refinement.x;
    if (params.light_set.y > 0u) return before + weight * batch;
    return weight < 1.0 ? mix(before, batch, weight) : batch;
}

layout(constant_id = RESOLVE_CONSTANT_FLOOR) const bool kFloorMap = false;
layout(std430, binding = TRANSPORT_BINDING_FLOOR_SHADOW) readonly buffer FloorShadow { vec4 floor_shadow_taken[]; };
// 1: the last light's resolve of a frame whose floor map is not spread after (transport.h,
// DIRECT_MODE_FLOOR_SHADOW): the floor shadow's closed form, every light's, joins this batch.
layout(push_constant) uniform Push { uint add_floor_shadow; };

void resolve_voxel(uint i) {
    uvec3 dims = params.radiance_grid.xyz;
    if (i >= dims.x * dims.y * dims.z) return;
    float reference_flux = params.photon_flux.w;
    ivec3 v = ivec3(i % dims.x, (i / dims.x) % dims.y, i / (dims.x * dims.y));
    float h = params.grid_origin.w * float(params.radiance_grid.w);  // a radiance voxel's side
    // sum is in photon-voxel-lengths x scale; flux x length / volume = sum / scale x flux x h / h^3.
    // On a side that is not a multiple of f the last radiance voxel reaches past the grid, where
    // photons never go: its fluence is per the volume it has inside.
    uint f = params.radiance_grid.w;
    uvec3 inside = min(uvec3(f), params.grid_dims.xyz - f * uvec3(v));
    float inside_fraction = float(inside.x * inside.y * inside.z) / float(f * f * f);
    float to_fluence = reference_flux / (params.stepping.z * h * h * inside_fraction);
    // Unpack (transport.h): the low half of each word is its own sum (unsigned, so the high half is
    // what an arithmetic shift leaves). Unbent photons carry their flux along the light's direction.
    uint64_t unbent = accum_flux.words[RADIANCE_FLUX_WORDS * i];
    float blue = float(uint(unbent & 0xffffffffUL));
    vec3 centre = params.grid_origin.xyz + (vec3(v) + 0.5) * h;
    vec3 net = float(uint(unbent >> 32)) *
               unbent_direction(params.models.z, params.light_position.xyz, params.emit_axis.xyz, centre);
    for (uint a = 0u; a < 3u; ++a) {
        uint64_t word = accum_flux.words[RADIANCE_FLUX_WORDS * i + 1u + a];
        blue += float(uint(word & 0xffffffffUL));
        net[a] += float(int(int64_t(word) >> 32));
    }
    float mean = blue;  // grey transport: the blue slot holds the channels' mean
    if (!kGreyTransport) {
        uint64_t rg = accum_rg.words[i];
        vec3 colour = vec3(float(uint(rg & 0xffffffffUL)), float(uint(rg >> 32)), blue);
        mean = (colour.r + colour.g + colour.b) * (1.0 / 3.0);
        imageStore(radiance, v, batch_mean(imageLoad(radiance, v), vec4(colour * to_fluence, 0.0)));
    }
    imageStore(flux, v, batch_mean(imageLoad(flux, v), vec4(net * to_fluence, mean * to_fluence)));
}

void resolve_floor_texel(uint texel) {
    float reference_flux = params.photon_flux.w;
    uint side = uint(params.floor_map.w);
    if (texel >= side * side) return;
    float texel_area = (params.floor_map.z / float(side)) * (params.floor_map.z / float(side));
    float to_irradiance = reference_flux / (params.stepping.w * texel_area);
    // Signed sums (two's complement in uint): the grid both removes and adds floor light.
    uint at = FLOOR_WORDS * texel;
    vec3 irradiance = vec3(float(int(accum_floor[at])), float(int(accum_floor[at + 1u])),
                           float(int(accum_floor[at + 2u]))) * to_irradiance;
    if (add_floor_shadow != 0u) irradiance -= floor_shadow_taken[texel].rgb;
    // w: the sum of the photons' squared shares, for the adaptive density estimate (radiance_spread.comp),
    // kept within half-float range.
    float squares = min(float(accum_floor[at + 3u]) * (1.0 / FLOOR_SQUARE_SCALE), 6.0e4);
    vec4 texel_value = batch_mean(floor_map_texel(floor_map[texel]), vec4(irradiance, squares));
    floor_map[texel] = floor_map_words(texel_value);
}

// Two dispatches, one per job (kFloorMap): lavapipe 22.3 would run both jobs' code in every invocation.
void main() {
    reach_radiance_sums(params.radiance_sums);
    if (kFloorMap) resolve_floor_texel(linear_invocation());
    else resolve_voxel(linear_invocation());
}
