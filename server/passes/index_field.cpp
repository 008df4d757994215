#include "passes/index_field.h"

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

void IndexFieldPass::record(vk::CommandRecorder& recorder, const protocol::Medium& medium,
                            std::span<const ObjectField> objects, const vk::Buffer& grid_values,
                            const vk::Image3D& index_field, const vk::Image3D& coverage_image) const {
    using protocol::IndexFieldKind;
    const bool several = objects.size() > 1;
    if (several) {
        // Where no object's box reaches: the medium, no coverage, no object.
        const float n_medium = static_cast<float>(medium.ior);
        recorder.clear(index_field, {n_medium, 0.0f, 0.0f, 0.0f});
        recorder.clear(coverage_image, {0.0f, 0.0f, 0.0f, 0.0f});
        recorder.transfer_to_compute_barrier();
    }
    for (size_t i = 0; i < objects.size(); ++i) {
        const ObjectField& part = objects[i];
        const protocol::Object& object = part.object;
        uint32_t kind = INDEX_KIND_UNIFORM;
        float n_object = static_cast<float>(object.ior);
        switch (object.index_field) {
            case IndexFieldKind::uniform: kind = INDEX_KIND_UNIFORM; break;
            case IndexFieldKind::luneburg: kind = INDEX_KIND_LUNEBURG; break;
            case IndexFieldKind::maxwell:
                kind = INDEX_KIND_MAXWELL;
                n_object = static_cast<float>(object.maxwell_n0);
                break;
            case IndexFieldKind::grid: kind = INDEX_KIND_GRID; break;
        }
        const auto& dims = part.box.dims;
        IndexFieldPush push{};
        push.dims = glm::uvec4(dims.x, dims.y, dims.z, 0);
        push.origin = glm::vec4(part.box.origin, part.box.voxel_size);
        push.offset = glm::uvec4(part.offset, several ? static_cast<uint32_t>(i) + 1u : 0u);
        push.sphere = glm::vec4(static_cast<float>(object.position[0]), static_cast<float>(object.position[1]),
                                static_cast<float>(object.position[2]), static_cast<float>(object.scale));
        push.n_medium = static_cast<float>(medium.ior);
        push.n_object = n_object;
        if (i > 0) recorder.compute_barrier();  // each object's voxels join what those before it left
        pipelines_[kind].dispatch(recorder.get(),
                                  {vk::Binding::storage_buffer(INDEX_BINDING_COVERAGE, part.coverage),
                                   vk::Binding::storage_buffer(INDEX_BINDING_GRID, grid_values),
                                   vk::Binding::storage_image(INDEX_BINDING_INDEX_FIELD, index_field),
                                   vk::Binding::storage_image(INDEX_BINDING_COVERAGE_IMAGE, coverage_image)},
                                  push, vk::group_count(dims.x, VOLUME_GROUP_3D), vk::group_count(dims.y, VOLUME_GROUP_3D),
                                  vk::group_count(dims.z, VOLUME_GROUP_3D));
    }
}

}  // namespace refract::passes
