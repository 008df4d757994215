#include "passes/view.h"

#include "transport.h"
#include "view_spv.h"

namespace refract::passes {

ViewPass::ViewPass(vk::Context& context)
    : pipeline_(context, view_spv,
                {{TRANSPORT_BINDING_PARAMS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
                 {TRANSPORT_BINDING_INDEX_FIELD, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER},
                 {TRANSPORT_BINDING_COVERAGE, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER},
                 {TRANSPORT_BINDING_LEVELS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
                 {TRANSPORT_BINDING_RADIANCE, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER},
                 {TRANSPORT_BINDING_DIRECTION, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER},
                 {TRANSPORT_BINDING_FLOOR_MAP, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER},
                 {TRANSPORT_BINDING_HDR, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
                 {TRANSPORT_BINDING_LDR, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER}},
                0, "view") {}

void ViewPass::record(vk::CommandRecorder& recorder, const TransportInputs& in, const vk::Image3D& radiance,
                      const vk::Image3D& direction, const vk::Image3D& floor_map, const ViewOutputs& out,
                      uint32_t width, uint32_t height) const {
    pipeline_.dispatch(recorder.get(),
                       {vk::Binding::storage_buffer(TRANSPORT_BINDING_PARAMS, in.params),
                        vk::Binding::sampled_image(TRANSPORT_BINDING_INDEX_FIELD, in.index_field, in.sampler),
                        vk::Binding::sampled_image(TRANSPORT_BINDING_COVERAGE, in.coverage, in.sampler),
                        vk::Binding::storage_buffer(TRANSPORT_BINDING_LEVELS, in.levels),
                        vk::Binding::sampled_image(TRANSPORT_BINDING_RADIANCE, radiance, in.sampler),
                        vk::Binding::sampled_image(TRANSPORT_BINDING_DIRECTION, direction, in.sampler),
                        vk::Binding::sampled_image(TRANSPORT_BINDING_FLOOR_MAP, floor_map, in.sampler),
                        vk::Binding::storage_buffer(TRANSPORT_BINDING_HDR, out.hdr),
                        vk::Binding::storage_buffer(TRANSPORT_BINDING_LDR, out.ldr)},
                       nullptr, 0, vk::group_count(width, VIEW_GROUP_SIZE), vk::group_count(height, VIEW_GROUP_SIZE));
}

}  // namespace refract::passes
