// Where the index field of a scene lives on the device: memory that follows the objects rather than the
// cube of the scene's box. Outside every object's box the field is the medium's (n constant, grad n
// zero, no coverage), so a scene of several objects stores it only in clusters of their boxes, packed
// into one atlas image; a coarse map of the lattice says, per cell, which cluster holds it or how far
// the medium around it reaches (transport.h, FIELD_*). A scene of one object keeps the dense lattice:
// its layout is one cluster, the whole lattice, at the atlas's origin.
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include <glm/glm.hpp>

#include "passes/grid_geometry.h"
#include "transport.h"
#include "vk/resources.h"

namespace refract::scene {

struct FieldAtlas {
    // One cluster: the lattice voxels [first, end) of one or more objects' boxes joined (grown to whole
    // map cells, so that no two clusters share a cell), stored from atlas_first on.
    struct Cluster {
        glm::uvec3 first{0u}, end{0u};
        glm::uvec3 atlas_first{0u};
        bool operator==(const Cluster&) const = default;
        glm::uvec3 extent() const { return end - first; }
        bool contains(glm::uvec3 v) const { return glm::all(glm::greaterThanEqual(v, first)) && glm::all(glm::lessThan(v, end)); }
    };
    std::vector<Cluster> clusters;
    vk::Extent3 dims{};       // the atlas's voxels
    bool dense = true;        // one cluster, the whole lattice, no map (a scene of one object)
    vk::Extent3 cells{};      // the map's cells (FIELD_CELL voxels a side) over the lattice
    std::vector<uint32_t> map;  // a word per cell (FIELD_*), x fastest

    bool operator==(const FieldAtlas&) const = default;
    uint32_t map_entry(glm::uvec3 cell) const { return map[(size_t{cell.z} * cells.y + cell.y) * cells.x + cell.x]; }
    // Where lattice voxel v is stored in the atlas (as the shaders find it), if a cluster holds it.
    std::optional<glm::uvec3> atlas_voxel(glm::uvec3 v) const;
};

// The dense layout of a scene of one object (or an imported grid): the atlas is the lattice.
FieldAtlas dense_field_atlas(const passes::GridGeometry& lattice);

// The layout of several objects' `boxes` (lattice voxels [first, end) each; empty ones hold nothing):
// each box grown to whole map cells, overlapping ones joined until no two share a cell, packed in
// rows, rows in layers, each at most `max_side` voxels (and what the map can address); `max_level` is
// the highest octree level a ray in the medium may step by (the lattice octree's). Throws
// std::length_error when the clusters do not fit.
FieldAtlas sparse_field_atlas(const passes::GridGeometry& lattice, std::span<const std::pair<glm::uvec3, glm::uvec3>> boxes,
                              uint32_t max_level, uint32_t max_side);

}  // namespace refract::scene
