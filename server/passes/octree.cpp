#include "passes/octree.h"

#include <algorithm>
#include <bit>

#include "octree_spv.h"
#include "volume_build.h"

namespace refract::passes {

using shaders::OctreePush;

OctreeLayout octree_layout(vk::Extent3 dims) {
    OctreeLayout layout;
    const uint32_t longest = std::max({dims.x, dims.y, dims.z});
    const uint32_t log2 = static_cast<uint32_t>(std::bit_width(longest)) - 1;
    layout.max_level = std::min<uint32_t>(OCTREE_MAX_LEVEL, log2 > 1 ? log2 - 1 : 0);
    uint64_t offset = 0;
    for (uint32_t level = 1; level <= layout.max_level; ++level) {
        layout.offsets[level] = static_cast<uint32_t>(offset);
        const uint32_t step = 1u << level;
        offset += uint64_t{(dims.x + step - 1) / step} * ((dims.y + step - 1) / step) * ((dims.z + step - 1) / step);
    }
    layout.node_count = offset;
    layout.cell_count = uint64_t{(dims.x + 1) / 2} * ((dims.y + 1) / 2) * ((dims.z + 1) / 2);
    return layout;
}

std::vector<uint32_t> levels_per_voxel(std::span<const uint32_t> cell_levels, vk::Extent3 dims) {
    const uint32_t cells_x = (dims.x + 1) / 2, cells_y = (dims.y + 1) / 2;
    std::vector<uint32_t> levels(dims.count());
    for (uint32_t z = 0; z < dims.z; ++z)
        for (uint32_t y = 0; y < dims.y; ++y)
            for (uint32_t x = 0; x < dims.x; ++x)
                levels[(size_t{z} * dims.y + y) * dims.x + x] =
                    cell_levels[(size_t{z / 2} * cells_y + y / 2) * cells_x + x / 2];
    return levels;
}

namespace {
constexpr vk::BindingLayout kLayout[] = {
    {OCTREE_BINDING_INDEX_FIELD, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE},
    {OCTREE_BINDING_PYRAMID, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {OCTREE_BINDING_LEVELS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
};

// The level-1 nodes whose range reads a voxel of `region`: node k reads voxels 2k - 1 .. 2k + 2. A box
// of one level's nodes is a VoxelRange in that level's units.
VoxelRange level1_nodes(VoxelRange region, glm::uvec3 level1_dims) {
    return {(glm::max(region.first, glm::uvec3(1u)) - 1u) / 2u, glm::min(region.end / 2u + 1u, level1_dims)};
}

// The parents of `nodes`.
VoxelRange parents(VoxelRange nodes) { return {nodes.first / 2u, (nodes.end + 1u) / 2u}; }
}  // namespace

OctreePass::OctreePass(vk::Context& context)
    : pipelines_(context, octree_spv, kLayout, sizeof(OctreePush),
                 {"octree level-1 ranges", "octree reduce", "octree level map"}, VOLUME_CONSTANT_MODE) {
    static_assert(OCTREE_MODE_LEVEL1_RANGE == 0 && OCTREE_MODE_REDUCE == 1 && OCTREE_MODE_LEVEL_MAP == 2);
}

void OctreePass::record(vk::CommandRecorder& recorder, const vk::Image3D& index_field, float epsilon, VoxelRange region,
                        const vk::Buffer& pyramid, const vk::Buffer& levels) const {
    const vk::Extent3 dims = index_field.extent();
    region.end = glm::min(region.end, glm::uvec3(dims.x, dims.y, dims.z));
    if (region.empty()) return;
    const OctreeLayout layout = octree_layout(dims);
    OctreePush push{};
    push.dims = glm::uvec4(dims.x, dims.y, dims.z, 0);
    push.offsets0 = glm::uvec4(layout.offsets[0], layout.offsets[1], layout.offsets[2], layout.offsets[3]);
    push.offsets1 = glm::uvec4(layout.offsets[4], layout.offsets[5], layout.max_level, 0);
    push.epsilon = epsilon;
    const std::initializer_list<vk::Binding> bindings = {
        vk::Binding::storage_image(OCTREE_BINDING_INDEX_FIELD, index_field),
        vk::Binding::storage_buffer(OCTREE_BINDING_PYRAMID, pyramid),
        vk::Binding::storage_buffer(OCTREE_BINDING_LEVELS, levels)};
    const VkCommandBuffer cmd = recorder.get();
    auto dispatch = [&](uint32_t mode, VoxelRange nodes) {
        push.first = glm::uvec4(nodes.first, 0u);
        push.extent = glm::uvec4(nodes.end - nodes.first, 0u);
        const auto groups = vk::linear_groups(nodes.count(), VOLUME_GROUP_SIZE);
        pipelines_[mode].dispatch(cmd, bindings, push, groups.x, groups.y);
    };
    // Level 1 over the nodes that read a changed voxel, then each level over the parents of the nodes
    // changed below it (all of a level when the region is the whole grid): a barrier between levels.
    const glm::uvec3 level1_dims((dims.x + 1) / 2, (dims.y + 1) / 2, (dims.z + 1) / 2);
    VoxelRange changed = level1_nodes(region, level1_dims);
    for (uint32_t level = 1; level <= layout.max_level; ++level) {
        if (level > 1) changed = parents(changed);
        push.dims.w = level;
        dispatch(level == 1 ? OCTREE_MODE_LEVEL1_RANGE : OCTREE_MODE_REDUCE, changed);
        recorder.compute_barrier();
    }
    // A level-1 node's leaf level reads every ancestor up to the top level, so the map is remade under
    // the changed top-level nodes: the region grown to the top level's node alignment.
    const uint32_t shift = layout.max_level > 1 ? layout.max_level - 1 : 0;
    dispatch(OCTREE_MODE_LEVEL_MAP, {changed.first << shift, glm::min(changed.end << shift, level1_dims)});
}

}  // namespace refract::passes
