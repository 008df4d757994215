// A light-transport pass (photons, resolve, view) compiled once per TransportVariant. The variant is
// given by specialization constants (transport.h), so each pipeline is compiled without the others'
// work: a uniform branch would not do, as lavapipe runs both sides of every branch.
#pragma once

#include <span>
#include <vector>

#include "vk/pipeline.h"

namespace refract::passes {

struct TransportVariant {
    bool grey = false;            // grey transport (TRANSPORT_CONSTANT_GREY)
    bool coverage_fetch = false;  // some coefficient reads the coverage texture (TRANSPORT_CONSTANT_COVERAGE_FETCH)
};

class TransportPipeline {
public:
    // `pass_constants`: the pass's own specialization constants, numbered after the transport constants.
    TransportPipeline(vk::Context& context, std::span<const uint32_t> spirv,
                      std::span<const vk::BindingLayout> layout, uint32_t push_constant_bytes, const char* name,
                      std::span<const uint32_t> pass_constants = {});
    const vk::ComputePipeline& operator()(TransportVariant variant) const {
        return pipelines_[(variant.grey ? 1u : 0u) + (variant.coverage_fetch ? 2u : 0u)];
    }

private:
    std::vector<vk::ComputePipeline> pipelines_;  // indexed as operator() does
};

}  // namespace refract::passes
