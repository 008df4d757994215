#include "render/scene_lattice.h"

#include <algorithm>
#include <cmath>

namespace refract::scene {

namespace {
// The scene's own grid, at volume.resolution over its box.
passes::GridGeometry scene_grid(const protocol::SceneDocument& document, const std::map<std::string, mesh::Mesh>& worlds,
                                const Densities& densities) {
    const auto& volume = document.volume;
    if (volume.bounds) {
        const auto& b = *volume.bounds;
        return passes::fit_grid(glm::vec3(b.min[0], b.min[1], b.min[2]), glm::vec3(b.max[0], b.max[1], b.max[2]),
                        volume.resolution);
    }
    glm::vec3 lo(1e30f), hi(-1e30f);
    for (const auto& [name, world] : worlds) {
        const mesh::Bounds box = mesh::bounds(world);
        lo = glm::min(lo, box.min);
        hi = glm::max(hi, box.max);
    }
    for (const auto& [name, member] : document.volumes) {
        const auto grids = densities.find(name);
        if (grids == densities.end()) continue;
        for (const auto& grid : {grids->second.density, grids->second.emission}) {
            glm::dvec3 box_lo, box_hi;
            if (!grid || !volume_world_box(member, *grid, box_lo, box_hi)) continue;
            lo = glm::min(lo, glm::vec3(box_lo));
            hi = glm::max(hi, glm::vec3(box_hi));
        }
    }
    const float margin = static_cast<float>(volume.margin);
    return passes::fit_grid(lo - margin, hi + margin, volume.resolution);
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

passes::GridGeometry grid_for(const protocol::SceneDocument& document, const std::map<std::string, mesh::Mesh>& worlds,
                              const Densities& densities) {
    passes::GridGeometry grid = scene_grid(document, worlds, densities);
    uint32_t factor = 1;
    for (const auto& [name, object] : document.objects) {
        const auto world = worlds.find(name);
        if (object.resolution == 0 || world == worlds.end() || world->second.positions.empty()) continue;
        const double wanted = own_extent(object, world->second) / object.resolution;  // the object's voxel
        const double ratio = std::ceil(double{grid.voxel_size} / wanted - 1e-6);
        factor = std::max(factor, static_cast<uint32_t>(std::clamp(ratio, 1.0, double{passes::kMaxLightFactor})));
    }
    grid.voxel_size /= static_cast<float>(factor);
    grid.dims = {grid.dims.x * factor, grid.dims.y * factor, grid.dims.z * factor};
    grid.light_factor = factor;
    return grid;
}

}  // namespace refract::scene
