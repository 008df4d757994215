#include "passes/grid_geometry.h"

#include <algorithm>
#include <cmath>

#include "mesh/mesh.h"

namespace refract::passes {

GridGeometry fit_grid(glm::vec3 lo, glm::vec3 hi, uint32_t resolution) {
    const glm::vec3 extent = hi - lo;
    const float longest = std::max({extent.x, extent.y, extent.z});
    GridGeometry grid;
    grid.voxel_size = longest / static_cast<float>(resolution);
    auto count = [&](float e) { return std::max(1u, static_cast<uint32_t>(std::ceil(e / grid.voxel_size - 1e-4f))); };
    grid.dims = {count(extent.x), count(extent.y), count(extent.z)};
    // Centre the (slightly larger) voxel box on the requested box.
    const glm::vec3 covered = grid.voxel_size * glm::vec3(static_cast<float>(grid.dims.x),
                                                          static_cast<float>(grid.dims.y),
                                                          static_cast<float>(grid.dims.z));
    grid.origin = lo - 0.5f * (covered - extent);
    return grid;
}

ObjectBox object_box(const GridGeometry& lattice, const mesh::Mesh& world, uint32_t apron) {
    const auto [lo, hi] = mesh::bounds(world);
    const glm::vec3 dims(static_cast<float>(lattice.dims.x), static_cast<float>(lattice.dims.y),
                         static_cast<float>(lattice.dims.z));
    const float reach = static_cast<float>(apron);
    const glm::vec3 first = glm::clamp(glm::floor(lattice.to_voxel(lo) - reach), glm::vec3(0.0f), dims);
    const glm::vec3 end = glm::clamp(glm::ceil(lattice.to_voxel(hi) + reach), first, dims);
    ObjectBox b;
    b.offset = glm::uvec3(first);
    const glm::uvec3 size = glm::uvec3(end) - b.offset;
    b.box.voxel_size = lattice.voxel_size;
    b.box.origin = lattice.origin + lattice.voxel_size * first;
    b.box.dims = {size.x, size.y, size.z};
    return b;
}

}  // namespace refract::passes
