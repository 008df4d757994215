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
// voxel instead of 27, in three dispatches). The floor map's texels (the photons' hits:
// what the grid changes of the floor's light) spread alike, in squares whose radius varies, in one gather,
// and the floor shadow's closed form (transport.h, DIRECT_MODE_FLOOR_SHADOW) is added after.
#include "transport.h"
layout(local_size_x = TRANSPORT_GROUP_SIZE) in;
#include "linear_id.glsl"

layout(std140, binding = TRANSPORT_BINDING_PARAMS) readonly buffer Params { TransportParams params; };
layout(binding = TRANSPORT_BINDING_RAW_RADIANCE, rgba32f) uniform readonly image3D raw_radiance;
layout(binding = TRANSPORT_BINDING_RAW_FLUX, rgba32f) uniform readonly image3D raw_flux;
layout(binding = TRANSPORT_BINDING_RADIANCE, rgba32f) uniform image3D radiance;
layout(binding = TRANSPORT_BINDING_FLUX, rgba32f) uniform image3D flux;
layout(binding = TRANSPORT_BINDING_RAW_FLOOR_MAP, rgba16f) uniform readonly image3D raw_floor_map;
layout(binding = TRANSPORT_BINDING_FLOOR_MAP, rgba16f) uniform writeonly image3D floor_map;
layout(binding = TRANSPORT_BINDING_SPREAD_FLUX_SHARES, rgba32f) uniform image3D flux_shares;
layout(binding = TRANSPORT_BINDING_SPREAD_RADIANCE_SHARES, rgba32f) uniform image3D radiance_shares;
layout(binding = TRANSPORT_BINDING_SPREAD_FLOOR_SHARES, rgba32f) uniform image3D floor_shares;
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

// Each texel's share of its source for every texel its square reaches, and the square's radius, once:
// the gather reads them instead of working out every neighbour's radius again.
void floor_texel_share(uint i) {
    int side = int(params.floor_map.w);
    if (i >= uint(side * side)) return;
    ivec2 j = ivec2(int(i) % side, int(i) / side);
    vec4 source = imageLoad(raw_floor_map, ivec3(j, 0));
    int r = spread_radius(effective_hits(source), 2, SPREAD_TEXEL_RADIUS);
    ivec2 square = min(j + r, ivec2(side - 1)) - max(j - r, ivec2(0)) + 1;
    imageStore(floor_shares, ivec3(j, 0), vec4(source.rgb / float(square.x * square.y), float(r)));
}

void gather_floor_texel(uint i) {
    int side = int(params.floor_map.w);
    if (i >= uint(side * side)) return;
    ivec2 t = ivec2(int(i) % side, int(i) / side);
    vec3 change = vec3(0.0);
    ivec2 lo = max(t - SPREAD_TEXEL_RADIUS, ivec2(0)), hi = min(t + SPREAD_TEXEL_RADIUS, ivec2(side - 1));
    for (int y = lo.y; y <= hi.y; ++y)
        for (int x = lo.x; x <= hi.x; ++x) {
            vec4 share = imageLoad(floor_shares, ivec3(x, y, 0));
            ivec2 apart = abs(t - ivec2(x, y));
            if (float(max(apart.x, apart.y)) <= share.w) change += share.rgb;
        }
    // The floor shadow's closed form carries no noise: added after the spread, where it was computed.
    change -= floor_shadow_taken[i].rgb;
    imageStore(floor_map, ivec3(t, 0), vec4(change, 0.0));
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

// Two jobs and their steps, one dispatch each (kFloorMap, kStep): lavapipe would run every branch's code
// in every invocation.
void main() {
    uint i = linear_invocation();
    if (kFloorMap) {
        if (kStep == SPREAD_STEP_SHARES) floor_texel_share(i);
        else gather_floor_texel(i);
    } else {
        if (kStep == SPREAD_STEP_SHARES) voxel_share(i);
        else gather_voxel(i);
    }
}
