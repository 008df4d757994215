// Where the voxel grid sits in the world: cubic voxels, `resolution` of them along the longest axis.
#pragma once

#include <glm/glm.hpp>

#include "protocol/scene_document.h"
#include "vk/resources.h"

namespace refract::mesh {
struct Mesh;
}

namespace refract::scene {

struct GridGeometry {
    glm::vec3 origin{0.0f};  // world position of the min corner
    float voxel_size = 0.0f;  // metres
    vk::Extent3 dims{};
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

// The grid a document asks for: volume.bounds when given, else the object's world bounds grown by
// volume.margin (procedural lenses: the sphere of radius scale around position).
GridGeometry grid_for(const protocol::SceneDocument& document, const mesh::Mesh& object_world);

}  // namespace refract::scene
