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

namespace {
// The scene's own grid, at volume.resolution over its box.
GridGeometry scene_grid(const protocol::SceneDocument& document, const std::map<std::string, mesh::Mesh>& worlds) {
    const auto& volume = document.volume;
    if (volume.bounds) {
        const auto& b = *volume.bounds;
        return fit_grid(glm::vec3(b.min[0], b.min[1], b.min[2]), glm::vec3(b.max[0], b.max[1], b.max[2]),
                        volume.resolution);
    }
    glm::vec3 lo(1e30f), hi(-1e30f);
    for (const auto& [name, world] : worlds)
        for (const auto& p : world.positions) {
            lo = glm::min(lo, p);
            hi = glm::max(hi, p);
        }
    const float margin = static_cast<float>(volume.margin);
    return fit_grid(lo - margin, hi + margin, volume.resolution);
}

// The longest side of the box around `world` in the object's own frame (its mesh's bounds at its scale).
double own_extent(const protocol::Object& object, const mesh::Mesh& world) {
    const glm::dmat3 back = glm::transpose(
        mesh::rotation(glm::vec3(object.rotation_deg[0], object.rotation_deg[1], object.rotation_deg[2])));
    const glm::dvec3 position(object.position[0], object.position[1], object.position[2]);
    glm::dvec3 lo(1e300), hi(-1e300);
    for (const auto& p : world.positions) {
        const glm::dvec3 own = back * (glm::dvec3(p) - position);
        lo = glm::min(lo, own);
        hi = glm::max(hi, own);
    }
    const glm::dvec3 extent = hi - lo;
    return std::max({extent.x, extent.y, extent.z});
}
}  // namespace

GridGeometry grid_for(const protocol::SceneDocument& document, const std::map<std::string, mesh::Mesh>& worlds) {
    GridGeometry grid = scene_grid(document, worlds);
    uint32_t factor = 1;
    for (const auto& [name, object] : document.objects) {
        const auto world = worlds.find(name);
        if (object.resolution == 0 || world == worlds.end() || world->second.positions.empty()) continue;
        const double wanted = own_extent(object, world->second) / object.resolution;  // the object's voxel
        const double ratio = std::ceil(double{grid.voxel_size} / wanted - 1e-6);
        factor = std::max(factor, static_cast<uint32_t>(std::clamp(ratio, 1.0, double{kMaxLightFactor})));
    }
    grid.voxel_size /= static_cast<float>(factor);
    grid.dims = {grid.dims.x * factor, grid.dims.y * factor, grid.dims.z * factor};
    grid.light_factor = factor;
    return grid;
}

ObjectBox object_box(const GridGeometry& lattice, const mesh::Mesh& world, uint32_t apron) {
    glm::vec3 lo(1e30f), hi(-1e30f);
    for (const auto& p : world.positions) {
        lo = glm::min(lo, p);
        hi = glm::max(hi, p);
    }
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
