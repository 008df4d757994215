// Pass 6b (view refinement), between the two rounds of an interactive frame: the pixels the coarse
// round left out are interpolated where their traced neighbours agree on screen, and listed for the
// second round where they do not (shaders/view_refine.comp).
#pragma once

#include "vk/commands.h"
#include "vk/pipeline.h"

namespace refract::passes {

class ViewRefinePass {
public:
    explicit ViewRefinePass(vk::Context& context);
    // Reads the coarse round's pixels of `hdr` (compared as they will look at the exposure in `params`)
    // and writes the interpolated ones (and, with `ends`, their eye rays' ends alike); appends the others to
    // `refine` (header zeroed but for groups_y = groups_z = 1 beforehand).
    void record(vk::CommandRecorder& recorder, const vk::Buffer& params, const vk::Buffer& hdr,
                const vk::Buffer& refine, const vk::Buffer& ends_buffer, bool ends, uint32_t width,
                uint32_t height) const;

private:
    vk::ComputePipeline pipeline_;
};

}  // namespace refract::passes
