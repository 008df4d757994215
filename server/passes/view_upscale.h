// Pass 6c (view upscale): an interactive frame traced smaller than its viewer's image, brought to the
// viewer's size (shaders/view_upscale.comp): the light gathered along the traced eye rays and their
// transmittance interpolated, the floor or sky at their straight ends, or at the ends of their last legs
// out of the glass, evaluated for every pixel, then tone-mapped. Reads what the viewing pass wrote with
// ViewPush::ends; in a light drag, each viewer pixel's own end from the still frame before it.
#pragma once

#include <vector>

#include "passes/transport_pipeline.h"
#include "vk/commands.h"
#include "vk/pipeline.h"

namespace refract::passes {

struct UpscaleBuffers {
    const vk::Buffer& traced_hdr;  // the traced frame (TRANSPORT_BINDING_HDR)
    const vk::Buffer& ends;        // where its eye rays end (TRANSPORT_BINDING_VIEW_ENDS)
    const vk::Buffer& viewer_hdr;  // vec4 per viewer pixel (w: 0, no inverse depth)
    const vk::Buffer& viewer_ldr;  // sRGB RGBA8 per viewer pixel
    // Where a still frame of this view left each viewer pixel's eye ray (TRANSPORT_BINDING_STILL_ENDS), or
    // nullptr: the eye rays have changed since (anything but the light).
    const vk::Buffer* still_ends = nullptr;
};

class ViewUpscalePass {
public:
    explicit ViewUpscalePass(vk::Context& context);
    // Over width x height viewer pixels from a frame traced at `traced` (the params' image size, whose
    // camera and exposure it takes); `one_light`: the params hold exactly one light.
    void record(vk::CommandRecorder& recorder, const TransportInputs& inputs, const vk::Buffer& floor_map,
                const UpscaleBuffers& buffers, glm::uvec2 traced, uint32_t width, uint32_t height,
                bool one_light) const;

private:
    // One for every transport variant (it reads none of their constants), by the loads each lane shares
    // with its subgroup (upscale_shared_loads: 0, 1, 2), without and then with a still frame's ends, for
    // any number of lights and then for one.
    std::vector<vk::ComputePipeline> pipelines_;
};

}  // namespace refract::passes
