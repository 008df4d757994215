#include "passes/lit_pyramid.h"

#include "lit_pyramid_spv.h"
#include "passes/transport_params.h"
#include "transport.h"

namespace refract::passes {

namespace {
constexpr vk::BindingLayout kLayout[] = {
    {TRANSPORT_BINDING_PARAMS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {TRANSPORT_BINDING_FLUX, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE},
    {TRANSPORT_BINDING_LIT_BLOCKS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
};
}  // namespace

LitPyramidPass::LitPyramidPass(vk::Context& context)
    : pipelines_(context, lit_pyramid_spv, kLayout, sizeof(shaders::LitPyramidPush),
                 {"lit pyramid (level 0)", "lit pyramid (merge)", "lit pyramid (unlit counts)"}, LIT_CONSTANT_MODE) {
    static_assert(LIT_MODE_BASE == 0 && LIT_MODE_MERGE == 1 && LIT_MODE_COUNT == 2);
}

void LitPyramidPass::record(vk::CommandRecorder& recorder, const vk::Buffer& params, const vk::Image3D& flux,
                            const vk::Buffer& lit_blocks, vk::Extent3 scene_dims) const {
    const vk::Binding bindings[] = {vk::Binding::storage_buffer(TRANSPORT_BINDING_PARAMS, params),
                                    vk::Binding::storage_image(TRANSPORT_BINDING_FLUX, flux),
                                    vk::Binding::storage_buffer(TRANSPORT_BINDING_LIT_BLOCKS, lit_blocks)};
    const auto offsets = lit_pyramid_offsets(scene_dims);
    const auto groups_at = [&](uint32_t level) {
        return vk::linear_groups(offsets[level + 1] - offsets[level], TRANSPORT_GROUP_SIZE);
    };
    for (uint32_t level = 0; level < LIT_LEVELS; ++level) {
        if (level > 0) recorder.compute_barrier();
        const auto groups = groups_at(level);
        pipelines_[level == 0 ? LIT_MODE_BASE : LIT_MODE_MERGE].dispatch(recorder.get(), bindings, shaders::LitPyramidPush{level}, groups.x, groups.y);
    }
    recorder.compute_barrier();
    const auto groups = groups_at(0);
    pipelines_[LIT_MODE_COUNT].dispatch(recorder.get(), bindings, shaders::LitPyramidPush{0}, groups.x, groups.y);
}

}  // namespace refract::passes
