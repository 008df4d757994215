#include "passes/view_upscale.h"

#include "transport.h"
#include "view_upscale_spv.h"

namespace refract::passes {

namespace {
constexpr vk::BindingLayout kOwnLayout[] = {
    {TRANSPORT_BINDING_FLOOR_MAP, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER},
    {TRANSPORT_BINDING_VIEW_ENDS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {TRANSPORT_BINDING_VIEWER_HDR, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {TRANSPORT_BINDING_VIEWER_LDR, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
};
constexpr auto kLayout = transport_layout(kOwnLayout);
}  // namespace

ViewUpscalePass::ViewUpscalePass(vk::Context& context)
    : pipeline_(context, view_upscale_spv, kLayout, sizeof(shaders::UpscalePush), "view upscale") {}

void ViewUpscalePass::record(vk::CommandRecorder& recorder, const TransportInputs& in, const vk::Image3D& floor_map,
                             const UpscaleBuffers& buffers, uint32_t width, uint32_t height) const {
    const vk::Binding own[] = {vk::Binding::sampled_image(TRANSPORT_BINDING_FLOOR_MAP, floor_map, in.sampler),
                               vk::Binding::storage_buffer(TRANSPORT_BINDING_VIEW_ENDS, buffers.ends),
                               vk::Binding::storage_buffer(TRANSPORT_BINDING_VIEWER_HDR, buffers.viewer_hdr),
                               vk::Binding::storage_buffer(TRANSPORT_BINDING_VIEWER_LDR, buffers.viewer_ldr)};
    const shaders::UpscalePush push{glm::uvec2(width, height)};
    pipeline_.dispatch(recorder.get(), transport_bindings(in, own), push, vk::group_count(width, VIEW_GROUP_SIZE),
                       vk::group_count(height, VIEW_GROUP_SIZE));
}

}  // namespace refract::passes
