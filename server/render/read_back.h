// Reading a device image or buffer back to the host, each a submission of its own (tests, the CLI's slices).
#pragma once

#include <vector>

#include "vk/commands.h"
#include "vk/resources.h"

namespace refract::scene {

template <typename T>
std::vector<T> read_buffer(vk::Context& context, const vk::Buffer& buffer) {
    vk::Buffer staging(context, buffer.size(), VK_BUFFER_USAGE_TRANSFER_DST_BIT, vk::MemoryUse::readback, "readback");
    vk::run_once(context, [&](vk::CommandRecorder& r) {
        r.copy(buffer, staging, buffer.size());
        r.to_host_barrier();
    });
    std::vector<T> out(buffer.size() / sizeof(T));
    staging.read(out.data(), out.size() * sizeof(T));
    return out;
}

template <typename T>
std::vector<T> read_image(vk::Context& context, const vk::Image3D& image) {
    const VkDeviceSize bytes = image.extent().count() * image.texel_bytes();
    vk::Buffer staging(context, bytes, VK_BUFFER_USAGE_TRANSFER_DST_BIT, vk::MemoryUse::readback, "readback");
    vk::run_once(context, [&](vk::CommandRecorder& r) {
        r.copy(image, staging);
        r.to_host_barrier();
    });
    std::vector<T> out(bytes / sizeof(T));
    staging.read(out.data(), bytes);
    return out;
}

}  // namespace refract::scene
