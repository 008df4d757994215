#include "vk/resources.h"

#include <cstring>

namespace refract::vk {
namespace {

VkMemoryPropertyFlags required_flags(MemoryUse use) {
    switch (use) {
        case MemoryUse::device: return VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT;
        case MemoryUse::upload: return VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;
        case MemoryUse::readback:
            return VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;
    }
    return 0;
}

}  // namespace

Buffer::Buffer(Context& context, VkDeviceSize size, VkBufferUsageFlags usage, MemoryUse use, const char* name)
    : size_(size), device_(context.device()), account_(&context.allocated_bytes_counter()) {
    if (size == 0) throw Error(std::string("buffer '") + name + "' has size 0");
    if ((usage & VK_BUFFER_USAGE_STORAGE_BUFFER_BIT) && size > context.limits().maxStorageBufferRange)
        throw LimitError(std::string("buffer '") + name + "' needs " + std::to_string(size) +
                    " bytes, more than this device's storage buffer limit of " +
                    std::to_string(context.limits().maxStorageBufferRange));
    VkBufferCreateInfo info{VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO};
    info.size = size;
    info.usage = usage;
    info.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
    VkBuffer buffer = VK_NULL_HANDLE;
    REFRACT_VK_CHECK(vkCreateBuffer(device_, &info, nullptr, &buffer));
    buffer_ = UniqueBuffer(device_, buffer);
    context.set_name(VK_OBJECT_TYPE_BUFFER, buffer, name);
    VkMemoryRequirements requirements{};
    vkGetBufferMemoryRequirements(device_, buffer, &requirements);
    const bool addressed = usage & VK_BUFFER_USAGE_SHADER_DEVICE_ADDRESS_BIT;
    if (requirements.size > context.max_memory_allocation_size())
        throw LimitError(std::string("buffer '") + name + "' needs " + std::to_string(requirements.size) +
                    " bytes, more than this device's largest allocation of " +
                    std::to_string(context.max_memory_allocation_size()));
    memory_ = context.allocate(requirements, required_flags(use), nullptr,
                               addressed ? VK_MEMORY_ALLOCATE_DEVICE_ADDRESS_BIT : 0);
    REFRACT_VK_CHECK(vkBindBufferMemory(device_, buffer, memory_.get(), 0));
    if (addressed) {
        VkBufferDeviceAddressInfo address_info{VK_STRUCTURE_TYPE_BUFFER_DEVICE_ADDRESS_INFO};
        address_info.buffer = buffer;
        address_ = vkGetBufferDeviceAddress(device_, &address_info);
    }
    allocation_bytes_ = requirements.size;
    account_->fetch_add(static_cast<int64_t>(allocation_bytes_));
    if (use != MemoryUse::device) REFRACT_VK_CHECK(vkMapMemory(device_, memory_.get(), 0, VK_WHOLE_SIZE, 0, &mapped_));
}

Buffer::Buffer(Buffer&& other) noexcept { *this = std::move(other); }

Buffer& Buffer::operator=(Buffer&& other) noexcept {
    if (this != &other) {
        release();
        buffer_ = std::move(other.buffer_);
        memory_ = std::move(other.memory_);
        size_ = std::exchange(other.size_, 0);
        allocation_bytes_ = std::exchange(other.allocation_bytes_, 0);
        mapped_ = std::exchange(other.mapped_, nullptr);
        address_ = std::exchange(other.address_, 0);
        device_ = other.device_;
        account_ = std::exchange(other.account_, nullptr);
    }
    return *this;
}

Buffer::~Buffer() { release(); }

void Buffer::release() {
    if (mapped_) vkUnmapMemory(device_, memory_.get());
    mapped_ = nullptr;
    buffer_.reset();
    memory_.reset();
    address_ = 0;
    if (account_) account_->fetch_sub(static_cast<int64_t>(allocation_bytes_));
    account_ = nullptr;
    allocation_bytes_ = 0;
}

void Buffer::write(const void* data, VkDeviceSize bytes, VkDeviceSize offset) {
    if (!mapped_) throw Error("write to a buffer that is not host visible");
    if (offset + bytes > size_) throw Error("write past the end of a buffer");
    std::memcpy(static_cast<char*>(mapped_) + offset, data, bytes);
}

void Buffer::read(void* data, VkDeviceSize bytes, VkDeviceSize offset) const {
    if (!mapped_) throw Error("read from a buffer that is not host visible");
    if (offset + bytes > size_) throw Error("read past the end of a buffer");
    std::memcpy(data, static_cast<const char*>(mapped_) + offset, bytes);
}

Image3D::Image3D(Context& context, Extent3 extent, VkFormat format, const char* name)
    : extent_(extent), format_(format), account_(&context.allocated_bytes_counter()) {
    const uint32_t limit = context.limits().maxImageDimension3D;
    if (extent.x == 0 || extent.y == 0 || extent.z == 0 || extent.x > limit || extent.y > limit || extent.z > limit)
        throw LimitError(std::string("image '") + name + "' extent " + std::to_string(extent.x) + "x" +
                    std::to_string(extent.y) + "x" + std::to_string(extent.z) +
                    " is empty or exceeds this device's 3D image limit of " + std::to_string(limit));
    const VkDevice device = context.device();
    VkImageCreateInfo info{VK_STRUCTURE_TYPE_IMAGE_CREATE_INFO};
    info.imageType = VK_IMAGE_TYPE_3D;
    info.format = format;
    info.extent = {extent.x, extent.y, extent.z};
    info.mipLevels = 1;
    info.arrayLayers = 1;
    info.samples = VK_SAMPLE_COUNT_1_BIT;
    info.tiling = VK_IMAGE_TILING_OPTIMAL;
    info.usage = VK_IMAGE_USAGE_STORAGE_BIT | VK_IMAGE_USAGE_SAMPLED_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT |
                 VK_IMAGE_USAGE_TRANSFER_DST_BIT;
    info.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
    info.initialLayout = VK_IMAGE_LAYOUT_UNDEFINED;
    VkImage image = VK_NULL_HANDLE;
    REFRACT_VK_CHECK(vkCreateImage(device, &info, nullptr, &image));
    image_ = UniqueImage(device, image);
    context.set_name(VK_OBJECT_TYPE_IMAGE, image, name);
    VkMemoryRequirements requirements{};
    vkGetImageMemoryRequirements(device, image, &requirements);
    memory_ = context.allocate(requirements, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT);
    REFRACT_VK_CHECK(vkBindImageMemory(device, image, memory_.get(), 0));
    allocation_bytes_ = requirements.size;
    account_->fetch_add(static_cast<int64_t>(allocation_bytes_));

    VkImageViewCreateInfo view_info{VK_STRUCTURE_TYPE_IMAGE_VIEW_CREATE_INFO};
    view_info.image = image;
    view_info.viewType = VK_IMAGE_VIEW_TYPE_3D;
    view_info.format = format;
    view_info.subresourceRange = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, 1};
    VkImageView view = VK_NULL_HANDLE;
    REFRACT_VK_CHECK(vkCreateImageView(device, &view_info, nullptr, &view));
    view_ = UniqueImageView(device, view);
}

Image3D::Image3D(Image3D&& other) noexcept { *this = std::move(other); }

Image3D& Image3D::operator=(Image3D&& other) noexcept {
    if (this != &other) {
        release();
        view_ = std::move(other.view_);
        image_ = std::move(other.image_);
        memory_ = std::move(other.memory_);
        extent_ = other.extent_;
        format_ = other.format_;
        allocation_bytes_ = std::exchange(other.allocation_bytes_, 0);
        account_ = std::exchange(other.account_, nullptr);
    }
    return *this;
}

Image3D::~Image3D() { release(); }

void Image3D::release() {
    view_.reset();
    image_.reset();
    memory_.reset();
    if (account_) account_->fetch_sub(static_cast<int64_t>(allocation_bytes_));
    account_ = nullptr;
    allocation_bytes_ = 0;
}

uint32_t Image3D::texel_bytes() const {
    switch (format_) {
        case VK_FORMAT_R32G32B32A32_SFLOAT: return 16;
        case VK_FORMAT_R16G16B16A16_SFLOAT: return 8;
        case VK_FORMAT_R32G32_SFLOAT: return 8;
        case VK_FORMAT_R32_SFLOAT: return 4;
        case VK_FORMAT_R32_UINT: return 4;
        case VK_FORMAT_R8_UINT: return 1;
        case VK_FORMAT_R8G8B8A8_SNORM: return 4;
        case VK_FORMAT_R8G8B8A8_UNORM: return 4;
        default: throw Error("texel_bytes: format " + std::to_string(format_) + " not used by refract");
    }
}

}  // namespace refract::vk
