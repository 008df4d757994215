#include "passes/temporal_reuse.h"

#include "temporal_reuse_spv.h"

namespace refract::passes {

namespace {
constexpr vk::BindingLayout kLayout[] = {
    {TEMPORAL_BINDING_PARAMS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {TEMPORAL_BINDING_SAMPLES, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {TEMPORAL_BINDING_HISTORY_IN, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {TEMPORAL_BINDING_DEPTH_IN, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {TEMPORAL_BINDING_HISTORY_OUT, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {TEMPORAL_BINDING_DEPTH_OUT, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {TEMPORAL_BINDING_LDR, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {TEMPORAL_BINDING_NEIGHBOURHOOD, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
};
}  // namespace

TemporalReusePass::TemporalReusePass(vk::Context& context)
    : pipeline_(context, temporal_reuse_spv, kLayout, 0, "temporal reuse") {}

void TemporalReusePass::record(vk::CommandRecorder& recorder, const Buffers& buffers, uint32_t width,
                               uint32_t height) const {
    const vk::Binding bindings[] = {
        vk::Binding::storage_buffer(TEMPORAL_BINDING_PARAMS, buffers.params),
        vk::Binding::storage_buffer(TEMPORAL_BINDING_SAMPLES, buffers.samples),
        vk::Binding::storage_buffer(TEMPORAL_BINDING_HISTORY_IN, buffers.history_in),
        vk::Binding::storage_buffer(TEMPORAL_BINDING_DEPTH_IN, buffers.depth_in),
        vk::Binding::storage_buffer(TEMPORAL_BINDING_HISTORY_OUT, buffers.history_out),
        vk::Binding::storage_buffer(TEMPORAL_BINDING_DEPTH_OUT, buffers.depth_out),
        vk::Binding::storage_buffer(TEMPORAL_BINDING_LDR, buffers.ldr),
        vk::Binding::storage_buffer(TEMPORAL_BINDING_NEIGHBOURHOOD, buffers.neighbourhood)};
    pipeline_.dispatch(recorder.get(), bindings, nullptr, 0, vk::group_count(width, TEMPORAL_GROUP_SIZE),
                       vk::group_count(height, TEMPORAL_GROUP_SIZE));
}

}  // namespace refract::passes
