#include "render/view_stage.h"

namespace refract::scene {
namespace {

// A frame buffer the host reads directly (vk::MemoryUse::readback): a value per pixel.
template <typename T>
std::vector<T> read_mapped(const vk::Buffer& buffer, uint32_t width, uint32_t height) {
    std::vector<T> out(size_t{width} * height);
    buffer.read(out.data(), out.size() * sizeof(T));
    return out;
}

}  // namespace

ViewStage::ViewStage(PassKit& kit) : kit_(kit), upscale_recorder_(kit.context, "view upscale") {}

void ViewStage::allocate(const FrameInputs::View& in) {
    if (in.width != width_ || in.height != height_) {
        hdr_ = {};
        ldr_ = {};
        refine_ = {};
        ends_ = {};
        ends_kept_ = false;
        width_ = in.width;
        height_ = in.height;
    }
    vk::Context& ctx = kit_.context;
    const auto usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT;
    const uint64_t pixels = uint64_t{in.width} * in.height;
    if (!hdr_.get())
        hdr_ = vk::Buffer(ctx, pixels * sizeof(glm::vec4), usage, vk::MemoryUse::readback, "hdr frame");
    if (!ldr_.get())
        ldr_ = vk::Buffer(ctx, pixels * sizeof(uint32_t), usage, vk::MemoryUse::readback, "ldr frame");
    if (!refine_.get())
        refine_ = vk::Buffer(ctx, sizeof(shaders::WorkListHeader) + pixels * sizeof(uint32_t),
                             usage | VK_BUFFER_USAGE_INDIRECT_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                             vk::MemoryUse::device, "view refinement list");
}

ViewStage::ParkedFrame ViewStage::park() {
    ends_kept_ = false;
    ParkedFrame parked{width_, height_, std::move(hdr_)};
    hdr_ = {};
    return parked;
}

void ViewStage::restore(ParkedFrame parked) {
    ends_kept_ = false;  // the parked image's rays are not these
    if (parked.width != width_ || parked.height != height_) {
        ldr_ = {};
        refine_ = {};
        ends_ = {};
        width_ = parked.width;
        height_ = parked.height;
    }
    hdr_ = std::move(parked.hdr);
    allocate({width_, height_});
}

bool ViewStage::record(FrameRecording& recording, PassSet stale, bool adaptive, Ends ends, bool paced,
                       const VolumeStage& volume, const TransportStage& transport) {
    vk::CommandRecorder& recorder = recording.recorder();
    if (stale & kView) {
        recording.begin(kView);
        const auto usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT;
        const uint64_t ends_bytes = uint64_t{width_} * height_ * sizeof(shaders::ViewEnd);
        if (ends == Ends::traced && !ends_.get())
            ends_ = vk::Buffer(kit_.context, ends_bytes, usage, vk::MemoryUse::device, "view ends");
        if (ends == Ends::still && still_ends_.size() != ends_bytes) {
            still_ends_ = {};  // the old one first: both need not fit at once
            still_ends_ =
                vk::Buffer(kit_.context, ends_bytes, usage, vk::MemoryUse::device, "still frame's view ends");
        }
        if (!no_ends_.get())
            no_ends_ = vk::Buffer(kit_.context, sizeof(shaders::ViewEnd), usage, vk::MemoryUse::device,
                                  "no view ends");
        ends_kept_ = false;  // until this view is whole
        if (ends == Ends::still) still_ends_kept_ = false;
        const passes::PhotonAccumulators& accum = transport.accumulators();
        const vk::Buffer& written = ends == Ends::traced  ? ends_
                                    : ends == Ends::still ? still_ends_
                                                          : no_ends_;
        if (!kit_.view.record(recorder, transport.view_inputs(volume), transport.radiance(), transport.flux(),
                              transport.floor_map(), {hdr_, accum.stats, refine_, written}, width_, height_,
                              adaptive, ends != Ends::none, recording.between_parts(kView),
                              parts_.paced(paced)))
            return false;
        ends_kept_ = ends == Ends::traced;
        if (ends == Ends::still) {
            still_ends_kept_ = true;
            still_ends_width_ = width_;
            still_ends_height_ = height_;
        }
        recorder.compute_barrier();
        recording.end();
    }
    if (stale & kToneMap) {
        recording.begin(kToneMap);
        kit_.tone_map.record(recorder, transport.params_buffer(), hdr_, ldr_, width_, height_);
        recording.end();
    }
    return true;
}

void ViewStage::upscale(uint32_t width, uint32_t height, bool still_ends, const VolumeStage& volume,
                        const TransportStage& transport) {
    if (width != viewer_width_ || height != viewer_height_) {
        const uint64_t pixels = uint64_t{width} * height;
        const auto usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT;
        viewer_hdr_ = vk::Buffer(kit_.context, pixels * sizeof(glm::vec4), usage, vk::MemoryUse::readback, "viewer hdr");
        viewer_ldr_ = vk::Buffer(kit_.context, pixels * sizeof(uint32_t), usage, vk::MemoryUse::readback, "viewer ldr");
        viewer_width_ = width;
        viewer_height_ = height;
    }
    upscale_recorder_.begin();
    kit_.view_upscale.record(upscale_recorder_, transport.view_inputs(volume), transport.floor_map(),
                             {hdr_, ends_, viewer_hdr_, viewer_ldr_,
                              still_ends && has_still_ends(width, height) ? &still_ends_ : nullptr},
                             glm::uvec2(width_, height_), width, height,
                             transport.light_params().front().light_set.x == 1);
    upscale_recorder_.to_host_barrier();
    upscale_recorder_.submit_and_wait();
}

int64_t ViewStage::upscale_bytes() const {
    return static_cast<int64_t>(ends_.size() + still_ends_.size()) +
           int64_t{viewer_width_} * viewer_height_ * int64_t{sizeof(glm::vec4) + sizeof(uint32_t)};
}

std::vector<glm::vec4> ViewStage::read_viewer_hdr() const {
    return read_mapped<glm::vec4>(viewer_hdr_, viewer_width_, viewer_height_);
}

std::vector<uint32_t> ViewStage::read_viewer_ldr() const {
    return read_mapped<uint32_t>(viewer_ldr_, viewer_width_, viewer_height_);
}

std::vector<glm::vec4> ViewStage::read_hdr() const { return read_mapped<glm::vec4>(hdr_, width_, height_); }

std::vector<uint32_t> ViewStage::read_ldr() const { return read_mapped<uint32_t>(ldr_, width_, height_); }

}  // namespace refract::scene
