#include "passes/view_refine.h"

#include "transport.h"
#include "view_refine_spv.h"

namespace refract::passes {

ViewRefinePass::ViewRefinePass(vk::Context& context)
    : pipeline_(context, view_refine_spv,
                {{TRANSPORT_BINDING_PARAMS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
                 {TRANSPORT_BINDING_HDR, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
                 {TRANSPORT_BINDING_REFINE, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER}},
                0, "view refinement") {}

void ViewRefinePass::record(vk::CommandRecorder& recorder, const vk::Buffer& params, const vk::Buffer& hdr,
                            const vk::Buffer& refine, uint32_t width, uint32_t height) const {
    pipeline_.dispatch(recorder.get(),
                       {vk::Binding::storage_buffer(TRANSPORT_BINDING_PARAMS, params),
                        vk::Binding::storage_buffer(TRANSPORT_BINDING_HDR, hdr),
                        vk::Binding::storage_buffer(TRANSPORT_BINDING_REFINE, refine)},
                       nullptr, 0, vk::group_count(width, VIEW_GROUP_SIZE), vk::group_count(height, VIEW_GROUP_SIZE));
}

}  // namespace refract::passes
