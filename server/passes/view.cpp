#include "passes/view.h"

#include <algorithm>

#include "fresnel.h"
#include "transport.h"
#include "view_spv.h"

#include <cstddef>

namespace refract::passes {

namespace {
// view.comp keeps a pixel's pending reflections in a stack whose pushes and pops shift three entries by
// constant indices.
static_assert(FRESNEL_EYE_REFLECTIONS == 3u);

constexpr vk::BindingLayout kOwnLayout[] = {
    {TRANSPORT_BINDING_RADIANCE, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE},
    {TRANSPORT_BINDING_FLUX, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE},
    {TRANSPORT_BINDING_FLOOR_MAP, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {TRANSPORT_BINDING_HDR, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {TRANSPORT_BINDING_STATS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {TRANSPORT_BINDING_REFINE, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
    {TRANSPORT_BINDING_VIEW_ENDS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
};
constexpr auto kLayout = transport_layout(kOwnLayout);
}  // namespace

ViewPass::ViewPass(vk::Context& context)
    : context_(context), pipeline_(context, view_spv, kLayout, sizeof(shaders::ViewPush), "view"), refine_(context) {}

bool ViewPass::record(vk::CommandRecorder& recorder, const TransportInputs& in, const vk::Image3D& radiance,
                      const vk::Image3D& flux, const vk::Buffer& floor_map, const ViewOutputs& out,
                      uint32_t width, uint32_t height, bool adaptive, bool ends, const BetweenParts& between,
                      PartPacer& pacer) const {
    // Only the view's counters restart (steps and its two pixel queues, adjacent): the photon pass's
    // counters belong to the last photon run.
    static_assert(offsetof(shaders::PhotonStats, queue_taken) + 4 * QUEUE_VIEW_PIXELS ==
                      offsetof(shaders::PhotonStats, view_steps) + 4 &&
                  QUEUE_VIEW_REFINED == QUEUE_VIEW_PIXELS + 1);
    vkCmdFillBuffer(recorder.get(), out.stats.get(), offsetof(shaders::PhotonStats, view_steps), 3 * sizeof(uint32_t), 0);
    // The listed round is one indirect dispatch of up to all non-coarse pixels: past the device's group
    // count limit (images far larger than interactive frames are), every pixel is traced.
    const uint64_t listable = uint64_t{width} * height - uint64_t{(width + 1) / 2} * ((height + 1) / 2);
    adaptive = adaptive && vk::group_count(static_cast<uint32_t>(listable), VIEW_GROUP_SIZE * VIEW_GROUP_SIZE) <=
                               context_.limits().maxComputeWorkGroupCount[0];
    // An empty list (also when not adaptive: every dispatch then reads a defined count).
    const shaders::WorkListHeader empty{0, 1, 1, 0};
    recorder.update(out.refine, 0, &empty, sizeof(empty));
    recorder.transfer_to_compute_barrier();
    const vk::Binding own[] = {vk::Binding::storage_image(TRANSPORT_BINDING_RADIANCE, radiance),
                               vk::Binding::storage_image(TRANSPORT_BINDING_FLUX, flux),
                               vk::Binding::storage_buffer(TRANSPORT_BINDING_FLOOR_MAP, floor_map),
                               vk::Binding::storage_buffer(TRANSPORT_BINDING_HDR, out.hdr),
                               vk::Binding::storage_buffer(TRANSPORT_BINDING_STATS, out.stats),
                               vk::Binding::storage_buffer(TRANSPORT_BINDING_REFINE, out.refine),
                               vk::Binding::storage_buffer(TRANSPORT_BINDING_VIEW_ENDS, out.ends)};
    const auto bindings = transport_bindings(in, own);
    const vk::ComputePipeline& view = pipeline_(in.variant);
    if (!adaptive) {
        // Pixels come from a queue in order (take_from_queue): parts of the group rows trace consecutive ones.
        const uint32_t columns = vk::group_count(width, VIEW_GROUP_SIZE), rows = vk::group_count(height, VIEW_GROUP_SIZE);
        const uint32_t largest = std::max(1u, kViewPart / (columns * VIEW_GROUP_SIZE * VIEW_GROUP_SIZE));
        if (between) pacer.begin();
        uint32_t part = between ? pacer.next(largest) : rows;
        for (uint32_t first = 0; first < rows; first += part) {
            if (first > 0) {
                if (pacer.between(between, part)) return false;
                part = pacer.next(largest);
            }
            view.dispatch(recorder.get(), bindings, shaders::ViewPush{VIEW_PIXELS_ALL, ends ? 1u : 0u}, columns,
                          std::min(part, rows - first));
        }
        return true;
    }
    view.dispatch(recorder.get(), bindings, shaders::ViewPush{VIEW_PIXELS_COARSE, ends ? 1u : 0u},
                  vk::group_count((width + 1) / 2, VIEW_GROUP_SIZE), vk::group_count((height + 1) / 2, VIEW_GROUP_SIZE));
    recorder.compute_barrier();
    refine_.record(recorder, in.params, out.hdr, out.refine, out.ends, ends, width, height);
    recorder.compute_barrier();
    const shaders::ViewPush listed{VIEW_PIXELS_LISTED, ends ? 1u : 0u};
    view.dispatch_indirect(recorder.get(), bindings, &listed, sizeof(listed), out.refine,
                           offsetof(shaders::WorkListHeader, groups_x));
    return true;
}

}  // namespace refract::passes
