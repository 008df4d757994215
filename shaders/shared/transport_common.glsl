// GLSL shared by the photon and viewing passes: the frame parameters, index-field lookups, octree
// stepping and the ray equation. Positions are in voxel units (voxel i spans [i, i+1)).
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_ballot : require
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_buffer_reference_uvec2 : require
#include "transport.h"
#include "hash.glsl"
#include "trilinear.glsl"

// The frame parameters (a storage buffer: transport.h says why), read through a private copy: lavapipe
// loads a buffer field inside divergent control flow (the passes' loops) lane by lane, a bounds-checked
// gather per field, while a copy taken once, at the start of main where every invocation is active,
// reads like a local variable (the viewing pass 10-25% faster; docs/perf-log/2026-11-24-round-6-sampled-deposits-while-dragging.md). Every main() begins
// with load_params().
layout(std140, binding = TRANSPORT_BINDING_PARAMS) readonly buffer Params { TransportParams frame_params; };
TransportParams params;
void load_params() { params = frame_params; }
// Every grid is read texel by texel and interpolated here (trilinear.glsl says why).
layout(binding = TRANSPORT_BINDING_INDEX_FIELD, rgba32f) readonly uniform image3D index_field;
layout(binding = TRANSPORT_BINDING_COVERAGE, rg32f) readonly uniform image3D coverage_field;
layout(std430, binding = TRANSPORT_BINDING_LEVELS) readonly buffer Levels { uint levels[]; };
layout(std430, binding = TRANSPORT_BINDING_STATS) buffer Stats { PhotonStats stats; };
layout(binding = TRANSPORT_BINDING_MEDIUM_EXTINCTION, rgba32f)
readonly uniform image3D medium_extinction_field;
layout(binding = TRANSPORT_BINDING_MEDIUM_SCATTERING, rgba32f)
readonly uniform image3D medium_scattering_field;
layout(binding = TRANSPORT_BINDING_MEDIUM_EMISSION, rgba32f)
readonly uniform image3D medium_emission_field;

// The index of the work item (pixel, photon) this invocation takes from `queue` (QUEUE_*), a subgroup's
// worth at a time in the order subgroups run, rather than by invocation ID. lavapipe hands each CPU
// thread one fixed, contiguous share of a dispatch's workgroups and items differ in cost (sky, fog,
// glass): taking the next items interleaves the threads' shares over all the work, so they finish
// together. One atomic per subgroup. Call it first, with every invocation of the dispatch active. (A
// loop taking items until the queue is empty would balance better, but lavapipe 22.3 shades some pixels
// of such a loop wrongly.)
uint take_from_queue(uint queue) {
    uint first = 0u;
    if (subgroupElect()) first = atomicAdd(stats.queue_taken[queue], gl_SubgroupSize);
    return subgroupBroadcastFirst(first) + gl_SubgroupInvocationID;
}

vec3 grid_dims() { return vec3(params.grid_dims.xyz); }
float voxel_size() { return params.grid_origin.w; }
vec3 to_voxel(vec3 world) { return (world - params.grid_origin.xyz) / params.grid_origin.w; }
vec3 to_world(vec3 voxel) { return params.grid_origin.xyz + voxel * params.grid_origin.w; }

layout(buffer_reference, std430, buffer_reference_align = 16) readonly buffer Materials { Material material[]; };
layout(buffer_reference, std430, buffer_reference_align = 4) readonly buffer FieldMap { uint cells[]; };

// The voxel holding p, clamped to the lattice (as the images' edges clamp a fetch).
ivec3 voxel_of(vec3 p) { return ivec3(clamp(p, vec3(0.0), grid_dims() - 1.0)); }

// The field atlas's map entry of the cell holding p (FIELD_*); 0 where the field is the lattice's (no
// kFieldAtlas). The lookups below take it, so that a ray reads it once per step (Ray::cell) for all.
uint field_entry(vec3 p) {
    if (!kFieldAtlas) return 0u;
    uvec3 cell = uvec3(voxel_of(p)) / FIELD_CELL;
    uvec3 cells = (params.grid_dims.xyz + FIELD_CELL - 1u) / FIELD_CELL;
    return FieldMap(params.field_atlas.xy).cells[(cell.z * cells.y + cell.y) * cells.x + cell.x];
}

// How far the atlas lies from the lattice (voxels) in the cell of map entry `entry` (not FIELD_EMPTY),
// which holds p. A cluster's outermost voxels hold the medium, as does all the atlas around its
// clusters: a trilinear fetch that reaches past a cluster's edge reads what the lattice holds there.
vec3 atlas_shift(uint entry, vec3 p) {
    uvec3 atlas_cell = (uvec3(entry) >> uvec3(0u, FIELD_AXIS_BITS, 2u * FIELD_AXIS_BITS)) & ((1u << FIELD_AXIS_BITS) - 1u);
    return vec3(atlas_cell * FIELD_CELL) - vec3((uvec3(voxel_of(p)) / FIELD_CELL) * FIELD_CELL);
}

// The index field's and coverage's texels around p (in the atlas where kFieldAtlas, its entry not empty).
TrilinearCell field_cell(vec3 p, uint entry) {
    vec3 q = kFieldAtlas ? (p + atlas_shift(entry, p)) / vec3(params.atlas_dims.xyz) : p / grid_dims();
    return trilinear_cell(q, imageSize(index_field));
}

// (n, dn/dx, dn/dy, dn/dz) per voxel length, trilinearly interpolated: the medium's outside every
// object's cluster.
vec4 index_at(vec3 p, uint entry) {
    if (kFieldAtlas && entry >= FIELD_EMPTY) return vec4(params.medium_extinction.w, 0.0, 0.0, 0.0);
    TrilinearCell cell = field_cell(p, entry);
    return TRILINEAR_AT(index_field, cell);
}
float coverage_at(vec3 p, uint entry) {
    if (kFieldAtlas && entry >= FIELD_EMPTY) return 0.0;
    TrilinearCell cell = field_cell(p, entry);
    return TRILINEAR_AT(coverage_field, cell).r;
}

// The object whose material mixes with the medium's at p: the one the index-field pass left in the voxel
// holding p (the object of most coverage there; the first where no object's box reaches, as coverage is
// 0 there); always 0 in a scene of one object.
uint object_at(vec3 p, uint entry) {
    if (!kMaterials) return 0u;
    ivec3 v = voxel_of(p);
    if (kFieldAtlas) {
        if (entry >= FIELD_EMPTY) return 0u;
        v += ivec3(atlas_shift(entry, p));
    }
    float held = imageLoad(coverage_field, v).g;
    return uint(max(held - 1.0, 0.0));
}

// Object `o`'s material (kMaterials only).
Material material_of(uint o) { return Materials(params.materials.xy).material[o]; }

// Coefficients at coverage c of object o: the medium's at 0, the object's at 1.
vec3 extinction_at(float c, uint o) {
    return mix(params.medium_extinction.rgb, kMaterials ? material_of(o).extinction.rgb : params.object_extinction.rgb, c);
}
vec3 scattering_at(float c, uint o) {
    return mix(params.medium_scattering.rgb, kMaterials ? material_of(o).scattering.rgb : params.object_scattering.rgb, c);
}

// The medium's density at voxel point p (medium.fade): 1 inside the grid, falling to 0 at its faces by a
// smoothstep of the distance to the nearest face that fades, so that lit fog shows no hard-edged box.
// Exactly 1 everywhere without a fade. It scales only the medium's share of the coefficients (thinned).
float medium_density(vec3 p) {
    if (!kMediumFade) return 1.0;
    vec3 nearest = min(p - vec3(0.0, params.medium_fade.y, 0.0), grid_dims() - p);
    float u = clamp(min(nearest.x, min(nearest.y, nearest.z)) * params.medium_fade.z, 0.0, 1.0);
    return params.medium_fade.x > 0.0 ? u * u * (3.0 - 2.0 * u) : 1.0;
}

// The integral of the smoothstep of clamp(v, 0, 1) over v from 0 to u: the density's antiderivative along
// a face's distance, in units of the fade.
float fade_integral(float u) {
    float v = clamp(u, 0.0, 1.0);
    return v * v * v * (1.0 - 0.5 * v) + max(u - 1.0, 0.0);
}

// The integral of medium_density along the straight segment p + t d, t in [0, len] (voxels), exactly, for
// steps whose coefficients must hold however long they are (the photons' steps, among them the direct
// span crossed in one; the direct light from the grid's face). Along a line each face's distance is
// affine in t, and the density is the smoothstep of the least of them, so the segment is cut where the
// nearest face changes (at most five times) and each piece integrates in closed form (fade_integral).
// Exactly len without a fade.
float medium_depth(vec3 p, vec3 d, float len) {
    if (!kMediumFade) return len;
    // The dense box is convex: a segment that starts and ends in it lies in it.
    if (medium_density(p) == 1.0 && medium_density(p + len * d) == 1.0) return len;
    float fade = params.medium_fade.x;
    vec3 lo = vec3(0.0, params.medium_fade.y, 0.0), hi = grid_dims();
    float depth = 0.0, t = 0.0;
    for (uint piece = 0u; piece < 8u && t < len; ++piece) {
        // The distances to the low and high faces, which change along the segment at rates d and -d.
        vec3 q = p + t * d;
        vec3 below = q - lo, above = hi - q;
        // The nearest face just past t: of the faces at the least distance (within rounding, 1e-3
        // voxels: a piece ends where two meet), the one that shrinks fastest.
        float least = min(min(below.x, min(below.y, below.z)), min(above.x, min(above.y, above.z)));
        vec3 rate_below = mix(vec3(1e30), d, lessThanEqual(below, vec3(least + 1e-3)));
        vec3 rate_above = mix(vec3(1e30), -d, lessThanEqual(above, vec3(least + 1e-3)));
        float rate = min(min(rate_below.x, min(rate_below.y, rate_below.z)), min(rate_above.x, min(rate_above.y, rate_above.z)));
        // Where another face becomes the nearer: it closes in on the nearest's distance.
        vec3 meet_below = (below - least) / (rate - d), meet_above = (above - least) / (rate + d);
        meet_below = mix(vec3(1e30), meet_below, greaterThan(rate - d, vec3(0.0)));
        meet_above = mix(vec3(1e30), meet_above, greaterThan(rate + d, vec3(0.0)));
        meet_below = mix(vec3(1e30), meet_below, greaterThan(meet_below, vec3(0.0)));
        meet_above = mix(vec3(1e30), meet_above, greaterThan(meet_above, vec3(0.0)));
        float run = min(len - t, min(min(meet_below.x, min(meet_below.y, meet_below.z)),
                                     min(meet_above.x, min(meet_above.y, meet_above.z))));
        float u0 = least / fade, u1 = (least + rate * run) / fade;
        depth += abs(rate) > 1e-6 ? (fade_integral(u1) - fade_integral(u0)) * fade / rate
                                  : medium_density(q + 0.5 * run * d) * run;
        t += run;
    }
    return params.medium_fade.x > 0.0 ? depth : len;
}

// A coefficient (per length, per channel) at coverage c where the medium's density is `density`: the
// medium's share, `medium` in the same units, thinned by it. The coefficient itself where density is 1.
vec3 thinned(vec3 coefficient, vec3 medium, float c, float density) {
    return max(coefficient - (1.0 - density) * (1.0 - c) * medium, vec3(0.0));
}

layout(buffer_reference, std430, buffer_reference_align = 8) readonly buffer MediumBlocks { uvec2 blocks[]; };

// Field point f (field voxels) held where a clamped dense field would take it (its texel centres).
vec3 field_point(vec3 p) { return clamp(p / params.medium_field.w, vec3(0.5), params.medium_field.xyz - 0.5); }

// The medium field's block holding field point f: its brick (MEDIUM_NO_BRICK: none) and majorant bits.
uvec2 medium_block(vec3 f) {
    uvec3 dims = uvec3(params.medium_field.xyz);
    uvec3 blocks = (dims + (MEDIUM_FIELD_BLOCK - 1u)) / MEDIUM_FIELD_BLOCK;
    uvec3 b = min(uvec3(f), dims - 1u) / MEDIUM_FIELD_BLOCK;
    return MediumBlocks(params.medium_blocks.xy).blocks[(b.z * blocks.y + b.y) * blocks.x + b.x];
}

// The atlases' texels around field point f of the block `block` (medium_block(f)), which has a brick.
// The three atlases share one layout.
TrilinearCell brick_cell(vec3 f, uvec2 block) {
    uint row = params.medium_blocks.z, column = params.medium_blocks.w;
    uvec3 brick = uvec3(block.x % row, block.x / row % column, block.x / (row * column));
    vec3 local = f - vec3(min(uvec3(f), uvec3(params.medium_field.xyz) - 1u) / MEDIUM_FIELD_BLOCK * MEDIUM_FIELD_BLOCK);
    vec3 texel = vec3(brick * MEDIUM_BRICK_SIDE) + 1.0 + local;
    ivec3 size = imageSize(medium_extinction_field);
    return trilinear_cell(texel / vec3(size), size);
}

// Where the medium field is read at voxel point p: its field point and block (one map lookup serves
// every coefficient read there).
struct FieldSample {
    vec3 f;
    uvec2 block;
};
FieldSample field_at(vec3 p) {
    if (!kMediumField) return FieldSample(vec3(0.0), uvec2(MEDIUM_NO_BRICK, 0u));
    vec3 f = field_point(p);
    return FieldSample(f, medium_block(f));
}

// The volumes' extinction and scattering (per metre) there, added to the medium's and the objects' where
// they lie (kMediumField only; 0 without). Scattering's w: the volumes' phase g times their channels'
// mean scattering.
vec3 field_extinction(FieldSample at) {
    if (!kMediumField || at.block.x == MEDIUM_NO_BRICK) return vec3(0.0);
    TrilinearCell cell = brick_cell(at.f, at.block);
    return TRILINEAR_AT(medium_extinction_field, cell).rgb;
}
vec4 field_scattering(FieldSample at) {
    if (!kMediumField || at.block.x == MEDIUM_NO_BRICK) return vec4(0.0);
    TrilinearCell cell = brick_cell(at.f, at.block);
    return TRILINEAR_AT(medium_scattering_field, cell);
}
// Whether the volumes emit, and what there (radiance per metre of path).
bool field_emits() { return kMediumField && params.volume_emission.y > 0u; }
vec3 field_emission(FieldSample at) {
    if (!field_emits() || at.block.x == MEDIUM_NO_BRICK) return vec3(0.0);
    TrilinearCell cell = brick_cell(at.f, at.block);
    return TRILINEAR_AT(medium_emission_field, cell).rgb;
}

// A small random stream (a PCG step and its output hash): the next number uniform in [0, 1).
float pcg_unit(inout uint state) {
    state = state * 747796405u + 2891336453u;
    uint x = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return float(((x >> 22u) ^ x) >> 8u) * (1.0 / 16777216.0);
}

// The volumes' transmittance over a step of `len` voxels (of side h) from p along d beyond what the step's
// Beer-Lambert factor took for them, their extinction `control` at its midpoint (`mid`): residual ratio
// tracking (Novak et al. 2014), the product over tentative points at the rate of the block's majorant
// of 1 - (sigma(x) - c(x)) / majorant, whose mean is exp(-integral of (sigma - c)) however the field
// varies along the step. c is the line through `control` at the midpoint with `slope` (per metre per
// voxel along the step): its integral over the step is the midpoint's, so the step's Beer-Lambert factor
// stands, and the better c follows the field, the closer each factor is to 1 (the less noise). So a
// step's transmittance is unbiased for the filtered field. `absorption`: sigma is the extinction less
// the channels' mean scattering (what a walking photon's weight takes; its scattering is delta-tracked),
// as `control` is then.
vec3 residual_ratio(FieldSample mid, vec3 p, vec3 d, float len, vec3 control, vec3 slope, float h, bool absorption,
                    inout uint rng) {
    float majorant = uintBitsToFloat(mid.block.y);  // per metre
    if (!kMediumField || mid.block.x == MEDIUM_NO_BRICK || !(majorant > 0.0)) return vec3(1.0);
    vec3 ratio = vec3(1.0);
    float t = 0.0;
    for (int guard = 0; guard < 64; ++guard) {
        t -= log(1.0 - pcg_unit(rng)) / (majorant * h);
        if (t >= len) break;
        FieldSample at = field_at(p + t * d);
        vec3 sigma = field_extinction(at);
        if (absorption) {
            vec4 s = field_scattering(at);
            sigma -= (s.r + s.g + s.b) * (1.0 / 3.0);
        }
        ratio *= 1.0 - (sigma - control - slope * (t - 0.5 * len)) / majorant;
    }
    return ratio;
}

// The phase function (model, g) where scattering takes the coverage c of object o: the object's over
// 0.5, the medium's below.
uint phase_model_at(float c, uint o) {
    if (c <= 0.5) return params.models.x;
    return kMaterials ? material_of(o).model.x : params.models.y;
}
float phase_g_at(float c, uint o) {
    if (c <= 0.5) return params.medium_scattering.w;
    return kMaterials ? material_of(o).scattering.w : params.object_scattering.w;
}

// Coverage at p where the index there is n, found the cheapest way `mode` allows (COVERAGE_*). lavapipe
// 22.3 runs both sides of a branch, so a pass that needs coverage for several modes should call this once
// with the most demanding mode and derive the others with coverage_as; and the fetch is compiled out
// of pipelines whose frames never need it (kCoverageFetch).
float coverage_for(uint mode, vec3 p, uint entry, float n) {
    if (mode == COVERAGE_CONSTANT) return 0.0;
    if (mode == COVERAGE_FETCH && kCoverageFetch) return coverage_at(p, entry);
    float n_medium = params.medium_extinction.w, n_object = params.object_extinction.w;
    return clamp((n - n_medium) / (n_object - n_medium), 0.0, 1.0);
}

// The coverage that `mode` sees, given what the most demanding mode found.
float coverage_as(uint mode, float coverage) { return mode == COVERAGE_CONSTANT ? 0.0 : coverage; }

bool inside_grid(vec3 p) { return all(greaterThanEqual(p, vec3(0.0))) && all(lessThan(p, grid_dims())); }

// The leaf level at p, from the level-1 node holding p's voxel (octree.comp). In a field atlas the
// octree is the atlas's, whose nodes above a map cell span other clusters: there the level stops at the
// cell's, and outside every cluster it is the map's.
uint octree_level(vec3 p, uint entry) {
    ivec3 v = voxel_of(p);
    uvec3 dims = params.grid_dims.xyz;
    if (kFieldAtlas) {
        if (entry >= FIELD_EMPTY) return entry - FIELD_EMPTY;
        v += ivec3(atlas_shift(entry, p));
        dims = params.atlas_dims.xyz;
    }
    uvec3 c = uvec3(v) >> 1u;
    uvec3 cells = (dims + 1u) >> 1u;
    uint level = levels[(c.z * cells.y + c.y) * cells.x + c.x];
    return kFieldAtlas ? min(level, FIELD_CELL_LEVEL) : level;
}

// Distance along unit direction d from p to the exit of the axis-aligned cube of side `size` (voxels)
// that contains p and is aligned to multiples of `size`.
float cell_exit(vec3 p, vec3 d, float size) {
    vec3 lo = floor(p / size) * size;
    vec3 hi = lo + size;
    vec3 t = mix((lo - p) / d, (hi - p) / d, greaterThan(d, vec3(0.0)));
    t = mix(t, vec3(1e30), equal(d, vec3(0.0)));
    return max(min(t.x, min(t.y, t.z)), 0.0);
}

// A step of `ds` voxels from p along d through the medium field: where the field's block holds anything
// (a brick with a majorant), cut where the ray next crosses a plane of texel centres, so that a step lies
// within one of the trilinear field's cells (the midpoint rule and the tracking's control line then miss
// only its curvature, not a kink); where it holds nothing, cut to the end of the largest empty cube of
// blocks around it (its span in the map, mark_empty_spans), just past it: empty space in one step.
float field_step(vec3 p, vec3 d, float ds) {
    if (!kMediumField) return ds;
    float side = params.medium_field.w;
    vec3 f = p / side;  // field voxels
    uvec2 block = medium_block(clamp(f, vec3(0.0), params.medium_field.xyz - 0.5));
    if (block.x != MEDIUM_NO_BRICK) return min(ds, cell_exit(f - 0.5, d, 1.0) * side + params.stepping.y);
    return min(ds, cell_exit(f, d, float(MEDIUM_FIELD_BLOCK << block.y)) * side + params.stepping.y);
}

// Ray-box slab test in voxel space: returns (t_enter, t_exit); t_enter > t_exit means a miss.
vec2 grid_interval(vec3 origin, vec3 d) {
    vec3 inv = 1.0 / d;
    vec3 t0 = (vec3(0.0) - origin) * inv;
    vec3 t1 = (grid_dims() - origin) * inv;
    vec3 lo = min(t0, t1), hi = max(t0, t1);
    return vec2(max(max(lo.x, lo.y), max(lo.z, 0.0)), min(hi.x, min(hi.y, hi.z)));
}

// What the medium lets through along the straight segment from world point x along unit d for
// `distance` metres (the part inside the grid; the medium is only there): its extinction thinned by
// medium_density, as a straight photon's weight falls. The floor's closed form takes it for each light's
// light on its way down (eye_ray_ends.glsl, direct_irradiance), and a photon takes away where it would
// have landed straight what that closed form counts (photon_trace.comp), so that photons that go
// straight leave the floor as they found it. The volumes' fields are left to the photons.
vec3 medium_transmittance(vec3 x, vec3 d, float distance) {
    if (all(equal(params.medium_extinction.rgb, vec3(0.0)))) return vec3(1.0);
    vec3 p = to_voxel(x);
    vec2 span = grid_interval(p, d);
    float end = min(span.y, distance / voxel_size());
    if (end <= span.x) return vec3(1.0);
    float depth = medium_depth(p + span.x * d, d, end - span.x) * voxel_size();  // metres at full density
    return exp(-params.medium_extinction.rgb * depth);
}

// The largest safe step (voxels) at p along d for a leaf of `level`: the exit of the leaf cube,
// slightly past it; the shell step where n varies (level 0).
float safe_step(uint level, vec3 p, vec3 d, float shell_step) {
    if (level == 0u) return shell_step;
    return max(cell_exit(p, d, float(1u << level)) + params.stepping.y, shell_step);
}

// A ray in the index field: position, unit direction, the field sample (n, grad n) at the position and
// the field atlas's map entry there, carried from one step to the next so each step fetches them once.
struct Ray {
    vec3 p;
    vec3 d;
    vec4 field;
    uint cell;
};

Ray start_ray(vec3 p, vec3 d) {
    uint cell = field_entry(p);
    return Ray(p, d, index_at(p, cell), cell);
}

// The lookups at a ray's position.
uint octree_level(Ray ray) { return octree_level(ray.p, ray.cell); }
uint object_at(Ray ray) { return object_at(ray.p, ray.cell); }
float coverage_for(uint mode, Ray ray) { return coverage_for(mode, ray.p, ray.cell, ray.field.x); }

// The channel's scale of the index contrast (TransportParams::dispersion) for the ray being traced:
// under dispersive transport a ray carries one channel, and its steps see n_medium + scale (n - n_medium).
// The field itself, its coverage and the octree are the reference channel's.
float ray_contrast = 1.0;

// Whether a ray step that starts or ends at this field sample (n, grad n) is the same in every channel
// under dispersion: ray_step scales grad n (and n where grad n bends the ray) by the channel, so a step
// with no gradient at either end goes straight in every channel, and one path can serve them all.
// Gradients up to DIRECT_FLAT count as none: the smoothing Gaussian's tails leave 1e-15 and so far from
// any object, which would part nearly every path at once, while channels part by at most (s_c - 1)
// DIRECT_FLAT radians per voxel there (under 1e-4 over a 1000-voxel path).
bool channel_free(vec4 field) { return all(lessThanEqual(abs(field.yzw), vec3(DIRECT_FLAT))); }

// 1 in channel c, 0 in the others.
vec3 channel_mask(uint c) { return vec3(equal(uvec3(0u, 1u, 2u), uvec3(c))); }

// One step of d/ds (n dx/ds) = grad n with v = n dx/ds (Sun et al. 2008, Ihrke et al. 2007). The
// paper's Euler update (x += ds/n v, v += ds grad n) is first order; here the position also takes the
// curvature term ds^2/(2n) (grad n across the ray) and v the trapezoid of grad n at both ends. The
// field at the far end is fetched anyway (to renormalize |v| = n there), so second order costs no
// extra fetch, and the octree's long leaf steps stay accurate in smooth fields (Luneburg, Maxwell).
void ray_step(inout Ray ray, float ds) {
    float contrast = kDispersive ? ray_contrast : 1.0;
    float n_medium = params.medium_extinction.w;
    float n = kDispersive ? n_medium + contrast * (ray.field.x - n_medium) : ray.field.x;
    vec3 g = contrast * ray.field.yzw;
    vec3 across = g - dot(g, ray.d) * ray.d;
    ray.p += ds * ray.d + (0.5 * ds * ds / n) * across;
    ray.cell = field_entry(ray.p);
    vec4 next = index_at(ray.p, ray.cell);
    vec3 g_mean = 0.5 * (g + contrast * next.yzw);
    vec3 v = n * ray.d + ds * g_mean;
    ray.field = next;
    if (kFresnel) {
        // |v| must be n at the far end. The trapezoid's error in it lies along grad n, so it is taken
        // out there: the momentum across grad n, n sin(theta), is kept exactly, as the ray equation keeps
        // it in a stratified shell. Snell's law and its critical angle then hold across a shell of any
        // smoothing (fresnel.glsl); rescaling v instead changed n sin(theta) by a few percent over a
        // shell, enough to turn back rays two degrees short of the critical angle.
        float g_length = length(g_mean);
        if (g_length > 0.0) {
            vec3 normal = g_mean / g_length;
            float v_along = dot(v, normal);
            vec3 v_across = v - v_along * normal;
            float n_next = kDispersive ? n_medium + contrast * (next.x - n_medium) : next.x;
            v = v_across + sign(v_along) * sqrt(max(n_next * n_next - dot(v_across, v_across), 0.0)) * normal;
        }
    }
    float len = length(v);
    if (len > 0.0) ray.d = v / len;
}

float floor_height_voxels() { return (params.floor_plane.x - params.grid_origin.y) / params.grid_origin.w; }
bool floor_enabled() { return params.floor_plane.z > 0.5; }
// The floor map's coordinates of world point x on the floor (texel centres at whole values: a landing
// splats bilinearly between the four around it), and the floor's point at coordinates m.
vec2 floor_map_coordinates(vec3 x) { return (x.xz - params.floor_map.xy) / params.floor_map.z * params.floor_map.w - 0.5; }
vec3 floor_map_point(vec2 m) {
    vec2 xz = params.floor_map.xy + (m + 0.5) * (params.floor_map.z / params.floor_map.w);
    return vec3(xz.x, params.floor_plane.x, xz.y);
}
