#include "passes/photon_trace.h"

#include <algorithm>
#include <cstddef>

#include "passes/transport_params.h"
#include "photon_trace_spv.h"
#include "transport.h"

namespace refract::passes {

uint64_t direct_reach_words(vk::Extent3 radiance_dims) {
    // One more word: the last run of voxels reads the word after its own.
    return uint64_t{(radiance_dims.x + 32) / 32} * (radiance_dims.y + 1) * (radiance_dims.z + 1) + 1;
}

PhotonAccumulators make_photon_accumulators(vk::Context& context, vk::Extent3 radiance_dims,
                                            uint32_t floor_texels, uint32_t light_map_side,
                                            uint32_t exit_count, bool grey) {
    const uint64_t voxels = radiance_dims.count();
    const auto usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT;
    PhotonAccumulators accum;
    // The sums are reached by device address (radiance_sums.glsl): the flux words outgrow a storage-buffer
    // binding on lavapipe from 162^3 voxels on.
    const auto addressed = VK_BUFFER_USAGE_SHADER_DEVICE_ADDRESS_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT;
    accum.red_green = vk::Buffer(context, (grey ? 1 : voxels) * sizeof(uint64_t), addressed, vk::MemoryUse::device,
                                 "radiance sums red+green");
    accum.flux = vk::Buffer(context, voxels * RADIANCE_FLUX_WORDS * sizeof(uint64_t), addressed,
                            vk::MemoryUse::device, "radiance sums blue (grey: mean)+net flux");
    accum.floor = vk::Buffer(context, uint64_t{floor_texels} * floor_texels * FLOOR_WORDS * sizeof(uint32_t), usage,
                             vk::MemoryUse::device, "floor flux sum");
    accum.floor_shadow = vk::Buffer(context, uint64_t{floor_texels} * floor_texels * 4 * sizeof(float), usage,
                                    vk::MemoryUse::device, "floor shadow (closed form)");
    accum.stats =
        vk::Buffer(context, sizeof(shaders::PhotonStats), usage, vk::MemoryUse::readback, "photon stats");
    const uint64_t light_map_bytes = uint64_t{light_map_side} * light_map_side * sizeof(float);
    accum.light_map_traced = vk::Buffer(context, light_map_bytes, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT,
                                        vk::MemoryUse::device, "light map (traced)");
    accum.light_map = vk::Buffer(context, light_map_bytes, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, vk::MemoryUse::device,
                                 "light map");
    // Room for every voxel, up to what one indirect dispatch can take (the pass does the rest at once).
    const uint64_t edge_capacity =
        std::min<uint64_t>(voxels, uint64_t{context.limits().maxComputeWorkGroupCount[0]} * TRANSPORT_GROUP_SIZE);
    accum.direct_edges = vk::Buffer(context, sizeof(shaders::WorkListHeader) + edge_capacity * sizeof(uint32_t),
                                    VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_INDIRECT_BUFFER_BIT |
                                        VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                                    vk::MemoryUse::device, "direct light edge voxels");
    accum.direct_reach = vk::Buffer(context, direct_reach_words(radiance_dims) * sizeof(uint32_t),
                                    VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, vk::MemoryUse::device, "direct light reach bits");
    accum.exits = vk::Buffer(context, uint64_t{std::max(exit_count, 1u)} * sizeof(shaders::PhotonExit), usage,
                             vk::MemoryUse::readback, "photon exits");
    return accum;
}

namespace {
constexpr vk::BindingLayout kOwnLayout[] = {
    {TRANSPORT_BINDING_ACCUM_FLOOR, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {TRANSPORT_BINDING_STATS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {TRANSPORT_BINDING_PHOTON_EXITS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {TRANSPORT_BINDING_LIGHT_MAP, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
};
// The photon pass's own specialization constants (PHOTON_CONSTANT_SAMPLED_DEPOSITS, then
// PHOTON_CONSTANT_RANDOM_WALKS), per pipeline set.
static_assert(PHOTON_CONSTANT_SAMPLED_DEPOSITS == TRANSPORT_CONSTANT_COUNT);
static_assert(PHOTON_CONSTANT_RANDOM_WALKS == PHOTON_CONSTANT_SAMPLED_DEPOSITS + 1);
constexpr uint32_t kExact[] = {0u, 0u}, kSampled[] = {1u, 0u}, kExactWalks[] = {0u, 1u}, kSampledWalks[] = {1u, 1u};
constexpr auto kLayout = transport_layout(kOwnLayout);
}  // namespace

PhotonTracePass::PhotonTracePass(vk::Context& context)
    : exact_(context, photon_trace_spv, kLayout, 0, "photon trace", kExact),
      sampled_(context, photon_trace_spv, kLayout, 0, "photon trace (sampled deposits)", kSampled),
      exact_walks_(context, photon_trace_spv, kLayout, 0, "photon trace (random walks)", kExactWalks),
      sampled_walks_(context, photon_trace_spv, kLayout, 0, "photon trace (random walks, sampled deposits)",
                     kSampledWalks) {}

namespace {
void clear_sums(vk::CommandRecorder& recorder, const PhotonAccumulators& accum, bool grey) {
    if (!grey) recorder.fill(accum.red_green, 0);
    recorder.fill(accum.flux, 0);
    recorder.fill(accum.floor, 0);
}
}  // namespace

void clear_photon_accumulators(vk::CommandRecorder& recorder, const PhotonAccumulators& accum, bool grey) {
    recorder.fill(accum.stats, 0);
    recorder.fill(accum.exits, 0);
    recorder.fill(accum.floor_shadow, 0);
    clear_sums(recorder, accum, grey);
    recorder.transfer_to_compute_barrier();
}

void clear_for_next_light(vk::CommandRecorder& recorder, const PhotonAccumulators& accum, bool grey) {
    clear_sums(recorder, accum, grey);
    const uint32_t none = 0;
    recorder.update(accum.stats, offsetof(shaders::PhotonStats, queue_taken) + QUEUE_PHOTONS * sizeof(uint32_t), &none,
                    sizeof(none));
    recorder.transfer_to_compute_barrier();
}

bool PhotonTracePass::record(vk::CommandRecorder& recorder, const TransportInputs& in,
                             const PhotonAccumulators& accum, uint32_t photon_count, bool sampled_deposits,
                             bool random_walks, const BetweenParts& between, PartPacer& pacer) const {
    const TransportPipeline& walks = sampled_deposits ? sampled_walks_ : exact_walks_;
    const vk::ComputePipeline& pipeline = (random_walks ? walks : sampled_deposits ? sampled_ : exact_)(in.variant);
    const vk::Binding own[] = {vk::Binding::storage_buffer(TRANSPORT_BINDING_ACCUM_FLOOR, accum.floor),
                               vk::Binding::storage_buffer(TRANSPORT_BINDING_STATS, accum.stats),
                               vk::Binding::storage_buffer(TRANSPORT_BINDING_PHOTON_EXITS, accum.exits),
                               vk::Binding::storage_buffer(TRANSPORT_BINDING_LIGHT_MAP, accum.light_map)};
    // Photons take their indices from a queue in order, so parts of the dispatch trace consecutive ranges.
    if (between) pacer.begin();
    uint32_t part = between ? pacer.next(kWorkPart) : photon_count;
    for (uint32_t first = 0; first < photon_count; first += part) {
        if (first > 0) {
            if (pacer.between(between, part)) return false;
            part = pacer.next(kWorkPart);
        }
        const auto groups = vk::linear_groups(std::min(part, photon_count - first), TRANSPORT_GROUP_SIZE);
        pipeline.dispatch(recorder.get(), transport_bindings(in, own), nullptr, 0, groups.x, groups.y);
    }
    return true;
}

}  // namespace refract::passes
