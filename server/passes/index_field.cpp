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

void IndexFieldPass::record(vk::CommandRecorder& recorder, const protocol::SceneDocument& document,
                            const scene::GridGeometry& grid, const vk::Buffer& coverage,
                            const vk::Buffer& grid_values, const vk::Image3D& index_field,
                            const vk::Image3D& coverage_image) const {
    using protocol::IndexFieldKind;
    const auto& object = document.object();
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
    IndexFieldPush push{};
    push.dims = glm::uvec4(grid.dims.x, grid.dims.y, grid.dims.z, 0);
    push.origin = glm::vec4(grid.origin, grid.voxel_size);
    push.sphere = glm::vec4(static_cast<float>(object.position[0]), static_cast<float>(object.position[1]),
                            static_cast<float>(object.position[2]), static_cast<float>(object.scale));
    push.n_medium = static_cast<float>(document.medium.ior);
    push.n_object = n_object;
    pipelines_[kind].dispatch(recorder.get(),
                       {vk::Binding::storage_buffer(INDEX_BINDING_COVERAGE, coverage),
                        vk::Binding::storage_buffer(INDEX_BINDING_GRID, grid_values),
                        vk::Binding::storage_image(INDEX_BINDING_INDEX_FIELD, index_field),
                        vk::Binding::storage_image(INDEX_BINDING_COVERAGE_IMAGE, coverage_image)},
                       push, vk::group_count(grid.dims.x, VOLUME_GROUP_3D), vk::group_count(grid.dims.y, VOLUME_GROUP_3D),
                       vk::group_count(grid.dims.z, VOLUME_GROUP_3D));
}

}  // namespace refract::passes
