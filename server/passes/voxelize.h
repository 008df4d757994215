// Pass 1 (voxelize + smooth): a world-space triangle mesh -> its occupancy filtered to the Gaussian width
// volume.smoothing asks for, per voxel. Triangles are binned on the host into tiles of voxel columns per
// axis; the GPU casts S x S rays per column along each axis, filters the occupancy with a quadratic
// B-spline before sampling it (see shaders/voxelize.comp) and smooths the rest of the width separably on
// the lattice (smooth.comp).
#pragma once

#include <array>
#include <optional>

#include "mesh/mesh.h"
#include "passes/mode_pipelines.h"
#include "passes/grid_geometry.h"
#include "vk/commands.h"
#include "vk/gpu_timer.h"
#include "vk/pipeline.h"
#include "volume_build.h"

namespace refract::passes {

// Buffers the voxelization reads while it runs; kept alive by the caller until the submission completes.
struct VoxelizeUploads {
    vk::Buffer triangles;
    std::array<vk::Buffer, 3> tile_ranges, tile_items;
    std::array<vk::Buffer, 3> axis_coverage;
    vk::Buffer intervals;  // one axis's rays at a time
    // Per axis, filled with zeros first: a column with no triangle over it writes none.
    std::array<vk::Buffer, 3> interval_counts;
};

class VoxelizePass {
public:
    explicit VoxelizePass(vk::Context& context);

    // Records voxelization of `mesh_world` into `coverage` (float per voxel; `scratch` is the same size),
    // filtered to a Gaussian of `sigma` voxels (0: each voxel's covered fraction), by `subsamples` x
    // `subsamples` rays per voxel column and axis (kSubsamples, or kPreviewSubsamples for a preview).
    // Returns the uploads the recorded commands use.
    VoxelizeUploads record(vk::CommandRecorder& recorder, const mesh::Mesh& mesh_world,
                           const passes::GridGeometry& grid, float sigma, const vk::Buffer& scratch,
                           const vk::Buffer& coverage, uint32_t subsamples = kSubsamples);

    // The Gaussian (sigma voxels, sampled on ceil(3 sigma) taps each side) left to the lattice once the
    // B-spline (variance 1/4 voxel^2) has filtered the surface. The shell keeps the width the voxel box
    // and the lattice Gaussian of `sigma` gave it before (variance 1/12 + that kernel's): the index
    // field's central differences and trilinear fetches were tuned to it, and a sharper shell bends rays
    // by worse sampled normals. 0 where the spline alone is that wide.
    static float lattice_sigma(float sigma);
    // The variance (voxel^2) of the sampled, normalized Gaussian of `sigma` voxels the lattice smooths with.
    static double kernel_variance(double sigma);

    static constexpr uint32_t kSubsamples = VOXELIZE_SUBSAMPLES;  // S x S rays per voxel column and axis
    // A preview's S: each axis resolves the surface to half a ray spacing, h / (2 S), so twice as coarsely;
    // the object moves, and the still after it voxelizes at kSubsamples.
    static constexpr uint32_t kPreviewSubsamples = VOXELIZE_PREVIEW_SUBSAMPLES;
    // Triangles are binned per tile of kTileSize^2 columns; each ray tests its tile's list. One column
    // per tile: every ray tests only triangles over its own column (sphere at 128^3: voxelize 700-750
    // -> 515 ms against 4 x 4 tiles; 28,496-triangle bunny 620-740 -> 320-330 ms), and binning stays
    // cheap on the host (the bunny's whole rebuild got faster).
    static constexpr uint32_t kTileSize = 1;

private:
    // The smoothing pipeline for `radius` taps each side (SMOOTH_CONSTANT_RADIUS), compiled on first use:
    // a scene keeps its sigma, and compiling all SMOOTH_MAX_RADIUS of them would slow every start.
    const vk::ComputePipeline& smooth(int radius);
    // The lattice Gaussian of width `rest` voxels, axis by axis: scratch -> coverage -> scratch -> coverage.
    void record_lattice_smoothing(vk::CommandRecorder& recorder, const std::array<uint32_t, 3>& dims, float rest,
                                  const vk::Buffer& scratch, const vk::Buffer& coverage);

    // The pipelines (by VOXELIZE_MODE_*) for S x S rays a column; a preview's compiled on first use.
    const ModePipelines& voxelize(uint32_t subsamples);

    vk::Context& context_;
    ModePipelines voxelize_;  // kSubsamples
    std::optional<ModePipelines> preview_voxelize_;  // kPreviewSubsamples
    std::array<std::optional<vk::ComputePipeline>, SMOOTH_MAX_RADIUS + 1> smooth_;
};

}  // namespace refract::passes
