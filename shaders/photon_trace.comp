#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#extension GL_EXT_shader_atomic_int64 : require
// Photon generation and tracing (passes 3-5 of Sun et al. 2008), one thread per photon run to
// completion. Photons start where the light's rays enter the grid, follow the ray equation with the
// octree's largest safe step, lose flux to extinction (Beer-Lambert per channel), and add flux x path
// length to every voxel they cross (the track-length estimator of fluence) plus a flux-weighted
// direction, except over the part of their path whose light the direct-light pass stores in closed
// form (transport.h, DIRECT_*). Up to photons.max_bounces times a photon scatters on its way
// (random_walk.glsl), and every order deposits alike. Accumulation is fixed-point integer atomics:
// deterministic on every device.
#include "transport_common.glsl"
#include "emission.glsl"
#include "radiance_sums.glsl"
#include "phase.h"
#include "random_walk.glsl"
#include "fresnel.glsl"
layout(local_size_x = TRANSPORT_GROUP_SIZE) in;
layout(constant_id = PHOTON_CONSTANT_SAMPLED_DEPOSITS) const bool kSampledDeposits = false;
layout(constant_id = PHOTON_CONSTANT_RANDOM_WALKS) const bool kRandomWalks = false;

layout(std430, binding = TRANSPORT_BINDING_ACCUM_FLOOR) buffer AccumFloor { uint accum_floor[]; };
layout(std430, binding = TRANSPORT_BINDING_PHOTON_EXITS) writeonly buffer Exits { PhotonExit exits[]; };
layout(std430, binding = TRANSPORT_BINDING_LIGHT_MAP) readonly buffer LightMap { float light_map[]; };

float to_unit(uint x) { return float(x >> 8u) * (1.0 / 16777216.0); }

// Per-photon random stream for stochastic rounding of fixed-point deposits: rounding up with probability
// equal to the fraction keeps small deposits (dim, attenuated photons) unbiased instead of lost.
uint rng_state;
float next_unit() {
    rng_state = hash(rng_state + 0x9e3779b9u);
    return to_unit(rng_state);
}

// A second stream for the Fresnel choices alone: a photon then reflects at the same boundaries however
// its deposits are made (exact or sampled, with or without direct light), which draw on rng_state.
uint fresnel_rng;
float next_fresnel_unit() {
    fresnel_rng = hash(fresnel_rng + 0x9e3779b9u);
    return to_unit(fresnel_rng);
}

// Stratified 2D sample i of n: a Hammersley point shifted by a seed-dependent rotation.
vec2 stratified(uint i, uint n, uint seed) {
    vec2 shift = vec2(to_unit(hash(seed * 2u + 1u)), to_unit(hash(seed * 2u + 2u)));
    vec2 h = vec2((float(i) + 0.5) / float(n), float(bitfieldReverse(i)) * 2.3283064365386963e-10);
    return fract(h + shift);
}

// Which photon invocation j traces. Neighbouring invocations run side by side in SIMD lanes (8 on
// lavapipe, 32 on NVIDIA), which cost what their slowest lane costs; consecutive Hammersley indices
// jump across the emission square (the second coordinate is the bit-reversed index). For n = 2^k the
// indices that differ only in three middle bits fill one small, nearly square cell of the square (the
// set is a (0,k,2)-net), so each run of 8 invocations gets such a cell: nearby photons, similar paths.
// Other counts (a light's photons only in its part of the emitter: emit_photon_ray) take the order of
// the power of two below them within its whole blocks, which cover all but the last few photons: in the
// plain order, a photon pass over the part took 1.3x the whole emitter's (twice its photons).
uint coherent_order(uint j, uint n) {
    if (n < 8u) return j;
    uint b = (uint(findMSB(n)) - 3u) / 2u;  // low bits of the index: the cell's height
    if (j >= n - n % (8u << b)) return j;   // past the last whole block
    uint low_mask = (1u << b) - 1u;
    return (j & ~((8u << b) - 1u)) | ((j & 7u) << b) | ((j >> 3u) & low_mask);
}

uint voxel_index(ivec3 v) { return (uint(v.z) * params.radiance_grid.y + uint(v.y)) * params.radiance_grid.x + uint(v.x); }

// The photon's deposits into the radiance-grid voxel it is in, summed until it moves on to another:
// consecutive steps often stay in one voxel (a third of all deposits at the interactive radiance
// resolution), and one set of atomics then serves them all. Sums are in fixed-point units, unrounded.
const uint kNoVoxel = 0xffffffffu;
uint pending_voxel = kNoVoxel;
vec3 pending_flux;       // weight x length per channel
vec3 pending_direction;  // direction x the channels' mean
bool pending_unbent;     // every deposit summed came before the photon bent (transport.h)
// A point or spot light in radiance-grid voxels, and the square of the distance from it (in the same
// units) below which a voxel takes no unbent deposits (0 for a directional light).
vec3 light_in_radiance_voxels;
float near_light_squared;

// Adds the pending sums to the radiance grid, stochastically rounded to fixed point: an unbent photon's
// to word 0, a bent one's to the word of one axis, drawn in proportion to that axis's share of
// |direction|_1 (transport.h). One word either way, so lanes of both kinds share one atomic.
void flush_deposit() {
    if (pending_voxel == kNoVoxel) return;
    float jitter = next_unit();
    float mean = (pending_flux.r + pending_flux.g + pending_flux.b) * (1.0 / 3.0);
    ivec3 q = ivec3(pending_flux + jitter);
    vec3 along = abs(pending_direction);
    float l1 = along.x + along.y + along.z;
    float pick = next_unit() * l1;
    uint axis = pick < along.x ? 0u : (pick < along.x + along.y ? 1u : 2u);
    int direction = pending_unbent ? int(mean + jitter) : int(floor(sign(pending_direction[axis]) * l1 + jitter));
    if (!kGreyTransport) atomicAdd(accum_rg.words[pending_voxel], pack(q.r, q.g));
    atomicAdd(accum_flux.words[RADIANCE_FLUX_WORDS * pending_voxel + (pending_unbent ? 0u : 1u + axis)],
              pack(kGreyTransport ? int(mean + jitter) : q.b, direction));
    pending_voxel = kNoVoxel;
}

// Adds deposit w (weight x length) of a photon travelling along d to radiance-grid voxel `cell`: to the
// pending sums while the photon stays in that voxel.
void add_deposit(ivec3 cell, vec3 w, vec3 d, bool photon_unbent) {
    if (any(lessThan(cell, ivec3(0))) || any(greaterThanEqual(cell, ivec3(params.radiance_grid.xyz)))) return;
    uint index = voxel_index(cell);
    vec3 from_light = vec3(cell) + 0.5 - light_in_radiance_voxels;
    bool unbent = photon_unbent && dot(from_light, from_light) >= near_light_squared;
    if (index != pending_voxel || unbent != pending_unbent) {
        flush_deposit();
        pending_voxel = index;
        pending_unbent = unbent;
        pending_flux = vec3(0.0);
        pending_direction = vec3(0.0);
    }
    pending_flux += w;
    pending_direction += d * ((w.r + w.g + w.b) * (1.0 / 3.0));
}

// Where each sampled deposit falls within its piece of a segment: a Weyl sequence over photons and, per
// photon, over segments, from a random start per frame. Every offset is uniform, so each sample is
// unbiased; neighbouring photons' offsets spread evenly, which makes their sum less noisy than
// independent offsets do.
uint deposit_phase;

// Adds weight x length along the straight segment p + t d, t in [0, len) (p, len and kappa in
// radiance-grid voxels), attenuated by exp(-kappa t), to the radiance grid: the track-length estimator
// of fluence. Exact by default: every voxel the segment crosses takes its crossing length (3D DDA),
// attenuated at the crossing's middle where the segment absorbs noticeably, else at the segment's.
// Sampled deposits (kSampledDeposits: every frame refractd renders, still or interactive) cut the
// segment into pieces of at most one voxel and give each piece's whole length to the voxel of one point
// drawn in it: unbiased, since the point is uniform in its piece, and cheaper, with one deposit per voxel
// of path where the DDA makes |d|_1 (up to 1.7) crossings and does more work for each.
void deposit(vec3 p, vec3 d, float len, vec3 weight, vec3 kappa, bool photon_unbent) {
    float scale = params.stepping.z;
    bool absorbs = max(kappa.r, max(kappa.g, kappa.b)) * len > 0.02;
    vec3 segment_weight = weight * exp(-kappa * (0.5 * len)) * scale;
    if (kSampledDeposits) {
        int pieces = max(int(ceil(len)), 1);
        float piece = len / float(pieces);
        float offset = to_unit(deposit_phase);
        deposit_phase += 3242174889u;  // 2^32 / the plastic number: a second, independent Weyl step
        for (int k = 0; k < pieces; ++k) {
            float t = (float(k) + offset) * piece;
            add_deposit(ivec3(floor(p + d * t)), (absorbs ? weight * exp(-kappa * t) * scale : segment_weight) * piece,
                        d, photon_unbent);
        }
        return;
    }
    ivec3 cell = ivec3(floor(p));
    ivec3 step_dir = ivec3(sign(d));
    vec3 inv = 1.0 / d;
    vec3 t_max = mix((vec3(cell) - p) * inv, (vec3(cell + 1) - p) * inv, greaterThan(d, vec3(0.0)));
    t_max = mix(t_max, vec3(1e30), equal(d, vec3(0.0)));
    vec3 t_delta = mix(abs(inv), vec3(1e30), equal(d, vec3(0.0)));
    float t = 0.0;
    for (int guard = 0; guard < 4096 && t < len; ++guard) {
        float t_next = min(min(t_max.x, t_max.y), min(t_max.z, len));
        float piece = t_next - t;
        if (piece > 0.0)
            add_deposit(cell, (absorbs ? weight * exp(-kappa * (t + 0.5 * piece)) * scale : segment_weight) * piece, d,
                        photon_unbent);
        t = t_next;
        if (t_max.x <= t_max.y && t_max.x <= t_max.z) { cell.x += step_dir.x; t_max.x += t_delta.x; }
        else if (t_max.y <= t_max.z) { cell.y += step_dir.y; t_max.y += t_delta.y; }
        else { cell.z += step_dir.z; t_max.z += t_delta.z; }
    }
}

// Splats flux bilinearly into the floor map at world point x, added (sign +1) or taken away (-1). The
// map holds how the grid changes the floor's irradiance: each photon that enters the grid takes its
// flux away from where its straight path from the light would have landed and adds what arrives where
// it actually lands. The viewing pass adds the map to the analytic unobstructed irradiance, so the
// floor has no seam at the edge of the grid's shadow and no photon noise where nothing changed.
void deposit_floor(vec3 x, vec3 weight, int sign) {
    float texels = params.floor_map.w;
    vec2 m = floor_map_coordinates(x);
    if (any(lessThan(m, vec2(-1.0))) || any(greaterThan(m, vec2(texels)))) return;
    ivec2 base = ivec2(floor(m));
    vec2 f = m - vec2(base);
    int side = int(texels);
    for (int k = 0; k < 4; ++k) {
        ivec2 t = base + ivec2(k & 1, k >> 1);
        if (any(lessThan(t, ivec2(0))) || any(greaterThanEqual(t, ivec2(side)))) continue;
        float bw = ((k & 1) == 1 ? f.x : 1.0 - f.x) * ((k >> 1) == 1 ? f.y : 1.0 - f.y);
        ivec3 q = sign * ivec3(weight * bw * params.stepping.w + next_unit());
        uint index = FLOOR_WORDS * uint(t.y * side + t.x);
        if (q.r != 0) atomicAdd(accum_floor[index], uint(q.r));
        if (q.g != 0) atomicAdd(accum_floor[index + 1u], uint(q.g));
        if (q.b != 0) atomicAdd(accum_floor[index + 2u], uint(q.b));
        // The share squared, for how many photons the texel's value stands on (radiance_spread.comp): a
        // shadow's removals cancel hits in the sum, so the sum cannot tell. Rounded to nearest, which
        // draws nothing from the photon's random stream.
        float share = (weight.r + weight.g + weight.b) * (1.0 / 3.0) * bw;
        uint square = uint(share * share * FLOOR_SQUARE_SCALE + 0.5);
        if (square != 0u) atomicAdd(accum_floor[index + 3u], square);
    }
    if (sign > 0) atomicAdd(stats.floor_hits, 1u);
}

// Whether the floor-map cell where world point x splats is flagged as the floor's shadow.
bool floor_shadow_flagged(vec3 x) {
    ivec2 cell = ivec2(floor(floor_map_coordinates(x)));
    int side = int(params.floor_map.w);
    if (any(lessThan(cell, ivec2(0))) || any(greaterThanEqual(cell, ivec2(side)))) return false;
    return accum_floor[FLOOR_WORDS * uint(cell.y * side + cell.x) + FLOOR_SHADOW_WORD] != 0u;
}

// Under dispersive transport (transport.h) a photon sample is one white path until its first step that
// depends on the channel (channel_free), and from the start of that step one path per channel, each
// carrying only its channel. What the white path deposited lay on its steps' straight starts, the same
// in every channel. Without dispersion a photon is one path.
void main() {
    load_params();
    reach_radiance_sums(params.radiance_sums);
    uint count = params.photon_info.x;
    uint job = take_from_queue(QUEUE_PHOTONS);
    if (job >= count) return;
    uint i = coherent_order(job, count);
    vec3 origin, direction;
    vec3 weight;  // relative to the reference flux
    // The last volume_emission.x photons come from the volumes, the environment.z before them from the
    // environment (transport.h), the others from the light.
    uint volume_first = count - params.volume_emission.x;
    uint light_photons = volume_first - params.environment.z;
    bool from_volume = i >= volume_first;
    bool from_environment = i >= light_photons && !from_volume;
    vec2 sample_point, emission_point = vec2(0.0);
    if (from_volume) {
        sample_point = stratified(i - volume_first, params.volume_emission.x, params.photon_info.y);
        uint seed = hash(i ^ hash(params.photon_info.y + 6u));
        vec3 within = vec3(to_unit(hash(seed + 1u)), to_unit(hash(seed + 2u)), to_unit(hash(seed + 3u)));
        emit_volume_ray(sample_point.x, within, vec2(sample_point.y, to_unit(hash(seed + 4u))), origin, direction, weight);
    } else if (from_environment) {
        sample_point = stratified(i - light_photons, params.environment.z, params.photon_info.y);
        vec2 disc = vec2(to_unit(hash(i ^ hash(params.photon_info.y + 3u))), to_unit(hash(i ^ hash(params.photon_info.y + 4u))));
        emit_environment_ray(sample_point, disc, origin, direction, weight);
    } else {
        sample_point = stratified(i, light_photons, params.photon_info.y);
        if (!emit_photon_ray(sample_point, origin, direction, emission_point)) return;
        weight = params.photon_flux.rgb / params.photon_flux.w;
    }
    rng_state = hash(i ^ hash(params.photon_info.y));
    uint fresnel_seed = hash(i ^ hash(params.photon_info.y + 2u));
    // Where shell steps start after a leaf (below), by step number: a channel's path replays its photon's.
    uint step_seed = hash(i ^ hash(params.photon_info.y + 5u));
    deposit_phase = i * 2654435769u + hash(params.photon_info.y + 1u);  // 2^32 / the golden ratio
    uint ratio_rng = hash(i ^ hash(params.photon_info.y + 8u));  // the volumes' residual ratio tracking

    vec3 p = to_voxel(origin);
    vec2 span = grid_interval(p, direction);
    bool floor_on = floor_enabled();
    float floor_y = floor_height_voxels();
    if (span.x >= span.y) {
        // Misses the grid: lands where the analytic irradiance already counts it.
        return;
    }
    float along = span.x + 1e-3;  // voxels from the emitter, while the photon goes straight
    p += direction * along;
    if (floor_on && p.y <= floor_y) return;  // entered the grid below the floor
    atomicAdd(stats.photons_entered, 1u);
    // Light and environment photons take away from the floor what reaches it in closed form; nothing
    // counts a volume's light there but its photons. In the floor's shadow the direct-light pass has
    // taken away what the light's photons would on average (DIRECT_MODE_FLOOR_SHADOW).
    if (floor_on && direction.y < 0.0 && !from_volume) {
        vec3 landing = origin + direction * ((origin.y - params.floor_plane.x) / -direction.y);
        if (from_environment) deposit_floor(landing, weight, -1);
        else if (!floor_shadow_flagged(landing))
            deposit_floor(landing, weight * straight_transmittance(landing), -1);
    }

    Ray ray = start_ray(p, direction);
    vec3 entry = to_world(p);
    float shell_step = params.stepping.x;
    bool fixed_step = params.photon_info.w == 1u;
    bool deposits = params.flags.w == 1u;
    uint steps = 0u;
    float h = voxel_size();
    float radiance_factor = float(params.radiance_grid.w);
    float path_length = 0.0;  // voxels travelled inside the grid
    // Unbent until the photon meets a gradient of n (transport.h); an environment or volume photon
    // never travels along the light's direction.
    bool unbent = !from_environment && !from_volume;
    light_in_radiance_voxels = to_voxel(origin) / radiance_factor;
    near_light_squared = params.models.z == LIGHT_DIRECTIONAL ? 0.0 : UNBENT_MIN_DISTANCE * UNBENT_MIN_DISTANCE;
    // Direct light (transport.h): from `near` to the light map's value the direct-light pass counts this
    // photon's light, so it deposits nothing there, and as the map says its path there is straight
    // through the medium, it crosses that span in one step. Steps before it end where it begins.
    float direct_from = params.direct_light.y;
    float direct_to = params.direct_light.w > 0.5 && !from_environment && !from_volume
                          ? light_map[light_map_texel(emission_point)]
                          : 0.0;
    bool jumped = false;   // the last step crossed the direct span
    bool after_leaf = true;  // the last step ended on a plane of the lattice (a leaf's, or the grid's face)
    bool overlap = false;  // it landed where n varies or on the object: the map was wrong for this photon
    // Where the channels part: the ray before that step, its length, and the path's state then.
    Ray split_ray = ray;
    float split_ds = 0.0, split_along = 0.0, split_length = 0.0;
    vec3 split_weight = weight;
    uint split_steps = 0u, split_rng = 0u, split_phase = 0u;
    bool split_jumped = false, split_overlap = false, split_unbent = true, split_after_leaf = true;
    // Multiple scattering (random_walk.glsl): compiled out where photons do not scatter.
    Walk walk = start_walk(kRandomWalks ? next_unit() : 0.0, hash(i ^ hash(params.photon_info.y + 7u)));
    Walk split_walk = walk;
    // One loop and one floor deposit for all paths: lavapipe 22.3 runs every line of a loop body on each
    // pass.
    for (uint path = 0u; path < (kDispersive ? 4u : 1u); ++path) {
        uint first_step = 0u;
        fresnel_rng = fresnel_seed;  // each channel chooses as a photon of its own index would
        if (kDispersive && path > 0u) {
            uint c = path - 1u;
            ray_contrast = params.dispersion[c];
            ray = split_ray;
            weight = split_weight * channel_mask(c);
            along = split_along;
            path_length = split_length;
            jumped = split_jumped;
            overlap = split_overlap;
            unbent = split_unbent;
            after_leaf = split_after_leaf;
            walk = split_walk;
            rng_state = split_rng;
            deposit_phase = split_phase;
            ray_step(ray, split_ds);
            along += split_ds;
            steps = split_steps + 1u;
            first_step = steps;
        }
        bool split = false;
        float outcome = 0.0;
        for (; steps < params.photon_info.z; ++steps) {
            if (kRandomWalks && walk.collides) {
                vec3 factor;
                ray.d = scatter(walk, ray.d, vec3(next_unit(), next_unit(), next_unit()), factor);
                weight *= factor;
                unbent = false;
                direct_to = -1.0;  // what direct light counts is light that never scattered
                if (!survives_roulette(weight, next_unit())) break;
            }
            uint level = fixed_step ? 0u : octree_level(ray);
            float ds = safe_step(level, ray.p, ray.d, shell_step_for(ray, shell_step));
            // A leaf ends on a plane of the lattice, so the shell steps after it would all start at the
            // same phase of the lattice, and what the steps make of a shell a voxel or two wide depends
            // on where the lattice cuts it: a caustic gathers that from many photons into rings (docs/rendering.md,
            // "Ring moire in caustics"). The first shell step after a leaf falls short by a random
            // fraction, so each photon crosses the shell at its own phase.
            if (level == 0u && after_leaf) ds *= 1.0 - to_unit(hash(step_seed ^ hash(steps)));
            after_leaf = level != 0u;
            float coverage = coverage_for(kRandomWalks ? max(params.flags.y, params.flags.z) : params.flags.y, ray);
            if (kRandomWalks) coverage = walk_step(ray.p, ray.d, ds, coverage, max(params.flags.y, params.flags.z), shell_step);
            uint object = object_at(ray);
            vec3 kappa = extinction_at(coverage, object) * h;  // per voxel length
            overlap = overlap || (jumped && !flat_medium(ray.field, coverage));
            bool in_direct = along >= direct_from && along < direct_to;
            if (in_direct) ds = direct_to - along;
            else if (along < direct_from && direct_from < direct_to) ds = min(ds, max(direct_from - along, 1e-3));
            jumped = in_direct;
            ds = field_step(ray.p, ray.d, ds);
            // Stop at the floor or the grid's far side within this step.
            float to_exit = grid_interval(ray.p, ray.d).y;
            bool hits_floor = floor_on && ray.d.y < 0.0 && ray.p.y + ds * ray.d.y <= floor_y;
            float to_floor = hits_floor ? (ray.p.y - floor_y) / -ray.d.y : 1e30;
            float len = min(ds, min(to_exit, to_floor));
            // The medium's density over the step (medium.fade): its integral, exact however long the step
            // (the direct span is crossed in one), so photons thin out as the direct light does.
            float density = len > 0.0 ? medium_depth(ray.p, ray.d, len) / len : 1.0;
            kappa = thinned(kappa, params.medium_extinction.rgb * h, coverage, density);
            FieldSample midpoint = field_at(ray.p + (0.5 * len) * ray.d);
            vec4 field_s = field_scattering(midpoint);
            vec3 field_sigma = field_extinction(midpoint);
            if (kMediumField) kappa += field_sigma * h;
            // What the volumes take of the weight beyond the midpoint's (residual_ratio): their absorption
            // while the photon walks (its scattering is delta-tracked), else their extinction.
            bool walking = kRandomWalks && walk.bounces < params.models.w;
            vec3 control = walking ? field_sigma - (field_s.r + field_s.g + field_s.b) * (1.0 / 3.0) : field_sigma;
            if (kRandomWalks) {
                // Absorption stays in the weight; scattering ends the step where the walk says.
                kappa -= walk_free_path(walk, ray.p, ray.d, coverage_as(params.flags.z, coverage), object, h, density, field_s, len);
                if (walk.collides) { ds = len; to_exit = 1e30; to_floor = 1e30; }
            }
            unbent = unbent && all(equal(ray.field.yzw, vec3(0.0)));
            if (deposits && !in_direct) deposit(ray.p / radiance_factor, ray.d, len / radiance_factor, weight, kappa * radiance_factor, unbent);
            path_length += len;
            if (to_floor <= min(ds, to_exit)) {
                weight *= exp(-kappa * to_floor) * residual_ratio(midpoint, ray.p, ray.d, to_floor, control, vec3(0.0), h, walking, ratio_rng);
                ray.p += ray.d * to_floor;
                outcome = 2.0;
                break;
            }
            weight *= exp(-kappa * len) * residual_ratio(midpoint, ray.p, ray.d, len, control, vec3(0.0), h, walking, ratio_rng);
            if (to_exit <= ds) {
                ray.p += ray.d * to_exit;
                outcome = 1.0;
                break;
            }
            Ray before = ray;
            ray_step(ray, ds);
            if (kDispersive && path == 0u && !(channel_free(before.field) && channel_free(ray.field))) {
                split = true;
                split_ray = before;
                split_ds = ds;
                split_along = along;
                split_length = path_length;
                split_weight = weight;
                split_steps = steps;
                split_jumped = jumped;
                split_overlap = overlap;
                split_unbent = unbent;
                split_after_leaf = after_leaf;
                split_walk = walk;
                break;
            }
            if (kFresnel) {
                // Reflected with probability R, transmitted otherwise: unbiased, and flux stays whole. A
                // film's R differs by channel: the chance is the flux-weighted mean, and each channel's
                // weight is scaled by its R (or 1 - R) over that chance, which keeps every channel unbiased.
                vec3 reflected;
                vec3 reflectance = shell_reflectance(before, ray, reflected);
                float chance = kFilm ? dot(weight, reflectance) / max(weight.r + weight.g + weight.b, 1e-30) : reflectance.r;
                if (chance > 0.0) {
                    bool reflects = next_fresnel_unit() < chance;
                    if (kFilm) weight *= reflects ? reflectance / chance : (1.0 - reflectance) / (1.0 - chance);
                    if (reflects) ray = Ray(before.p, reflected, before.field, before.cell);
                }
            }
            along += ds;
            if (max(weight.r, max(weight.g, weight.b)) < 1e-4) break;
        }
        flush_deposit();
        if (path == 0u) {
            // Each channel's path goes on with the same random streams, as one photon's channels would.
            split_rng = rng_state;
            split_phase = deposit_phase;
        }
        atomicAdd(stats.steps, steps + 1u - first_step);
        if (kRandomWalks) atomicAdd(stats.scatterings, walk.bounces - (kDispersive && path > 0u ? split_walk.bounces : 0u));
        if (split) continue;
        // A photon that left the grid goes on straight (outside is empty) to the floor.
        if (outcome == 2.0 || (outcome == 1.0 && floor_on && ray.d.y < 0.0)) {
            vec3 landing = outcome == 2.0 ? ray.p : ray.p + ray.d * ((ray.p.y - floor_y) / -ray.d.y);
            deposit_floor(to_world(landing), weight, 1);
        }
        if (overlap) atomicAdd(stats.direct_overlaps, 1u);
        if (params.flags.x == 1u) {
            // Under dispersive transport exits are kept per channel, channel by channel: a white path's
            // in all three.
            PhotonExit exit = PhotonExit(vec4(entry, 1.0), vec4(direction, path_length * h),
                                         vec4(to_world(ray.p), outcome), vec4(ray.d, float(steps + 1u)),
                                         vec4(weight, float(walk.bounces)));
            uint first = kDispersive && path > 0u ? path - 1u : 0u;
            uint last = kDispersive ? (path > 0u ? path : 3u) : 1u;
            for (uint c = first; c < last; ++c) exits[i + c * count] = exit;
        }
        if (path == 0u) break;  // one path served every channel
    }
}
