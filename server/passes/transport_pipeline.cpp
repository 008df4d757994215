#include "passes/transport_pipeline.h"

#include <array>

#include "transport.h"

namespace refract::passes {
namespace {
static_assert(TRANSPORT_CONSTANT_GREY == 0);
constexpr std::array<uint32_t, 1> kColoured{0u}, kGrey{1u};
}  // namespace

TransportPipeline::TransportPipeline(vk::Context& context, std::span<const uint32_t> spirv,
                                     std::span<const vk::BindingLayout> layout, const char* name)
    : coloured_(context, spirv, layout, 0, name, kColoured), grey_(context, spirv, layout, 0, name, kGrey) {}

}  // namespace refract::passes
