// A light-transport pass (photons, resolve, view) compiled for both kinds of transport: grey (every
// channel attenuates alike, the radiance grid keeps one fluence) and coloured. The choice is a
// specialization constant (TRANSPORT_CONSTANT_GREY), so each variant is compiled without the other's
// work: a uniform branch would not do, as lavapipe runs both sides of every branch.
#pragma once

#include <span>

#include "vk/pipeline.h"

namespace refract::passes {

class TransportPipeline {
public:
    TransportPipeline(vk::Context& context, std::span<const uint32_t> spirv,
                      std::span<const vk::BindingLayout> layout, const char* name);
    const vk::ComputePipeline& operator()(bool grey) const { return grey ? grey_ : coloured_; }

private:
    vk::ComputePipeline coloured_, grey_;
};

}  // namespace refract::passes
