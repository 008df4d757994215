// Buffers and 3D images, each owning its memory. Sizes are checked against device limits before any
// Vulkan call, so an absurd request is an Error with a reason, not a driver failure.
#pragma once

#include <cstdint>
#include <span>
#include <string>

#include "vk/context.h"

namespace refract::vk {

enum class MemoryUse {
    device,    // GPU-only storage (host-visible anyway on lavapipe)
    upload,    // host writes, GPU reads
    readback,  // GPU writes, host reads
};

class Buffer {
public:
    Buffer() = default;
    Buffer(Context& context, VkDeviceSize size, VkBufferUsageFlags usage, MemoryUse use, const char* name);
    Buffer(Buffer&&) noexcept;
    Buffer& operator=(Buffer&&) noexcept;
    ~Buffer();

    VkBuffer get() const { return buffer_.get(); }
    VkDeviceSize size() const { return size_; }
    // Where shaders reach the buffer through a buffer_reference (GL_EXT_buffer_reference): created with
    // VK_BUFFER_USAGE_SHADER_DEVICE_ADDRESS_BIT, for data larger than a storage-buffer binding may span
    // (maxStorageBufferRange); 0 otherwise.
    VkDeviceAddress address() const { return address_; }
    // Host pointer for upload/readback buffers (persistently mapped); nullptr for device buffers.
    void* mapped() const { return mapped_; }
    template <typename T>
    std::span<T> mapped_span() const {
        return {static_cast<T*>(mapped_), static_cast<size_t>(size_ / sizeof(T))};
    }
    void write(const void* data, VkDeviceSize bytes, VkDeviceSize offset = 0);
    void read(void* data, VkDeviceSize bytes, VkDeviceSize offset = 0) const;

private:
    void release();
    UniqueBuffer buffer_;
    UniqueMemory memory_;
    VkDeviceSize size_ = 0;
    VkDeviceSize allocation_bytes_ = 0;
    void* mapped_ = nullptr;
    VkDeviceAddress address_ = 0;
    VkDevice device_ = VK_NULL_HANDLE;
    std::atomic<int64_t>* account_ = nullptr;
};

struct Extent3 {
    uint32_t x = 0, y = 0, z = 0;
    uint64_t count() const { return uint64_t{x} * y * z; }
    bool operator==(const Extent3&) const = default;
};

// A 3D (or, with z == 1, 2D-shaped 3D) image used as storage image and trilinearly sampled texture.
// It is created in VK_IMAGE_LAYOUT_GENERAL-ready state: the first use transitions it (see commands.h).
class Image3D {
public:
    Image3D() = default;
    Image3D(Context& context, Extent3 extent, VkFormat format, const char* name);
    Image3D(Image3D&&) noexcept;
    Image3D& operator=(Image3D&&) noexcept;
    ~Image3D();

    VkImage get() const { return image_.get(); }
    VkImageView view() const { return view_.get(); }
    VkFormat format() const { return format_; }
    Extent3 extent() const { return extent_; }
    uint32_t texel_bytes() const;

private:
    void release();
    UniqueImage image_;
    UniqueMemory memory_;
    UniqueImageView view_;
    Extent3 extent_{};
    VkFormat format_ = VK_FORMAT_UNDEFINED;
    VkDeviceSize allocation_bytes_ = 0;
    std::atomic<int64_t>* account_ = nullptr;
};

}  // namespace refract::vk
