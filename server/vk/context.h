// The one Vulkan context: instance, chosen physical device, logical device, one compute queue and all
// device memory allocation. Headless (no surface). Everything else borrows it and must not outlive it.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include <vulkan/vulkan.h>

#include "vk/check.h"
#include "vk/handle.h"

namespace refract::vk {

// What a user needs to know about a device, and why it was or was not usable.
struct DeviceInfo {
    uint32_t index = 0;
    std::string name;
    std::string type;         // "discrete", "integrated", "virtual", "cpu", "other"
    std::string driver_name;  // e.g. "llvmpipe", "NVIDIA"
    std::string driver_info;  // e.g. "Mesa 22.3.6 (LLVM 15.0.6)"
    std::string api_version;  // "1.3.230"
    uint64_t device_local_bytes = 0;
    bool suitable = false;
    std::vector<std::string> missing;  // requirements this device fails, in words
};

struct ContextOptions {
    std::string device_name;  // substring of the device name to force; empty: best suitable device
    bool validation = false;  // enable VK_LAYER_KHRONOS_validation and count its errors
    // Compile each compute pipeline at its first dispatch instead of when its pass is made. The passes
    // hold variants for every kind of scene, and creating them all took 74% of a small GPU test's time
    // on lavapipe with validation, and 0.3 s of the daemon's 1.9 to the end of its warm-up. The tests,
    // the daemon (whose warm-up compiles what first frames need) and the one-shot commands opt in;
    // `refract bench` compiles up front, so that its timings never hold the driver's compiler.
    bool compile_on_first_use = false;
};

// Reads REFRACT_DEVICE (device name) and REFRACT_VALIDATION=1 into options, unless already set.
ContextOptions options_from_environment(ContextOptions options);

// lavapipe (Vulkan on the CPU) splits each dispatch into one equal, fixed share per thread, one thread
// a core by default, and a dispatch ends with its last share: where another process takes turns on a
// core (the browser showing the frames), the share on that core holds up every dispatch. Four threads a
// core let the OS even the shares out. Sets LP_NUM_THREADS to four times `cores` unless it is set (not
// empty), before the first instance reads it (GPU drivers ignore it); returns the value in effect.
std::string split_cpu_dispatches_finely(unsigned cores);

// Lists every device the loader sees, with each one's suitability. Throws Error if Vulkan is unusable.
std::vector<DeviceInfo> list_devices();

class Context {
public:
    explicit Context(const ContextOptions& options = {});
    ~Context();
    Context(const Context&) = delete;
    Context& operator=(const Context&) = delete;

    VkInstance instance() const { return instance_; }
    VkPhysicalDevice physical_device() const { return physical_device_; }
    VkDevice device() const { return device_; }
    VkQueue queue() const { return queue_; }
    uint32_t queue_family() const { return queue_family_; }
    const DeviceInfo& info() const { return info_; }
    const VkPhysicalDeviceLimits& limits() const { return properties_.limits; }
    // The largest single allocation the device allows (Vulkan 1.1 maintenance3; lavapipe: 2 GiB).
    VkDeviceSize max_memory_allocation_size() const { return max_memory_allocation_size_; }
    double timestamp_period_ns() const { return properties_.limits.timestampPeriod; }
    bool is_cpu_device() const { return properties_.deviceType == VK_PHYSICAL_DEVICE_TYPE_CPU; }
    // VK_EXT_shader_atomic_float's buffer float add is enabled (optional; only the deposit benchmark uses it).
    bool float_atomics() const { return float_atomics_; }

    // Allocates memory of a type allowed by `type_bits` with all of `required` flags; throws when none fits.
    // `allocate_flags`: VkMemoryAllocateFlags (VK_MEMORY_ALLOCATE_DEVICE_ADDRESS_BIT for addressed buffers).
    UniqueMemory allocate(const VkMemoryRequirements& requirements, VkMemoryPropertyFlags required,
                          VkMemoryPropertyFlags* chosen_flags = nullptr, VkMemoryAllocateFlags allocate_flags = 0);
    // Device memory currently held by resources of this context (bytes).
    int64_t allocated_bytes() const { return allocated_bytes_.load(); }
    std::atomic<int64_t>& allocated_bytes_counter() { return allocated_bytes_; }

    // Gives a Vulkan object a name that validation messages and debuggers show (no-op without debug utils).
    void set_name(VkObjectType type, uint64_t handle, const char* name) const;
    template <typename T>
    void set_name(VkObjectType type, T handle, const char* name) const {
        set_name(type, reinterpret_cast<uint64_t>(handle), name);
    }

    // Validation messages of error severity seen so far (always 0 when validation is off).
    size_t validation_error_count() const { return validation_errors_.load(); }
    std::string last_validation_message() const;
    bool validation_enabled() const { return messenger_ != VK_NULL_HANDLE; }
    bool compiles_on_first_use() const { return compile_on_first_use_; }
    // Pipelines compiled so far (ComputePipeline counts each): what a warm-up left a frame to compile.
    uint64_t pipelines_compiled() const { return pipelines_compiled_.load(); }
    void count_compiled_pipeline() { pipelines_compiled_.fetch_add(1); }

    // Queue submission is serialized: the queue has one owner at a time.
    void submit_and_wait(VkCommandBuffer command_buffer);

    PFN_vkCmdPushDescriptorSetKHR push_descriptor_set = nullptr;

private:
    // The constructor's steps, in this order (when one throws, the constructor releases what was made).
    // The messenger that counts validation errors (validation with debug utils only).
    void create_messenger();
    // Picks the device named by `device_name` (a substring; empty: the best-ranked suitable one) and
    // reads its properties. Throws Error, saying of every device why it was not chosen, when none fits.
    void choose_device(const std::string& device_name);
    // The logical device with its one compute queue and the features the passes need.
    void create_device();

    static VKAPI_ATTR VkBool32 VKAPI_CALL on_debug_message(VkDebugUtilsMessageSeverityFlagBitsEXT severity,
                                                          VkDebugUtilsMessageTypeFlagsEXT types,
                                                          const VkDebugUtilsMessengerCallbackDataEXT* data,
                                                          void* user);

    VkInstance instance_ = VK_NULL_HANDLE;
    VkDebugUtilsMessengerEXT messenger_ = VK_NULL_HANDLE;
    VkPhysicalDevice physical_device_ = VK_NULL_HANDLE;
    VkDevice device_ = VK_NULL_HANDLE;
    VkQueue queue_ = VK_NULL_HANDLE;
    uint32_t queue_family_ = 0;
    DeviceInfo info_;
    VkPhysicalDeviceProperties properties_{};
    VkPhysicalDeviceMemoryProperties memory_properties_{};
    PFN_vkSetDebugUtilsObjectNameEXT set_object_name_ = nullptr;
    bool float_atomics_ = false;
    bool compile_on_first_use_ = false;
    VkDeviceSize max_memory_allocation_size_ = 0;
    std::atomic<int64_t> allocated_bytes_{0};
    std::atomic<uint64_t> pipelines_compiled_{0};
    std::atomic<size_t> validation_errors_{0};
    mutable std::mutex message_mutex_;
    std::string last_validation_message_;
    std::mutex queue_mutex_;
    UniqueFence fence_;
};

}  // namespace refract::vk
