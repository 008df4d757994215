// Command recording: one pool + buffer per recorder, reusable (reset and re-record), submitted on the
// context's single queue. Images stay in VK_IMAGE_LAYOUT_GENERAL for their whole life: every pass both
// writes (storage) and samples them, and GENERAL serves both without per-pass transitions.
#pragma once

#include "vk/context.h"
#include "vk/resources.h"

namespace refract::vk {

class CommandRecorder {
public:
    CommandRecorder(Context& context, const char* name);
    CommandRecorder(const CommandRecorder&) = delete;
    CommandRecorder& operator=(const CommandRecorder&) = delete;

    // Resets the buffer and starts recording (one-time-submit: re-recorded for every use).
    VkCommandBuffer begin();
    // Ends recording, submits and waits for completion.
    void submit_and_wait();
    VkCommandBuffer get() const { return command_buffer_; }

    // Compute writes visible to later compute reads/writes, indirect dispatch arguments and transfers.
    void compute_barrier();
    // Transfer writes (copies, fills) visible to compute shaders.
    void transfer_to_compute_barrier();
    // Compute or transfer writes visible to host reads after the submission completes.
    void to_host_barrier();
    // First use of an image: UNDEFINED -> GENERAL (contents discarded).
    void init_image(const Image3D& image);
    void fill(const Buffer& buffer, uint32_t value);
    // Sets every texel of a float image (in the GENERAL layout) to `value`, the channels it has.
    void clear(const Image3D& image, const float (&value)[4]);
    // Writes `bytes` (at most 65536, a multiple of 4) from host memory into `buffer` at `offset`.
    void update(const Buffer& buffer, VkDeviceSize offset, const void* data, VkDeviceSize bytes);
    void copy(const Buffer& src, const Buffer& dst, VkDeviceSize bytes);
    void copy(const Buffer& src, const Image3D& dst);
    void copy(const Image3D& src, const Buffer& dst);
    // The texels of `extent` from `src_first` in `src` to `dst_first` in `dst` (same format).
    void copy(const Image3D& src, Extent3 src_first, const Image3D& dst, Extent3 dst_first, Extent3 extent);

private:
    Context& context_;
    UniqueCommandPool pool_;
    VkCommandBuffer command_buffer_ = VK_NULL_HANDLE;
};

// Records a whole command buffer with `record`, submits it and waits: for uploads and tests.
template <typename F>
void run_once(Context& context, F&& record) {
    CommandRecorder recorder(context, "one-shot");
    recorder.begin();
    record(recorder);
    recorder.submit_and_wait();
}

}  // namespace refract::vk
