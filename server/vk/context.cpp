#include "vk/context.h"

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <sstream>

namespace refract::vk {
namespace {

constexpr const char* kValidationLayer = "VK_LAYER_KHRONOS_validation";

std::string version_string(uint32_t v) {
    std::ostringstream s;
    s << VK_API_VERSION_MAJOR(v) << "." << VK_API_VERSION_MINOR(v) << "." << VK_API_VERSION_PATCH(v);
    return s.str();
}

std::string device_type_name(VkPhysicalDeviceType type) {
    switch (type) {
        case VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU: return "discrete";
        case VK_PHYSICAL_DEVICE_TYPE_INTEGRATED_GPU: return "integrated";
        case VK_PHYSICAL_DEVICE_TYPE_VIRTUAL_GPU: return "virtual";
        case VK_PHYSICAL_DEVICE_TYPE_CPU: return "cpu";
        default: return "other";
    }
}

// Preference among suitable devices: real GPUs first, lavapipe last.
int type_rank(VkPhysicalDeviceType type) {
    switch (type) {
        case VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU: return 4;
        case VK_PHYSICAL_DEVICE_TYPE_INTEGRATED_GPU: return 3;
        case VK_PHYSICAL_DEVICE_TYPE_VIRTUAL_GPU: return 2;
        case VK_PHYSICAL_DEVICE_TYPE_CPU: return 1;
        default: return 0;
    }
}

bool has_instance_layer(const char* name) {
    uint32_t count = 0;
    REFRACT_VK_CHECK(vkEnumerateInstanceLayerProperties(&count, nullptr));
    std::vector<VkLayerProperties> layers(count);
    REFRACT_VK_CHECK(vkEnumerateInstanceLayerProperties(&count, layers.data()));
    return std::any_of(layers.begin(), layers.end(),
                       [&](const VkLayerProperties& l) { return std::strcmp(l.layerName, name) == 0; });
}

bool has_instance_extension(const char* name) {
    uint32_t count = 0;
    REFRACT_VK_CHECK(vkEnumerateInstanceExtensionProperties(nullptr, &count, nullptr));
    std::vector<VkExtensionProperties> extensions(count);
    REFRACT_VK_CHECK(vkEnumerateInstanceExtensionProperties(nullptr, &count, extensions.data()));
    return std::any_of(extensions.begin(), extensions.end(),
                       [&](const VkExtensionProperties& e) { return std::strcmp(e.extensionName, name) == 0; });
}

VkInstance create_instance(bool validation, bool debug_utils) {
    VkApplicationInfo app{VK_STRUCTURE_TYPE_APPLICATION_INFO};
    app.pApplicationName = "refract";
    app.applicationVersion = VK_MAKE_API_VERSION(0, 0, 1, 0);
    app.pEngineName = "refract";
    app.apiVersion = VK_API_VERSION_1_2;
    std::vector<const char*> layers;
    if (validation) layers.push_back(kValidationLayer);
    std::vector<const char*> extensions;
    if (debug_utils) extensions.push_back(VK_EXT_DEBUG_UTILS_EXTENSION_NAME);
    VkInstanceCreateInfo info{VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO};
    info.pApplicationInfo = &app;
    info.enabledLayerCount = static_cast<uint32_t>(layers.size());
    info.ppEnabledLayerNames = layers.data();
    info.enabledExtensionCount = static_cast<uint32_t>(extensions.size());
    info.ppEnabledExtensionNames = extensions.data();
    VkInstance instance = VK_NULL_HANDLE;
    REFRACT_VK_CHECK(vkCreateInstance(&info, nullptr, &instance));
    return instance;
}

// Checks one device against what Refract needs; fills `info` and returns the compute queue family.
uint32_t inspect_device(VkPhysicalDevice device, uint32_t index, DeviceInfo& info) {
    VkPhysicalDeviceDriverProperties driver{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_DRIVER_PROPERTIES};
    VkPhysicalDeviceProperties2 properties{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PROPERTIES_2};
    properties.pNext = &driver;
    vkGetPhysicalDeviceProperties2(device, &properties);
    const VkPhysicalDeviceProperties& p = properties.properties;
    info.index = index;
    info.name = p.deviceName;
    info.type = device_type_name(p.deviceType);
    info.driver_name = driver.driverName;
    info.driver_info = driver.driverInfo;
    info.api_version = version_string(p.apiVersion);

    VkPhysicalDeviceMemoryProperties memory{};
    vkGetPhysicalDeviceMemoryProperties(device, &memory);
    for (uint32_t i = 0; i < memory.memoryHeapCount; ++i)
        if (memory.memoryHeaps[i].flags & VK_MEMORY_HEAP_DEVICE_LOCAL_BIT)
            info.device_local_bytes = std::max<uint64_t>(info.device_local_bytes, memory.memoryHeaps[i].size);

    if (p.apiVersion < VK_API_VERSION_1_2) info.missing.push_back("Vulkan 1.2 (has " + info.api_version + ")");

    uint32_t family_count = 0;
    vkGetPhysicalDeviceQueueFamilyProperties(device, &family_count, nullptr);
    std::vector<VkQueueFamilyProperties> families(family_count);
    vkGetPhysicalDeviceQueueFamilyProperties(device, &family_count, families.data());
    uint32_t family = UINT32_MAX;
    for (uint32_t i = 0; i < family_count; ++i) {
        if ((families[i].queueFlags & VK_QUEUE_COMPUTE_BIT) && families[i].timestampValidBits > 0) {
            family = i;
            break;
        }
    }
    if (family == UINT32_MAX) info.missing.push_back("a compute queue with timestamp queries");

    uint32_t extension_count = 0;
    REFRACT_VK_CHECK(vkEnumerateDeviceExtensionProperties(device, nullptr, &extension_count, nullptr));
    std::vector<VkExtensionProperties> extensions(extension_count);
    REFRACT_VK_CHECK(vkEnumerateDeviceExtensionProperties(device, nullptr, &extension_count, extensions.data()));
    const bool push_descriptor = std::any_of(extensions.begin(), extensions.end(), [](const auto& e) {
        return std::strcmp(e.extensionName, VK_KHR_PUSH_DESCRIPTOR_EXTENSION_NAME) == 0;
    });
    if (!push_descriptor) info.missing.push_back(VK_KHR_PUSH_DESCRIPTOR_EXTENSION_NAME);

    // The index field and radiance grid are float 3D images sampled with trilinear filtering.
    for (VkFormat format : {VK_FORMAT_R32G32B32A32_SFLOAT, VK_FORMAT_R16G16B16A16_SFLOAT, VK_FORMAT_R32_SFLOAT}) {
        VkFormatProperties fp{};
        vkGetPhysicalDeviceFormatProperties(device, format, &fp);
        const VkFormatFeatureFlags need = VK_FORMAT_FEATURE_STORAGE_IMAGE_BIT |
                                          VK_FORMAT_FEATURE_SAMPLED_IMAGE_BIT |
                                          VK_FORMAT_FEATURE_SAMPLED_IMAGE_FILTER_LINEAR_BIT;
        if ((fp.optimalTilingFeatures & need) != need)
            info.missing.push_back("storage + linear-filtered sampling for format " + std::to_string(format));
    }
    // Photon deposits add two fixed-point sums with one 64-bit atomic.
    VkPhysicalDeviceVulkan12Features features12{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_FEATURES};
    VkPhysicalDeviceFeatures2 features{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2};
    features.pNext = &features12;
    if (p.apiVersion >= VK_API_VERSION_1_2) {
        vkGetPhysicalDeviceFeatures2(device, &features);
        if (!features.features.shaderInt64) info.missing.push_back("shaderInt64");
        if (!features12.shaderBufferInt64Atomics) info.missing.push_back("shaderBufferInt64Atomics");
        // The radiance sums outgrow a storage buffer binding (maxStorageBufferRange, 128 MiB on
        // lavapipe) and are reached by device address instead.
        if (!features12.bufferDeviceAddress) info.missing.push_back("bufferDeviceAddress");
        // The viewing pass hands out pixels a subgroup at a time (elect + broadcast), and a still frame's
        // eye paths take their footprint from their neighbours' in the subgroup (shuffle).
        VkPhysicalDeviceSubgroupProperties subgroup{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_SUBGROUP_PROPERTIES};
        VkPhysicalDeviceProperties2 properties2{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PROPERTIES_2};
        properties2.pNext = &subgroup;
        vkGetPhysicalDeviceProperties2(device, &properties2);
        const VkSubgroupFeatureFlags ops =
            VK_SUBGROUP_FEATURE_BASIC_BIT | VK_SUBGROUP_FEATURE_BALLOT_BIT | VK_SUBGROUP_FEATURE_SHUFFLE_BIT;
        if (!(subgroup.supportedStages & VK_SHADER_STAGE_COMPUTE_BIT) || (subgroup.supportedOperations & ops) != ops)
            info.missing.push_back("subgroup basic, ballot and shuffle operations in compute shaders");
    }
    info.suitable = info.missing.empty();
    return family;
}

// True when the device offers VK_EXT_shader_atomic_float's add on float32 storage buffers.
bool has_float_atomic_add(VkPhysicalDevice device) {
    uint32_t extension_count = 0;
    REFRACT_VK_CHECK(vkEnumerateDeviceExtensionProperties(device, nullptr, &extension_count, nullptr));
    std::vector<VkExtensionProperties> available(extension_count);
    REFRACT_VK_CHECK(
        vkEnumerateDeviceExtensionProperties(device, nullptr, &extension_count, available.data()));
    const bool has = std::any_of(available.begin(), available.end(), [](const auto& e) {
        return std::strcmp(e.extensionName, VK_EXT_SHADER_ATOMIC_FLOAT_EXTENSION_NAME) == 0;
    });
    if (!has) return false;
    VkPhysicalDeviceShaderAtomicFloatFeaturesEXT float_atomics{
        VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_SHADER_ATOMIC_FLOAT_FEATURES_EXT};
    VkPhysicalDeviceFeatures2 query{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2};
    query.pNext = &float_atomics;
    vkGetPhysicalDeviceFeatures2(device, &query);
    return float_atomics.shaderBufferFloat32AtomicAdd == VK_TRUE;
}

}  // namespace

ContextOptions options_from_environment(ContextOptions options) {
    if (options.device_name.empty())
        if (const char* name = std::getenv("REFRACT_DEVICE")) options.device_name = name;
    if (const char* v = std::getenv("REFRACT_VALIDATION"); v && std::strcmp(v, "1") == 0) options.validation = true;
    return options;
}

std::string split_cpu_dispatches_finely(unsigned cores) {
    constexpr const char* kThreads = "LP_NUM_THREADS";
    if (const char* set = std::getenv(kThreads); set && *set) return set;  // lavapipe reads empty as unset
    const std::string threads = std::to_string(4 * std::max(cores, 1u));
    if (setenv(kThreads, threads.c_str(), 1) != 0) return {};
    return threads;
}

std::vector<DeviceInfo> list_devices() {
    VkInstance instance = create_instance(false, false);
    std::vector<DeviceInfo> result;
    try {
        uint32_t count = 0;
        REFRACT_VK_CHECK(vkEnumeratePhysicalDevices(instance, &count, nullptr));
        std::vector<VkPhysicalDevice> devices(count);
        REFRACT_VK_CHECK(vkEnumeratePhysicalDevices(instance, &count, devices.data()));
        for (uint32_t i = 0; i < count; ++i) {
            DeviceInfo info;
            inspect_device(devices[i], i, info);
            result.push_back(std::move(info));
        }
    } catch (...) {
        vkDestroyInstance(instance, nullptr);
        throw;
    }
    vkDestroyInstance(instance, nullptr);
    return result;
}

Context::Context(const ContextOptions& options) : compile_on_first_use_(options.compile_on_first_use) {
    if (options.validation && !has_instance_layer(kValidationLayer))
        throw Error("validation requested but VK_LAYER_KHRONOS_validation is not installed "
                    "(Debian package vulkan-validationlayers)");
    const bool debug_utils = has_instance_extension(VK_EXT_DEBUG_UTILS_EXTENSION_NAME);
    instance_ = create_instance(options.validation, debug_utils);
    try {
        if (debug_utils) {
            set_object_name_ = reinterpret_cast<PFN_vkSetDebugUtilsObjectNameEXT>(
                vkGetInstanceProcAddr(instance_, "vkSetDebugUtilsObjectNameEXT"));
        }
        if (options.validation && debug_utils) create_messenger();
        choose_device(options.device_name);
        create_device();
        VkFenceCreateInfo fence_info{VK_STRUCTURE_TYPE_FENCE_CREATE_INFO};
        VkFence fence = VK_NULL_HANDLE;
        REFRACT_VK_CHECK(vkCreateFence(device_, &fence_info, nullptr, &fence));
        fence_ = UniqueFence(device_, fence);
    } catch (...) {
        // The destructor does not run for a constructor that throws: undo here what was made.
        fence_.reset();
        if (device_) vkDestroyDevice(device_, nullptr);
        if (messenger_) {
            auto destroy = reinterpret_cast<PFN_vkDestroyDebugUtilsMessengerEXT>(
                vkGetInstanceProcAddr(instance_, "vkDestroyDebugUtilsMessengerEXT"));
            destroy(instance_, messenger_, nullptr);
        }
        vkDestroyInstance(instance_, nullptr);
        throw;
    }
}

void Context::create_messenger() {
    // Warnings and errors of every kind reach on_debug_message, which counts the errors.
    auto create = reinterpret_cast<PFN_vkCreateDebugUtilsMessengerEXT>(
        vkGetInstanceProcAddr(instance_, "vkCreateDebugUtilsMessengerEXT"));
    VkDebugUtilsMessengerCreateInfoEXT info{VK_STRUCTURE_TYPE_DEBUG_UTILS_MESSENGER_CREATE_INFO_EXT};
    info.messageSeverity =
        VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT;
    info.messageType = VK_DEBUG_UTILS_MESSAGE_TYPE_GENERAL_BIT_EXT |
                       VK_DEBUG_UTILS_MESSAGE_TYPE_VALIDATION_BIT_EXT |
                       VK_DEBUG_UTILS_MESSAGE_TYPE_PERFORMANCE_BIT_EXT;
    info.pfnUserCallback = &Context::on_debug_message;
    info.pUserData = this;
    REFRACT_VK_CHECK(create(instance_, &info, nullptr, &messenger_));
}

void Context::choose_device(const std::string& device_name) {
    uint32_t count = 0;
    REFRACT_VK_CHECK(vkEnumeratePhysicalDevices(instance_, &count, nullptr));
    std::vector<VkPhysicalDevice> devices(count);
    REFRACT_VK_CHECK(vkEnumeratePhysicalDevices(instance_, &count, devices.data()));
    if (count == 0) throw Error("no Vulkan devices found (install mesa-vulkan-drivers for lavapipe)");

    // Pick: the named device if asked for, else the best-ranked suitable one. Every device's verdict goes
    // into the error when none will do.
    std::ostringstream report;
    int best_rank = -1;
    for (uint32_t i = 0; i < count; ++i) {
        DeviceInfo info;
        const uint32_t family = inspect_device(devices[i], i, info);
        VkPhysicalDeviceProperties p{};
        vkGetPhysicalDeviceProperties(devices[i], &p);
        const bool name_matches = device_name.empty() || info.name.find(device_name) != std::string::npos;
        report << "\n  " << info.name << " (" << info.type << "): ";
        if (!name_matches)
            report << "not named by --device '" << device_name << "'";
        else if (!info.suitable) {
            report << "missing";
            for (const auto& m : info.missing) report << " [" << m << "]";
        } else
            report << "suitable";
        if (!name_matches || !info.suitable) continue;
        const int rank = type_rank(p.deviceType);
        if (rank > best_rank) {
            best_rank = rank;
            physical_device_ = devices[i];
            queue_family_ = family;
            info_ = info;
        }
    }
    if (physical_device_ == VK_NULL_HANDLE) throw Error("no suitable Vulkan device:" + report.str());
    vkGetPhysicalDeviceProperties(physical_device_, &properties_);
    vkGetPhysicalDeviceMemoryProperties(physical_device_, &memory_properties_);
    VkPhysicalDeviceMaintenance3Properties maintenance3{
        VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_MAINTENANCE_3_PROPERTIES};
    VkPhysicalDeviceProperties2 properties2{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PROPERTIES_2};
    properties2.pNext = &maintenance3;
    vkGetPhysicalDeviceProperties2(physical_device_, &properties2);
    max_memory_allocation_size_ = maintenance3.maxMemoryAllocationSize;
}

void Context::create_device() {
    const float priority = 1.0f;
    VkDeviceQueueCreateInfo queue_info{VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO};
    queue_info.queueFamilyIndex = queue_family_;
    queue_info.queueCount = 1;
    queue_info.pQueuePriorities = &priority;
    std::vector<const char*> extensions = {VK_KHR_PUSH_DESCRIPTOR_EXTENSION_NAME};
    // Float atomics are optional: only `refract bench` uses them, to compare with integer deposits.
    float_atomics_ = has_float_atomic_add(physical_device_);
    VkPhysicalDeviceShaderAtomicFloatFeaturesEXT float_atomics{
        VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_SHADER_ATOMIC_FLOAT_FEATURES_EXT};
    float_atomics.shaderBufferFloat32AtomicAdd = float_atomics_ ? VK_TRUE : VK_FALSE;
    if (float_atomics_) extensions.push_back(VK_EXT_SHADER_ATOMIC_FLOAT_EXTENSION_NAME);
    VkPhysicalDeviceVulkan12Features features12{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_FEATURES};
    features12.pNext = float_atomics_ ? &float_atomics : nullptr;
    features12.shaderBufferInt64Atomics = VK_TRUE;
    features12.bufferDeviceAddress = VK_TRUE;
    VkPhysicalDeviceFeatures2 features{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2};
    features.pNext = &features12;
    features.features.shaderInt64 = VK_TRUE;
    VkDeviceCreateInfo device_info{VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO};
    device_info.pNext = &features;
    device_info.queueCreateInfoCount = 1;
    device_info.pQueueCreateInfos = &queue_info;
    device_info.enabledExtensionCount = static_cast<uint32_t>(extensions.size());
    device_info.ppEnabledExtensionNames = extensions.data();
    REFRACT_VK_CHECK(vkCreateDevice(physical_device_, &device_info, nullptr, &device_));
    vkGetDeviceQueue(device_, queue_family_, 0, &queue_);
    push_descriptor_set = reinterpret_cast<PFN_vkCmdPushDescriptorSetKHR>(
        vkGetDeviceProcAddr(device_, "vkCmdPushDescriptorSetKHR"));
    if (!push_descriptor_set) throw Error("vkCmdPushDescriptorSetKHR not found on " + info_.name);
}

Context::~Context() {
    fence_.reset();
    // Every resource returns its memory to this count when destroyed: anything left is a resource
    // that outlived its context (a destructor cannot throw, so say it loudly instead).
    if (const int64_t leaked = allocated_bytes_.load(); leaked != 0)
        std::fprintf(stderr, "refract: %lld bytes of device memory still allocated when the Vulkan context was destroyed\n",
                     static_cast<long long>(leaked));
    if (device_) {
        vkDeviceWaitIdle(device_);
        vkDestroyDevice(device_, nullptr);
    }
    if (messenger_) {
        auto destroy = reinterpret_cast<PFN_vkDestroyDebugUtilsMessengerEXT>(
            vkGetInstanceProcAddr(instance_, "vkDestroyDebugUtilsMessengerEXT"));
        destroy(instance_, messenger_, nullptr);
    }
    vkDestroyInstance(instance_, nullptr);
}

UniqueMemory Context::allocate(const VkMemoryRequirements& requirements, VkMemoryPropertyFlags required,
                               VkMemoryPropertyFlags* chosen_flags, VkMemoryAllocateFlags allocate_flags) {
    for (uint32_t i = 0; i < memory_properties_.memoryTypeCount; ++i) {
        const VkMemoryPropertyFlags flags = memory_properties_.memoryTypes[i].propertyFlags;
        if (!(requirements.memoryTypeBits & (1u << i)) || (flags & required) != required) continue;
        VkMemoryAllocateFlagsInfo flags_info{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_FLAGS_INFO};
        flags_info.flags = allocate_flags;
        VkMemoryAllocateInfo info{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO};
        info.pNext = allocate_flags ? &flags_info : nullptr;
        info.allocationSize = requirements.size;
        info.memoryTypeIndex = i;
        VkDeviceMemory memory = VK_NULL_HANDLE;
        REFRACT_VK_CHECK(vkAllocateMemory(device_, &info, nullptr, &memory));
        if (chosen_flags) *chosen_flags = flags;
        return UniqueMemory(device_, memory);
    }
    throw Error("no memory type with flags " + std::to_string(required) + " for type bits " +
                std::to_string(requirements.memoryTypeBits));
}

void Context::set_name(VkObjectType type, uint64_t handle, const char* name) const {
    if (!set_object_name_) return;
    VkDebugUtilsObjectNameInfoEXT info{VK_STRUCTURE_TYPE_DEBUG_UTILS_OBJECT_NAME_INFO_EXT};
    info.objectType = type;
    info.objectHandle = handle;
    info.pObjectName = name;
    REFRACT_VK_CHECK(set_object_name_(device_, &info));
}

std::string Context::last_validation_message() const {
    std::lock_guard lock(message_mutex_);
    return last_validation_message_;
}

void Context::submit_and_wait(VkCommandBuffer command_buffer) {
    std::lock_guard lock(queue_mutex_);
    VkFence fence = fence_.get();
    REFRACT_VK_CHECK(vkResetFences(device_, 1, &fence));
    VkSubmitInfo submit{VK_STRUCTURE_TYPE_SUBMIT_INFO};
    submit.commandBufferCount = 1;
    submit.pCommandBuffers = &command_buffer;
    REFRACT_VK_CHECK(vkQueueSubmit(queue_, 1, &submit, fence));
    REFRACT_VK_CHECK(vkWaitForFences(device_, 1, &fence, VK_TRUE, UINT64_MAX));
}

VKAPI_ATTR VkBool32 VKAPI_CALL Context::on_debug_message(VkDebugUtilsMessageSeverityFlagBitsEXT severity,
                                                        VkDebugUtilsMessageTypeFlagsEXT,
                                                        const VkDebugUtilsMessengerCallbackDataEXT* data,
                                                        void* user) {
    auto* self = static_cast<Context*>(user);
    if (severity & VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT) {
        self->validation_errors_.fetch_add(1);
        std::lock_guard lock(self->message_mutex_);
        self->last_validation_message_ = data && data->pMessage ? data->pMessage : "(no message)";
    }
    return VK_FALSE;
}

}  // namespace refract::vk
