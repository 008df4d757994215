#include "passes/view_upscale.h"

#include <algorithm>
#include <array>

#include "transport.h"
#include "view_upscale_spv.h"

namespace refract::passes {

namespace {
constexpr vk::BindingLayout kOwnLayout[] = {
    {TRANSPORT_BINDING_FLOOR_MAP, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {TRANSPORT_BINDING_HDR, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {TRANSPORT_BINDING_VIEW_ENDS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {TRANSPORT_BINDING_VIEWER_HDR, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {TRANSPORT_BINDING_VIEWER_LDR, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {TRANSPORT_BINDING_STILL_ENDS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
};
constexpr auto kLayout = transport_layout(kOwnLayout);

// The transport constants at their defaults (the pass reads none of them), then the loads a lane shares
// and whether the viewer's pixels' own ends are a still frame's.
static_assert(TRANSPORT_CONSTANT_CHANNELS == 0 && TRANSPORT_CONSTANT_COVERAGE_FETCH == 1 &&
              TRANSPORT_CONSTANT_MEDIUM_FADE == 7 && UPSCALE_CONSTANT_SHARED_LOADS == 8 &&
              UPSCALE_CONSTANT_STILL_ENDS == 9 && UPSCALE_CONSTANT_ONE_LIGHT == 10 && CHANNELS_RGB == 0);
std::array<uint32_t, 11> constants(uint32_t shared_loads, bool still_ends, bool one_light) {
    return {CHANNELS_RGB,       1u, 0u, 0u, 0u, 0u, 0u, 1u, shared_loads, still_ends ? 1u : 0u,
            one_light ? 1u : 0u};
}
constexpr uint32_t kSharedLoadsVariants = 3;  // upscale_shared_loads: 0, 1, 2

}  // namespace

ViewUpscalePass::ViewUpscalePass(vk::Context& context) {
    pipelines_.reserve(4 * kSharedLoadsVariants);
    for (const bool one_light : {false, true})
        for (const bool still_ends : {false, true})
            for (uint32_t shared_loads = 0; shared_loads < kSharedLoadsVariants; ++shared_loads)
                pipelines_.emplace_back(context, view_upscale_spv, kLayout, sizeof(shaders::UpscalePush),
                                        still_ends ? "view upscale (still's ends)" : "view upscale",
                                        constants(shared_loads, still_ends, one_light));
}

void ViewUpscalePass::record(vk::CommandRecorder& recorder, const TransportInputs& in,
                             const vk::Buffer& floor_map, const UpscaleBuffers& buffers, glm::uvec2 traced,
                             uint32_t width, uint32_t height, bool one_light) const {
    const vk::Binding own[] = {
        vk::Binding::storage_buffer(TRANSPORT_BINDING_FLOOR_MAP, floor_map),
        vk::Binding::storage_buffer(TRANSPORT_BINDING_HDR, buffers.traced_hdr),
        vk::Binding::storage_buffer(TRANSPORT_BINDING_VIEW_ENDS, buffers.ends),
        vk::Binding::storage_buffer(TRANSPORT_BINDING_VIEWER_HDR, buffers.viewer_hdr),
        vk::Binding::storage_buffer(TRANSPORT_BINDING_VIEWER_LDR, buffers.viewer_ldr),
        vk::Binding::storage_buffer(TRANSPORT_BINDING_STILL_ENDS,
                                    buffers.still_ends ? *buffers.still_ends : buffers.ends)};
    const shaders::UpscalePush push{glm::uvec2(width, height)};
    const float scale = std::max(static_cast<float>(traced.x) / static_cast<float>(width),
                                 static_cast<float>(traced.y) / static_cast<float>(height));
    const uint32_t variant = shaders::upscale_shared_loads(scale) +
                             (buffers.still_ends ? kSharedLoadsVariants : 0u) +
                             (one_light ? 2 * kSharedLoadsVariants : 0u);
    pipelines_[variant].dispatch(recorder.get(), transport_bindings(in, own), push,
                                 vk::group_count(width, VIEW_GROUP_SIZE),
                                 vk::group_count(height, VIEW_GROUP_SIZE));
}

}  // namespace refract::passes
