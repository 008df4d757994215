#include "passes/tone_map.h"

#include "tone_map_spv.h"
#include "transport.h"

namespace refract::passes {

namespace {
constexpr vk::BindingLayout kLayout[] = {
    {TRANSPORT_BINDING_PARAMS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {TRANSPORT_BINDING_HDR, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {TRANSPORT_BINDING_LDR, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
};
}  // namespace

ToneMapPass::ToneMapPass(vk::Context& context) : pipeline_(context, tone_map_spv, kLayout, 0, "tone map") {}

void ToneMapPass::record(vk::CommandRecorder& recorder, const vk::Buffer& params, const vk::Buffer& hdr,
                         const vk::Buffer& ldr, uint32_t width, uint32_t height) const {
    const vk::Binding bindings[] = {vk::Binding::storage_buffer(TRANSPORT_BINDING_PARAMS, params),
                                    vk::Binding::storage_buffer(TRANSPORT_BINDING_HDR, hdr),
                                    vk::Binding::storage_buffer(TRANSPORT_BINDING_LDR, ldr)};
    const auto groups = vk::linear_groups(uint64_t{width} * height, TRANSPORT_GROUP_SIZE);
    pipeline_.dispatch(recorder.get(), bindings, nullptr, 0, groups.x, groups.y);
}

}  // namespace refract::passes
