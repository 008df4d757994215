#include "render/temporal_history.h"

#include <algorithm>
#include <cmath>

#include "render/transport_inputs.h"

namespace refract::scene {
namespace {

// Whether a history of `before` still shows `after`: the same scene, seen from wherever, lit from
// wherever (a moving light's change is what the neighbourhood clamp follows), at any exposure.
bool same_but_camera_and_lights(protocol::SceneDocument before, const protocol::SceneDocument& after) {
    before.camera = after.camera;
    before.lights = after.lights;
    before.image.exposure = after.image.exposure;
    return before == after;
}

shaders::TemporalParams params_for(const protocol::SceneDocument& shown, uint32_t width, uint32_t height) {
    shaders::TemporalParams p{};
    p.now = pinhole_camera(shown.camera);
    p.before = p.now;
    p.sizes = glm::uvec4(shown.image.width, shown.image.height, width, height);
    p.jitter = glm::vec4(0.0f, 0.0f, std::exp2(static_cast<float>(shown.image.exposure)), 0.0f);
    return p;
}

}  // namespace

TemporalHistory::TemporalHistory(PassKit& kit)
    : kit_(kit),
      recorder_(kit.context, "temporal reuse"),
      params_(kit.context, sizeof(shaders::TemporalParams),
              VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT, vk::MemoryUse::device,
              "temporal params") {}

int64_t TemporalHistory::bytes() const {
    return int64_t{width_} * height_ * int64_t{2 * sizeof(glm::vec4) + 2 * sizeof(float) + sizeof(uint32_t)} +
           static_cast<int64_t>(neighbourhood_.size());
}

void TemporalHistory::resize(uint32_t width, uint32_t height) {
    if (width == width_ && height == height_) return;
    width_ = width;
    height_ = height;
    frames_ = 0;
    const uint64_t pixels = uint64_t{width} * height;
    const auto usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT;
    for (int k = 0; k < 2; ++k) {
        radiance_[k] = vk::Buffer(kit_.context, pixels * sizeof(glm::vec4), usage, vk::MemoryUse::readback, "history");
        depth_[k] = vk::Buffer(kit_.context, pixels * sizeof(float), usage, vk::MemoryUse::device, "history depth");
    }
    ldr_ = vk::Buffer(kit_.context, pixels * sizeof(uint32_t), usage, vk::MemoryUse::readback, "history ldr");
}

void TemporalHistory::run(const vk::Buffer& samples, const shaders::TemporalParams& params) {
    recorder_.begin();
    recorder_.update(params_, 0, &params, sizeof params);
    recorder_.transfer_to_compute_barrier();
    const uint64_t sample_count = uint64_t{params.sizes.z} * params.sizes.w;
    if (neighbourhood_.size() < sample_count * 2 * sizeof(glm::vec4))
        neighbourhood_ = vk::Buffer(kit_.context, sample_count * 2 * sizeof(glm::vec4), VK_BUFFER_USAGE_STORAGE_BUFFER_BIT,
                                    vk::MemoryUse::device, "history neighbourhood");
    kit_.temporal_neighbourhood.record(recorder_, params_, samples, neighbourhood_, params.sizes.z, params.sizes.w);
    recorder_.compute_barrier();
    const uint32_t next = 1 - current_;
    kit_.temporal_reuse.record(recorder_,
                               {params_, samples, radiance_[current_], depth_[current_], radiance_[next], depth_[next], ldr_,
                                neighbourhood_},
                               width_, height_);
    recorder_.to_host_barrier();
    recorder_.submit_and_wait();
    current_ = next;
}

void TemporalHistory::seed(const vk::Buffer& still, const protocol::SceneDocument& document) {
    resize(document.image.width, document.image.height);
    shaders::TemporalParams p = params_for(document, width_, height_);
    p.blend = glm::vec4(kSeedSamples, kSeedSamples, kStillHistorySamples, 0.0f);
    run(still, p);
    frames_ = 1;
    samples_jitter_ = 0;
    document_ = document;
}

void TemporalHistory::add(const vk::Buffer& samples, uint32_t width, uint32_t height,
                          const protocol::SceneDocument& shown, bool view_ran) {
    // The offset the samples were traced at: this frame's, or the last frame's when the view did not run.
    const uint32_t jitter = view_ran ? next_jitter() : samples_jitter_;
    samples_jitter_ = jitter;
    const bool kept = frames_ > 0 && shown.image.width == width_ && shown.image.height == height_ &&
                      same_but_camera_and_lights(document_, shown);
    resize(shown.image.width, shown.image.height);
    if (!kept) frames_ = 0;
    shaders::TemporalParams p = params_for(shown, width, height);
    p.jitter = glm::vec4(passes::view_sample_offset(jitter), p.jitter.z, 0.0f);
    const bool camera_moved = kept && document_.camera != shown.camera;
    const bool moved = camera_moved || (kept && document_.lights != shown.lights);
    if (kept) p.before = pinhole_camera(document_.camera);
    p.state = glm::uvec4(kept ? 1u : 0u, camera_moved ? 1u : 0u, 0u, 0u);
    // A history pixel no sample falls in takes the samples' estimate as a whole sample while anything
    // moves (the history is the reprojection of a moving picture, and the estimate keeps it from
    // trailing); while nothing does, at about the share of pixels a sample falls in, so that it follows a
    // change within a cycle of offsets and is not held to the blurred estimate.
    const float side = static_cast<float>(shown.image.height) / static_cast<float>(height);
    const float estimate = moved ? 1.0f : std::clamp(1.0f / (side * side), 1.0f / static_cast<float>(kJitterCycle), 1.0f);
    const float sample = view_ran || !kept ? 1.0f : 0.0f;
    p.blend = glm::vec4(sample, sample * estimate, moved ? kMovingHistorySamples : kStillHistorySamples,
                        moved ? 1.0f : 0.0f);
    run(samples, p);
    if (view_ran) ++frames_;
    document_ = shown;
}

std::vector<uint32_t> TemporalHistory::read_ldr() const {
    std::vector<uint32_t> out(size_t{width_} * height_);
    ldr_.read(out.data(), out.size() * sizeof(uint32_t));
    return out;
}

std::vector<glm::vec4> TemporalHistory::read_radiance() const {
    std::vector<glm::vec4> out(size_t{width_} * height_);
    radiance_[current_].read(out.data(), out.size() * sizeof(glm::vec4));
    return out;
}

}  // namespace refract::scene
