// One run of a scene's stale passes as it is recorded: a command buffer at a time, each pass bracketed
// by timestamps, and, when the run may give way (RunOptions::give_way), a submission after each part so
// that it can stop there. The stages record into it; where it stopped is a value, not an exception.
#pragma once

#include <functional>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "passes/transport_pipeline.h"
#include "render/invalidation.h"
#include "vk/commands.h"
#include "vk/gpu_timer.h"

namespace refract::scene {

class FrameRecording {
public:
    // Begins the first command buffer. `give_way` (may be empty: the run is one submission) is asked
    // after each part.
    FrameRecording(vk::CommandRecorder& recorder, vk::GpuTimer& timer, std::function<bool()> give_way);

    vk::CommandRecorder& recorder() { return recorder_; }
    bool in_parts() const { return static_cast<bool>(give_way_); }
    void begin(Pass pass);
    void end();
    // Submits the parts recorded so far, `pass` unfinished (begun or next), and asks whether to give way:
    // true when the run stops here (nothing more may be recorded). Does nothing when not in parts.
    bool part(Pass pass);
    // What a pass runs between two parts of `pass` (timed under its name); empty when not in parts.
    passes::BetweenParts between_parts(Pass pass);
    // The pass the run stopped in (given way before or within it), if it stopped.
    std::optional<Pass> stopped() const { return stopped_; }
    // Submits what is left and waits; each pass's GPU milliseconds, its parts summed, in the order run.
    std::vector<std::pair<std::string, double>> finish();

private:
    vk::CommandRecorder& recorder_;
    vk::GpuTimer& timer_;
    std::function<bool()> give_way_;
    VkCommandBuffer cmd_ = VK_NULL_HANDLE;
    std::vector<std::pair<std::string, double>> earlier_ms_;  // of the submissions before the current one
    std::optional<Pass> stopped_;
};

}  // namespace refract::scene
