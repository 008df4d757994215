#include "passes/direct_light.h"

#include <array>
#include <cstddef>
#include <iterator>

#include "direct_light_modes_spv.h"
#include "transport.h"

namespace refract::passes {

namespace {
constexpr vk::BindingLayout kOwnLayout[] = {
    {TRANSPORT_BINDING_LIGHT_MAP_TRACED, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {TRANSPORT_BINDING_LIGHT_MAP, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {TRANSPORT_BINDING_DIRECT_EDGES, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {TRANSPORT_BINDING_DIRECT_REACH, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {TRANSPORT_BINDING_ACCUM_FLOOR, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {TRANSPORT_BINDING_FLOOR_SHADOW, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
};
constexpr auto kLayout = transport_layout(kOwnLayout);
static_assert(std::size(direct_light_modes_spv) == DIRECT_MODE_FLOOR_SHADOW + 1);

std::array<vk::Binding, kLayout.size()> bindings(const TransportInputs& in, const PhotonAccumulators& accum) {
    const vk::Binding own[] = {vk::Binding::storage_buffer(TRANSPORT_BINDING_LIGHT_MAP_TRACED, accum.light_map_traced),
                               vk::Binding::storage_buffer(TRANSPORT_BINDING_LIGHT_MAP, accum.light_map),
                               vk::Binding::storage_buffer(TRANSPORT_BINDING_DIRECT_EDGES, accum.direct_edges),
                               vk::Binding::storage_buffer(TRANSPORT_BINDING_DIRECT_REACH, accum.direct_reach),
                               vk::Binding::storage_buffer(TRANSPORT_BINDING_ACCUM_FLOOR, accum.floor),
                               vk::Binding::storage_buffer(TRANSPORT_BINDING_FLOOR_SHADOW, accum.floor_shadow)};
    return transport_bindings(in, own);
}

// Direct light has met no gradient of n, so it is the same light in every channel's path, and has met no
// shell to reflect from: dispersive transport takes the RGB pipelines and Fresnel the plain ones (the same
// sums, and no variant compiled for nothing).
TransportVariant direct_variant(TransportVariant variant) {
    if (variant.channels == CHANNELS_DISPERSIVE) variant.channels = CHANNELS_RGB;
    variant.fresnel = variant.film = false;
    return variant;
}

void dispatch(const TransportPipeline& pipeline, vk::CommandRecorder& recorder, const TransportInputs& in,
              const PhotonAccumulators& accum, uint64_t items) {
    const auto groups = vk::linear_groups(items, TRANSPORT_GROUP_SIZE);
    pipeline(direct_variant(in.variant)).dispatch(recorder.get(), bindings(in, accum), nullptr, 0, groups.x, groups.y);
}
}  // namespace

DirectLightPass::DirectLightPass(vk::Context& context)
    : trace_(context, direct_light_modes_spv[DIRECT_MODE_TRACE], kLayout, 0, "light map (trace)"),
      margin_(context, direct_light_modes_spv[DIRECT_MODE_MARGIN], kLayout, 0, "light map (margin)"),
      reach_(context, direct_light_modes_spv[DIRECT_MODE_REACH], kLayout, 0, "direct light (reach)"),
      deposit_(context, direct_light_modes_spv[DIRECT_MODE_DEPOSIT], kLayout, 0, "direct light"),
      deposit_full_(context, direct_light_modes_spv[DIRECT_MODE_DEPOSIT_FULL], kLayout, 0,
                    "direct light (edge list full)"),
      edge_(context, direct_light_modes_spv[DIRECT_MODE_EDGE], kLayout, 0, "direct light (edge voxels)"),
      floor_corners_(context, direct_light_modes_spv[DIRECT_MODE_FLOOR_CORNERS], kLayout, 0,
                     "floor shadow (corners)"),
      floor_shadow_(context, direct_light_modes_spv[DIRECT_MODE_FLOOR_SHADOW], kLayout, 0, "floor shadow") {}

void DirectLightPass::record(vk::CommandRecorder& recorder, const TransportInputs& inputs,
                             const PhotonAccumulators& accum, uint32_t light_map_side, vk::Extent3 radiance_dims) const {
    const shaders::WorkListHeader empty{0, 1, 1, 0};
    recorder.update(accum.direct_edges, 0, &empty, sizeof(empty));
    recorder.transfer_to_compute_barrier();
    const uint64_t texels = uint64_t{light_map_side} * light_map_side;
    dispatch(trace_, recorder, inputs, accum, texels);
    recorder.compute_barrier();
    dispatch(margin_, recorder, inputs, accum, texels);
    record_floor_shadow_after_trace(recorder, inputs, accum);
    recorder.compute_barrier();
    dispatch(reach_, recorder, inputs, accum, direct_reach_words(radiance_dims));
    recorder.compute_barrier();
    const uint64_t listed = (accum.direct_edges.size() - sizeof(shaders::WorkListHeader)) / sizeof(uint32_t);
    dispatch(radiance_dims.count() > listed ? deposit_full_ : deposit_, recorder, inputs, accum,
             uint64_t{(radiance_dims.x + 31) / 32} * radiance_dims.y * radiance_dims.z);
    recorder.compute_barrier();
    edge_(direct_variant(inputs.variant)).dispatch_indirect(recorder.get(), bindings(inputs, accum), nullptr, 0, accum.direct_edges,
                                           offsetof(shaders::WorkListHeader, groups_x));
}

void DirectLightPass::record_floor_shadow(vk::CommandRecorder& recorder, const TransportInputs& inputs,
                                          const PhotonAccumulators& accum, uint32_t light_map_side) const {
    dispatch(trace_, recorder, inputs, accum, uint64_t{light_map_side} * light_map_side);
    recorder.compute_barrier();
    record_floor_shadow_after_trace(recorder, inputs, accum);
}

void DirectLightPass::record_floor_shadow_after_trace(vk::CommandRecorder& recorder, const TransportInputs& inputs,
                                                      const PhotonAccumulators& accum) const {
    const uint64_t texels = accum.floor.size() / (FLOOR_WORDS * sizeof(uint32_t));
    dispatch(floor_corners_, recorder, inputs, accum, texels);
    recorder.compute_barrier();
    dispatch(floor_shadow_, recorder, inputs, accum, texels);
}

}  // namespace refract::passes
