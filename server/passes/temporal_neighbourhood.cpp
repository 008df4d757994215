#include "passes/temporal_neighbourhood.h"

#include "temporal_neighbourhood_spv.h"

namespace refract::passes {

TemporalNeighbourhoodPass::TemporalNeighbourhoodPass(vk::Context& context)
    : pipeline_(context, temporal_neighbourhood_spv,
                {{TEMPORAL_BINDING_PARAMS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
                 {TEMPORAL_BINDING_SAMPLES, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
                 {TEMPORAL_BINDING_NEIGHBOURHOOD, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER}},
                0, "temporal neighbourhood") {}

void TemporalNeighbourhoodPass::record(vk::CommandRecorder& recorder, const vk::Buffer& params,
                                       const vk::Buffer& samples, const vk::Buffer& neighbourhood, uint32_t width,
                                       uint32_t height) const {
    pipeline_.dispatch(recorder.get(),
                       {vk::Binding::storage_buffer(TEMPORAL_BINDING_PARAMS, params),
                        vk::Binding::storage_buffer(TEMPORAL_BINDING_SAMPLES, samples),
                        vk::Binding::storage_buffer(TEMPORAL_BINDING_NEIGHBOURHOOD, neighbourhood)},
                       nullptr, 0, vk::group_count(width, TEMPORAL_GROUP_SIZE), vk::group_count(height, TEMPORAL_GROUP_SIZE));
}

}  // namespace refract::passes
