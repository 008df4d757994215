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
    {TRANSPORT_BINDING_RAW_FLOOR_MAP, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {TRANSPORT_BINDING_FLOOR_MAP, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {TRANSPORT_BINDING_SPREAD_FLUX_SHARES, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE},
    {TRANSPORT_BINDING_SPREAD_RADIANCE_SHARES, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE},
    {TRANSPORT_BINDING_SPREAD_FLOOR_SUMS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {TRANSPORT_BINDING_FLOOR_SHADOW, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
};
}  // namespace

uint64_t floor_spread_bytes(uint32_t side) {
    return (uint64_t{side} + 1) * (uint64_t{side} + 1) * 4 * sizeof(int32_t);
}

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
        {{"floor spread start", "floor spread start (grey)"}, 1, SPREAD_FLOOR_STEP_START},
        {{"floor events along x", "floor events along x (grey)"}, 1, SPREAD_FLOOR_STEP_EVENT_ROWS},
        {{"floor events along y", "floor events along y (grey)"}, 1, SPREAD_FLOOR_STEP_EVENT_COLUMNS},
        {{"floor spread squares", "floor spread squares (grey)"}, 1, SPREAD_FLOOR_STEP_SCATTER},
        {{"floor spread along x", "floor spread along x (grey)"}, 1, SPREAD_FLOOR_STEP_ROWS},
        {{"floor spread along y", "floor spread along y (grey)"}, 1, SPREAD_FLOOR_STEP_COLUMNS},
        {{"floor spread light", "floor spread light (grey)"}, 1, SPREAD_FLOOR_STEP_LIGHT}};
    pipelines_.reserve(2 * std::size(kJobs));
    for (const Job& job : kJobs)
        for (const uint32_t grey : {0u, 1u}) {
            // The coverage fetch, Fresnel, films, materials, field atlas, medium field and fade are never used here.
            const std::array<uint32_t, 10> constants{grey, 0u, 0u, 0u, 0u, 0u, 0u, 0u, job.floor, job.step};
            pipelines_.emplace_back(context, radiance_spread_spv, kLayout, 0, job.names[grey], constants);
        }
}

void RadianceSpreadPass::record(vk::CommandRecorder& recorder, const vk::Buffer& params, bool grey,
                                const SpreadImages& raw, const SpreadShares& shares, const SpreadImages& out,
                                const vk::Buffer& floor_shadow) const {
    const vk::Binding bindings[] = {
        vk::Binding::storage_buffer(TRANSPORT_BINDING_PARAMS, params),
        vk::Binding::storage_image(TRANSPORT_BINDING_RAW_RADIANCE, raw.radiance),
        vk::Binding::storage_image(TRANSPORT_BINDING_RAW_FLUX, raw.flux),
        vk::Binding::storage_image(TRANSPORT_BINDING_RADIANCE, out.radiance),
        vk::Binding::storage_image(TRANSPORT_BINDING_FLUX, out.flux),
        vk::Binding::storage_buffer(TRANSPORT_BINDING_RAW_FLOOR_MAP, raw.floor_map),
        vk::Binding::storage_buffer(TRANSPORT_BINDING_FLOOR_MAP, out.floor_map),
        vk::Binding::storage_image(TRANSPORT_BINDING_SPREAD_FLUX_SHARES, shares.flux),
        vk::Binding::storage_image(TRANSPORT_BINDING_SPREAD_RADIANCE_SHARES, shares.radiance),
        vk::Binding::storage_buffer(TRANSPORT_BINDING_SPREAD_FLOOR_SUMS, shares.floor_sums),
        vk::Binding::storage_buffer(TRANSPORT_BINDING_FLOOR_SHADOW, floor_shadow)};
    const uint32_t variant = grey ? 1u : 0u;
    auto run = [&](uint32_t job, uint64_t items) {
        const auto groups = vk::linear_groups(items, TRANSPORT_GROUP_SIZE);
        pipelines_[2 * job + variant].dispatch(recorder.get(), bindings, nullptr, 0, groups.x, groups.y);
    };
    const uint64_t voxels = out.flux.extent().count(), texels = uint64_t{out.floor_side} * out.floor_side;
    // The voxels' four steps (jobs 0-3) and the texels' seven (jobs 4-10) side by side: threads per cell of
    // the sums, per line, per line, per texel, per line, per line, per texel.
    const uint64_t cells = uint64_t{out.floor_side + 1} * (out.floor_side + 1), lines = out.floor_side + 1;
    const uint64_t texel_items[] = {cells, lines, lines, texels, lines, lines, texels};
    for (uint32_t step = 0; step < 7; ++step) {
        if (step < 4) run(step, voxels);
        run(4 + step, texel_items[step]);
        if (step < 6) recorder.compute_barrier();
    }
}

}  // namespace refract::passes
