#version 460
#extension GL_GOOGLE_include_directive : require
// Adaptive density estimation for interactive frames (TEMPORAL.md): each radiance voxel's light is
// spread evenly over a box of (2r + 1)^3 voxels around it, r chosen from the photon tracks behind its
// fluence (transport.h, SPREAD_*): wide where few photons passed, the voxel alone where many did or
// where the direct light's closed form fills it. A low-photon frame then shows a smooth, slightly soft
// beam instead of speckle, and the estimate sharpens by itself as photons grow. Each voxel's share is
// divided by its box's voxels inside the grid, so the grid's sum is what the resolve left (energy kept).
// Written as a gather (each voxel adds the boxes that reach it), so no atomics: each source's share and
// reach once, then, as every spreading box is the same 3^3 (SPREAD_VOXEL_RADIUS 1) clipped to the grid,
// the shares' sum over each voxel's neighbourhood as three box sums of 3 along x, y and z (9 reads a
// voxel instead of 27, in three dispatches). The floor map's texels (the photons' hits: what the grid
// changes of the floor's light) spread in squares sized by their own hits and the photons around them,
// up to 17 x 17 texels, through running sums (floor_texel_scatter), and the floor shadow's closed form
// (transport.h, DIRECT_MODE_FLOOR_SHADOW) is added after.
#include "transport.h"
layout(local_size_x = TRANSPORT_GROUP_SIZE) in;
#include "linear_id.glsl"

layout(std140, binding = TRANSPORT_BINDING_PARAMS) readonly buffer Params { TransportParams params; };
layout(binding = TRANSPORT_BINDING_RAW_RADIANCE, rgba32f) uniform readonly image3D raw_radiance;
layout(binding = TRANSPORT_BINDING_RAW_FLUX, rgba32f) uniform readonly image3D raw_flux;
layout(binding = TRANSPORT_BINDING_RADIANCE, rgba32f) uniform image3D radiance;
layout(binding = TRANSPORT_BINDING_FLUX, rgba32f) uniform image3D flux;
layout(std430, binding = TRANSPORT_BINDING_RAW_FLOOR_MAP) readonly buffer RawFloorMap {
    uvec2 raw_floor_map[];
};
layout(std430, binding = TRANSPORT_BINDING_FLOOR_MAP) writeonly buffer FloorMap { uvec2 floor_map[]; };
layout(binding = TRANSPORT_BINDING_SPREAD_FLUX_SHARES, rgba32f) uniform image3D flux_shares;
layout(binding = TRANSPORT_BINDING_SPREAD_RADIANCE_SHARES, rgba32f) uniform image3D radiance_shares;
layout(std430, binding = TRANSPORT_BINDING_SPREAD_FLOOR_SUMS) buffer FloorSums { ivec4 floor_sums[]; };
layout(std430, binding = TRANSPORT_BINDING_FLOOR_SHADOW) readonly buffer FloorShadow { vec4 floor_shadow_taken[]; };
layout(constant_id = SPREAD_CONSTANT_FLOOR) const bool kFloorMap = false;
layout(constant_id = SPREAD_CONSTANT_STEP) const uint kStep = SPREAD_STEP_SHARES;

// The photon track length behind fluence `fluence` of radiance voxel v, in its voxel lengths, as photons
// of the reference flux would lay it (the resolve's conversion backwards: radiance_resolve.comp).
float tracks(float fluence, ivec3 v) {
    uint f = params.radiance_grid.w;
    uvec3 inside = min(uvec3(f), params.grid_dims.xyz - f * uvec3(v));
    float inside_fraction = float(inside.x * inside.y * inside.z) / float(f * f * f);
    float h = params.grid_origin.w * float(f);
    return fluence * h * h * inside_fraction / params.photon_flux.w;
}

// The radius of the box (dimensions 3: voxels) or square (2: texels) that holds SPREAD_TRACKS tracks or
// hits at n per voxel or texel, at most `most`.
int spread_radius(float n, int dimensions, int most) {
    for (int r = 0; r < most; ++r)
        if (pow(float(2 * r + 1), float(dimensions)) * n >= SPREAD_TRACKS) return r;
    return most;
}

// The photons floor-map texel value `source` stands on, as an effective count (sum w)^2 / sum w^2 of
// its shares w (relative to the reference flux): their number where all are alike, fewer where hits and
// removals cancel (a shadow's edge), whose sum is noisier than its size suggests.
float effective_hits(vec4 source) {
    float texel = params.floor_map.z / params.floor_map.w;
    float shares = (source.r + source.g + source.b) * (1.0 / 3.0) * texel * texel / params.photon_flux.w;
    return source.w > 0.0 ? shares * shares / source.w : 0.0;
}

// The floor map's sums (TRANSPORT_BINDING_SPREAD_FLOOR_SUMS): cell (x, y), 0 <= x, y <= side.
uint floor_cell(int x, int y) { return uint(y * (int(params.floor_map.w) + 1) + x); }

// A light value of the floor map in the sums' fixed point, and back: units of one photon of the
// reference flux landing in one texel.
float floor_unit() {
    float texel = params.floor_map.z / params.floor_map.w;
    return params.photon_flux.w / (texel * texel);
}

// Cell c of the sums as the spread starts: no light (the squares' corners are added next), and texel
// c - 1's photon events (the sum of its photons' squared shares: about one per photon of the reference
// flux), none on the first row and column, so that the running sums of the events along x and then y
// leave in cell (i, j) the events of the texels x < i, y < j (a summed-area table).
void floor_cell_start(uint i) {
    int cells = int(params.floor_map.w) + 1;
    if (i >= uint(cells * cells)) return;
    ivec2 c = ivec2(int(i) % cells, int(i) / cells);
    int side = cells - 1;
    float events = c.x > 0 && c.y > 0 ? floor_map_texel(raw_floor_map[(c.y - 1) * side + c.x - 1]).w : 0.0;
    floor_sums[i] = ivec4(0, 0, 0, int(events * SPREAD_EVENT_UNITS + 0.5));
}

// Running sums in place along x (`along_x`) or y, thread k taking line k, of the light (xyz) or the
// events (w). Sums wrap around 2^32 as they please: the differences taken of them are exact.
void running_sums(uint k, bool along_x, bool light) {
    int cells = int(params.floor_map.w) + 1;
    if (k >= uint(cells)) return;
    int line = int(k);
    ivec4 sum = ivec4(0);
    for (int c = 0; c < cells; ++c) {
        uint at = along_x ? floor_cell(c, line) : floor_cell(line, c);
        ivec4 cell = floor_sums[at];
        sum += cell;
        if (light) floor_sums[at].xyz = sum.xyz;
        else floor_sums[at].w = sum.w;
    }
}

// The photon events of the texels in [lo, hi] (inclusive), from the summed-area table.
int events_in(ivec2 lo, ivec2 hi) {
    return floor_sums[floor_cell(hi.x + 1, hi.y + 1)].w - floor_sums[floor_cell(lo.x, hi.y + 1)].w -
           floor_sums[floor_cell(hi.x + 1, lo.y)].w + floor_sums[floor_cell(lo.x, lo.y)].w;
}

// Texel j's light spread evenly over a square of (2r + 1)^2 texels around it (clipped to the map). Its
// own effective hits set r as a voxel's tracks do (at most SPREAD_TEXEL_RADIUS), and r grows, up to
// SPREAD_SPARSE_TEXEL_RADIUS, until the square holds SPREAD_SPARSE_EVENTS photon events: a lone hit (a
// photon the glass reflected off into the dark) reaches out to its neighbours and spreads wide and faint
// instead of standing out as a speck, while where hits are merely few (a shadow's edge) the square stays
// as small as the hit's own count makes it. Added as the square's four corners (+, -, -, +) to the sums'
// light, whose running sums along x and y then make the squares: every texel's light lands, in fixed
// point, whatever the squares' sizes.
const int kSparseEvents = int(SPREAD_SPARSE_EVENTS * SPREAD_EVENT_UNITS);
int floor_texel_radius(ivec2 j, vec4 source) {
    int side = int(params.floor_map.w);
    int r = spread_radius(effective_hits(source), 2, SPREAD_TEXEL_RADIUS);
    while (r < SPREAD_SPARSE_TEXEL_RADIUS) {
        if (events_in(max(j - r, ivec2(0)), min(j + r, ivec2(side - 1))) >= kSparseEvents) break;
        ++r;
    }
    return r;
}

// Whether texel j keeps its light (r = 0): floor_texel_light adds it in place, with no corners.
bool keeps_light(ivec2 j, vec4 source) {
    if (source.rgb == vec3(0.0)) return false;
    return effective_hits(source) >= SPREAD_TRACKS && events_in(j, j) >= kSparseEvents;
}

void floor_texel_scatter(uint i) {
    int side = int(params.floor_map.w);
    if (i >= uint(side * side)) return;
    ivec2 j = ivec2(int(i) % side, int(i) / side);
    vec4 source = floor_map_texel(raw_floor_map[i]);
    if (source.rgb == vec3(0.0) || keeps_light(j, source)) return;
    int r = floor_texel_radius(j, source);
    ivec2 lo = max(j - r, ivec2(0)), hi = min(j + r, ivec2(side - 1)) + 1;
    ivec2 square = hi - lo;
    vec3 share = source.rgb / (floor_unit() * float(square.x * square.y)) * SPREAD_FLOOR_UNITS;
    ivec3 q = ivec3(round(share));
    uint corners[4] =
        uint[4](floor_cell(lo.x, lo.y), floor_cell(hi.x, lo.y), floor_cell(lo.x, hi.y), floor_cell(hi.x, hi.y));
    for (uint k = 0u; k < 4u; ++k) {
        ivec3 signed_q = k == 1u || k == 2u ? -q : q;
        atomicAdd(floor_sums[corners[k]].x, signed_q.x);
        atomicAdd(floor_sums[corners[k]].y, signed_q.y);
        atomicAdd(floor_sums[corners[k]].z, signed_q.z);
    }
}

// Texel t of the spread map: the light's running sums (along x, then y) at its cell, with its own
// light where it keeps it, and the floor shadow's closed form, which carries no noise, added where it was
// computed.
void floor_texel_light(uint i) {
    int side = int(params.floor_map.w);
    if (i >= uint(side * side)) return;
    ivec2 t = ivec2(int(i) % side, int(i) / side);
    ivec3 sum = floor_sums[floor_cell(t.x, t.y)].xyz;
    vec4 source = floor_map_texel(raw_floor_map[i]);
    vec3 kept = keeps_light(t, source) ? source.rgb : vec3(0.0);
    vec3 change = vec3(sum) * (floor_unit() / SPREAD_FLOOR_UNITS) + kept - floor_shadow_taken[i].rgb;
    floor_map[i] = floor_map_words(vec4(change, 0.0));
}

// The radius of radiance voxel j's box, from the photon tracks behind its fluence.
int voxel_radius(ivec3 j, vec4 source) { return spread_radius(tracks(source.w, j), 3, SPREAD_VOXEL_RADIUS); }

// Each voxel's share of its light for every voxel its box reaches, once; none where its box is itself
// (the last box sum adds that voxel's light in its own place).
void voxel_share(uint i) {
    ivec3 dims = ivec3(params.radiance_grid.xyz);
    if (i >= uint(dims.x * dims.y * dims.z)) return;
    ivec3 j = ivec3(int(i) % dims.x, (int(i) / dims.x) % dims.y, int(i) / (dims.x * dims.y));
    vec4 source = imageLoad(raw_flux, j);
    int r = voxel_radius(j, source);
    ivec3 box = min(j + r, dims - 1) - max(j - r, ivec3(0)) + 1;  // its box's voxels inside the grid
    float share = r > 0 ? 1.0 / float(box.x * box.y * box.z) : 0.0;
    imageStore(flux_shares, j, share * source);
    if (!kGreyTransport) imageStore(radiance_shares, j, vec4(share * imageLoad(raw_radiance, j).rgb, 0.0));
}

// The sums over voxel v and its neighbours along `axis` inside the grid: of the shares (`from_shares`) or
// of the output, net flux and fluence, and per-channel fluence (coloured transport).
void box_sums(ivec3 v, ivec3 axis, ivec3 dims, bool from_shares, out vec4 net, out vec3 colour) {
    net = vec4(0.0);
    colour = vec3(0.0);
    for (int k = -SPREAD_VOXEL_RADIUS; k <= SPREAD_VOXEL_RADIUS; ++k) {
        ivec3 j = v + k * axis;
        if (any(lessThan(j, ivec3(0))) || any(greaterThanEqual(j, dims))) continue;
        net += from_shares ? imageLoad(flux_shares, j) : imageLoad(flux, j);
        if (!kGreyTransport) colour += (from_shares ? imageLoad(radiance_shares, j) : imageLoad(radiance, j)).rgb;
    }
}

// One box sum along the step's axis, ping-ponging between the shares and the output: x from the shares
// into the output, y back into the shares, z into the output with the voxel's own kept light added.
void gather_voxel(uint i) {
    ivec3 dims = ivec3(params.radiance_grid.xyz);
    if (i >= uint(dims.x * dims.y * dims.z)) return;
    ivec3 v = ivec3(int(i) % dims.x, (int(i) / dims.x) % dims.y, int(i) / (dims.x * dims.y));
    // Chosen by branches: a ternary of vectors on the specialization constant compiled to the wrong axis
    // on lavapipe (a specialization-constant select of vectors).
    ivec3 axis = ivec3(0, 0, 1);
    if (kStep == SPREAD_STEP_GATHER_X) axis = ivec3(1, 0, 0);
    else if (kStep == SPREAD_STEP_GATHER_Y) axis = ivec3(0, 1, 0);
    bool from_shares = kStep != SPREAD_STEP_GATHER_Y;
    vec4 net;
    vec3 colour;
    box_sums(v, axis, dims, from_shares, net, colour);
    if (kStep == SPREAD_STEP_GATHER_Y) {
        imageStore(flux_shares, v, net);
        if (!kGreyTransport) imageStore(radiance_shares, v, vec4(colour, 0.0));
        return;
    }
    if (kStep == SPREAD_STEP_GATHER_Z) {
        vec4 source = imageLoad(raw_flux, v);
        bool kept = voxel_radius(v, source) == 0;
        if (kept) net += source;
        if (!kGreyTransport && kept) colour += imageLoad(raw_radiance, v).rgb;
    }
    imageStore(flux, v, net);
    if (!kGreyTransport) imageStore(radiance, v, vec4(colour, 0.0));
}

// Two jobs and their steps, one dispatch each (kFloorMap, kStep): lavapipe 22.3 would run every branch's code
// in every invocation.
void main() {
    uint i = linear_invocation();
    if (kFloorMap) {
        if (kStep == SPREAD_FLOOR_STEP_START) floor_cell_start(i);
        else if (kStep == SPREAD_FLOOR_STEP_EVENT_ROWS) running_sums(i, true, false);
        else if (kStep == SPREAD_FLOOR_STEP_EVENT_COLUMNS) running_sums(i, false, false);
        else if (kStep == SPREAD_FLOOR_STEP_SCATTER) floor_texel_scatter(i);
        else if (kStep == SPREAD_FLOOR_STEP_ROWS) running_sums(i, true, true);
        else if (kStep == SPREAD_FLOOR_STEP_COLUMNS) running_sums(i, false, true);
        else floor_texel_light(i);
    } else {
        if (kStep == SPREAD_STEP_SHARES) voxel_share(i);
        else gather_voxel(i);
    }
}
