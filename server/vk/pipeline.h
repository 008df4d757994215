// Compute pipelines with push descriptors: a pass declares its bindings once and pushes resources at
// record time, so there are no descriptor pools or sets to own.
#pragma once

#include <algorithm>
#include <cstdint>
#include <initializer_list>
#include <memory>
#include <mutex>
#include <span>
#include <type_traits>
#include <utility>
#include <vector>

#include "vk/context.h"
#include "vk/resources.h"

namespace refract::vk {

// One resource bound at one binding number of the pass's only descriptor set.
struct Binding {
    uint32_t binding = 0;
    VkDescriptorType type = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
    VkBuffer buffer = VK_NULL_HANDLE;
    VkImageView view = VK_NULL_HANDLE;

    static Binding storage_buffer(uint32_t binding, const Buffer& buffer);
    static Binding uniform_buffer(uint32_t binding, const Buffer& buffer);
    static Binding storage_image(uint32_t binding, const Image3D& image);
};

using BindingLayout = std::pair<uint32_t, VkDescriptorType>;

class ComputePipeline {
public:
    // `constants` specialize the shader: constant_id i takes constants[i] (32-bit values, bools as 0/1),
    // so the driver compiles each variant with its dead branches removed. Compiled here, or at the first
    // dispatch where the context says so (ContextOptions::compile_on_first_use); `spirv` and `name` must
    // then outlive the pipeline (the compiled-in shaders and string literals do).
    ComputePipeline(Context& context, std::span<const uint32_t> spirv, std::span<const BindingLayout> layout,
                    uint32_t push_constant_bytes, const char* name, std::span<const uint32_t> constants = {});
    ComputePipeline(Context& context, std::span<const uint32_t> spirv, std::initializer_list<BindingLayout> layout,
                    uint32_t push_constant_bytes, const char* name)
        : ComputePipeline(context, spirv, std::span<const BindingLayout>(layout.begin(), layout.size()),
                          push_constant_bytes, name) {}

    // Binds the pipeline, pushes the descriptors and push constants and dispatches `groups`.
    void dispatch(VkCommandBuffer cmd, std::span<const Binding> bindings, const void* push_constants,
                  uint32_t push_bytes, uint32_t groups_x, uint32_t groups_y = 1, uint32_t groups_z = 1) const;
    void dispatch(VkCommandBuffer cmd, std::initializer_list<Binding> bindings, const void* push_constants,
                  uint32_t push_bytes, uint32_t groups_x, uint32_t groups_y = 1, uint32_t groups_z = 1) const {
        dispatch(cmd, std::span<const Binding>(bindings.begin(), bindings.size()), push_constants, push_bytes,
                 groups_x, groups_y, groups_z);
    }
    template <typename PushConstants>
        requires std::is_class_v<PushConstants>
    void dispatch(VkCommandBuffer cmd, std::span<const Binding> bindings, const PushConstants& push,
                  uint32_t groups_x, uint32_t groups_y = 1, uint32_t groups_z = 1) const {
        dispatch(cmd, bindings, &push, sizeof(push), groups_x, groups_y, groups_z);
    }
    template <typename PushConstants>
        requires std::is_class_v<PushConstants>
    void dispatch(VkCommandBuffer cmd, std::initializer_list<Binding> bindings, const PushConstants& push,
                  uint32_t groups_x, uint32_t groups_y = 1, uint32_t groups_z = 1) const {
        dispatch(cmd, std::span<const Binding>(bindings.begin(), bindings.size()), &push, sizeof(push), groups_x,
                 groups_y, groups_z);
    }

    // The same with the group counts read by the device from `args` at `offset` (a
    // VkDispatchIndirectCommand an earlier pass wrote; the barrier before must cover indirect reads).
    void dispatch_indirect(VkCommandBuffer cmd, std::span<const Binding> bindings, const void* push_constants,
                           uint32_t push_bytes, const Buffer& args, VkDeviceSize offset) const;

private:
    // The driver's objects, made once (std::call_once: whichever thread dispatches first).
    struct Compiled {
        std::once_flag once;
        UniqueShaderModule module;
        UniqueDescriptorSetLayout set_layout;
        UniquePipelineLayout layout;
        UniquePipeline pipeline;
    };
    const Compiled& compiled() const;
    void compile() const;
    void bind(VkCommandBuffer cmd, std::span<const Binding> bindings, const void* push_constants,
              uint32_t push_bytes) const;

    Context& context_;
    std::span<const uint32_t> spirv_;
    std::vector<BindingLayout> bindings_;
    std::vector<uint32_t> constants_;
    uint32_t push_constant_bytes_ = 0;
    const char* name_;
    std::unique_ptr<Compiled> compiled_ = std::make_unique<Compiled>();
};

// Workgroups needed to cover `items` with groups of `group_size`.
constexpr uint32_t group_count(uint32_t items, uint32_t group_size) { return (items + group_size - 1) / group_size; }

// Groups (x, y) covering `items` in 1D work with groups of `group_size`, folded into a second
// dimension past the 65535-group limit (shaders recover the index with linear_invocation()). Rows
// are balanced: lavapipe ran a fold of 65535 + 1 groups on one thread (2^22 photons: 53 s against
// 26 s balanced).
struct LinearGroups {
    uint32_t x = 1, y = 1;
};
constexpr LinearGroups linear_groups(uint64_t items, uint32_t group_size) {
    const uint64_t groups = std::max<uint64_t>((items + group_size - 1) / group_size, 1);
    constexpr uint64_t max_x = 65535;
    const uint64_t rows = (groups + max_x - 1) / max_x;
    return {static_cast<uint32_t>((groups + rows - 1) / rows), static_cast<uint32_t>(rows)};
}

}  // namespace refract::vk
