// The scene's volumes (protocol::DensityVolume) resampled on a copy of the lattice, the medium field:
// what the transport passes add to the homogeneous medium's and the objects' coefficients where the
// volumes lie (TRANSPORT_CONSTANT_MEDIUM_FIELD). Sparse: only blocks of MEDIUM_FIELD_BLOCK^3 field voxels
// that the volumes reach are stored, each as a brick (the block and the voxels around it, so the
// hardware filters across blocks) in brick atlases, found through a map of blocks (transport.h).
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "passes/grid_geometry.h"
#include "protocol/scene_document.h"
#include "transport.h"
#include "volume/density_export.h"

namespace refract::scene {

// The grids one volume member reads: its density and, where it emits, its emission or temperature grid
// (protocol::DensityVolume::emission_grid; null where it emits nothing).
struct VolumeGrids {
    std::shared_ptr<const volume::DensityGrid> density;
    std::shared_ptr<const volume::DensityGrid> emission;

    bool operator==(const VolumeGrids&) const = default;
};
// Each volume member's grids, by the member's name (Assets::density resolves them).
using Densities = std::map<std::string, VolumeGrids>;

// The side (field voxels) of a block, and of its brick in the atlases: the block and one voxel around it.
inline constexpr uint32_t kMediumFieldBlock = MEDIUM_FIELD_BLOCK;
inline constexpr uint32_t kMediumBrickSide = MEDIUM_BRICK_SIDE;
// The most bricks a medium field holds: 4,096,000 texels an atlas (62.5 MiB of rgba32f), laid out at
// most kMediumAtlasBricks a side (160 texels: within every Vulkan device's 3D image limit of 256).
inline constexpr uint32_t kMaxMediumBricks = 4096;
inline constexpr uint32_t kMediumAtlasBricks = 16;

// How a medium field lies on the lattice.
struct MediumFieldLayout {
    uint32_t step = 1;          // a field voxel's side in lattice voxels: rays step at most this far through it
    vk::Extent3 dims{1, 1, 1};  // field voxels
    vk::Extent3 bricks{1, 1, 1};  // the atlases' size in bricks
    uint32_t brick_count = 0;
    bool emits = false;         // a volume emits (the emission atlas and the emitters' table are its size)

    bool operator==(const MediumFieldLayout&) const = default;
};

// The field's layout for these volumes on `lattice`: the finest step (1 lattice voxel at best) at which
// the blocks their grids' leaves reach (through each member's transform, dilated by the voxel a filtered
// fetch reaches) number at most kMaxMediumBricks.
MediumFieldLayout plan_medium_field(const passes::GridGeometry& lattice,
                                    const std::map<std::string, protocol::DensityVolume>& volumes, const Densities& densities);
// Device memory a medium field of `layout` takes (its atlases, map of blocks and emitters' table; the
// placeholders' few bytes without volumes).
uint64_t medium_field_bytes(const MediumFieldLayout& layout);

// What a medium field's volumes emit in all, the channels' mean (W: 4 pi x emitted radiance per metre x
// volume, summed), and the largest channel over that mean in any emitting voxel (how far one photon's
// flux may exceed the mean): what the photons' shares and fluxes need.
struct MediumEmission {
    double power = 0.0;
    double channel_ratio = 1.0;
};

struct MediumField {
    MediumFieldLayout layout;
    // Per block (x fastest): its brick (MEDIUM_NO_BRICK where the block and the voxels around it hold
    // nothing) and the float bits of its majorant, the most extinction (any channel) its brick holds, or a
    // trace where it only emits (0: rays cross the block in one step).
    std::vector<glm::uvec2> blocks;
    // The atlases, texel by texel (x fastest), brick b at bricks (b % X, b / X % Y, b / XY): rgb extinction
    // per metre; rgb scattering per metre and, in w, the phase g times the channels' mean scattering (so
    // that overlapping volumes' g mix by their scattering); where a volume emits (else empty), rgb the
    // emitted radiance per metre of path (VolumeEmission), summed.
    std::vector<glm::vec4> extinction, scattering, emission;
    // The field voxels that emit, for photons drawn in proportion to what each emits (transport.h,
    // volume_emission): each voxel (MEDIUM_VOXEL_BITS a coordinate, x lowest) and the inclusive CDF of
    // its channels' mean emission.
    std::vector<glm::uvec2> emitters;
    MediumEmission emitted;
};

// The world box a volume member's grid holds (its leaves' voxels, through its transform and the
// member's); false for a grid without voxels.
bool volume_world_box(const protocol::DensityVolume& member, const volume::DensityGrid& grid, glm::dvec3& lo, glm::dvec3& hi);

// The volumes' coefficients at each field voxel of the planned blocks: every volume's density (its grid's
// value, trilinear between voxel centres, 0 outside its active voxels, times density_scale) times its
// extinction and scattering, summed over the volumes. A field voxel takes the mean of 1 or 2^3 samples
// (2^3 where the grid's voxel is smaller than the field's), so a fine grid is averaged more than
// point-sampled. Each emitting volume adds its emission likewise (intensity x colour x its emission
// grid's value, or intensity x blackbody_rgb of its temperature grid's), and the voxels that emit make the
// emitters' table. Bricks that end up holding nothing are dropped. Throws RenderError for a member whose
// density (or emission grid, where it emits) is missing from `densities`.
MediumField resample_volumes(const passes::GridGeometry& lattice,
                             const std::map<std::string, protocol::DensityVolume>& volumes, const Densities& densities);

}  // namespace refract::scene
