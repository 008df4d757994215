#include "passes/radiance_resolve.h"

#include <array>

#include "radiance_resolve_spv.h"
#include "transport.h"

namespace refract::passes {

namespace {
constexpr vk::BindingLayout kLayout[] = {
    {TRANSPORT_BINDING_PARAMS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {TRANSPORT_BINDING_ACCUM_FLOOR, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {TRANSPORT_BINDING_RADIANCE, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE},
    {TRANSPORT_BINDING_FLUX, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE},
    {TRANSPORT_BINDING_FLOOR_MAP, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {TRANSPORT_BINDING_FLOOR_SHADOW, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
};
}  // namespace

RadianceResolvePass::RadianceResolvePass(vk::Context& context) {
    // Dispersive transport resolves as RGB does: per-channel sums either way.
    static_assert(TRANSPORT_CONSTANT_CHANNELS == 0 && RESOLVE_CONSTANT_FLOOR == 8 && CHANNELS_RGB == 0 &&
                  CHANNELS_GREY == 1);
    const char* names[] = {"radiance resolve", "radiance resolve (grey)", "floor map resolve",
                           "floor map resolve (grey)"};
    pipelines_.reserve(4);
    for (uint32_t i = 0; i < 4; ++i) {
        // The coverage fetch, Fresnel, films, materials, field atlas, medium field and fade are never used here.
        const std::array<uint32_t, 9> constants{i & 1u, 0u, 0u, 0u, 0u, 0u, 0u, 0u, i >> 1};
        pipelines_.emplace_back(context, radiance_resolve_spv, kLayout, sizeof(uint32_t), names[i], constants);
    }
}

void RadianceResolvePass::record(vk::CommandRecorder& recorder, const vk::Buffer& params,
                                 const PhotonAccumulators& accum, bool grey, const vk::Image3D& radiance,
                                 const vk::Image3D& flux, const vk::Buffer& floor_map, uint32_t floor_side,
                                 bool add_floor_shadow) const {
    const vk::Binding bindings[] = {
        vk::Binding::storage_buffer(TRANSPORT_BINDING_PARAMS, params),
        vk::Binding::storage_buffer(TRANSPORT_BINDING_ACCUM_FLOOR, accum.floor),
        vk::Binding::storage_image(TRANSPORT_BINDING_RADIANCE, radiance),
        vk::Binding::storage_image(TRANSPORT_BINDING_FLUX, flux),
        vk::Binding::storage_buffer(TRANSPORT_BINDING_FLOOR_MAP, floor_map),
        vk::Binding::storage_buffer(TRANSPORT_BINDING_FLOOR_SHADOW, accum.floor_shadow)};
    const uint32_t push = add_floor_shadow ? 1u : 0u;
    const uint32_t variant = grey ? 1u : 0u;
    const auto voxel_groups = vk::linear_groups(flux.extent().count(), TRANSPORT_GROUP_SIZE);
    pipelines_[variant].dispatch(recorder.get(), bindings, &push, sizeof(push), voxel_groups.x, voxel_groups.y);
    const auto texel_groups = vk::linear_groups(uint64_t{floor_side} * floor_side, TRANSPORT_GROUP_SIZE);
    pipelines_[variant + 2].dispatch(recorder.get(), bindings, &push, sizeof(push), texel_groups.x, texel_groups.y);
}

}  // namespace refract::passes
