#include "passes/view_refine.h"

#include "transport.h"
#include "view_refine_spv.h"

namespace refract::passes {

ViewRefinePass::ViewRefinePass(vk::Context& context)
    : pipeline_(context, view_refine_spv,
                {{TRANSPORT_BINDING_PARAMS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
                 {TRANSPORT_BINDING_HDR, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
                 {TRANSPORT_BINDING_REFINE, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
                 {TRANSPORT_BINDING_VIEW_ENDS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER}},
                sizeof(uint32_t), "view refinement") {}

void ViewRefinePass::record(vk::CommandRecorder& recorder, const vk::Buffer& params, const vk::Buffer& hdr,
                            const vk::Buffer& refine, const vk::Buffer& ends_buffer, bool ends, uint32_t width,
                            uint32_t height) const {
    const uint32_t write_ends = ends ? 1u : 0u;
    pipeline_.dispatch(recorder.get(),
                       {vk::Binding::storage_buffer(TRANSPORT_BINDING_PARAMS, params),
                        vk::Binding::storage_buffer(TRANSPORT_BINDING_HDR, hdr),
                        vk::Binding::storage_buffer(TRANSPORT_BINDING_REFINE, refine),
                        vk::Binding::storage_buffer(TRANSPORT_BINDING_VIEW_ENDS, ends_buffer)},
                       &write_ends, sizeof(write_ends), vk::group_count(width, VIEW_GROUP_SIZE),
                       vk::group_count(height, VIEW_GROUP_SIZE));
}

}  // namespace refract::passes
