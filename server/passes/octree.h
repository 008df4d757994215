// Pass 3 (octree): min/max pyramid of n and the per-voxel leaf level (the paper's data-parallel octree),
// so photons and eye rays can step to the exit of the leaf cube they are in.
#pragma once

#include <array>
#include <span>
#include <vector>

#include "passes/index_field.h"
#include "passes/mode_pipelines.h"
#include "vk/commands.h"
#include "vk/pipeline.h"

namespace refract::passes {

struct OctreeLayout {
    uint32_t max_level = 0;
    std::array<uint32_t, 6> offsets{};  // first node of each level (1..max_level) in the pyramid buffer
    uint64_t node_count = 0;            // levels 1..max_level
    uint64_t cell_count = 0;            // level-1 nodes: the level map's entries
};

// Levels 0..max_level for a grid of `dims`; max_level = min(5, floor(log2(longest side)) - 1). The
// pyramid holds nodes of levels 1 and up: level 0 is where no level-1 node is a leaf.
OctreeLayout octree_layout(vk::Extent3 dims);

// The level map holds one level per level-1 node (its 2x2x2 voxels share every ancestor, so they share
// their leaf level); this expands it to one level per voxel.
std::vector<uint32_t> levels_per_voxel(std::span<const uint32_t> cell_levels, vk::Extent3 dims);

class OctreePass {
public:
    explicit OctreePass(vk::Context& context);

    // Reads n from `index_field`; writes the pyramid (vec2 per node, octree_layout(dims).node_count of
    // them) and `levels` (uint per level-1 node, octree_layout(dims).cell_count of them) where the
    // voxels of `region` reach: the level-1 nodes that read them, their ancestors, and the level map
    // under the top-level ones. The rest must hold the octree, for this epsilon, of a field that
    // differs from this one only inside `region`; the whole grid as region builds it all.
    void record(vk::CommandRecorder& recorder, const vk::Image3D& index_field, float epsilon, VoxelRange region,
                const vk::Buffer& pyramid, const vk::Buffer& levels) const;

private:
    ModePipelines pipelines_;  // by OCTREE_MODE_*
};

}  // namespace refract::passes
