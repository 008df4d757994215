#include "passes/view.h"

#include "transport.h"
#include "view_spv.h"

#include <cstddef>

namespace refract::passes {

namespace {
constexpr vk::BindingLayout kLayout[] = {
    {TRANSPORT_BINDING_PARAMS, VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER},
    {TRANSPORT_BINDING_INDEX_FIELD, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER},
    {TRANSPORT_BINDING_COVERAGE, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER},
    {TRANSPORT_BINDING_LEVELS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {TRANSPORT_BINDING_RADIANCE, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER},
    {TRANSPORT_BINDING_FLUX, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER},
    {TRANSPORT_BINDING_FLOOR_MAP, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER},
    {TRANSPORT_BINDING_HDR, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {TRANSPORT_BINDING_LDR, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {TRANSPORT_BINDING_STATS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {TRANSPORT_BINDING_LIT_BLOCKS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
};
}  // namespace

ViewPass::ViewPass(vk::Context& context) : pipeline_(context, view_spv, kLayout, "view") {}

void ViewPass::record(vk::CommandRecorder& recorder, const TransportInputs& in, const vk::Image3D& radiance,
                      const vk::Image3D& flux, const vk::Image3D& floor_map, const ViewOutputs& out,
                      uint32_t width, uint32_t height) const {
    // Only the view's counters restart (steps and the pixel queue, adjacent): the photon pass's counters
    // belong to the last photon run.
    static_assert(offsetof(shaders::PhotonStats, queue_taken) + 4 * QUEUE_VIEW_PIXELS ==
                  offsetof(shaders::PhotonStats, view_steps) + 4);
    vkCmdFillBuffer(recorder.get(), out.stats.get(), offsetof(shaders::PhotonStats, view_steps), 2 * sizeof(uint32_t), 0);
    recorder.transfer_to_compute_barrier();
    pipeline_(in.variant).dispatch(recorder.get(),
                                {vk::Binding::uniform_buffer(TRANSPORT_BINDING_PARAMS, in.params),
                                 vk::Binding::sampled_image(TRANSPORT_BINDING_INDEX_FIELD, in.index_field, in.sampler),
                                 vk::Binding::sampled_image(TRANSPORT_BINDING_COVERAGE, in.coverage, in.sampler),
                                 vk::Binding::storage_buffer(TRANSPORT_BINDING_LEVELS, in.levels),
                                 vk::Binding::sampled_image(TRANSPORT_BINDING_RADIANCE, radiance, in.sampler),
                                 vk::Binding::sampled_image(TRANSPORT_BINDING_FLUX, flux, in.sampler),
                                 vk::Binding::sampled_image(TRANSPORT_BINDING_FLOOR_MAP, floor_map, in.sampler),
                                 vk::Binding::storage_buffer(TRANSPORT_BINDING_HDR, out.hdr),
                                 vk::Binding::storage_buffer(TRANSPORT_BINDING_LDR, out.ldr),
                                 vk::Binding::storage_buffer(TRANSPORT_BINDING_STATS, out.stats),
                                 vk::Binding::storage_buffer(TRANSPORT_BINDING_LIT_BLOCKS, out.lit_blocks)},
                                nullptr, 0, vk::group_count(width, VIEW_GROUP_SIZE),
                                vk::group_count(height, VIEW_GROUP_SIZE));
}

}  // namespace refract::passes
