// Layouts of the volume-building passes (voxelize, smooth, index field, octree), shared by the
// shaders and their host files in server/passes/.
#ifndef REFRACT_SHADERS_VOLUME_BUILD_H
#define REFRACT_SHADERS_VOLUME_BUILD_H

#include "shared_types.h"

REFRACT_SHADERS_BEGIN

#define VOLUME_GROUP_SIZE 64
#define VOLUME_GROUP_3D 4  // 4x4x4 workgroups for per-voxel passes

// Specialization constant: which job (*_MODE_*, INDEX_KIND_*) a pipeline of a multi-job shader does.
// lavapipe 22.3 runs both sides of every branch, even one on a push constant, so a shader that branched on
// its job at run time would run all of them in every dispatch.
#define VOLUME_CONSTANT_MODE 0
#ifndef __cplusplus
layout(constant_id = VOLUME_CONSTANT_MODE) const uint kMode = 0u;
#endif

// --- voxelize ---------------------------------------------------------------------------------------
#define VOXELIZE_BINDING_TRIANGLES 0   // 3 x vec4 per triangle, positions in voxel coordinates
#define VOXELIZE_BINDING_TILE_RANGES 1 // uvec2 (first, count) per tile of the column plane
#define VOXELIZE_BINDING_TILE_ITEMS 2  // triangle indices, grouped by tile
#define VOXELIZE_BINDING_COVERAGE_X 3  // per-axis filtered occupancy, -1 where that axis's rays were
                                       // unreliable; GATHER binds the cast axis's here
#define VOXELIZE_BINDING_COVERAGE_Y 4
#define VOXELIZE_BINDING_COVERAGE_Z 5
#define VOXELIZE_BINDING_COVERAGE 6    // combined (mean) coverage
#define VOXELIZE_BINDING_INTERVALS 7   // vec2 (in, out) along the axis, VOXELIZE_MAX_INTERVALS per ray
#define VOXELIZE_BINDING_INTERVAL_COUNTS 8  // int per ray: its intervals, -1 where its column is unreliable
#define VOXELIZE_BINDING_STEPS 9       // float per voxel, zero between dispatches: whole weights past a
                                       // crossing's reach, summed along the column
#define VOXELIZE_MAX_CROSSINGS 32  // per ray
#define VOXELIZE_MAX_INTERVALS 8   // inside intervals per ray kept for the gather
#define VOXELIZE_SUBSAMPLES 4      // S: S x S rays per voxel column and axis
// A preview's S (an interactive frame that voxelizes: an object drag, a load): a quarter of the rays,
// the cast and the gather a third of their time at the drag's lattice (64^3: 44-53 -> 19 ms).
#define VOXELIZE_PREVIEW_SUBSAMPLES 2
// S specializes the shader (its arrays and loops sized by it), after VOLUME_CONSTANT_MODE.
#define VOXELIZE_CONSTANT_SUBSAMPLES 1
#define VOXELIZE_MODE_CAST 0u
#define VOXELIZE_MODE_GATHER_BOX 1u     // the covered fraction of each voxel (volume.smoothing 0)
#define VOXELIZE_MODE_GATHER_SPLINE 2u  // the occupancy filtered by a quadratic B-spline
#define VOXELIZE_MODE_COMBINE 3u

struct VoxelizePush {
    uvec4 dims;    // xyz: grid size; w: unused
    uint axis;     // column direction of this dispatch (0, 1, 2)
    uint tile_size;   // voxels per tile side on the column plane
    uint tiles_u;     // tiles along the plane's first axis ((axis + 1) % 3)
    uint pad0;
};

// --- smooth -----------------------------------------------------------------------------------------
#define SMOOTH_BINDING_SOURCE 0
#define SMOOTH_BINDING_TARGET 1

#define SMOOTH_MAX_RADIUS 12  // taps each side for sigma up to 4 voxels (3 sigma)
#define SMOOTH_RUN 4          // consecutive voxels along the axis per invocation
// The taps each side (<= SMOOTH_MAX_RADIUS) specialize the shader: with the loops' lengths known, the
// driver unrolls them and each weight is a fixed push-constant word instead of an indexed load
// (lavapipe, 128^3: voxelize 191-248 -> 133-151 ms).
#define SMOOTH_CONSTANT_RADIUS 1  // after VOLUME_CONSTANT_MODE, which smooth.comp does not use

struct SmoothPush {
    uvec4 dims;    // xyz: grid size; w: axis of this 1D pass
    // Gaussian weights exp(-o^2 / (2 sigma^2)) of the taps at distance o = 0..radius, computed once
    // on the host rather than an exp per tap per voxel.
    float weights[SMOOTH_MAX_RADIUS + 1];
    uint pad0, pad1, pad2;
};

// --- index field ------------------------------------------------------------------------------------
#define INDEX_BINDING_COVERAGE 0      // smoothed coverage (float per voxel)
#define INDEX_BINDING_GRID 1          // imported index grid (float per voxel), for INDEX_KIND_GRID
#define INDEX_BINDING_INDEX_FIELD 2   // out: rgba32f (n, dn/dx, dn/dy, dn/dz), gradient per voxel length
#define INDEX_BINDING_COVERAGE_IMAGE 3 // out: rg32f: coverage, for extinction and scattering; 1 + the
                                       // number of the object it is of (0 where no object's box reaches)

#define INDEX_KIND_UNIFORM 0u
#define INDEX_KIND_LUNEBURG 1u
#define INDEX_KIND_MAXWELL 2u
#define INDEX_KIND_GRID 3u

// One dispatch per object over its own box of the scene's lattice (the whole lattice in a scene of one).
struct IndexFieldPush {
    uvec4 dims;        // xyz: the object's box (voxels; its coverage's size); w: unused
    vec4 origin;       // xyz: world position of the box's min corner; w: voxel size (m)
    uvec4 offset;      // xyz: the box's min corner in the lattice (voxels); w: 0 in a scene of one object,
                       // else 1 + the object's number: its voxels then join those of the objects before
    uvec4 first;       // xyz: the box's first voxel this dispatch writes (the part of the box inside the
                       // region an edit changed); w: unused
    uvec4 extent;      // xyz: how many voxels from there; w: unused
    vec4 sphere;       // procedural fields: xyz centre (world), w radius
    float n_medium;
    float n_object;    // uniform: object index; maxwell: n0
    float pad0, pad1;
};

// --- octree -----------------------------------------------------------------------------------------
#define OCTREE_BINDING_INDEX_FIELD 0  // rgba32f storage image (n in .r)
#define OCTREE_BINDING_PYRAMID 1      // vec2 (min, max) per node, levels 1 and up back to back
#define OCTREE_BINDING_LEVELS 2       // uint per level-1 node: level of the leaf covering its voxels
#define OCTREE_MAX_LEVEL 5            // leaves up to 32 voxels on a side
#define OCTREE_MODE_LEVEL1_RANGE 0u
#define OCTREE_MODE_REDUCE 1u
#define OCTREE_MODE_LEVEL_MAP 2u

struct OctreePush {
    uvec4 dims;        // xyz: grid size; w: the level being written (REDUCE)
    uvec4 first;       // xyz: first node of the box of nodes written (of level 1 for the ranges and map)
    uvec4 extent;      // xyz: that box's nodes along each axis
    uvec4 offsets0;    // node offset of levels 0..3 in the pyramid buffer (level 0 has no nodes there)
    uvec4 offsets1;    // node offset of levels 4..5; z: max level; w: unused
    float epsilon;     // a node is a leaf when max n - min n < epsilon
    float pad0, pad1, pad2;
};

REFRACT_SHADERS_END

#ifdef __cplusplus
static_assert(sizeof(refract::shaders::VoxelizePush) == 32);
static_assert(sizeof(refract::shaders::SmoothPush) == 80);
static_assert(sizeof(refract::shaders::IndexFieldPush) == 112);
static_assert(sizeof(refract::shaders::OctreePush) == 96);
#endif

#endif
