// The scene's volumes (protocol::DensityVolume) resampled on a coarse copy of the lattice, the medium
// field: what the transport passes add to the homogeneous medium's and the objects' coefficients where
// the volumes lie (TRANSPORT_CONSTANT_MEDIUM_FIELD).
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

// The most voxels a medium field holds: 2^21, 64 MiB in its two rgba32f images.
inline constexpr uint64_t kMaxMediumFieldVoxels = uint64_t{1} << 21;
// The side (field voxels) of the blocks whose empty ones rays cross in one step (transport.h).
inline constexpr uint32_t kMediumFieldBlock = MEDIUM_FIELD_BLOCK;

// The side of a medium field voxel in lattice voxels: the fewest that keep the field within
// kMaxMediumFieldVoxels. Rays and photons step at most this far through it.
uint32_t medium_field_step(const passes::GridGeometry& lattice);
// Device memory the medium field of a scene with volumes takes on `lattice` (0 without volumes): its
// extinction and scattering and, where a volume emits, its emission and the emitters' table (at most one
// entry a field voxel).
uint64_t medium_field_bytes(const passes::GridGeometry& lattice, bool volumes, bool emits);

// What a medium field's volumes emit in all, the channels' mean (W: 4 pi x emitted radiance per metre x
// volume, summed), and the largest channel over that mean in any emitting voxel (how far one photon's
// flux may exceed the mean): what the photons' shares and fluxes need.
struct MediumEmission {
    double power = 0.0;
    double channel_ratio = 1.0;
};

struct MediumField {
    vk::Extent3 dims{1, 1, 1};
    // Per field voxel, x fastest: rgb extinction per metre and, in w, the most extinction its block
    // (MEDIUM_FIELD_BLOCK^3 field voxels) and the voxels around it hold (0: a ray crosses the block in one
    // step); rgb scattering per metre and, in w, the phase g times the channels' mean scattering (so that
    // overlapping volumes' g mix by their scattering).
    std::vector<glm::vec4> extinction, scattering;
    // Where a volume emits (else empty): per field voxel, rgb the volumes' emitted radiance per metre of
    // path (VolumeEmission), summed; w unused.
    std::vector<glm::vec4> emission;
    // The field voxels that emit, for photons drawn in proportion to what each emits (transport.h,
    // MediumEmitter): each voxel's index and the inclusive CDF of its channels' mean emission.
    std::vector<glm::uvec2> emitters;
    // What they emit in all.
    MediumEmission emitted;
};

// The world box a volume member's grid holds (its leaves' voxels, through its transform and the
// member's); false for a grid without voxels.
bool volume_world_box(const protocol::DensityVolume& member, const volume::DensityGrid& grid, glm::dvec3& lo, glm::dvec3& hi);

// The volumes' coefficients at each field voxel: every volume's density (its grid's value, trilinear
// between voxel centres, 0 outside its active voxels, times density_scale) times its extinction and
// scattering, summed over the volumes. A field voxel takes the mean of 1 or 2^3 samples (2^3 where the
// grid's voxel is smaller than the field's), so a fine grid is averaged more than point-sampled (a grid
// much finer than the field is still partly aliased). One voxel of zeros
// without volumes. Each emitting volume adds its emission likewise (intensity x colour x its emission
// grid's value, or intensity x blackbody_rgb of its temperature grid's), and the voxels that emit make
// the emitters' table. Throws RenderError for a member whose density (or emission grid, where it emits)
// is missing from `densities`.
MediumField resample_volumes(const passes::GridGeometry& lattice,
                             const std::map<std::string, protocol::DensityVolume>& volumes, const Densities& densities);

}  // namespace refract::scene
