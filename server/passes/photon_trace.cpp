#include "passes/photon_trace.h"

#include <algorithm>

#include "passes/transport_params.h"
#include "photon_trace_spv.h"
#include "transport.h"

namespace refract::passes {

PhotonAccumulators make_photon_accumulators(vk::Context& context, vk::Extent3 dims, vk::Extent3 radiance_dims,
                                            uint32_t floor_texels, uint32_t exit_count, bool grey) {
    const uint64_t voxels = radiance_dims.count();
    const auto usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT;
    PhotonAccumulators accum;
    accum.red_green = vk::Buffer(context, (grey ? 1 : voxels) * sizeof(uint64_t), usage, vk::MemoryUse::device,
                                 "radiance sums red+green");
    accum.flux = vk::Buffer(context, voxels * RADIANCE_FLUX_WORDS * sizeof(uint64_t), usage, vk::MemoryUse::device,
                            "radiance sums blue (grey: mean)+net flux");
    accum.floor = vk::Buffer(context, uint64_t{floor_texels} * floor_texels * 3 * sizeof(uint32_t), usage,
                             vk::MemoryUse::device, "floor flux sum");
    accum.stats = vk::Buffer(context, sizeof(shaders::PhotonStats), usage, vk::MemoryUse::readback, "photon stats");
    const uint64_t lit_cells = passes::lit_pyramid_offsets(dims)[LIT_LEVELS];
    // Every cell is written by the lit-pyramid pass (no clear); read back by the tests.
    accum.lit_blocks = vk::Buffer(context, lit_cells * sizeof(uint32_t),
                                  VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_SRC_BIT,
                                  vk::MemoryUse::device, "lit pyramid");
    accum.exits = vk::Buffer(context, uint64_t{std::max(exit_count, 1u)} * sizeof(shaders::PhotonExit), usage,
                             vk::MemoryUse::readback, "photon exits");
    return accum;
}

namespace {
constexpr vk::BindingLayout kLayout[] = {
    {TRANSPORT_BINDING_PARAMS, VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER},
    {TRANSPORT_BINDING_INDEX_FIELD, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER},
    {TRANSPORT_BINDING_COVERAGE, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER},
    {TRANSPORT_BINDING_LEVELS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {TRANSPORT_BINDING_ACCUM_RG, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {TRANSPORT_BINDING_ACCUM_FLUX, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {TRANSPORT_BINDING_ACCUM_FLOOR, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {TRANSPORT_BINDING_STATS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {TRANSPORT_BINDING_PHOTON_EXITS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
};
// The photon pass's own specialization constant (PHOTON_CONSTANT_SAMPLED_DEPOSITS), per pipeline set.
static_assert(PHOTON_CONSTANT_SAMPLED_DEPOSITS == TRANSPORT_CONSTANT_COVERAGE_FETCH + 1);
constexpr uint32_t kExact[] = {0u}, kSampled[] = {1u};
}  // namespace

PhotonTracePass::PhotonTracePass(vk::Context& context)
    : exact_(context, photon_trace_spv, kLayout, 0, "photon trace", kExact),
      sampled_(context, photon_trace_spv, kLayout, 0, "photon trace (sampled deposits)", kSampled) {}

void PhotonTracePass::record(vk::CommandRecorder& recorder, const TransportInputs& in,
                             const PhotonAccumulators& accum, uint32_t photon_count, bool sampled_deposits) const {
    if (!in.variant.grey) recorder.fill(accum.red_green, 0);
    recorder.fill(accum.flux, 0);
    recorder.fill(accum.floor, 0);
    recorder.fill(accum.stats, 0);
    recorder.fill(accum.exits, 0);
    recorder.transfer_to_compute_barrier();
    const auto groups = vk::linear_groups(photon_count, TRANSPORT_GROUP_SIZE);
    const vk::ComputePipeline& pipeline = (sampled_deposits ? sampled_ : exact_)(in.variant);
    pipeline.dispatch(recorder.get(),
                      {vk::Binding::uniform_buffer(TRANSPORT_BINDING_PARAMS, in.params),
                       vk::Binding::sampled_image(TRANSPORT_BINDING_INDEX_FIELD, in.index_field, in.sampler),
                       vk::Binding::sampled_image(TRANSPORT_BINDING_COVERAGE, in.coverage, in.sampler),
                       vk::Binding::storage_buffer(TRANSPORT_BINDING_LEVELS, in.levels),
                       vk::Binding::storage_buffer(TRANSPORT_BINDING_ACCUM_RG, accum.red_green),
                       vk::Binding::storage_buffer(TRANSPORT_BINDING_ACCUM_FLUX, accum.flux),
                       vk::Binding::storage_buffer(TRANSPORT_BINDING_ACCUM_FLOOR, accum.floor),
                       vk::Binding::storage_buffer(TRANSPORT_BINDING_STATS, accum.stats),
                       vk::Binding::storage_buffer(TRANSPORT_BINDING_PHOTON_EXITS, accum.exits)},
                      nullptr, 0, groups.x, groups.y);
}

}  // namespace refract::passes
