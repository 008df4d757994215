#include "passes/index_field.h"

#include <algorithm>

#include "index_field_spv.h"
#include "volume_build.h"

namespace refract::passes {

using shaders::IndexFieldPush;

namespace {
constexpr vk::BindingLayout kLayout[] = {
    {INDEX_BINDING_COVERAGE, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {INDEX_BINDING_GRID, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {INDEX_BINDING_INDEX_FIELD, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE},
    {INDEX_BINDING_COVERAGE_IMAGE, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE},
};
}  // namespace

IndexFieldPass::IndexFieldPass(vk::Context& context)
    : pipelines_(context, index_field_spv, kLayout, sizeof(IndexFieldPush),
                 {"index field (uniform)", "index field (Luneburg)", "index field (Maxwell)", "index field (grid)"},
                 VOLUME_CONSTANT_MODE) {
    static_assert(INDEX_KIND_UNIFORM == 0 && INDEX_KIND_LUNEBURG == 1 && INDEX_KIND_MAXWELL == 2 &&
                  INDEX_KIND_GRID == 3);
}

namespace {
VoxelRange part_in(const FieldBlock& block, VoxelRange region) {
    return {glm::max(region.first, block.lattice.first), glm::min(region.end, block.lattice.end)};
}

// The part of a box of `dims` voxels at `offset` in the lattice that lies inside `within`.
VoxelRange part_of_box(glm::uvec3 offset, vk::Extent3 dims, VoxelRange within) {
    return {glm::max(within.first, offset), glm::min(within.end, offset + glm::uvec3(dims.x, dims.y, dims.z))};
}
}  // namespace

uint64_t largest_part(std::span<const FieldBlock> blocks, VoxelRange region) {
    uint64_t most = 0;
    for (const FieldBlock& block : blocks) most = std::max(most, part_in(block, region).count());
    return most;
}

VoxelRange IndexFieldPass::record(vk::CommandRecorder& recorder, const FieldShape& medium,
                                  const passes::GridGeometry& lattice, std::span<const ObjectField> objects,
                                  std::span<const FieldBlock> blocks, VoxelRange region, const vk::Buffer* zeros,
                                  const vk::Buffer& grid_values, const vk::Image3D& index_field,
                                  const vk::Image3D& coverage_image) const {
    const float n_medium = medium.n;
    // One dispatch: `object` over the part of `box` (its coverage's extent, at `offset` in the lattice)
    // inside `within`, written `shift` voxels from its place in the lattice; `number` 0 writes, else
    // joins (IndexFieldPush::offset).
    auto dispatch = [&](const FieldShape& shape, const passes::GridGeometry& box, glm::uvec3 offset,
                        const vk::Buffer& coverage, uint32_t number, VoxelRange within, glm::ivec3 shift) {
        const VoxelRange part = part_of_box(offset, box.dims, within);
        if (part.empty()) return;
        const glm::uvec3 extent = part.end - part.first;
        IndexFieldPush push{};
        push.dims = glm::uvec4(box.dims.x, box.dims.y, box.dims.z, 0);
        push.origin = glm::vec4(box.origin, box.voxel_size);
        push.offset = glm::uvec4(glm::uvec3(glm::ivec3(offset) + shift), number);
        push.first = glm::uvec4(part.first - offset, 0u);
        push.extent = glm::uvec4(extent, 0u);
        push.sphere = shape.sphere;
        push.n_medium = n_medium;
        push.n_object = shape.n;
        pipelines_[shape.kind].dispatch(recorder.get(),
                                  {vk::Binding::storage_buffer(INDEX_BINDING_COVERAGE, coverage),
                                   vk::Binding::storage_buffer(INDEX_BINDING_GRID, grid_values),
                                   vk::Binding::storage_image(INDEX_BINDING_INDEX_FIELD, index_field),
                                   vk::Binding::storage_image(INDEX_BINDING_COVERAGE_IMAGE, coverage_image)},
                                  push, vk::group_count(extent.x, VOLUME_GROUP_3D), vk::group_count(extent.y, VOLUME_GROUP_3D),
                                  vk::group_count(extent.z, VOLUME_GROUP_3D));
    };
    if (objects.size() == 1 && objects.front().number == 0) {
        const ObjectField& only = objects.front();
        dispatch(only.shape, only.box, only.offset, only.coverage, 0u, region, glm::ivec3(0));
        return region;
    }
    // Block by block, the part of the region there to the medium (a uniform object of the medium's
    // index and no coverage, numbered none), then the objects over it.
    VoxelRange written;
    for (const FieldBlock& block : blocks) {
        const VoxelRange part = part_in(block, region);
        if (part.empty()) continue;
        const glm::ivec3 shift = glm::ivec3(block.atlas_first) - glm::ivec3(block.lattice.first);
        const glm::uvec3 size = part.end - part.first;
        const passes::GridGeometry part_box{lattice.origin + lattice.voxel_size * glm::vec3(part.first),
                                           lattice.voxel_size, {size.x, size.y, size.z}};
        if (zeros) dispatch(medium, part_box, part.first, *zeros, 0u, part, shift);
        bool first = !zeros;
        for (const ObjectField& object : objects) {
            if (part_of_box(object.offset, object.box.dims, part).empty()) continue;
            if (!first) recorder.compute_barrier();  // each object's voxels join what those before it left
            first = false;
            dispatch(object.shape, object.box, object.offset, object.coverage, object.number, part, shift);
        }
        const VoxelRange stored{glm::uvec3(glm::ivec3(part.first) + shift), glm::uvec3(glm::ivec3(part.end) + shift)};
        written = written.empty() ? stored : VoxelRange{glm::min(written.first, stored.first), glm::max(written.end, stored.end)};
    }
    return written;
}

}  // namespace refract::passes
