#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
// Direct light in closed form (transport.h, DIRECT_*): the light map, then the fluence of the light that
// photons leave to this pass, stored in the radiance grid's sums (in the photons' own fixed-point units)
// before the photons add theirs. Unbent light was a third of the photon pass's time; in closed form it
// costs about one evaluation per radiance-voxel corner and carries no photon noise.
#include "transport_common.glsl"
#include "emission.glsl"
#include "radiance_sums.glsl"
layout(local_size_x = TRANSPORT_GROUP_SIZE) in;
#include "linear_id.glsl"
// Each job its own SPIR-V (DIRECT_MODE, defined per build of this shader: cmake/shaders.cmake), so that a
// pipeline's driver compile sees only its job's code.
const uint kMode = uint(DIRECT_MODE);

layout(std430, binding = TRANSPORT_BINDING_LIGHT_MAP_TRACED) buffer Traced { float traced[]; };
layout(std430, binding = TRANSPORT_BINDING_LIGHT_MAP) buffer LightMap { float light_map[]; };
layout(std430, binding = TRANSPORT_BINDING_DIRECT_EDGES) buffer Edges {
    WorkListHeader edges;
    uint edge_voxels[];
};
layout(std430, binding = TRANSPORT_BINDING_DIRECT_REACH) buffer Reach { uint reach[]; };
layout(std430, binding = TRANSPORT_BINDING_ACCUM_FLOOR) buffer AccumFloor { uint accum_floor[]; };
layout(std430, binding = TRANSPORT_BINDING_FLOOR_SHADOW) buffer FloorShadow { vec4 floor_shadow_taken[]; };

const float kStraightOn = 1e30;  // a ray that leaves the grid without bending

// How far (voxels from the emitter) the photon of emission sample s goes straight through medium: the
// photon pass's own stepping, stopped at the first step that starts on a gradient of n or on the
// object, or at the floor; 0 where no photon is emitted or it enters below the floor.
float straight_run(vec2 s) {
    vec3 origin, direction;
    if (!emit_ray(s, origin, direction)) return 0.0;
    vec3 p = to_voxel(origin);
    vec2 span = grid_interval(p, direction);
    if (span.x >= span.y) return kStraightOn;
    float along = span.x + 1e-3;
    p += direction * along;
    bool floor_on = floor_enabled();
    float floor_y = floor_height_voxels();
    if (floor_on && p.y <= floor_y) return 0.0;
    Ray ray = start_ray(p, direction);
    bool fixed_step = params.photon_info.w == 1u;
    float near = params.direct_light.y;
    for (uint steps = 0u; steps < params.photon_info.z; ++steps) {
        if (!flat_medium(ray.field, coverage_for(params.flags.y, ray))) return along;
        float ds = safe_step(fixed_step ? 0u : octree_level(ray), ray.p, ray.d, params.stepping.x);
        if (along < near) ds = min(ds, max(near - along, 1e-3));  // the photons' step there (photon_trace.comp)
        float to_exit = grid_interval(ray.p, ray.d).y;
        if (floor_on && ray.d.y < 0.0 && ray.p.y + ds * ray.d.y <= floor_y && (ray.p.y - floor_y) / -ray.d.y < to_exit)
            return along + (ray.p.y - floor_y) / -ray.d.y;
        // Photons of the texel's other rays start their steps elsewhere: look for the object or a
        // gradient of n every voxel along this step, not only where it starts.
        for (float t = 1.0; t < min(ds, to_exit); t += 1.0) {
            vec3 q = ray.p + t * ray.d;
            uint cell = field_entry(q);
            vec4 field = index_at(q, cell);
            if (!flat_medium(field, coverage_for(params.flags.y, q, cell, field.x))) return along + t - 1.0;
        }
        if (to_exit <= ds) return kStraightOn;
        ray_step(ray, ds);
        along += ds;
    }
    return along;
}

// The light map: the least straight run over a texel and its neighbours, less DIRECT_MARGIN, so that the
// photons of a texel (anywhere in it) still go straight where the map says. The emission square of a
// cone is polar (s.x from the axis, s.y around it, which wraps); near the axis every texel of the first
// columns neighbours every other, so those take the least of the first three columns.
float light_map_value(uvec2 t) {
    int side = int(params.direct_light.x);
    bool cone = params.models.z != LIGHT_DIRECTIONAL;
    float least = kStraightOn;
    if (cone && (t.x <= 1u || t.x + 2u >= uint(side))) {
        int first = t.x <= 1u ? 0 : side - 3;
        for (int y = 0; y < side; ++y)
            for (int x = first; x < first + 3; ++x) least = min(least, traced[y * side + x]);
    } else {
        for (int dy = -1; dy <= 1; ++dy)
            for (int dx = -1; dx <= 1; ++dx) {
                int x = clamp(int(t.x) + dx, 0, side - 1);
                int y = int(t.y) + dy;
                y = cone ? (y + side) % side : clamp(y, 0, side - 1);
                least = min(least, traced[y * side + x]);
            }
    }
    return least - DIRECT_MARGIN;
}

// Whether photons leave the light at world point x to this pass; then `along` is how far x lies along its
// ray (voxels) and d the ray's direction. Outside the photons' part of the emitter no ray meets a gradient
// of n or an object, so the light reaches every point above the floor there.
bool direct_reaches(vec3 x, out float along, out vec3 d) {
    vec2 s;
    if (!emission_sample(x, s, along, d) || along < params.direct_light.y) return false;
    if (!in_photon_part(s, d)) return !floor_enabled() || x.y > params.floor_plane.x;
    return along < light_map[light_map_texel(s)];
}

// The direct light's fluence rate (rgb, W/m^2) at voxel point p, `along` voxels down its ray along d: the
// light's intensity over r^2 (or its irradiance), through the medium from the grid's face (its optical
// depth by the medium's density, as photons take it).
vec3 direct_fluence(vec3 p, float along, vec3 d) {
    float h = voxel_size();
    float in_grid = along - grid_interval(p - d * along, d).x;
    float in_medium = medium_depth(p - d * in_grid, d, in_grid) * h;  // metres at full density
    vec3 light = params.models.z == LIGHT_DIRECTIONAL ? params.light_power.rgb : params.light_power.rgb / (along * along * h * h);
    return light * exp(-params.medium_extinction.rgb * in_medium);
}

// The mean of a point light's 1/r^2 over a box of `extent` (voxels) centred `along` voxels from it in
// direction d, over its value at the centre: 1 + sum_i extent_i^2 / 24 (d^2/dx_i^2 r^-2) / r^-2 to second
// order, which the midpoint rule misses (a third of a percent five voxels from the light). Beer-Lambert
// and a directional light vary too slowly across a voxel to matter.
float box_mean_factor(vec3 extent, float along, vec3 d) {
    if (params.models.z == LIGHT_DIRECTIONAL) return 1.0;
    return 1.0 + dot(extent * extent, 8.0 * d * d - 2.0) / (24.0 * along * along);
}

// The part of radiance voxel v inside the grid (index-field voxels): its low corner and extent.
void voxel_box_at(uvec3 v, out vec3 lo, out vec3 extent) {
    uint f = params.radiance_grid.w;
    lo = vec3(f * v);
    extent = vec3(min(uvec3(f), params.grid_dims.xyz - f * v));
}
// The same for the voxel of linear index i.
void voxel_box(uint i, out vec3 lo, out vec3 extent) {
    uvec3 dims = params.radiance_grid.xyz;
    voxel_box_at(uvec3(i % dims.x, (i / dims.x) % dims.y, i / (dims.x * dims.y)), lo, extent);
}

// Stores mean fluence rate `fluence` over radiance voxel i's part inside the grid as the photons' sums
// would hold it (flux x length x scale / reference flux), for the resolve pass to read back. The pass
// runs between the sums' clear and the photons, which add to them.
void store_sums(uint i, vec3 extent, vec3 fluence) {
    float f = float(params.radiance_grid.w);
    float h_r = voxel_size() * f;
    float inside_fraction = extent.x * extent.y * extent.z / (f * f * f);
    vec3 units = fluence * (params.stepping.z * h_r * h_r * inside_fraction / params.photon_flux.w);
    ivec3 q = ivec3(units + 0.5);
    int mean = int((units.r + units.g + units.b) * (1.0 / 3.0) + 0.5);
    // Word 0 holds unbent light's sums.
    if (!kGreyTransport) accum_rg.words[i] = pack(q.r, q.g);
    accum_flux.words[RADIANCE_FLUX_WORDS * i] = pack(kGreyTransport ? mean : q.b, mean);
}

// A voxel the direct light's edge crosses: the mean over 3^3 points of the light that reaches each. The
// fluence (1/r^2 through the medium, smooth across a voxel) is evaluated once, at the mean of the points
// reached: exact wherever it varies linearly across the voxel. Evaluated at every point, it took two
// thirds of the edges' time (23 ms of a still light edit in the default scene on two cores).
void deposit_edge_voxel(uint i) {
    vec3 lo, extent;
    voxel_box(i, lo, extent);
    vec3 mean_point = vec3(0.0);
    uint reached = 0u;
    for (uint k = 0u; k < 27u; ++k) {
        vec3 p = lo + extent * ((vec3(k % 3u, (k / 3u) % 3u, k / 9u) + 0.5) * (1.0 / 3.0));
        float along;
        vec3 d;
        if (direct_reaches(to_world(p), along, d)) {
            mean_point += p;
            ++reached;
        }
    }
    vec3 fluence = vec3(0.0);
    if (reached > 0u) {
        mean_point /= float(reached);
        float along;
        vec3 d = ray_through(to_world(mean_point), along);
        fluence = direct_fluence(mean_point, along, d) * (float(reached) / 27.0);
    }
    store_sums(i, extent, fluence);
}

// The corners of the radiance voxels: (dims + 1) per axis, at index-field voxel points clamped to the
// grid (where the last voxel of a side reaches past it). Their reach bits lie in rows along x of
// reach_words() words each.
uint reach_words() { return (params.radiance_grid.x + 32u) / 32u; }
vec3 corner_point(uvec3 c) { return vec3(min(c * params.radiance_grid.w, params.grid_dims.xyz)); }
uint reach_bit(uvec3 c) {
    uint word = ((c.z * (params.radiance_grid.y + 1u) + c.y) * reach_words() + c.x / 32u);
    return (reach[word] >> (c.x % 32u)) & 1u;
}

// One word of reach bits: 32 corners along x.
void mark_reach(uint i) {
    uint words = reach_words();
    uvec3 dims = params.radiance_grid.xyz + 1u;
    if (i >= words * dims.y * dims.z) return;
    uvec3 c = uvec3(32u * (i % words), (i / words) % dims.y, i / (words * dims.y));
    uint bits = 0u;
    for (uint b = 0u; b < 32u; ++b) {
        float along;
        vec3 d;
        uvec3 corner = uvec3(c.x + b, c.yz);
        if (corner.x < dims.x && direct_reaches(to_world(corner_point(corner)), along, d)) bits |= 1u << b;
    }
    reach[i] = bits;
}

// 32 radiance voxels along x (one word of reach bits): where all of a voxel's corners take direct light,
// the fluence at its centre (the midpoint rule); where some do, the voxel is listed for
// deposit_edge_voxel, or done at once if the list is full (DIRECT_MODE_DEPOSIT_FULL only: lavapipe 22.3 would
// run that under an empty mask in every iteration where the list holds every voxel).
void deposit_run(uint i) {
    uvec3 dims = params.radiance_grid.xyz;
    uint words = (dims.x + 31u) / 32u;
    bool valid = i < words * dims.y * dims.z;
    uvec3 first = uvec3(32u * (i % words), (i / words) % dims.y, min(i / (words * dims.y), dims.z - 1u));
    // The four rows of corners around the run, each with the word after (the corner past its last voxel).
    uint64_t rows[4];
    for (uint r = 0u; r < 4u; ++r) {
        uvec3 c = uvec3(first.x, first.y + (r & 1u), first.z + (r >> 1u));
        uint word = (c.z * (dims.y + 1u) + c.y) * reach_words() + c.x / 32u;
        rows[r] = uint64_t(reach[word]) | (uint64_t(reach[word + 1u]) << 32);
    }
    for (uint b = 0u; b < 32u; ++b) {
        uint x = first.x + b;
        bool inside = valid && x < dims.x;
        uint reached = 0u;
        for (uint r = 0u; r < 4u; ++r) reached += bitCount(uint(rows[r] >> b) & 3u);
        uint voxel = (first.z * dims.y + first.y) * dims.x + min(x, dims.x - 1u);
        if (inside && reached == 8u) {
            vec3 lo, extent;
            voxel_box_at(uvec3(x, first.yz), lo, extent);
            vec3 centre = lo + 0.5 * extent;
            float along;
            vec3 d = ray_through(to_world(centre), along);
            store_sums(voxel, extent, direct_fluence(centre, along, d) * box_mean_factor(extent, along, d));
        }
        // Appends the crossed voxels to the list a subgroup at a time, as view_refine.comp does.
        bool edge = inside && reached != 0u && reached != 8u;
        uvec4 ballot = subgroupBallot(edge);
        uint count = subgroupBallotBitCount(ballot);
        uint slot = 0u;
        if (subgroupElect() && count > 0u) {
            slot = atomicAdd(edges.count, count);
            uint end = min(slot + count, uint(edge_voxels.length()));  // what fits; the rest is done at once
            uint groups = work_list_groups_begun(min(slot, end), end, TRANSPORT_GROUP_SIZE);
            if (groups > 0u) atomicAdd(edges.groups_x, groups);
        }
        slot = subgroupBroadcastFirst(slot) + subgroupBallotExclusiveBitCount(ballot);
        if (edge && slot < uint(edge_voxels.length())) edge_voxels[slot] = voxel;
        else if (kMode == DIRECT_MODE_DEPOSIT_FULL && edge) deposit_edge_voxel(voxel);
    }
}

// Whether a light photon whose straight path lands at floor point x takes its flux away there (inside
// the emitter, downward, entering the grid above the floor: photon_trace.comp) and its light-map texel's
// traced ray meets a gradient of n or the object a voxel or more before x.
bool in_floor_shadow(vec3 x) {
    float along;
    vec3 d = ray_through(x, along);
    if (d.y >= 0.0) return false;
    // The grid first: most of the floor map lies outside its shadow, and the test is cheaper than the
    // emission sample's.
    vec3 p = to_voxel(x) - d * along;  // where its ray starts: the light, or the emitter's plane
    vec2 span = grid_interval(p, d);
    if (span.x >= span.y || (p + d * (span.x + 1e-3)).y <= floor_height_voxels()) return false;
    vec2 s;
    return emission_sample(x, s, along, d) && in_photon_part(s, d) &&
           traced[light_map_texel(s)] < along - 1.0;
}

// Light photons' samples per unit area of floor-map coordinates at floor point x (in the photons' part
// of the emitter): |ds/dm| over that part's share of the emission square.
float samples_per_texel(vec3 x) {
    float texel = params.floor_map.z / params.floor_map.w;
    float per_texel = texel * texel * photon_samples_per_emission_sample();
    if (params.models.z == LIGHT_DIRECTIONAL) {
        vec3 u = params.emit_u.xyz, v = params.emit_v.xyz;
        return abs(u.x * v.z - u.z * v.x) / (dot(u, u) * dot(v, v)) * per_texel;
    }
    // Uniform in solid angle over the cone: ds = dw / (2 pi (1 - cos)), dw = |cos| dA / r^2.
    vec3 rel = x - params.emit_origin.xyz;
    float r2 = dot(rel, rel);
    return abs(rel.y) / (r2 * sqrt(r2) * kTwoPi * (1.0 - params.emit_axis.w)) * per_texel;
}

// Floor-map texel i (DIRECT_MODE_FLOOR_CORNERS): whether its centre, a corner of four cells, is in the
// floor's shadow, kept in floor_shadow_taken[i].w for the next step.
void floor_corner(uint i) {
    uint side = uint(params.floor_map.w);
    if (i >= side * side || params.direct_light.z < 0.5) return;
    floor_shadow_taken[i].w = in_floor_shadow(floor_map_point(vec2(i % side, i / side))) ? 1.0 : 0.0;
}

// Floor-map texel i (DIRECT_MODE_FLOOR_SHADOW): the flag of the cell whose low corner it is (a cell with a
// corner off the map has none), and what the light's photons landing straight in the four flagged cells
// around it would take away from its irradiance on average, added to the other lights'.
void floor_shadow(uint i) {
    uint side = uint(params.floor_map.w);
    if (i >= side * side || params.direct_light.z < 0.5) return;  // the clear's zeros: no cell flagged, nothing taken
    ivec2 t = ivec2(i % side, i / side);
    bool corner[9];
    for (int k = 0; k < 9; ++k) {
        ivec2 c = t + ivec2(k % 3 - 1, k / 3 - 1);
        bool on_map = all(greaterThanEqual(c, ivec2(0))) && all(lessThan(c, ivec2(side)));
        corner[k] = on_map && floor_shadow_taken[c.y * int(side) + c.x].w > 0.5;
    }
    bool own = corner[4] && corner[5] && corner[7] && corner[8];
    accum_floor[FLOOR_WORDS * i + FLOOR_SHADOW_WORD] = own ? 1u : 0u;
    if (!corner[4]) return;  // a corner of every cell around it: none of them flagged
    const float g = 0.5 / sqrt(3.0);  // two-point Gauss abscissae at 0.5 -+ g, each weighing a half
    float removed = 0.0;  // in emission samples times bilinear weight
    for (int b = 0; b < 2; ++b)
        for (int a = 0; a < 2; ++a) {
            if (!(corner[b * 3 + a] && corner[b * 3 + a + 1] && corner[b * 3 + a + 3] && corner[b * 3 + a + 4])) continue;
            for (int k = 0; k < 4; ++k) {
                vec2 f = vec2(0.5) + g * vec2((k & 1) == 1 ? 1.0 : -1.0, (k & 2) == 2 ? 1.0 : -1.0);
                // t is the cell's corner (1 - a, 1 - b): its bilinear weight at f.
                float weight = (a == 0 ? f.x : 1.0 - f.x) * (b == 0 ? f.y : 1.0 - f.y);
                removed += 0.25 * weight * samples_per_texel(floor_map_point(vec2(t + ivec2(a - 1, b - 1)) + f));
            }
        }
    // Each sample carries photon_flux.rgb; over the texel's area that is irradiance.
    uint light_photons = params.photon_info.x - params.environment.z - params.volume_emission.x;
    float texel = params.floor_map.z / params.floor_map.w;
    // What the medium lets through to the texel's centre stands for its cells' (it changes over metres).
    vec3 through = straight_transmittance(floor_map_point(vec2(t)));
    floor_shadow_taken[i].rgb += removed * float(light_photons) * params.photon_flux.rgb * through /
                                 (texel * texel);
}

void main() {
    load_params();
    reach_radiance_sums(params.radiance_sums);
    uint i = linear_invocation();
    uint side = uint(params.direct_light.x);
    if (kMode == DIRECT_MODE_TRACE) {
        if (i < side * side) traced[i] = straight_run((vec2(i % side, i / side) + 0.5) / float(side));
    } else if (kMode == DIRECT_MODE_MARGIN) {
        if (i < side * side) light_map[i] = light_map_value(uvec2(i % side, i / side));
    } else if (kMode == DIRECT_MODE_REACH) {
        mark_reach(i);
    } else if (kMode == DIRECT_MODE_FLOOR_CORNERS) {
        floor_corner(i);
    } else if (kMode == DIRECT_MODE_FLOOR_SHADOW) {
        floor_shadow(i);
    } else if (kMode == DIRECT_MODE_DEPOSIT || kMode == DIRECT_MODE_DEPOSIT_FULL) {
        deposit_run(i);
    } else {
        if (i < min(edges.count, uint(edge_voxels.length()))) deposit_edge_voxel(edge_voxels[i]);
    }
}
