#include "render/view_stage.h"

namespace refract::scene {

ViewStage::ViewStage(PassKit& kit) : kit_(kit) {}

void ViewStage::allocate(const FrameInputs::View& in) {
    if (in.width != width_ || in.height != height_) {
        hdr_ = {};
        ldr_ = {};
        refine_ = {};
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
    ParkedFrame parked{width_, height_, std::move(hdr_)};
    hdr_ = {};
    return parked;
}

void ViewStage::restore(ParkedFrame parked) {
    if (parked.width != width_ || parked.height != height_) {
        ldr_ = {};
        refine_ = {};
        width_ = parked.width;
        height_ = parked.height;
    }
    hdr_ = std::move(parked.hdr);
    allocate({width_, height_});
}

bool ViewStage::record(FrameRecording& recording, PassSet stale, bool adaptive, bool paced, const VolumeStage& volume,
                       const TransportStage& transport) {
    vk::CommandRecorder& recorder = recording.recorder();
    if (stale & kView) {
        recording.begin(kView);
        const passes::PhotonAccumulators& accum = transport.accumulators();
        if (!kit_.view.record(recorder, transport.view_inputs(volume), transport.radiance(), transport.flux(),
                              transport.floor_map(), {hdr_, accum.stats, accum.lit_blocks, refine_}, width_, height_,
                              adaptive, recording.between_parts(kView), parts_.paced(paced)))
            return false;
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

std::vector<glm::vec4> ViewStage::read_hdr() const {
    std::vector<glm::vec4> out(size_t{width_} * height_);
    hdr_.read(out.data(), out.size() * sizeof(glm::vec4));
    return out;
}

std::vector<uint32_t> ViewStage::read_ldr() const {
    std::vector<uint32_t> out(size_t{width_} * height_);
    ldr_.read(out.data(), out.size() * sizeof(uint32_t));
    return out;
}

}  // namespace refract::scene
