#include "passes/voxelize.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "smooth_spv.h"
#include "volume_build.h"
#include "voxelize_spv.h"

namespace refract::passes {

using shaders::SmoothPush;
using shaders::VoxelizePush;

namespace {
constexpr vk::BindingLayout kVoxelizeLayout[] = {
    {VOXELIZE_BINDING_TRIANGLES, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {VOXELIZE_BINDING_TILE_RANGES, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {VOXELIZE_BINDING_TILE_ITEMS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {VOXELIZE_BINDING_COVERAGE_X, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {VOXELIZE_BINDING_COVERAGE_Y, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {VOXELIZE_BINDING_COVERAGE_Z, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {VOXELIZE_BINDING_COVERAGE, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {VOXELIZE_BINDING_INTERVALS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {VOXELIZE_BINDING_INTERVAL_COUNTS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {VOXELIZE_BINDING_STEPS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
};
static_assert(VOXELIZE_MODE_CAST == 0 && VOXELIZE_MODE_GATHER_BOX == 1 && VOXELIZE_MODE_GATHER_SPLINE == 2 &&
              VOXELIZE_MODE_COMBINE == 3);

// The voxelize pipelines for S x S rays a voxel column (VOXELIZE_CONSTANT_SUBSAMPLES).
ModePipelines voxelize_pipelines(vk::Context& context, uint32_t subsamples) {
    static_assert(VOLUME_CONSTANT_MODE == 0 && VOXELIZE_CONSTANT_SUBSAMPLES == 1);
    const uint32_t constants[] = {0u, subsamples};
    return ModePipelines(context, voxelize_spv, kVoxelizeLayout, sizeof(VoxelizePush),
                         {"voxelize cast", "voxelize gather (box)", "voxelize gather (spline)", "voxelize combine"},
                         VOLUME_CONSTANT_MODE, constants);
}
}  // namespace

VoxelizePass::VoxelizePass(vk::Context& context) : context_(context), voxelize_(voxelize_pipelines(context, kSubsamples)) {}

const ModePipelines& VoxelizePass::voxelize(uint32_t subsamples) {
    if (subsamples == kSubsamples) return voxelize_;
    if (subsamples != kPreviewSubsamples) throw vk::Error("voxelize: " + std::to_string(subsamples) + " rays a column side is not built");
    if (!preview_voxelize_) preview_voxelize_.emplace(voxelize_pipelines(context_, kPreviewSubsamples));
    return *preview_voxelize_;
}

const vk::ComputePipeline& VoxelizePass::smooth(int radius) {
    static_assert(VOLUME_CONSTANT_MODE == 0 && SMOOTH_CONSTANT_RADIUS == 1);
    static constexpr vk::BindingLayout kLayout[] = {{SMOOTH_BINDING_SOURCE, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
                                                    {SMOOTH_BINDING_TARGET, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER}};
    auto& pipeline = smooth_.at(static_cast<size_t>(radius));
    if (!pipeline) {
        const uint32_t constants[] = {0u, static_cast<uint32_t>(radius)};
        pipeline.emplace(context_, smooth_spv, kLayout, static_cast<uint32_t>(sizeof(SmoothPush)), "smooth", constants);
    }
    return *pipeline;
}

double VoxelizePass::kernel_variance(double sigma) {
    if (sigma <= 0.0) return 0.0;
    const int radius = std::min(static_cast<int>(std::ceil(3.0 * sigma)), SMOOTH_MAX_RADIUS);
    double sum = 0.0, second = 0.0;
    for (int o = -radius; o <= radius; ++o) {
        const double w = std::exp(-0.5 * o * o / (sigma * sigma));
        sum += w;
        second += w * o * o;
    }
    return second / sum;
}

float VoxelizePass::lattice_sigma(float sigma) {
    const double target = kernel_variance(sigma) + 1.0 / 12.0 - 0.25;
    if (target <= 0.0) return 0.0f;
    // The kernel's variance grows with its sigma: bisect.
    double lo = 0.0, hi = static_cast<double>(sigma);
    for (int i = 0; i < 40; ++i) {
        const double mid = 0.5 * (lo + hi);
        (kernel_variance(mid) < target ? lo : hi) = mid;
    }
    return static_cast<float>(0.5 * (lo + hi));
}

void VoxelizePass::record_lattice_smoothing(vk::CommandRecorder& recorder, const std::array<uint32_t, 3>& dims,
                                            float rest, const vk::Buffer& scratch, const vk::Buffer& coverage) {
    const VkCommandBuffer cmd = recorder.get();
    const uint64_t voxels = uint64_t{dims[0]} * dims[1] * dims[2];
    // x: scratch -> coverage, y: coverage -> scratch, z: scratch -> coverage.
    const vk::Buffer* source = &scratch;
    const vk::Buffer* target = &coverage;
    const int radius = std::min(static_cast<int>(std::ceil(3.0f * rest)), SMOOTH_MAX_RADIUS);
    const vk::ComputePipeline& pipeline = smooth(radius);
    SmoothPush push{};
    for (int o = 0; o <= radius; ++o) push.weights[o] = std::exp(-0.5f * static_cast<float>(o * o) / (rest * rest));
    for (uint32_t axis = 0; axis < 3; ++axis) {
        push.dims = glm::uvec4(dims[0], dims[1], dims[2], axis);
        // One invocation per SMOOTH_RUN voxels along the axis (smooth.comp).
        const auto run_groups = vk::linear_groups(
            voxels / dims[axis] * vk::group_count(dims[axis], SMOOTH_RUN), VOLUME_GROUP_SIZE);
        pipeline.dispatch(cmd,
                          {vk::Binding::storage_buffer(SMOOTH_BINDING_SOURCE, *source),
                           vk::Binding::storage_buffer(SMOOTH_BINDING_TARGET, *target)},
                          push, run_groups.x, run_groups.y);
        recorder.compute_barrier();
        std::swap(source, target);
    }
}

VoxelizeUploads VoxelizePass::record(vk::CommandRecorder& recorder, const mesh::Mesh& mesh_world,
                                     const passes::GridGeometry& grid, float sigma, const vk::Buffer& scratch,
                                     const vk::Buffer& coverage, uint32_t subsamples) {
    if (mesh_world.triangles.empty()) throw vk::Error("voxelize: the mesh has no triangles");
    const ModePipelines& pipelines = voxelize(subsamples);
    const std::array<uint32_t, 3> dims{grid.dims.x, grid.dims.y, grid.dims.z};
    const VkDeviceSize voxel_bytes = grid.dims.count() * sizeof(float);
    const auto storage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT;
    VoxelizeUploads uploads;

    // Triangles in voxel coordinates, 3 x vec4 each.
    const size_t triangle_count = mesh_world.triangles.size();
    uploads.triangles = vk::Buffer(context_, triangle_count * 3 * sizeof(glm::vec4), storage,
                                   vk::MemoryUse::upload, "voxelize triangles");
    auto vertices = uploads.triangles.mapped_span<glm::vec4>();
    std::vector<glm::vec3> voxel_positions(mesh_world.positions.size());
    for (size_t i = 0; i < voxel_positions.size(); ++i) voxel_positions[i] = grid.to_voxel(mesh_world.positions[i]);
    for (size_t t = 0; t < triangle_count; ++t)
        for (int k = 0; k < 3; ++k) vertices[3 * t + static_cast<size_t>(k)] = glm::vec4(voxel_positions[mesh_world.triangles[t][k]], 1.0f);

    // Bin triangles into tiles of kTileSize x kTileSize columns on each axis's column plane.
    for (uint32_t axis = 0; axis < 3; ++axis) {
        const int ua = static_cast<int>((axis + 1) % 3), va = static_cast<int>((axis + 2) % 3);
        const uint32_t dim_u = dims[static_cast<size_t>(ua)], dim_v = dims[static_cast<size_t>(va)];
        const uint32_t tiles_u = (dim_u + kTileSize - 1) / kTileSize;
        const uint32_t tiles_v = (dim_v + kTileSize - 1) / kTileSize;
        std::vector<std::vector<uint32_t>> bins(size_t{tiles_u} * tiles_v);
        for (size_t t = 0; t < triangle_count; ++t) {
            glm::vec3 lo(1e30f), hi(-1e30f);
            for (int k = 0; k < 3; ++k) {
                lo = glm::min(lo, voxel_positions[mesh_world.triangles[t][k]]);
                hi = glm::max(hi, voxel_positions[mesh_world.triangles[t][k]]);
            }
            auto tile_of = [&](float x, uint32_t count) {
                return static_cast<uint32_t>(std::clamp(std::floor(x / static_cast<float>(kTileSize)), 0.0f,
                                                        static_cast<float>(count - 1)));
            };
            if (hi[ua] < 0.0f || hi[va] < 0.0f || lo[ua] > static_cast<float>(dim_u) ||
                lo[va] > static_cast<float>(dim_v))
                continue;
            for (uint32_t tv = tile_of(lo[va], tiles_v); tv <= tile_of(hi[va], tiles_v); ++tv)
                for (uint32_t tu = tile_of(lo[ua], tiles_u); tu <= tile_of(hi[ua], tiles_u); ++tu)
                    bins[size_t{tv} * tiles_u + tu].push_back(static_cast<uint32_t>(t));
        }
        std::vector<glm::uvec2> ranges(bins.size());
        std::vector<uint32_t> items;
        for (size_t b = 0; b < bins.size(); ++b) {
            ranges[b] = glm::uvec2(static_cast<uint32_t>(items.size()), static_cast<uint32_t>(bins[b].size()));
            items.insert(items.end(), bins[b].begin(), bins[b].end());
        }
        if (items.empty()) items.push_back(0);
        uploads.tile_ranges[axis] = vk::Buffer(context_, ranges.size() * sizeof(glm::uvec2), storage,
                                               vk::MemoryUse::upload, "voxelize tile ranges");
        uploads.tile_ranges[axis].write(ranges.data(), ranges.size() * sizeof(glm::uvec2));
        uploads.tile_items[axis] = vk::Buffer(context_, items.size() * sizeof(uint32_t), storage,
                                              vk::MemoryUse::upload, "voxelize tile items");
        uploads.tile_items[axis].write(items.data(), items.size() * sizeof(uint32_t));
        uploads.axis_coverage[axis] = vk::Buffer(context_, voxel_bytes, storage | VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                                                 vk::MemoryUse::device, "axis coverage");
    }

    // The largest axis's rays: the axes take turns with the intervals, not with their counts (zeroed once).
    uint64_t most_columns = 0;
    for (uint32_t axis = 0; axis < 3; ++axis)
        most_columns = std::max(most_columns, uint64_t{dims[(axis + 1) % 3]} * dims[(axis + 2) % 3]);
    const uint64_t rays = most_columns * subsamples * subsamples;
    uploads.intervals = vk::Buffer(context_, rays * VOXELIZE_MAX_INTERVALS * sizeof(glm::vec2), storage,
                                   vk::MemoryUse::device, "voxelize intervals");
    for (auto& counts : uploads.interval_counts)
        counts = vk::Buffer(context_, rays * sizeof(int32_t), storage | VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                            vk::MemoryUse::device, "voxelize interval counts");

    const VkCommandBuffer cmd = recorder.get();
    for (const auto& b : uploads.axis_coverage) recorder.fill(b, 0);
    for (const auto& b : uploads.interval_counts) recorder.fill(b, 0);
    recorder.fill(scratch, 0);  // the gathers' steps
    recorder.transfer_to_compute_barrier();
    // Below a twentieth of a voxel: each voxel's covered fraction, unfiltered. Otherwise the spline filters
    // the surface and the lattice smooths whatever width is left.
    const bool filtered = sigma >= 0.05f;
    const float rest = lattice_sigma(sigma);
    const bool smoothing = filtered && rest >= 0.05f;
    const uint32_t gather = filtered ? VOXELIZE_MODE_GATHER_SPLINE : VOXELIZE_MODE_GATHER_BOX;
    // Without lattice smoothing the combined coverage is the result; otherwise it goes to scratch first.
    const vk::Buffer& combined = smoothing ? scratch : coverage;
    // Casts and gathers write their axis's coverage through the x binding; the combine reads all three.
    auto bindings = [&](uint32_t axis) {
        return std::array<vk::Binding, 10>{
            vk::Binding::storage_buffer(VOXELIZE_BINDING_TRIANGLES, uploads.triangles),
            vk::Binding::storage_buffer(VOXELIZE_BINDING_TILE_RANGES, uploads.tile_ranges[axis]),
            vk::Binding::storage_buffer(VOXELIZE_BINDING_TILE_ITEMS, uploads.tile_items[axis]),
            vk::Binding::storage_buffer(VOXELIZE_BINDING_COVERAGE_X, uploads.axis_coverage[axis]),
            vk::Binding::storage_buffer(VOXELIZE_BINDING_COVERAGE_Y, uploads.axis_coverage[1]),
            vk::Binding::storage_buffer(VOXELIZE_BINDING_COVERAGE_Z, uploads.axis_coverage[2]),
            vk::Binding::storage_buffer(VOXELIZE_BINDING_COVERAGE, combined),
            vk::Binding::storage_buffer(VOXELIZE_BINDING_INTERVALS, uploads.intervals),
            vk::Binding::storage_buffer(VOXELIZE_BINDING_INTERVAL_COUNTS, uploads.interval_counts[axis]),
            vk::Binding::storage_buffer(VOXELIZE_BINDING_STEPS, scratch)};
    };
    for (uint32_t axis = 0; axis < 3; ++axis) {
        const uint32_t ua = (axis + 1) % 3, va = (axis + 2) % 3;
        VoxelizePush push{glm::uvec4(dims[0], dims[1], dims[2], 0), axis, kTileSize,
                          (dims[ua] + kTileSize - 1) / kTileSize, 0};
        const auto groups = vk::linear_groups(uint64_t{dims[ua]} * dims[va], VOLUME_GROUP_SIZE);
        const auto axis_bindings = bindings(axis);
        pipelines[VOXELIZE_MODE_CAST].dispatch(cmd, std::span<const vk::Binding>(axis_bindings), push, groups.x, groups.y);
        recorder.compute_barrier();
        // The next axis's cast overwrites the rays this gather reads: the barrier after it orders them.
        pipelines[gather].dispatch(cmd, std::span<const vk::Binding>(axis_bindings), push, groups.x, groups.y);
        recorder.compute_barrier();
    }
    const auto voxel_groups = vk::linear_groups(grid.dims.count(), VOLUME_GROUP_SIZE);
    VoxelizePush combine{glm::uvec4(dims[0], dims[1], dims[2], 0), 0, kTileSize, 1, 0};
    pipelines[VOXELIZE_MODE_COMBINE].dispatch(cmd, std::span<const vk::Binding>(bindings(0)), combine, voxel_groups.x, voxel_groups.y);
    recorder.compute_barrier();
    if (smoothing) record_lattice_smoothing(recorder, dims, rest, scratch, coverage);
    return uploads;
}

}  // namespace refract::passes
