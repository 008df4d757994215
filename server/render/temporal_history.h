// A viewer's full-resolution history of what it was shown, for temporal reuse (TEMPORAL.md). While a
// user drags, an interactive frame traces fewer pixels than the viewer shows, each at a sub-pixel offset
// that changes from frame to frame (RunOptions::view_jitter), and the history takes them in
// (shaders/temporal_reuse.comp): reprojected through the camera's motion, clamped where anything moved,
// blended as a running mean where nothing did. So the frames sent during a drag are at the viewer's full
// size, and sharpen while it holds still. One per viewing session of a scene, kept by the renderer.
#pragma once

#include <cstdint>
#include <vector>

#include "protocol/scene_document.h"
#include "render/pass_kit.h"
#include "vk/commands.h"
#include "vk/resources.h"

namespace refract::scene {

// The samples a history pixel counts at most: while anything moves, so that it follows within a few
// frames; while nothing does, as many as a still frame's refinement takes (kMaxViewSamples).
inline constexpr float kMovingHistorySamples = 4.0f;
inline constexpr float kStillHistorySamples = 16.0f;
// What a still frame counts for when it starts a history: as much as a moving history holds.
inline constexpr float kSeedSamples = kMovingHistorySamples;
// Sub-pixel offsets the frames cycle through: view samples 0 to this - 1, as a still frame refines (the
// pixel centre, then a Halton sequence, which covers the pixel evenly at any prefix).
inline constexpr uint32_t kJitterCycle = 16;

class TemporalHistory {
public:
    explicit TemporalHistory(PassKit& kit);

    // The view sample (passes::view_sample_offset) whose sub-pixel offset the next frame's samples take.
    uint32_t next_jitter() const { return frames_ % kJitterCycle; }
    // Starts the history over from a still frame of `document` (`still`: its linear radiance and inverse
    // depth per pixel, at the document's size, at pixel centres or refined), so that a drag begun after
    // it starts from the still's sharpness rather than from a frame of few samples.
    void seed(const vk::Buffer& still, const protocol::SceneDocument& document);
    // Takes in an interactive frame's samples (width x height, the offset of next_jitter(); vec4 radiance
    // and inverse depth) of `shown`, the document as the viewer sees it (its full size and camera).
    // `view_ran`: false when the frame only re-toned its samples (an exposure edit): the history is then
    // re-toned as it is. Starts over when `shown` differs from the last frame's document in more than the
    // camera, the lights and the exposure, or in size.
    void add(const vk::Buffer& samples, uint32_t width, uint32_t height, const protocol::SceneDocument& shown,
             bool view_ran);
    // The history tone-mapped (RGBA8 per pixel, top row first), as the last add() left it.
    std::vector<uint32_t> read_ldr() const;
    // The history's linear radiance (vec4: rgb, the samples each pixel stands on), for tests.
    std::vector<glm::vec4> read_radiance() const;

    uint32_t width() const { return width_; }
    uint32_t height() const { return height_; }
    int64_t bytes() const;
    uint64_t seeded_from = 0;  // the still frame it was last seeded from (the renderer's count of stills)
    uint64_t last_used = 0;

private:
    void resize(uint32_t width, uint32_t height);
    void run(const vk::Buffer& samples, const shaders::TemporalParams& params);

    PassKit& kit_;
    vk::CommandRecorder recorder_;
    vk::Buffer params_;
    vk::Buffer radiance_[2], depth_[2];  // ping-pong: the frame reads one and writes the other
    vk::Buffer ldr_;
    vk::Buffer neighbourhood_;  // the samples' statistics, grown to the largest sample frame seen
    uint32_t current_ = 0;  // which of the pair holds the history
    uint32_t width_ = 0, height_ = 0;
    uint32_t frames_ = 0;  // frames taken in since the history started over
    uint32_t samples_jitter_ = 0;  // the view sample whose offset the last samples taken in were traced at
    protocol::SceneDocument document_;  // the last frame's, as the viewer saw it
};

}  // namespace refract::scene
