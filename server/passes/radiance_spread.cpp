#include "passes/radiance_spread.h"

#include <array>
#include <iterator>

#include "radiance_spread_spv.h"
#include "transport.h"

namespace refract::passes {

namespace {
constexpr vk::BindingLayout kLayout[] = {
    {TRANSPORT_BINDING_PARAMS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {TRANSPORT_BINDING_RAW_RADIANCE, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE},
    {TRANSPORT_BINDING_RAW_FLUX, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE},
    {TRANSPORT_BINDING_RADIANCE, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE},
    {TRANSPORT_BINDING_FLUX, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE},
    {TRANSPORT_BINDING_RAW_FLOOR_MAP, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE},
    {TRANSPORT_BINDING_FLOOR_MAP, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE},
    {TRANSPORT_BINDING_SPREAD_FLUX_SHARES, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE},
    {TRANSPORT_BINDING_SPREAD_RADIANCE_SHARES, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE},
    {TRANSPORT_BINDING_SPREAD_FLOOR_SHARES, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE},
    {TRANSPORT_BINDING_FLOOR_SHADOW, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
};
}  // namespace

RadianceSpreadPass::RadianceSpreadPass(vk::Context& context) {
    static_assert(TRANSPORT_CONSTANT_CHANNELS == 0 && SPREAD_CONSTANT_FLOOR == 8 && SPREAD_CONSTANT_STEP == 9 &&
                  CHANNELS_RGB == 0 && CHANNELS_GREY == 1);
    struct Job {
        const char* names[2];  // coloured, grey
        uint32_t floor, step;
    };
    static constexpr Job kJobs[] = {
        {{"radiance spread shares", "radiance spread shares (grey)"}, 0, SPREAD_STEP_SHARES},
        {{"radiance spread along x", "radiance spread along x (grey)"}, 0, SPREAD_STEP_GATHER_X},
        {{"radiance spread along y", "radiance spread along y (grey)"}, 0, SPREAD_STEP_GATHER_Y},
        {{"radiance spread along z", "radiance spread along z (grey)"}, 0, SPREAD_STEP_GATHER_Z},
        {{"floor map spread shares", "floor map spread shares (grey)"}, 1, SPREAD_STEP_SHARES},
        {{"floor map spread", "floor map spread (grey)"}, 1, SPREAD_STEP_GATHER_X}};
    pipelines_.reserve(2 * std::size(kJobs));
    for (const Job& job : kJobs)
        for (const uint32_t grey : {0u, 1u}) {
            // The coverage fetch, Fresnel, films, materials, field atlas, medium field and fade are never used here.
            const std::array<uint32_t, 10> constants{grey, 0u, 0u, 0u, 0u, 0u, 0u, 0u, job.floor, job.step};
            pipelines_.emplace_back(context, radiance_spread_spv, kLayout, 0, job.names[grey], constants);
        }
}

void RadianceSpreadPass::record(vk::CommandRecorder& recorder, const vk::Buffer& params, bool grey,
                                const SpreadImages& raw, const SpreadImages& shares, const SpreadImages& out,
                                const vk::Buffer& floor_shadow) const {
    const vk::Binding bindings[] = {vk::Binding::storage_buffer(TRANSPORT_BINDING_PARAMS, params),
                                    vk::Binding::storage_image(TRANSPORT_BINDING_RAW_RADIANCE, raw.radiance),
                                    vk::Binding::storage_image(TRANSPORT_BINDING_RAW_FLUX, raw.flux),
                                    vk::Binding::storage_image(TRANSPORT_BINDING_RADIANCE, out.radiance),
                                    vk::Binding::storage_image(TRANSPORT_BINDING_FLUX, out.flux),
                                    vk::Binding::storage_image(TRANSPORT_BINDING_RAW_FLOOR_MAP, raw.floor_map),
                                    vk::Binding::storage_image(TRANSPORT_BINDING_FLOOR_MAP, out.floor_map),
                                    vk::Binding::storage_image(TRANSPORT_BINDING_SPREAD_FLUX_SHARES, shares.flux),
                                    vk::Binding::storage_image(TRANSPORT_BINDING_SPREAD_RADIANCE_SHARES, shares.radiance),
                                    vk::Binding::storage_image(TRANSPORT_BINDING_SPREAD_FLOOR_SHARES, shares.floor_map),
                                    vk::Binding::storage_buffer(TRANSPORT_BINDING_FLOOR_SHADOW, floor_shadow)};
    const uint32_t variant = grey ? 1u : 0u;
    const auto voxel_groups = vk::linear_groups(out.flux.extent().count(), TRANSPORT_GROUP_SIZE);
    const auto texel_groups = vk::linear_groups(out.floor_map.extent().count(), TRANSPORT_GROUP_SIZE);
    auto voxels = [&](uint32_t job) { pipelines_[2 * job + variant].dispatch(recorder.get(), bindings, nullptr, 0, voxel_groups.x, voxel_groups.y); };
    auto texels = [&](uint32_t job) { pipelines_[2 * job + variant].dispatch(recorder.get(), bindings, nullptr, 0, texel_groups.x, texel_groups.y); };
    voxels(0);
    texels(4);
    recorder.compute_barrier();
    voxels(1);
    texels(5);
    recorder.compute_barrier();
    voxels(2);
    recorder.compute_barrier();
    voxels(3);
}

}  // namespace refract::passes
