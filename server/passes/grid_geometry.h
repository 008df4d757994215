// Where the voxel grid sits in the world: cubic voxels, `resolution` of them along the longest axis.
#pragma once

#include <glm/glm.hpp>

#include "vk/resources.h"

namespace refract::mesh {
struct Mesh;
}

namespace refract::passes {

struct GridGeometry {
    glm::vec3 origin{0.0f};  // world position of the min corner
    float voxel_size = 0.0f;  // metres
    vk::Extent3 dims{};
    // Lattice voxels per voxel of the scene's own grid (volume.resolution over its box) along each axis:
    // more than 1 where an object asks for finer voxels (protocol::Object::resolution); the radiance
    // grid keeps the scene's voxel.
    uint32_t light_factor = 1;
    glm::vec3 max_corner() const {
        return origin + voxel_size * glm::vec3(static_cast<float>(dims.x), static_cast<float>(dims.y),
                                               static_cast<float>(dims.z));
    }
    glm::vec3 to_voxel(glm::vec3 world) const { return (world - origin) / voxel_size; }
    // Voxels of a grid over the same box whose voxels are `factor` of these wide (rounded up).
    vk::Extent3 coarsened(uint32_t factor) const {
        return {(dims.x + factor - 1) / factor, (dims.y + factor - 1) / factor, (dims.z + factor - 1) / factor};
    }
    bool operator==(const GridGeometry&) const = default;
};

// Fits a grid with `resolution` voxels along the longest side of the box [lo, hi].
GridGeometry fit_grid(glm::vec3 lo, glm::vec3 hi, uint32_t resolution);

// Most lattice voxels per scene voxel an object's resolution can ask for, along each axis.
inline constexpr uint32_t kMaxLightFactor = 8;

// An object's own box in the scene's lattice: the lattice's voxels from `offset` on that hold its world
// bounds grown by `apron` voxels (where its smoothed coverage can reach), clipped to the lattice;
// empty (a zero side) where it lies outside. In a scene of one object its box is the whole lattice.
struct ObjectBox {
    GridGeometry box;
    glm::uvec3 offset{0u};
    bool empty() const { return box.dims.count() == 0; }
};
ObjectBox object_box(const GridGeometry& lattice, const mesh::Mesh& world, uint32_t apron);

}  // namespace refract::passes
