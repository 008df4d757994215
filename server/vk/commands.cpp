#include "vk/commands.h"

namespace refract::vk {

CommandRecorder::CommandRecorder(Context& context, const char* name) : context_(context) {
    VkCommandPoolCreateInfo pool_info{VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO};
    pool_info.flags = VK_COMMAND_POOL_CREATE_RESET_COMMAND_BUFFER_BIT;
    pool_info.queueFamilyIndex = context.queue_family();
    VkCommandPool pool = VK_NULL_HANDLE;
    REFRACT_VK_CHECK(vkCreateCommandPool(context.device(), &pool_info, nullptr, &pool));
    pool_ = UniqueCommandPool(context.device(), pool);
    context.set_name(VK_OBJECT_TYPE_COMMAND_POOL, pool, name);
    VkCommandBufferAllocateInfo info{VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO};
    info.commandPool = pool;
    info.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
    info.commandBufferCount = 1;
    REFRACT_VK_CHECK(vkAllocateCommandBuffers(context.device(), &info, &command_buffer_));
    context.set_name(VK_OBJECT_TYPE_COMMAND_BUFFER, command_buffer_, name);
}

VkCommandBuffer CommandRecorder::begin() {
    REFRACT_VK_CHECK(vkResetCommandBuffer(command_buffer_, 0));
    VkCommandBufferBeginInfo info{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
    info.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
    REFRACT_VK_CHECK(vkBeginCommandBuffer(command_buffer_, &info));
    return command_buffer_;
}

void CommandRecorder::submit_and_wait() {
    REFRACT_VK_CHECK(vkEndCommandBuffer(command_buffer_));
    context_.submit_and_wait(command_buffer_);
}

namespace {
void memory_barrier(VkCommandBuffer cmd, VkPipelineStageFlags src_stage, VkAccessFlags src_access,
                    VkPipelineStageFlags dst_stage, VkAccessFlags dst_access) {
    VkMemoryBarrier barrier{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
    barrier.srcAccessMask = src_access;
    barrier.dstAccessMask = dst_access;
    vkCmdPipelineBarrier(cmd, src_stage, dst_stage, 0, 1, &barrier, 0, nullptr, 0, nullptr);
}
}  // namespace

void CommandRecorder::compute_barrier() {
    memory_barrier(command_buffer_, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT,
                   VK_ACCESS_SHADER_WRITE_BIT | VK_ACCESS_TRANSFER_WRITE_BIT,
                   VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT |
                       VK_PIPELINE_STAGE_DRAW_INDIRECT_BIT,
                   VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT | VK_ACCESS_TRANSFER_READ_BIT |
                       VK_ACCESS_TRANSFER_WRITE_BIT | VK_ACCESS_INDIRECT_COMMAND_READ_BIT);
}

void CommandRecorder::transfer_to_compute_barrier() {
    memory_barrier(command_buffer_, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT,
                   VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT);
}

void CommandRecorder::to_host_barrier() {
    memory_barrier(command_buffer_, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT,
                   VK_ACCESS_SHADER_WRITE_BIT | VK_ACCESS_TRANSFER_WRITE_BIT, VK_PIPELINE_STAGE_HOST_BIT,
                   VK_ACCESS_HOST_READ_BIT);
}

void CommandRecorder::init_image(const Image3D& image) {
    VkImageMemoryBarrier barrier{VK_STRUCTURE_TYPE_IMAGE_MEMORY_BARRIER};
    barrier.srcAccessMask = 0;
    barrier.dstAccessMask = VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT | VK_ACCESS_TRANSFER_WRITE_BIT;
    barrier.oldLayout = VK_IMAGE_LAYOUT_UNDEFINED;
    barrier.newLayout = VK_IMAGE_LAYOUT_GENERAL;
    barrier.srcQueueFamilyIndex = barrier.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
    barrier.image = image.get();
    barrier.subresourceRange = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, 1};
    vkCmdPipelineBarrier(command_buffer_, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT,
                         VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT, 0, 0, nullptr, 0,
                         nullptr, 1, &barrier);
}

void CommandRecorder::fill(const Buffer& buffer, uint32_t value) {
    vkCmdFillBuffer(command_buffer_, buffer.get(), 0, VK_WHOLE_SIZE, value);
}

void CommandRecorder::clear(const Image3D& image, const float (&value)[4]) {
    VkClearColorValue colour{};
    for (int i = 0; i < 4; ++i) colour.float32[i] = value[i];
    const VkImageSubresourceRange range{VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, 1};
    vkCmdClearColorImage(command_buffer_, image.get(), VK_IMAGE_LAYOUT_GENERAL, &colour, 1, &range);
}

void CommandRecorder::update(const Buffer& buffer, VkDeviceSize offset, const void* data, VkDeviceSize bytes) {
    if (bytes == 0 || bytes > 65536 || bytes % 4 != 0 || offset % 4 != 0 || offset + bytes > buffer.size())
        throw Error("buffer update of " + std::to_string(bytes) + " bytes at " + std::to_string(offset) +
                    " does not fit vkCmdUpdateBuffer's rules or the buffer");
    vkCmdUpdateBuffer(command_buffer_, buffer.get(), offset, bytes, data);
}

void CommandRecorder::copy(const Buffer& src, const Buffer& dst, VkDeviceSize bytes) {
    VkBufferCopy region{0, 0, bytes};
    vkCmdCopyBuffer(command_buffer_, src.get(), dst.get(), 1, &region);
}

namespace {
VkBufferImageCopy whole_image(const Image3D& image) {
    VkBufferImageCopy region{};
    region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
    region.imageExtent = {image.extent().x, image.extent().y, image.extent().z};
    return region;
}
}  // namespace

void CommandRecorder::copy(const Buffer& src, const Image3D& dst) {
    const VkBufferImageCopy region = whole_image(dst);
    vkCmdCopyBufferToImage(command_buffer_, src.get(), dst.get(), VK_IMAGE_LAYOUT_GENERAL, 1, &region);
}

void CommandRecorder::copy(const Image3D& src, const Buffer& dst) {
    const VkBufferImageCopy region = whole_image(src);
    vkCmdCopyImageToBuffer(command_buffer_, src.get(), VK_IMAGE_LAYOUT_GENERAL, dst.get(), 1, &region);
}

void CommandRecorder::copy(const Image3D& src, Extent3 src_first, const Image3D& dst, Extent3 dst_first, Extent3 extent) {
    auto offset = [](Extent3 e) { return VkOffset3D{static_cast<int32_t>(e.x), static_cast<int32_t>(e.y), static_cast<int32_t>(e.z)}; };
    VkImageCopy region{};
    region.srcSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
    region.dstSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
    region.srcOffset = offset(src_first);
    region.dstOffset = offset(dst_first);
    region.extent = {extent.x, extent.y, extent.z};
    vkCmdCopyImage(command_buffer_, src.get(), VK_IMAGE_LAYOUT_GENERAL, dst.get(), VK_IMAGE_LAYOUT_GENERAL, 1, &region);
}

}  // namespace refract::vk
