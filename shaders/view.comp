#version 460
#extension GL_GOOGLE_include_directive : require
// The viewing pass: one thread per pixel. Eye rays travel straight outside the grid and follow the ray
// equation inside it, gathering single scattering (transmittance x scattering x phase x fluence) from
// the radiance grid, then finish on the floor (lit analytically, plus the photons' floor map of what
// the grid changes: its shadow and caustics) or the sky. Output: linear radiance and a tone-mapped sRGB pixel.
#include "transport_common.glsl"
#include "phase.h"

layout(local_size_x = VIEW_GROUP_SIZE, local_size_y = VIEW_GROUP_SIZE) in;
layout(binding = TRANSPORT_BINDING_RADIANCE) uniform sampler3D radiance;
layout(binding = TRANSPORT_BINDING_DIRECTION) uniform sampler3D light_direction;
layout(binding = TRANSPORT_BINDING_FLOOR_MAP) uniform sampler3D floor_map;
layout(std430, binding = TRANSPORT_BINDING_HDR) writeonly buffer Hdr { vec4 hdr[]; };
layout(std430, binding = TRANSPORT_BINDING_LDR) writeonly buffer Ldr { uint ldr[]; };
layout(std430, binding = TRANSPORT_BINDING_STATS) buffer Stats { PhotonStats stats; };
layout(std430, binding = TRANSPORT_BINDING_LIT_BLOCKS) readonly buffer LitBlocks { uint lit_blocks[]; };

bool block_lit(vec3 p) {
    uvec3 blocks = (params.grid_dims.xyz + LIT_BLOCK - 1u) / LIT_BLOCK;
    uvec3 b = uvec3(clamp(p, vec3(0.0), grid_dims() - 1.0)) / LIT_BLOCK;
    return lit_blocks[(b.z * blocks.y + b.y) * blocks.x + b.x] != 0u;
}

const float kPi = 3.14159265358979;

// Irradiance straight from the light at a floor point (normal +y), without occlusion.
vec3 direct_irradiance(vec3 x) {
    if (params.models.z == LIGHT_DIRECTIONAL)
        return params.light_power.rgb * max(0.0, -params.light_direction.y);
    vec3 l = params.light_position.xyz - x;
    float r2 = dot(l, l);
    vec3 to_light = l / sqrt(r2);
    if (params.models.z == LIGHT_SPOT && dot(-to_light, params.light_direction.xyz) < params.light_position.w)
        return vec3(0.0);
    return params.light_power.rgb * max(0.0, to_light.y) / r2;
}

vec3 floor_radiance(vec3 x) {
    // Unobstructed light plus what the grid changed (shadow, caustics; see photon_trace.comp).
    vec2 m = (x.xz - params.floor_map.xy) / params.floor_map.z;
    vec3 irradiance = direct_irradiance(x);
    if (all(greaterThanEqual(m, vec2(0.0))) && all(lessThanEqual(m, vec2(1.0))))
        irradiance = max(irradiance + textureLod(floor_map, vec3(m, 0.5), 0.0).rgb, vec3(0.0));
    vec3 albedo = params.floor_albedo.rgb;
    if (params.floor_plane.w > 0.5) {
        ivec2 cell = ivec2(floor(x.xz / params.floor_plane.y));
        if (((cell.x + cell.y) & 1) != 0) albedo *= 0.35;
    }
    return albedo * (1.0 / kPi) * irradiance;
}

vec3 sky(vec3 d) { return mix(params.sky_horizon.rgb, params.sky_zenith.rgb, clamp(d.y, 0.0, 1.0)); }

// Narkowicz's fit of the ACES filmic curve, then the sRGB transfer function.
vec3 tone_map(vec3 x) {
    x = clamp((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14), 0.0, 1.0);
    return mix(12.92 * x, 1.055 * pow(x, vec3(1.0 / 2.4)) - 0.055, greaterThan(x, vec3(0.0031308)));
}

void main() {
    uvec2 pixel = gl_GlobalInvocationID.xy;
    uint width = params.image.x, height = params.image.y;
    if (pixel.x >= width || pixel.y >= height) return;
    float tan_half = params.camera_position.w;
    float aspect = float(width) / float(height);
    vec2 ndc = vec2((2.0 * (float(pixel.x) + 0.5) / float(width) - 1.0) * aspect,
                    1.0 - 2.0 * (float(pixel.y) + 0.5) / float(height)) * tan_half;
    vec3 d = normalize(params.camera_forward.xyz + ndc.x * params.camera_right.xyz + ndc.y * params.camera_up.xyz);
    vec3 position = params.camera_position.xyz;  // world, where the straight part of the ray resumes

    vec3 radiance_sum = vec3(0.0);
    vec3 transmittance = vec3(1.0);
    bool on_floor = false;
    bool floor_on = floor_enabled();
    float h = voxel_size();

    vec3 p = to_voxel(position);
    vec2 span = grid_interval(p, d);
    float floor_y = floor_height_voxels();
    float floor_t = (floor_on && d.y < 0.0) ? (p.y - floor_y) / -d.y : 1e30;
    uint march_steps = 0u;
    if (span.x < span.y && span.x < floor_t) {
        p += d * (span.x + 1e-3);
        Ray ray = start_ray(p, d);
        float view_step = params.tone.y;
        for (; march_steps < 8192u; ++march_steps) {
            float n = ray.field.x;
            float scatter_coverage = coverage_for(params.flags.z, ray.p, n);
            vec3 sigma_s = scattering_at(scatter_coverage) * h;
            vec3 kappa = extinction_at(coverage_for(params.flags.y, ray.p, n)) * h;
            bool scatters = max(sigma_s.r, max(sigma_s.g, sigma_s.b)) > 0.0;
            uint level = octree_level(ray.p);
            // Unlit fog where n is constant: nothing to gather, cross the whole block at once.
            if (scatters && level > 0u && !block_lit(ray.p)) scatters = false;
            // Refracting shells (octree level 0) take the photons' shell step, for the same refraction;
            // homogeneous fog takes the view step, which only samples the in-scattering.
            float ds = scatters ? (level == 0u ? params.stepping.x : view_step)
                                : min(safe_step(level, ray.p, ray.d, view_step),
                                      level > 0u && max(sigma_s.r, max(sigma_s.g, sigma_s.b)) > 0.0
                                          ? max(cell_exit(ray.p, ray.d, float(LIT_BLOCK)) + params.stepping.y, view_step)
                                          : 1e30);
            float to_exit = grid_interval(ray.p, ray.d).y;
            bool hits_floor = floor_on && ray.d.y < 0.0 && ray.p.y + ds * ray.d.y <= floor_y;
            float to_floor = hits_floor ? (ray.p.y - floor_y) / -ray.d.y : 1e30;
            float len = min(ds, min(to_exit, to_floor));
            vec3 attenuation = exp(-kappa * len);
            if (scatters) {
                vec3 q = (ray.p + 0.5 * len * ray.d) / grid_dims();
                vec3 fluence = textureLod(radiance, q, 0.0).rgb;
                vec4 light_dir = textureLod(light_direction, q, 0.0);
                bool in_object = scatter_coverage > 0.5;
                uint model = in_object ? params.models.y : params.models.x;
                float g = in_object ? params.object_scattering.w : params.medium_scattering.w;
                // Where photons arrive from many directions the mean direction is short: blend towards
                // isotropic by its length (coherence).
                float coherence = clamp(light_dir.w, 0.0, 1.0);
                float cos_theta = dot(light_dir.xyz / max(length(light_dir.xyz), 1e-6), -ray.d);
                float phase = mix(phase_isotropic(), phase_value(model, cos_theta, g), coherence);
                // The step's transmittance-weighted length: integral of exp(-kappa t) over the step.
                vec3 path = mix(vec3(len), (1.0 - attenuation) / kappa, greaterThan(kappa, vec3(1e-7)));
                radiance_sum += transmittance * sigma_s * phase * fluence * path;
            }
            transmittance *= attenuation;
            if (to_floor <= min(ds, to_exit)) {
                ray.p += ray.d * to_floor;
                on_floor = true;
                break;
            }
            if (to_exit <= ds) {
                ray.p += ray.d * to_exit;
                break;
            }
            // In fog the march takes short steps for the in-scattering sum; inside an octree leaf n is
            // constant to epsilon, so those steps go straight without fetching the field again.
            if (level > 0u && scatters) ray.p += ds * ray.d;
            else ray_step(ray, ds);
            if (max(transmittance.r, max(transmittance.g, transmittance.b)) < 1e-3) {
                transmittance = vec3(0.0);
                break;
            }
        }
        p = ray.p;
        d = ray.d;
        position = to_world(p);
    }
    if (any(greaterThan(transmittance, vec3(0.0)))) {
        vec3 background;
        if (on_floor) {
            background = floor_radiance(position);
        } else if (floor_on && d.y < 0.0 && position.y > params.floor_plane.x) {
            background = floor_radiance(position + d * ((position.y - params.floor_plane.x) / -d.y));
        } else {
            background = sky(d);
        }
        radiance_sum += transmittance * background;
    }
    atomicAdd(stats.view_steps, march_steps);
    uint index = pixel.y * width + pixel.x;
    hdr[index] = vec4(radiance_sum, 1.0);
    vec3 srgb = tone_map(radiance_sum * params.tone.x);
    uvec3 bytes = uvec3(clamp(srgb, 0.0, 1.0) * 255.0 + 0.5);
    ldr[index] = bytes.r | (bytes.g << 8u) | (bytes.b << 16u) | (255u << 24u);
}
