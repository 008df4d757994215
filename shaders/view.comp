#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_shuffle : require
// The viewing pass: one thread per pixel. Eye rays travel straight outside the grid and follow the ray
// equation inside it, gathering single scattering (transmittance x scattering x phase x fluence) from
// the radiance grid, then finish on the floor (lit analytically, plus the photons' floor map of what
// the grid changes: its shadow and caustics) or the environment. Where a ray crosses the object's boundary the
// reflected part is traced too (fresnel.glsl). Output: linear radiance, and in w the inverse depth its
// light comes from (temporal reuse).
#include "transport_common.glsl"
#include "fresnel.glsl"
#include "phase.h"
#include "view_tiles.glsl"
#include "environment.glsl"

layout(local_size_x = VIEW_GROUP_SIZE, local_size_y = VIEW_GROUP_SIZE) in;
layout(binding = TRANSPORT_BINDING_RADIANCE, rgba32f) readonly uniform image3D radiance;
layout(binding = TRANSPORT_BINDING_FLUX, rgba32f) readonly uniform image3D flux;
layout(std430, binding = TRANSPORT_BINDING_FLOOR_MAP) readonly buffer FloorMap { uvec2 floor_map[]; };
layout(std430, binding = TRANSPORT_BINDING_HDR) buffer Hdr { vec4 hdr[]; };
layout(std430, binding = TRANSPORT_BINDING_VIEW_ENDS) writeonly buffer Ends { ViewEnd ends[]; };
layout(std430, binding = TRANSPORT_BINDING_REFINE) readonly buffer Refine {
    WorkListHeader refine;
    uint refine_pixels[];
};
layout(push_constant) uniform Push { ViewPush push; };
#include "eye_ray_ends.glsl"

// Fluence x phase at voxel point x for an eye ray travelling along d: what one unit of scattering
// coefficient sends back along -d. The phase function is centred on the net flux's direction and
// blends towards isotropic as the net flux shortens against the fluence (light from many directions).
// Both are interpolated as sums, so the blend is flux-weighted between voxels.
vec3 in_scattered(vec3 x, vec3 d, uint model, float g) {
    // The radiance grid's voxel v spans index-field voxels [f v, f (v + 1)) (transport.h), so its
    // texture covers f x its dims: more than the index field where a side is not a multiple of f.
    vec3 q = x / (vec3(params.radiance_grid.xyz) * float(params.radiance_grid.w));
    TrilinearCell cell = trilinear_cell(q, imageSize(flux));  // the radiance image's size too
    vec4 net = TRILINEAR_AT(flux, cell);  // xyz: net flux vector, w: fluence (channel mean)
    vec3 fluence = kGreyTransport ? net.w * grey_colour(params.photon_flux)
                                  : TRILINEAR_AT(radiance, cell).rgb;
    float along = length(net.xyz);
    float coherence = min(along / max(net.w, 1e-30), 1.0);
    float cos_theta = dot(net.xyz, -d) / max(along, 1e-30);
    return fluence * mix(phase_isotropic(), phase_value(model, cos_theta, g), coherence);
}

// Beer-Lambert: what extinction `kappa` (per channel, per unit of `len`) lets through over `len`. Under
// grey transport every channel's extinction is the same float, so one exponential serves all three, to
// the bit: lavapipe evaluates each component of a vector's on its own.
vec3 beer_lambert(vec3 kappa, float len) {
    return kGreyTransport ? vec3(exp(-kappa.r * len)) : exp(-kappa * len);
}

// The transmittance-weighted length of a step: the integral of exp(-kappa t) over it.
vec3 transmitted_path(vec3 kappa, float len, vec3 attenuation) {
    // One channel's under grey transport, as beer_lambert.
    if (kGreyTransport) return vec3(kappa.r > 1e-7 ? (1.0 - attenuation.r) / kappa.r : len);
    return mix(vec3(len), (1.0 - attenuation) / kappa, greaterThan(kappa, vec3(1e-7)));
}

// The volumes' residual ratio tracking along an eye ray (residual_ratio): its random stream, and the
// extinction at the last step's midpoint and that step's half length, from which the next step's control
// takes its slope.
struct EyeTrack {
    uint rng;
    vec3 sigma;
    float half_len;  // 0: no step yet on this path
};

// The volumes' transmittance over an eye ray's step of `len` voxels from p along d beyond the Beer-Lambert
// factor of their extinction `sigma` at its midpoint `at`: unbiased for the field whatever the control,
// and the control line through the midpoint takes the slope from the last step's midpoint, so that what
// is left to track is the field's curvature, not its gradient (the midpoint's constant alone left the
// gradient, and its noise showed in the frames), at no fetch beyond the tentative points'. Steps end
// where the field's interpolation cells do (field_step), so that no step straddles a kink of the field.
vec3 eye_ratio(inout EyeTrack track, FieldSample at, vec3 sigma, vec3 p, vec3 d, float len, float h) {
    vec3 slope = track.half_len > 0.0 ? (sigma - track.sigma) / (track.half_len + 0.5 * len) : vec3(0.0);
    track.sigma = sigma;
    track.half_len = 0.5 * len;
    if (at.block.x == MEDIUM_NO_BRICK) return vec3(1.0);
    return residual_ratio(at, p, d, len, sigma, slope, h, false, track.rng);
}

// A reflection an eye ray still has to trace (fresnel.glsl): its transmittance carries the reflectance,
// so everything it gathers is weighted. A faint one (FRESNEL_EYE_TRACED_SHARE) is not marched: it takes
// the floor or sky straight along its direction. Where it starts, not the whole Ray: the field there
// is fetched again when it is traced (the stack's entries are carried through every march step).
struct PendingPath {
    vec3 p;
    vec3 d;
    vec3 transmittance;
    float cutoff;  // see shade
    bool straight;
};
// Paths per pixel: one (one per channel after the white one under dispersion), and with Fresnel up to
// FRESNEL_EYE_REFLECTIONS reflected ones per channel. A channel traces its reflections before the next
// channel starts, and counts its own paths, so it is traced exactly as a frame of its own index would be.
const uint kPathsPerChannel = kFresnel ? 1u + FRESNEL_EYE_REFLECTIONS : 1u;
const uint kPaths = (kDispersive ? 1u : 0u) + (kDispersive ? 3u : 1u) * kPathsPerChannel;

// The footprint on the floor of a pixel whose path bent before it got there (glass magnifies or shrinks
// the floor it shows, and a reflection's footprint grows at grazing incidence), from where its
// neighbours' rays of the same kind landed: a ray differential by finite differences, as a fragment
// shader's derivatives are differences across a quad. The pixels of a subgroup are a block of the image
// (view_tiles.glsl: lanes 1 and 5 apart hold x neighbours, 2 and 10 apart y neighbours, whatever their
// number); along each axis the nearer landing of the neighbours there counts (one across an edge of what
// the glass shows lands far off). One axis alone gives the other edge as long, at right angles. `along`
// and `across` as cone_footprint's; false where no neighbour lands alike. Every invocation of the path's
// end calls it: it shuffles. Still frames only (params.image.z): the pixels of an interactive frame's
// second round come in the order they were listed, which varies from run to run.
bool neighbour_footprint(bool lands, vec3 x, uint kind, uvec2 pixel, out vec3 along, out vec3 across) {
    uvec4 landing = subgroupBallot(lands);
    uint lane = gl_SubgroupInvocationID;
    vec3 edge[2] = vec3[2](vec3(0.0), vec3(0.0));
    float edge_square[2] = float[2](1e30, 1e30);
    const uint kApart[4] = uint[4](1u, 5u, 2u, 10u);
    for (int k = 0; k < 4; ++k) {
        uint other = lane ^ kApart[k];
        uint id = other < gl_SubgroupSize ? other : lane;
        vec3 other_x = subgroupShuffle(x, id);
        uvec2 other_pixel = subgroupShuffle(pixel, id);
        uint other_kind = subgroupShuffle(kind, id);
        int axis = k / 2;
        ivec2 apart = ivec2(other_pixel) - ivec2(pixel);
        bool neighbour = apart[1 - axis] == 0 && abs(apart[axis]) == 1;
        vec3 difference = other_x - x;
        float square = dot(difference, difference);
        if (lands && id != lane && subgroupBallotBitExtract(landing, id) && other_kind == kind && neighbour &&
            square < edge_square[axis]) {
            edge[axis] = difference;
            edge_square[axis] = square;
        }
    }
    if (edge_square[0] == 1e30 && edge_square[1] == 1e30) return false;
    if (edge_square[0] == 1e30) edge[0] = vec3(edge[1].z, 0.0, -edge[1].x);
    if (edge_square[1] == 1e30) edge[1] = vec3(-edge[0].z, 0.0, edge[0].x);
    along = edge[0];
    across = edge[1];
    return true;
}

// Traces the eye ray of one pixel and writes its HDR and sRGB values. Under dispersive transport the ray
// is one path until its first step that depends on the channel (channel_free), and from the start of that
// step each channel follows its own path, bent by its own index, and brings back its own channel. Where
// a path crosses the object's boundary it goes on with the transmitted share and leaves the reflected one
// for a path of its own.
void shade(uvec2 pixel) {
    uint width = params.image.x, height = params.image.y;
    // Through the sample's point in the pixel.
    vec3 d = eye_direction(image_plane_point(vec2(pixel) + 0.5 + params.refinement.zw, width, height));
    vec3 position = params.camera_position.xyz;  // world, where the straight part of the ray resumes
    bool floor_on = floor_enabled();
    float h = voxel_size();
    float view_step = params.tone.y;

    vec3 p = to_voxel(position);
    vec2 span = grid_interval(p, d);
    float floor_t = to_floor_plane(p, d);
    bool marches = span.x < span.y && span.x < floor_t;
    Ray ray = start_ray(p + d * (marches ? span.x + 1e-3 : 0.0), d);
    vec3 radiance_sum = vec3(0.0);
    vec3 transmittance = vec3(1.0);
    // A path ends once extinction has dimmed it a thousandfold: the share a boundary passes on lowers the
    // bar with it, so no light is cut from a lossless object.
    float cutoff = 1e-3;
    bool on_floor = false;
    uint march_steps = 0u;
    // A last-in, first-out stack whose top is pending[0]: a push or pop shifts the entries by constant
    // indices. Indexed by a count that differs between lanes, lavapipe addressed the array lane by lane on
    // every march step, whichever lanes pushed (a fifth of a still's view in the default scene).
    PendingPath pending[FRESNEL_EYE_REFLECTIONS];
    uint pending_count = 0u;
    uint channel_paths = 1u;  // paths the channel being traced has begun
    // Where the channels part: the ray before that step, the step's length, and the path's state then.
    Ray split_ray = ray;
    float split_run = 0.0, split_cutoff = cutoff;
    vec3 split_transmittance = vec3(1.0);
    bool parted = false;
    uint next_channel = 0u;
    vec3 pixel_radiance = vec3(0.0);
    // The inverse depth the pixel's light comes from, for temporal reuse (temporal_reuse.comp): each
    // run's gathered light and the floor's or sky's weigh 1 / their distance from the eye, as parallax
    // goes; the sky's is 0. Light that comes through or off the object takes the depth of the first
    // place the eye ray bends (its surface): what is seen through glass moves with the glass.
    float light_weight = 0.0, weighted_inverse_depth = 0.0, surface_inverse_depth = -1.0;
    // Where the eye ray ends, for the viewer's size (TRANSPORT_BINDING_VIEW_ENDS): by default all gathered.
    // A straight ray's light before its end and the transmittance to it; a bent one's last leg, from the
    // end of its last shell step (leg_start, voxels).
    vec3 end_front = vec3(0.0), end_transmittance = vec3(0.0);
    uint bent_end = VIEW_END_GATHERED;
    vec3 bent_through = vec3(0.0), bent_start = vec3(0.0), bent_seen = vec3(0.0);
    vec3 bent_direction = vec3(0.0, 1.0, 0.0);  // a unit vector even where unused, for pack_direction
    vec3 leg_start = vec3(0.0);
    // The volumes' residual ratio tracking (eye_ratio): a stream per pixel, sample and photon seed, so
    // refinement averages it as it averages the sub-pixel positions.
    EyeTrack track = EyeTrack(hash(pixel.y * width + pixel.x ^ hash(floatBitsToUint(params.refinement.z) ^ hash(
        floatBitsToUint(params.refinement.w) ^ hash(params.photon_info.y + 9u)))), vec3(0.0), 0.0);
    // What the path being traced is, for neighbour_footprint: 0 the eye's, else which reflection of which
    // channel.
    uint path_kind = 0u;
    // One march and one floor_radiance_over call site for all paths: lavapipe 22.3 runs every call (and its
    // fetches) for every pixel.
    for (uint path = 0u; path < kPaths; ++path) {
        bool split = false;
        if (path > 0u) {
            bool straight = false;
            if (kFresnel && pending_count > 0u) {
                PendingPath next = pending[0];
                pending[0] = pending[1];
                pending[1] = pending[2];
                --pending_count;
                path_kind = (next_channel << 4u) | (1u + pending_count);
                view_step = params.tone.z;
                ray = start_ray(next.p, next.d);
                transmittance = next.transmittance;
                cutoff = next.cutoff;
                ++channel_paths;
                straight = next.straight;
                if (straight) {
                    // The end of the path below looks up the floor or sky from here, as for a ray that
                    // misses the grid, dimmed by the medium it crosses on the way (its glow left out).
                    float crossed = max(min(grid_interval(ray.p, ray.d).y, to_floor_plane(ray.p, ray.d)), 0.0);
                    transmittance *= exp(-params.medium_extinction.rgb * h * medium_depth(ray.p, ray.d, crossed));
                    position = to_world(ray.p);
                    d = ray.d;
                }
            } else if (kDispersive && parted && next_channel < 3u) {
                uint c = next_channel++;
                path_kind = next_channel << 4u;
                ray_contrast = params.dispersion[c];
                view_step = params.tone.y;
                ray = split_ray;
                transmittance = split_transmittance * channel_mask(c);
                cutoff = split_cutoff;
                channel_paths = 1u;
                ray_step(ray, split_run);
            } else {
                break;
            }
            radiance_sum = vec3(0.0);
            track.half_len = 0.0;  // a new path: no slope to take yet
            on_floor = false;
            marches = !straight;
        }
        uint steps = 0u;
        // lavapipe 22.3 runs every line of a loop body for all lanes whatever the branches say, so each fetch
        // appears once: the loop below takes one octree leaf (or shell step) per pass, and the inner
        // loop, which holds the only in-scattering fetches, takes its view steps.
        while (marches && steps < 8192u) {
            float coverage = coverage_for(max(params.flags.y, params.flags.z), ray);
            float scatter_coverage = coverage_as(params.flags.z, coverage);
            float extinction_coverage = coverage_as(params.flags.y, coverage);
            uint object = object_at(ray);
            vec3 sigma_s = scattering_at(scatter_coverage, object) * h;
            vec3 kappa = extinction_at(extinction_coverage, object) * h;
            // Volumes may scatter where the medium does not: the march then gathers wherever light is.
            bool scatters = kMediumField || max(sigma_s.r, max(sigma_s.g, sigma_s.b)) > 0.0;
            uint level = octree_level(ray);
            if (level == 0u && surface_inverse_depth < 0.0)
                surface_inverse_depth = 1.0 / max(length(to_world(ray.p) - params.camera_position.xyz), 1e-6);
            float to_exit = grid_interval(ray.p, ray.d).y;
            float to_floor = to_floor_plane(ray.p, ray.d);
            float to_end = min(to_exit, to_floor);
            // Refracting shells (level 0) take the photons' shell step, for the same refraction, and
            // gather once over it; fog in a leaf (n constant, the ray straight) gathers every view step
            // to the leaf's end, lit or not (crossing unlit fog in cells of a pyramid of lit cells cost
            // more than the steps it saved: docs/perf-log/2026-12-07-unlit-fog-gathered.md); space that
            // does not scatter is crossed to the leaf's end in one step. No leaf step is shorter than
            // the shell step, and none longer than the leaf, so coarse view steps never step over a
            // shell.
            float shell_step = shell_step_for(ray, params.stepping.x);
            float run = min(field_step(ray.p, ray.d, safe_step(level, ray.p, ray.d, shell_step)), to_end);
            if (scatters) {
                uint model = phase_model_at(scatter_coverage, object);
                float g = phase_g_at(scatter_coverage, object);
                float gather_step = level == 0u ? run : view_step;
                vec3 step_attenuation = beer_lambert(kappa, gather_step);
                vec3 step_path = transmitted_path(kappa, gather_step, step_attenuation);
                float t = 0.0;
                vec3 gathered_before = radiance_sum;
                // The medium's density at a view step's midpoint stands for the step (medium.fade): a
                // view step is one to three voxels, under a quarter of the default fade.
                while (t < run) {
                    float len = min(gather_step, run - t);
                    vec3 x = ray.p + (t + 0.5 * len) * ray.d;
                    float density = medium_density(x);
                    bool whole = !kMediumField && len == gather_step && density == 1.0;
                    vec3 kappa_here = thinned(kappa, params.medium_extinction.rgb * h, extinction_coverage, density);
                    FieldSample at = field_at(x);
                    vec4 field_s = field_scattering(at);
                    vec3 field_sigma = field_extinction(at);
                    if (kMediumField) kappa_here += field_sigma * h;
                    vec3 attenuation = whole ? step_attenuation : beer_lambert(kappa_here, len);
                    vec3 path_length = whole ? step_path : transmitted_path(kappa_here, len, attenuation);
                    vec3 sigma_here = thinned(sigma_s, params.medium_scattering.rgb * h, scatter_coverage, density);
                    radiance_sum += transmittance * sigma_here * path_length * in_scattered(x, ray.d, model, g);
                    if (kMediumField) {
                        // The volumes' share, by their own (Henyey-Greenstein) phase function.
                        float field_mean = (field_s.r + field_s.g + field_s.b) * (1.0 / 3.0);
                        float field_g = field_mean > 0.0 ? clamp(field_s.a / field_mean, -0.99, 0.99) : 0.0;
                        radiance_sum += transmittance * field_s.rgb * h * path_length * in_scattered(x, ray.d, PHASE_HG_ID, field_g);
                    }
                    if (field_emits()) radiance_sum += transmittance * field_emission(at) * h * path_length;
                    transmittance *= attenuation;
                    if (kMediumField) transmittance *= eye_ratio(track, at, field_sigma, ray.p + t * ray.d, ray.d, len, h);
                    t += len;
                    ++steps;
                }
                run = t;
                vec3 gathered = radiance_sum - gathered_before;
                float share = (gathered.r + gathered.g + gathered.b) * (1.0 / 3.0);
                light_weight += share;
                weighted_inverse_depth += share * (surface_inverse_depth >= 0.0 ? surface_inverse_depth
                    : 1.0 / max(length(to_world(ray.p + (0.5 * run) * ray.d) - params.camera_position.xyz), 1e-6));
            } else {
                // Space that does not scatter, crossed in one step: never where volumes lie (kMediumField
                // scatters everywhere), so only the medium and the object dim it.
                float density = run > 0.0 ? medium_depth(ray.p, ray.d, run) / run : 1.0;
                vec3 kappa_run = thinned(kappa, params.medium_extinction.rgb * h, extinction_coverage, density);
                transmittance *= beer_lambert(kappa_run, run);
                ++steps;
            }
            if (run >= to_end) {
                ray.p += ray.d * run;
                on_floor = to_floor <= to_exit;
                break;
            }
            Ray before = ray;
            ray_step(ray, run);
            if (kDispersive && path == 0u && !(channel_free(before.field) && channel_free(ray.field))) {
                // What this step gathered lay on its straight start, the same in every channel.
                split = true;
                parted = true;
                split_ray = before;
                split_run = run;
                split_transmittance = transmittance;
                split_cutoff = cutoff;
                break;
            }
            if (kFresnel) {
                vec3 reflected;
                vec3 reflectance = shell_reflectance(before, ray, reflected);
                float mean_reflectance = (reflectance.r + reflectance.g + reflectance.b) * (1.0 / 3.0);
                Ray mirrored = Ray(before.p, reflected, before.field, before.cell);
                vec3 reflected_share = transmittance * reflectance;
                // The reflection gets a path of its own unless the pixel has traced all it may or the share
                // is too small to see (the march's own cut-off below); then the ray takes all of the light
                // to the stronger side, so none is lost (a white furnace stays white).
                float strongest_share = max(reflected_share.r, max(reflected_share.g, reflected_share.b));
                if (channel_paths + pending_count < kPathsPerChannel && strongest_share >= 1e-3) {
                    pending[2] = pending[1];
                    pending[1] = pending[0];
                    pending[0] = PendingPath(before.p, reflected, reflected_share, cutoff * mean_reflectance,
                                             strongest_share < params.tone.w);
                    ++pending_count;
                    transmittance *= 1.0 - reflectance;
                    cutoff *= 1.0 - mean_reflectance;
                } else if (mean_reflectance > 0.5) {
                    ray = mirrored;
                }
            }
            if (level == 0u) leg_start = ray.p;
            if (max(transmittance.r, max(transmittance.g, transmittance.b)) < cutoff) {
                transmittance = vec3(0.0);
                break;
            }
        }
        march_steps += steps;
        pixel_radiance += radiance_sum;
        if (split) continue;
        vec3 end = marches ? to_world(ray.p) : position;
        vec3 end_d = marches ? ray.d : d;
        // A path that never met a refracting shell went straight from the eye: its end is where the
        // pixel's own direction meets the floor or the sky, which view_upscale.comp finds again at the
        // viewer's size.
        if (path == 0u && surface_inverse_depth < 0.0) {
            end_front = pixel_radiance;
            end_transmittance = transmittance;
        }
        if (any(greaterThan(transmittance, vec3(0.0)))) {
            // A ray that left the grid through its bottom face where the floor lies in that face ends on
            // the floor, whichever of the two the march's rounding found first.
            bool sees_floor = on_floor || (floor_on && end_d.y < 0.0 && end.y > params.floor_plane.x - 1e-3 * h);
            vec3 floor_point = on_floor ? end : end + end_d * ((end.y - params.floor_plane.x) / -end_d.y);
            float floor_distance = length(floor_point - params.camera_position.xyz);
            vec3 along, across;
            vec2 checker_width;
            cone_footprint(end_d, floor_distance, float(params.image.y), along, across, checker_width);
            // A path that bent takes its footprint from its neighbours' landings instead, each edge at most 16
            // times the cone's longer one: a neighbour farther off took another way through the glass (both
            // neighbours on an axis can), and the spot's rim filter would light the floor far outside its cone.
            bool bent = path_kind != 0u || surface_inverse_depth >= 0.0;
            float reach = 16.0 * length(along);
            vec3 a, b;
            if (neighbour_footprint(params.image.z != 0u && sees_floor && bent, floor_point, path_kind, pixel, a, b)) {
                along = a * min(1.0, reach / max(length(a), 1e-30));
                across = b * min(1.0, reach / max(length(b), 1e-30));
                checker_width = sqrt(along.xz * along.xz + across.xz * across.xz) / params.floor_plane.y;
            }
            vec3 seen = transmittance * (sees_floor ? floor_radiance_over(floor_point, along, across, checker_width) : sky(end_d));
            pixel_radiance += seen;
            if (path == 0u && surface_inverse_depth >= 0.0) {
                bent_end = VIEW_END_BENT;
                bent_through = transmittance;
                bent_start = to_world(leg_start);
                bent_direction = end_d;
                bent_seen = seen;
            }
            float share = (seen.r + seen.g + seen.b) * (1.0 / 3.0);
            light_weight += share;
            weighted_inverse_depth += share * (surface_inverse_depth >= 0.0 ? surface_inverse_depth
                                               : sees_floor ? 1.0 / max(floor_distance, 1e-6) : 0.0);
        }
    }
    atomicAdd(stats.view_steps, march_steps);
    uint index = pixel.y * width + pixel.x;
    // Refinement samples keep the frame the running mean of every sample so far (a box filter).
    float weight = params.refinement.y;
    float inverse_depth = light_weight > 0.0 ? weighted_inverse_depth / light_weight : 0.0;
    hdr[index] = weight < 1.0 ? mix(hdr[index], vec4(pixel_radiance, inverse_depth), weight) : vec4(pixel_radiance, inverse_depth);
    if (push.ends != 0u) {
        ViewEnd end;
        end.kind = any(greaterThan(end_transmittance, vec3(0.0))) ? VIEW_END_STRAIGHT : bent_end;
        bool straight = end.kind == VIEW_END_STRAIGHT;
        end.gathered = straight ? end_front : pixel_radiance - bent_seen;
        end.through = straight ? end_transmittance : bent_through;
        end.leg_direction = pack_direction(bent_direction);
        end.leg_start = vec4(bent_start, 0.0);
        ends[index] = end;
    }
}

// The queue runs through the image (or its coarse pixels) tile by tile (view_tiles.glsl). Listed pixels
// come in the order view_refine.comp listed them, which keeps a subgroup's neighbours together.
void main() {
    load_params();
    bool listed = push.pixels == VIEW_PIXELS_LISTED;
    uint job = take_from_queue(listed ? QUEUE_VIEW_REFINED : QUEUE_VIEW_PIXELS);
    uint stride = push.pixels == VIEW_PIXELS_COARSE ? 2u : 1u;
    uvec2 extent = (params.image.xy + (stride - 1u)) / stride;  // the pixels this dispatch walks
    uint tiles_x = (extent.x + (VIEW_GROUP_SIZE - 1u)) / VIEW_GROUP_SIZE;
    uint tile = job / (VIEW_GROUP_SIZE * VIEW_GROUP_SIZE), within = job % (VIEW_GROUP_SIZE * VIEW_GROUP_SIZE);
    uvec2 walked = tile_pixel(uvec2(tile % tiles_x, tile / tiles_x), within);
    uvec2 pixel = walked * stride;
    bool valid = all(lessThan(walked, extent));
    if (listed) {
        valid = job < refine.count;
        uint index = refine_pixels[min(job, refine.count - 1u)];
        pixel = uvec2(index % params.image.x, index / params.image.x);
    }
    if (valid) shade(pixel);
}
