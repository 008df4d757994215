// Layouts of the light-transport passes (photon trace, radiance resolve, viewing pass), shared by the
// shaders and server/passes/. One TransportParams block describes the frame; the host fills it from
// the scene document (server/passes/transport_params.cpp).
#ifndef REFRACT_SHADERS_TRANSPORT_H
#define REFRACT_SHADERS_TRANSPORT_H

#include "shared_types.h"

REFRACT_SHADERS_BEGIN

#define TRANSPORT_GROUP_SIZE 64
#define VIEW_GROUP_SIZE 8  // 8x8 pixel tiles

// TransportParams, std140, in a read-only storage buffer, not a uniform buffer: lavapipe (Mesa 22.3)
// folds uniform-buffer values that decide a branch or loop into a copy of the shader that it compiles
// with LLVM each time the pipeline is bound for a dispatch, and every copy stays resident: a new
// executable mapping and 0.5 MiB of resident memory per camera frame, 1.5 MiB per frame that reruns
// photons (issue 20). Storage-buffer loads are never folded.
#define TRANSPORT_BINDING_PARAMS 0
#define TRANSPORT_BINDING_INDEX_FIELD 1     // image3D rgba32f (n, grad n per voxel)
#define TRANSPORT_BINDING_COVERAGE 2        // image3D rg32f: coverage, 1 + the object of most coverage
#define TRANSPORT_BINDING_LEVELS 3          // uint per level-1 octree node (its voxels' leaf level)
// The radiance sums (reached by device address, TransportParams::radiance_sums; radiance_sums.glsl).
// Per voxel, fixed-point sums packed in pairs into 64-bit words, so one 64-bit atomic adds two. Colour
// sums are flux x path length; the net flux (direction x the channels' mean) is signed. RG holds
// red | green << 32 (coloured transport only). FLUX holds RADIANCE_FLUX_WORDS words per voxel, and
// each deposit adds to one of them (blue below is the channels' mean under grey transport):
//  - word 0: blue | the channels' mean << 32 from unbent photons, which have met no gradient of n yet
//    (and are UNBENT_MIN_DISTANCE from a point or spot light): the resolve pass knows their net flux
//    without storing it, that mean along the light's own direction at the voxel (unbent_direction).
//    The direct-light pass stores its closed-form sums here too, before the photons add theirs;
//  - word 1 + a: blue of bent photons | their net flux along axis a << 32. A bent deposit picks axis a
//    with probability |d_a| / |d|_1 and adds d_a's sign x |d|_1: unbiased, and one atomic.
// Every half-sum stays within 31 bits by the choice of fixed-point scale, so halves never carry into
// each other beyond what decoding undoes exactly.
#define RADIANCE_FLUX_WORDS 4
// A point or spot light's photons go in every direction from it: only voxels whose centres are this
// many radiance-voxel sides from the light or more take unbent deposits. Directions within such a voxel
// stay within 12 degrees of the direction to its centre, and their mean is that direction to second order.
#define UNBENT_MIN_DISTANCE 4.0f
#define TRANSPORT_BINDING_ACCUM_FLOOR 10    // FLOOR_WORDS per texel: fixed-point signed floor flux change
                                            // (rgb), the sum of its squared shares (FLOOR_SQUARE_SCALE),
                                            // then whether the floor's shadow takes the light's flux
                                            // away in closed form in the cell whose low corner the
                                            // texel is (FLOOR_SHADOW_WORD, DIRECT_MODE_FLOOR_SHADOW)
#define FLOOR_WORDS 5u
#define FLOOR_SHADOW_WORD 4u
// Fixed-point units of the floor map's sum of squared shares: each share (a photon's channel mean, relative
// to the reference flux, times its bilinear weight) squared, in 1/1024ths. 2^21 photon events on one
// texel stay within 2^31.
#define FLOOR_SQUARE_SCALE 1024.0f
#define TRANSPORT_BINDING_STATS 11          // photon statistics (see PhotonStats)
#define TRANSPORT_BINDING_RADIANCE 12       // rgba32f: fluence rate (W/m^2) rgb; coloured transport only
#define TRANSPORT_BINDING_FLUX 13           // rgba32f: net flux vector (W/m^2) xyz, w fluence rate (channel mean)
#define TRANSPORT_BINDING_FLOOR_MAP 14      // FloorMap texels: change of floor irradiance by the grid (W/m^2)
#define TRANSPORT_BINDING_HDR 15            // vec4 per pixel: linear radiance before exposure
#define TRANSPORT_BINDING_LDR 16            // uint per pixel: tone-mapped sRGB RGBA8
#define TRANSPORT_BINDING_PHOTON_EXITS 17   // PhotonExit per photon, when flags.x == 1
#define TRANSPORT_BINDING_REFINE 19         // WorkListHeader + pixels the viewing pass traces after the coarse ones
#define TRANSPORT_BINDING_LIGHT_MAP 20      // float per light-map texel: where its photons' direct light ends
#define TRANSPORT_BINDING_LIGHT_MAP_TRACED 21  // float per texel: where the texel's own ray stops going straight

// Direct light (direct_light.comp). Light that has met no gradient of n and no object travels straight
// from the light through the medium, so its fluence is known in closed form: the light's intensity
// over r^2 (or its irradiance), times Beer-Lambert through the medium. Photons and the direct-light
// pass split it between them by one rule: a photon skips its deposits over the part of its path from
// `near` (direct_light.y; 0 for a directional light) to the light map's value at its emission sample,
// and the pass stores, per radiance voxel, the closed-form fluence of exactly that part of every ray.
// The light map holds, per texel of the emission square (emission.glsl), how far (voxels, from the
// light or the emitter's plane) the rays of that texel certainly still go straight: the least of the
// traced stops of the texel and its neighbours, less a margin. So a photon crosses that part of its
// path in one straight step; one that lands where n varies or on the object (the map was wrong for
// it) is counted in PhotonStats::direct_overlaps. Rays outside the photons' part of the emitter
// (photon_cone, photon_rect) meet nothing that bends them: the pass takes their whole way from `near` to
// the floor, and no photon is traced there. The pass's jobs, direct_light.comp built once for each
// (DIRECT_MODE):
#define DIRECT_MODE_TRACE 0u     // one ray per light-map texel: where it stops going straight
#define DIRECT_MODE_MARGIN 1u    // the light map: the least stop around each texel, less the margin
#define DIRECT_MODE_REACH 2u     // one invocation per 32 radiance-voxel corners along x: which of them
                                 // photons leave to the direct light, a bit each
#define DIRECT_MODE_DEPOSIT 3u   // one invocation per radiance voxel: the closed-form direct light where
                                 // all its corners take it; listed where only some do
#define DIRECT_MODE_EDGE 4u      // one invocation per listed voxel: the same on a finer rule
#define DIRECT_MODE_DEPOSIT_FULL 5u  // DIRECT_MODE_DEPOSIT where the list may fill up (more radiance voxels
                                     // than one indirect dispatch takes): the voxels past it at once
// The floor's shadow in closed form. Each light photon that enters the grid takes its flux away from
// where its straight path would land on the floor (photon_trace.comp, deposit_floor), so the shadow of
// a glass ball was a sum of a few hundred random removals: speckle wherever few photons are traced. A
// floor-map cell (the square between four texel centres, where a landing splats bilinearly) is in the
// shadow when the straight rays to its four corners all meet a gradient of n before the floor (the
// light map's traced runs) and all would take flux away (inside the emitter, entering the grid above
// the floor). There the photons take nothing away, and this pass takes away what they would have on
// average: the emitter's photon density over the cell times their flux and bilinear weights, integrated
// by two-point Gauss rules (exact for the weights times a density that varies smoothly across the cell).
// Which cells take part only decides where the estimate is random; its expectation is the same. What
// it takes away is kept apart from the photons' sums (TRANSPORT_BINDING_FLOOR_SHADOW, every light's
// added), so that the adaptive density estimate spreads only what is random: the resolve adds it to a
// still frame's floor map after the last light, the spread to an interactive frame's after spreading.
#define DIRECT_MODE_FLOOR_CORNERS 6u  // one invocation per floor-map texel: is its centre in the shadow
#define DIRECT_MODE_FLOOR_SHADOW 7u   // one per texel: the flag of its cell, and what it takes away
#define TRANSPORT_BINDING_DIRECT_EDGES 22  // WorkListHeader + radiance voxels (DIRECT_MODE_EDGE)
#define TRANSPORT_BINDING_DIRECT_REACH 23  // bits per radiance-voxel corner, rows of 32 along x (DIRECT_MODE_REACH)
// The adaptive density estimate of interactive frames (radiance_spread.comp): the radiance grid as the
// resolve left it, before each voxel's light is spread over a box sized by the photon tracks behind it.
#define TRANSPORT_BINDING_RAW_RADIANCE 24  // rgba32f, as TRANSPORT_BINDING_RADIANCE
#define TRANSPORT_BINDING_RAW_FLUX 25      // rgba32f, as TRANSPORT_BINDING_FLUX
#define TRANSPORT_BINDING_RAW_FLOOR_MAP 26  // FloorMap texels, as TRANSPORT_BINDING_FLOOR_MAP
// The spread's shares (radiance_spread.comp): rgba32f, what each voxel gives each one its box reaches.
#define TRANSPORT_BINDING_SPREAD_FLUX_SHARES 30
#define TRANSPORT_BINDING_SPREAD_RADIANCE_SHARES 31
// The floor map's spread sums: an ivec4 per cell of (side + 1)^2, x fastest: red, green and blue (the
// squares' corners, then their running sums; SPREAD_FLOOR_UNITS), and the texels' photon events (a
// summed-area table; SPREAD_EVENT_UNITS). One load or store a cell where a plane each took four.
#define TRANSPORT_BINDING_SPREAD_FLOOR_SUMS 32
#define SPREAD_FLOOR_UNITS 65536.0f  // per photon of the reference flux in one texel: 2^16
#define SPREAD_EVENT_UNITS 4096.0f   // per photon event (a squared share of 1): 2^12
// Where an interactive frame's eye rays end (ViewPush::ends, view_upscale.comp): a ViewEnd per pixel.
#define TRANSPORT_BINDING_VIEW_ENDS 33
// The viewer's size (view_upscale.comp): vec4 linear radiance and uint sRGB per pixel.
#define TRANSPORT_BINDING_VIEWER_HDR 34
#define TRANSPORT_BINDING_VIEWER_LDR 35
// The ends of a still frame's eye rays at the viewer's size (ViewEnd per pixel), for the interactive
// frames of a light drag, whose eye rays are the still's (view_upscale.comp, UPSCALE_CONSTANT_STILL_ENDS).
#define TRANSPORT_BINDING_STILL_ENDS 37
// vec4 per floor-map texel: rgb, what the floor's shadow takes away from its irradiance in closed form
// (W/m^2, the frame's lights together; DIRECT_MODE_FLOOR_SHADOW); w, whether its centre is in the shadow
// (DIRECT_MODE_FLOOR_CORNERS, the light's).
#define TRANSPORT_BINDING_FLOOR_SHADOW 36
// The medium field (TRANSPORT_CONSTANT_MEDIUM_FIELD): the scene's volumes resampled on a coarse copy of the
// lattice (render/medium_field.h), trilinearly filtered; a texel of zeros where a scene has none.
// Three image3D rgba32f atlases of bricks (below): rgb extinction per metre; rgb scattering per metre with
// a: the phase g of each volume there times its channels' mean scattering; rgb the volumes' emitted
// radiance per metre of path (one texel of zeros where none emits).
#define TRANSPORT_BINDING_MEDIUM_EXTINCTION 27
#define TRANSPORT_BINDING_MEDIUM_SCATTERING 28
#define TRANSPORT_BINDING_MEDIUM_EMISSION 29
// The field is stored sparse: per block of MEDIUM_FIELD_BLOCK^3 field voxels a brick of MEDIUM_BRICK_SIDE^3
// texels in each atlas above (the block and the voxel around it, so filtering is the dense field's),
// found through the map of blocks (medium_blocks: uvec2 per block, x fastest: its brick and its
// majorant's float bits, the most extinction its brick holds; or MEDIUM_NO_BRICK where the block and the
// voxels around it hold nothing, and its empty span k: the aligned cube of 2^k blocks around it holds no
// brick). Rays cross an empty span in one step, and elsewhere step through the field's cells.
#define MEDIUM_FIELD_BLOCK 8
#define MEDIUM_BRICK_SIDE 10
#define MEDIUM_NO_BRICK 0xffffffffu
// An emitting voxel's coordinates in the emitters' table: MEDIUM_VOXEL_BITS each, x lowest.
#define MEDIUM_VOXEL_BITS 10u
// A voxel whose photon tracks (in voxel lengths of photons of the reference flux) number fewer than
// SPREAD_TRACKS spreads its light evenly over the smallest box of (2r + 1)^3 voxels that would hold that
// many at its density, r at most SPREAD_VOXEL_RADIUS: about a quarter relative noise where photons are
// few, the voxel itself where they are many. (A voxel radius of 2 read 125 voxels for each: a third of
// an interactive light edit's photon time on two cores.) A floor-map texel likewise over (2r + 1)^2
// texels by its own effective hits, r at most SPREAD_TEXEL_RADIUS, and wider, up to
// SPREAD_SPARSE_TEXEL_RADIUS, until the square holds SPREAD_SPARSE_EVENTS photon events (about two
// photons' landings or removals): a lone hit spreads to its nearest neighbours, wide and faint. Waiting
// for SPREAD_TRACKS events instead blurred the shadow's sharp edge, where hits are few per texel (the
// light drag's frame 7.8 -> 9.8 8-bit RMSE against its still; 4 events: 8.2).
#define SPREAD_TRACKS 16.0f
#define SPREAD_VOXEL_RADIUS 1
#define SPREAD_TEXEL_RADIUS 2
#define SPREAD_SPARSE_TEXEL_RADIUS 8
#define SPREAD_SPARSE_EVENTS 2.0f
// One specialization per job, as the resolve's (after the transport constants): true for the dispatches
// that spread the floor map's texels, false for the radiance grid's voxels; and the job's step. Voxels:
// each source's share and reach once, then box sums along x, y and z. Texels: the sums' start (the
// photon events), the events' running sums along x then y, the squares' corners, their running sums along
// x then y, each texel's light into the map.
#define SPREAD_CONSTANT_FLOOR TRANSPORT_CONSTANT_COUNT
#define SPREAD_CONSTANT_STEP (TRANSPORT_CONSTANT_COUNT + 1)
#define SPREAD_STEP_SHARES 0u
#define SPREAD_STEP_GATHER_X 1u
#define SPREAD_STEP_GATHER_Y 2u
#define SPREAD_STEP_GATHER_Z 3u
#define SPREAD_FLOOR_STEP_START 0u
#define SPREAD_FLOOR_STEP_EVENT_ROWS 1u
#define SPREAD_FLOOR_STEP_EVENT_COLUMNS 2u
#define SPREAD_FLOOR_STEP_SCATTER 3u
#define SPREAD_FLOOR_STEP_ROWS 4u
#define SPREAD_FLOOR_STEP_COLUMNS 5u
#define SPREAD_FLOOR_STEP_LIGHT 6u
#define DIRECT_MARGIN 2.0f       // voxels: a photon's ray lies between its texel's neighbours', not on one
// Direct light treats a gradient of n (per voxel) and a coverage up to this as none: the smoothing
// Gaussian's tails leave values of 1e-15 and so far from any object, which over a 1000-voxel path bend
// light by under 1e-3 rad and change its extinction by a millionth of the object's.
#define DIRECT_FLAT 1e-6f

#define LIGHT_POINT 0u
#define LIGHT_SPOT 1u
#define LIGHT_DIRECTIONAL 2u

// The most lights a scene holds (protocol::kMaxLights). Each light's photons run the direct-light, photon
// and resolve passes with their own TransportParams (the light_* and emit_* fields, photon_flux,
// photon_info, stepping, direct_light), and the resolve adds each light's share into the radiance grid
// and floor map; the viewing pass lights the floor from every light in TransportParams::lights.
#define TRANSPORT_MAX_LIGHTS 8
struct LightParams {
    vec4 position;   // xyz world; w: cos of the spot half-angle
    vec4 direction;  // xyz: spot axis or directional travel direction (unit); w: unused
    vec4 power;      // rgb: intensity x colour (W/sr or W/m^2); w: unused
    uvec4 type;      // x: LIGHT_*; yzw: unused
};

// Specialization constant of the photon, resolve and viewing passes: how the three colour channels
// travel (CHANNELS_*).
//  - Grey: extinction is the same in every channel and nothing disperses, so a photon's colour never
//    changes from emission to deposit. The radiance grid then keeps one fluence (the channels' mean)
//    and the light's colour is applied when shading: one atomic word per deposit and one texture fetch
//    per eye-ray step fewer.
//  - RGB: one path carries all three channels, each attenuated by its own extinction.
//  - Dispersive: the index contrast differs by channel (TransportParams::dispersion), so each channel
//    takes its own path once light meets a gradient of n: a photon sample, or a pixel's eye ray, is one
//    path until its first step that depends on the channel (channel_free), and from that step on one
//    path per channel, a photon's carrying only its channel.
#define TRANSPORT_CONSTANT_CHANNELS 0
#define CHANNELS_RGB 0u
#define CHANNELS_GREY 1u
#define CHANNELS_DISPERSIVE 2u
// Specialization constant of the same passes: some coefficient finds its coverage by a fetch
// (COVERAGE_FETCH). Without it the coverage texture is never read: lavapipe 22.3 would fetch it on
// every step whatever the mode.
#define TRANSPORT_CONSTANT_COVERAGE_FETCH 1
// Specialization constant of the same passes: the object's boundary reflects (Fresnel, fresnel.glsl). Off
// where nothing can reflect (Fresnel off in the document, or no index step at the boundary), so such
// scenes run the shaders they ran before reflection existed.
#define TRANSPORT_CONSTANT_FRESNEL 2
// Specialization constant of the same passes, with Fresnel on: the boundary carries a thin film (its
// Airy reflectance per channel, fresnel.h), so reflection may colour light.
#define TRANSPORT_CONSTANT_FILM 3
// Specialization constant of the same passes: the scene holds several objects, each with its own
// material (Material, in the table at TransportParams::materials), and each voxel names the object whose
// material mixes with the medium's there (the coverage texture's second channel, written by the
// index-field pass). Off for a scene of one object, whose material is TransportParams' object_*, shell
// and film: such scenes run the shaders they ran before several objects existed.
#define TRANSPORT_CONSTANT_MATERIALS 4
// Specialization constant of the same passes, with several objects only: their field is stored in a
// field atlas (render/field_atlas.h), found through its map (TransportParams::field_atlas), rather than in
// images the lattice's size. A lookup through the map costs the photon and viewing passes a quarter more
// on lavapipe (docs/perf-log/2026-12-02-memory-that-follows-the-content.md), so a scene takes the atlas only where it saves memory
// (scene::field_atlas_for).
#define TRANSPORT_CONSTANT_FIELD_ATLAS 5
// Specialization constant of the same passes: the scene holds volumes (protocol::DensityVolume), whose
// coefficients the medium field adds to the medium's where they lie. Rays and photons then step at most
// a field voxel (TransportParams::medium_field.w) where the field's block holds anything
// (MEDIUM_FIELD_BLOCK), to the block's end where not, and take each step's coefficients at its midpoint, and
// the direct light is left to the photons (its closed form knows only the homogeneous medium). Off for
// a scene without volumes, which runs the shaders it ran before volumes existed.
#define TRANSPORT_CONSTANT_MEDIUM_FIELD 6
// Specialization constant of the same passes: the homogeneous medium thins out towards the grid's faces
// (medium.fade above 0, in a medium that extincts or scatters: TransportParams::medium_fade). Off, its
// density is 1 wherever it matters and the fade's code (a step's exact integral, the density at each view
// step) is compiled out: lavapipe 22.3 paid for the code a shader held whether its lanes took it or not, 15%
// of the view and 10% of the photons (docs/perf-log/2026-12-04-where-the-still-frame-stands.md).
#define TRANSPORT_CONSTANT_MEDIUM_FADE 7
#define TRANSPORT_CONSTANT_COUNT 8  // a pass's own constants are numbered from here
// Specialization constant of the photon pass (after the transport constants): deposits are sampled, one
// per radiance voxel of path, rather than exact per voxel crossed (photon_trace.comp, deposit).
#define PHOTON_CONSTANT_SAMPLED_DEPOSITS TRANSPORT_CONSTANT_COUNT
// Specialization constant of the photon pass: photons scatter (random walks, models.w > 0 bounces and
// something scatters; random_walk.glsl). Without it the walk is compiled out and photons do what they
// did before walks existed, operation for operation.
#define PHOTON_CONSTANT_RANDOM_WALKS (TRANSPORT_CONSTANT_COUNT + 1)
#ifndef __cplusplus
layout(constant_id = TRANSPORT_CONSTANT_CHANNELS) const uint kChannels = CHANNELS_RGB;
const bool kGreyTransport = kChannels == CHANNELS_GREY;
const bool kDispersive = kChannels == CHANNELS_DISPERSIVE;
layout(constant_id = TRANSPORT_CONSTANT_COVERAGE_FETCH) const bool kCoverageFetch = true;
layout(constant_id = TRANSPORT_CONSTANT_FRESNEL) const bool kFresnel = false;
layout(constant_id = TRANSPORT_CONSTANT_FILM) const bool kFilm = false;
layout(constant_id = TRANSPORT_CONSTANT_MATERIALS) const bool kMaterials = false;
layout(constant_id = TRANSPORT_CONSTANT_FIELD_ATLAS) const bool kFieldAtlas = false;
layout(constant_id = TRANSPORT_CONSTANT_MEDIUM_FIELD) const bool kMediumField = false;
layout(constant_id = TRANSPORT_CONSTANT_MEDIUM_FADE) const bool kMediumFade = true;
#endif

// One object's material, as the table of a scene of several objects holds it (TRANSPORT_CONSTANT_MATERIALS):
// the fields TransportParams holds for the one object of a scene without the table.
struct Material {
    vec4 extinction;  // rgb per metre; w: the object's index at its surface (reference channel; shell.x)
    vec4 scattering;  // rgb per metre; w: phase g
    vec4 shell;       // x: 1 = its boundary reflects (Fresnel), y: the shell's midpoint, z, w: the heights
                      // (voxels) where its film has its top and bottom thickness
    vec4 film;        // x: the film's index, y: its thickness at the top, z: at the bottom (nm); w: unused
    uvec4 model;      // x: phase model (PHASE_*_ID); yzw: unused
};

// The field atlas of a scene of several objects (render/field_atlas.h): the index field, coverage and
// octree are stored only in clusters of the objects' boxes, packed into one atlas image. A map holds a
// word per cell of FIELD_CELL^3 lattice voxels: where the cell lies in the atlas (in cells, 10 bits an
// axis, x lowest), or FIELD_EMPTY + the octree level of the largest aligned cube around it that no
// cluster meets (the medium there: a ray steps to its exit).
#define FIELD_CELL 4u
#define FIELD_CELL_LEVEL 2u  // log2(FIELD_CELL): the highest octree level inside a cluster
#define FIELD_EMPTY 0x80000000u
#define FIELD_AXIS_BITS 10u   // so the atlas is at most FIELD_CELL << FIELD_AXIS_BITS voxels a side

// How a pass finds the coverage that mixes medium and object coefficients: not at all when both are
// equal, from n when the field is the uniform object's (n is linear in coverage), else by a fetch.
// Ordered by cost: the larger of two modes serves both (see coverage_for).
#define COVERAGE_CONSTANT 0u
#define COVERAGE_FROM_INDEX 1u
#define COVERAGE_FETCH 2u

struct TransportParams {
    // Grid
    vec4 grid_origin;     // xyz: world min corner; w: voxel size h (m)
    uvec4 grid_dims;      // xyz: voxels; w: max octree level
    // Materials: coverage 0 is the surrounding medium, 1 the object
    vec4 medium_extinction;   // rgb per metre; w: medium ior
    vec4 medium_scattering;   // rgb per metre; w: phase g
    vec4 object_extinction;   // rgb per metre; w: object ior (uniform field)
    vec4 object_scattering;   // rgb per metre; w: phase g
    uvec4 models;             // x: medium phase model, y: object phase model, z: light type, w: most
                              // scattering events per photon (photons.max_bounces; interactive: capped)
    // Light
    vec4 light_position;      // xyz world; w: cos of the spot half-angle
    vec4 light_direction;     // xyz: spot axis / directional travel direction; w: unused
    vec4 light_power;         // rgb: intensity x colour (W/sr or W/m^2); w: unused
    // Photon generation: photons cover a cone (point, spot) or a rectangle (directional)
    vec4 emit_axis;           // cone axis or rectangle normal (= travel direction); w: cos of cone half-angle
    vec4 emit_u;              // rectangle first edge (world, full length); a cone's unit x across its axis; w: unused
    vec4 emit_v;              // rectangle second edge; a cone's unit y (axis x emit_u); w: unused
    vec4 emit_origin;         // rectangle corner (world) or cone apex (light position)
    // The photons' own part of the emitter (emission.glsl, emit_photon_ray): the rays that may meet a
    // gradient of n or an object. The rest go straight to the floor or out of the grid, and the direct
    // light's closed form takes their light whole, so tracing them would add nothing (transport.h,
    // Direct light).
    vec4 photon_cone;         // point, spot: xyz its axis, w the cos of its half-angle
    vec4 photon_part;         // xyz: the cone's unit x across its axis; w: 1 = photons only in this part,
                              // 0 = over the whole emitter
    vec4 photon_rect;         // directional: the part of the emitter's sample square, xy low, zw high corner
    vec4 photon_flux;         // rgb: flux carried by each photon at emission (W); w: reference flux
    uvec4 photon_info;        // x: photon count, y: seed, z: max steps per photon, w: fixed step (1) or adaptive (0)
    vec4 stepping;            // x: shell step (voxels), y: leaf-exit overshoot (voxels), z: deposit scale
                              // (fixed-point units per photon-voxel), w: floor deposit scale
    // Floor and its caustic map
    vec4 floor_plane;         // x: height, y: checker size, z: enabled (1/0), w: checker (1/0)
    vec4 floor_albedo;        // rgb; w: unused
    vec4 floor_map;           // x, y: world x, z of the map's min corner; z: map side (m); w: texels per side
    // Camera and image
    vec4 camera_position;     // xyz; w: tan(fov_y / 2)
    vec4 camera_forward;
    vec4 camera_right;
    vec4 camera_up;
    uvec4 image;              // x: width, y: height, z: 1 = eye paths that bent filter the floor over where
                              // their neighbours land (view.comp, neighbour_footprint); w: unused
    vec4 tone;                // x: exposure multiplier (2^exposure), y: view step (voxels), z: the view step
                              // of reflected eye paths (FRESNEL_REFLECTED_VIEW_STEP times y), w: the share of
                              // a pixel's light below which a reflected eye path goes straight
                              // (FRESNEL_EYE_TRACED_SHARE, FRESNEL_PREVIEW_TRACED_SHARE)
    vec4 sky_zenith;          // rgb background above the horizon
    vec4 sky_horizon;         // rgb background at the horizon
    uvec4 flags;              // x: 1 = record each photon's exit state (tests)
                              // y: how extinction finds coverage, z: how scattering does (COVERAGE_*)
                              // w: 1 = something scatters (photons deposit into the radiance grid)
    uvec4 radiance_grid;      // xyz: radiance grid voxels; w: index-field voxels per radiance voxel along
                              // each axis (1; 3 for interactive frames: 1/27 the voxels to clear and
                              // resolve, 1/3 as many for a photon to cross)
    vec4 direct_light;        // x: light-map texels per side; y: near, where direct light may begin (voxels
                              // from a point or spot light); z: 1 = the floor's shadow in closed form
                              // (DIRECT_MODE_FLOOR_SHADOW); w: 1 = direct light in closed form
    vec4 dispersion;          // rgb: each channel's index contrast against the medium over the field's,
                              // n_c - n_medium = dispersion[c] (n - n_medium) (1 without dispersion); w: unused
    uvec4 radiance_sums;      // device addresses (low, high 32 bits) of the radiance sums: xy red | green,
                              // zw the flux words (radiance_sums.glsl)
    vec4 refinement;          // progressive refinement of still frames: x: this photon batch's weight in
                              // the radiance grid's and floor map's running mean (1/batches; 1 replaces),
                              // y: this eye-ray sample's weight in the frame's running mean (1/samples; 1
                              // replaces), zw: the sample's offset from the pixel centre (pixels)
    vec4 shell;               // the object's boundary (fresnel.glsl): x: the object's index at its surface
                              // (reference channel), y: the shell's midpoint, where rays reflect; z, w: the
                              // heights (voxels) where a film has its top and bottom thickness
    vec4 film;                // x: the film's index, y: its thickness at the top, z: at the bottom (nm); w: unused
    // The environment (passes/environment_light.h). A uniform or image environment lights the scene:
    // the last environment.z of the photon_info.x photons come from it, and the floor takes its
    // unoccluded irradiance in closed form (environment_light.rgb; the photons' floor map then holds
    // what the grid changes, as for the light).
    uvec4 environment;        // x, y: map width and height; z: photons from the environment; w: 1 = rays
                              // that leave the scene see the map (an image environment)
    vec4 environment_frame;   // x, y: cos and sin of the map's rotation about +y; z: radius (m) of the
                              // disc environment photons start on, around the grid's bounding sphere;
                              // w: an environment photon's weight per unit of its pixel's colour over
                              // the colour's mean (relative to photon_flux.w)
    vec4 environment_light;   // rgb: the environment's irradiance on the open floor (W/m^2); w: unused
    uvec4 environment_map;    // xy: device address (low, high) of the map (ENVIRONMENT_* below); zw: unused
    uvec4 light_set;          // x: the scene's lights (in lights[]), y: the one whose photons these parameters
                              // trace (light_*, emit_*; the resolve of light 0 replaces a batch, the others'
                              // add to it); zw: unused
    uvec4 materials;          // xy: device address (low, high) of the Material table, one per object in
                              // name order (TRANSPORT_CONSTANT_MATERIALS); z: objects; w: unused
    uvec4 field_atlas;        // a field atlas (TRANSPORT_CONSTANT_FIELD_ATLAS): xy: device address (low, high)
                              // of the field atlas's map (FIELD_* above); zw: unused
    uvec4 atlas_dims;         // xyz: the atlas's voxels (the index field's and coverage image's size);
                              // w: unused
    vec4 medium_fade;         // the medium's density (medium_density): x: the width (voxels) over which it falls
                              // to 0 at the grid's faces, 0: none; y: where the lowest face that fades lies
                              // (voxels: 0, or -1e30 where the floor hides the bottom face); z: 1 / x (0
                              // without a fade); w: unused
    vec4 medium_field;        // the medium field (TRANSPORT_CONSTANT_MEDIUM_FIELD): xyz: its voxels; w: its
                              // voxel's side in lattice voxels, the longest step through it
    uvec4 medium_blocks;      // xy: device address (low, high) of its map of blocks (MEDIUM_NO_BRICK above);
                              // z, w: the atlases' bricks along x and y
    // The volumes' emission (render/medium_field.h): the last volume_emission.x of the photon_info.x
    // photons (after the light's and the environment's) leave field voxels drawn in proportion to what
    // each emits, from a point uniform in the voxel, in a direction uniform on the sphere.
    uvec4 volume_emission;    // x: photons from the volumes; y: emitting field voxels (entries of the
                              // emitters' table; 0: nothing emits); zw: the table's device address (low,
                              // high): per entry uvec2(field voxel, MEDIUM_VOXEL_BITS a coordinate; the
                              // inclusive CDF of what the voxels emit as float bits)
    vec4 volume_emission_flux;  // x: a volume photon's flux (the channels' mean) relative to photon_flux.w;
                                // yzw: unused
    LightParams lights[TRANSPORT_MAX_LIGHTS];
};

// The environment map as the GPU reads it, by device address: width x height texels, rows from the
// zenith down, each vec4(rgb radiance x intensity, the inclusive CDF of the photon-sampling weight along
// its row), then one vec4 per row: (the inclusive CDF over rows, cos theta at the row's top, cos theta at
// the bottom of its sampled part (0 at the horizon when the floor hides what is below), unused). A
// pixel's weight is the mean of its colour times its sampled solid angle, so every photon of a pixel
// carries its colour over that mean times one flux (environment_frame.w).
#define ENVIRONMENT_ROWS_AT(width, height) ((width) * (height))

// The unit direction light travels at world point x as if nothing were in its way: the net flux
// direction of photons the object has not bent.
REFRACT_INLINE vec3 unbent_direction(uint light_type, vec3 light_position, vec3 emit_axis, vec3 x) {
    return light_type == LIGHT_DIRECTIONAL ? emit_axis : normalize(x - light_position);
}

// Grey transport: each channel's fluence is the channels' mean times this, the light's colour scaled to
// a mean of 1 (photon_flux is TransportParams::photon_flux).
REFRACT_INLINE vec3 grey_colour(vec4 photon_flux) {
    return vec3(photon_flux) * (3.0f / max(photon_flux.x + photon_flux.y + photon_flux.z, 1e-30f));
}

// The radiance resolve, one specialization per job (constant RESOLVE_CONSTANT_FLOOR, after the transport
// constants): true for the dispatch that resolves the floor map, false for the radiance grid's voxels.
#define RESOLVE_CONSTANT_FLOOR TRANSPORT_CONSTANT_COUNT

// Where a photon left the grid (or stopped), for the optics tests.
struct PhotonExit {
    vec4 entry;            // world point where it entered the grid; w: 1 if it entered
    vec4 entry_direction;  // unit direction there; w: path length inside the grid (m)
    vec4 position;         // world point where it left the grid or stopped; w: 1 left, 2 hit the floor
    vec4 direction;        // unit travel direction there; w: steps taken
    vec4 weight;           // rgb: its flux there over photon_flux.w; w: scattering events
};

// Counters the photon and viewing passes keep for statistics and benchmarks (atomic adds).
struct PhotonStats {
    uint photons_entered;   // photons that reached the grid
    uint steps;             // photon integration steps taken
    uint floor_hits;
    uint view_steps;        // eye-ray march steps (the viewing pass)
    uint queue_taken[3];    // work items handed out so far by each pass's queue (take_from_queue)
    uint direct_overlaps;   // photons whose straight step over their direct span landed where n varies
    uint scatterings;       // scattering events of photon random walks (photons.max_bounces)
};
#define QUEUE_VIEW_PIXELS 0u
#define QUEUE_VIEW_REFINED 1u
#define QUEUE_PHOTONS 2u

// Which pixels one dispatch of the viewing pass traces (ViewPush::pixels). Interactive frames trace in
// two rounds: first the pixels with even x and y (a quarter), then view_refine.comp fills each other
// pixel by interpolating its traced neighbours where they agree and lists it for a second, indirect
// dispatch where they do not (edges, silhouettes, caustics).
#define VIEW_PIXELS_ALL 0u
#define VIEW_PIXELS_COARSE 1u
#define VIEW_PIXELS_LISTED 2u
struct ViewPush {
    uint pixels;  // VIEW_PIXELS_*
    uint ends;    // 1: also write where each eye ray ends (TRANSPORT_BINDING_VIEW_ENDS)
};

// How a traced pixel's light ends (ViewEnd::kind). A straight ray's end, the floor or the sky, is where
// the viewer pixel's own ray meets it; a bent ray's last leg, the straight line it leaves the glass on, is
// interpolated between traced pixels whose legs took one way through the glass and followed again to
// the floor or the sky (view_upscale.comp); elsewhere the viewer's pixel takes the traced pixels' light.
#define VIEW_END_GATHERED 0u  // none: the pixel is all gathered light (cut off, or parted by channel)
#define VIEW_END_STRAIGHT 1u  // straight from the eye to the floor or the sky
#define VIEW_END_BENT 2u      // bent by the object, then straight along its last leg to the floor or the sky
struct ViewEnd {
    vec3 gathered;       // light gathered before the end (rgb): fog, glass, volumes, reflections
    uint kind;           // VIEW_END_*
    vec3 through;        // the transmittance the end's light comes through (0 for VIEW_END_GATHERED)
    uint leg_direction;  // a bent end: its last leg's direction, octahedral (pack_direction)
    vec4 leg_start;      // xyz: where that leg leaves the glass (the last shell step's end), world; w: 0
};
// The floor map (TRANSPORT_BINDING_FLOOR_MAP, TRANSPORT_BINDING_RAW_FLOOR_MAP): a storage buffer of its
// side x side texels row by row, each RGBA as four half floats in two words (rg, ba; the first in the low
// half), as an rgba16f image lays them out. A buffer rather than an image: the eye-ray ends read four
// texels of it for every pixel that sees the floor, and on lavapipe a filtered image sample cost twice
// the four buffer loads and the interpolation
// (docs/perf-log/2026-12-07-lavapipe-threads-and-the-floor-map.md).
#ifndef __cplusplus
vec4 floor_map_texel(uvec2 words) {
    return vec4(unpackHalf2x16(words.x), unpackHalf2x16(words.y));
}
uvec2 floor_map_words(vec4 texel) {
    return uvec2(packHalf2x16(texel.xy), packHalf2x16(texel.zw));
}
#endif

#ifndef __cplusplus
// A unit direction in 32 bits, octahedral (the sphere folded onto the octahedron |x| + |y| + |z| = 1, its
// lower half unfolded around the y axis): within 1e-4 radians, a tenth of a viewer pixel's cone.
uint pack_direction(vec3 d) {
    vec2 p = d.xz / (abs(d.x) + abs(d.y) + abs(d.z));
    if (d.y < 0.0) p = (1.0 - abs(p.yx)) * vec2(p.x >= 0.0 ? 1.0 : -1.0, p.y >= 0.0 ? 1.0 : -1.0);
    return packSnorm2x16(p);
}
vec3 unpack_direction(uint packed) {
    vec2 p = unpackSnorm2x16(packed);
    vec3 d = vec3(p.x, 1.0 - abs(p.x) - abs(p.y), p.y);
    if (d.y < 0.0) d.xz = (1.0 - abs(d.zx)) * vec2(d.x >= 0.0 ? 1.0 : -1.0, d.z >= 0.0 ? 1.0 : -1.0);
    return normalize(d);
}
// How far from a bent leg's start a neighbouring leg may start and still have taken the same way
// through the glass: 16 times the cone of a pixel of an image `image_height` tall there (view.comp's
// rule for the neighbours that give a bent ray's floor its footprint).
float leg_reach(vec3 start, vec4 camera_position, uint image_height) {
    return 16.0 * 2.0 * camera_position.w / float(image_height) * length(start - camera_position.xyz);
}
#endif

// An interactive frame scaled to the viewer's size (view_upscale.comp): that size, in pixels.
struct UpscalePush {
    uvec2 viewer;
};
// How many traced pixels each lane of the upscale loads for its subgroup (view_upscale.comp,
// kSharedLoads), for a traced frame `scale` of the viewer's size along each axis: a subgroup of 8 lanes
// holds a row of 8 viewer pixels (the workgroup's invocations in order), which fall between at most
// (ceil(7 scale) + 2) x 2 traced pixels: 4 x 2 up to 2/7, one a lane; 6 x 2 up to 1/2, two a lane.
// Subgroups of 16 to 64 lanes hold whole rows and need fewer: 6 x 3, 6 x 4, 6 x 6 up to 1/2. Above
// 1/2, each lane loads its own four (0).
#define UPSCALE_CONSTANT_SHARED_LOADS TRANSPORT_CONSTANT_COUNT
// Whether the upscale reads each viewer pixel's own eye ray from a still frame of the same view
// (TRANSPORT_BINDING_STILL_ENDS; view_upscale.comp, kStillEnds).
#define UPSCALE_CONSTANT_STILL_ENDS (TRANSPORT_CONSTANT_COUNT + 1)
// Whether the frame has exactly one light (view_upscale.comp, kOneLight).
#define UPSCALE_CONSTANT_ONE_LIGHT (TRANSPORT_CONSTANT_COUNT + 2)
REFRACT_INLINE uint upscale_shared_loads(float scale) {
    return scale <= 2.0f / 7.0f ? 1u : scale <= 0.5f ? 2u : 0u;
}

// Traced neighbours whose sRGB values differ by at most this many 8-bit levels in every channel are
// interpolated; 4 levels keeps 99% of the interpolated pixels within 3 levels of the traced value in
// the default scene (half a percent of the display range), while a quarter of the pixels plus ~12% are
// traced.
#define VIEW_REFINE_LEVELS 4u
#define VIEW_REFINE_GROUP_SIZE (VIEW_GROUP_SIZE * VIEW_GROUP_SIZE)  // one group per tile

// A list of work items one pass appends and an indirect dispatch then takes: the header is that
// dispatch's group counts, then the count of items, then the items in the order listed. view_refine.comp
// lists pixels (y * width + x; groups of VIEW_GROUP_SIZE^2), direct_light.comp radiance voxels.
struct WorkListHeader {
    uint groups_x, groups_y, groups_z;
    uint count;
};

// The groups of `group` invocations an append of items [first, end) adds to a work list's dispatch:
// it needs ceil(items / group) in all, so each append adds those whose first item it holds.
REFRACT_INLINE uint work_list_groups_begun(uint first, uint end, uint group) {
    return (end + group - 1u) / group - (first + group - 1u) / group;
}

REFRACT_SHADERS_END

#ifdef __cplusplus
static_assert(sizeof(refract::shaders::TransportParams) == (52 + 4 * TRANSPORT_MAX_LIGHTS) * 16);
static_assert(sizeof(refract::shaders::Material) == 80);
static_assert(sizeof(refract::shaders::PhotonStats) == 36);
static_assert(sizeof(refract::shaders::WorkListHeader) == 16);
static_assert(sizeof(refract::shaders::PhotonExit) == 80);
static_assert(sizeof(refract::shaders::ViewEnd) == 48);  // std430: a vec3 and a uint in each 16 bytes
#endif

#endif
