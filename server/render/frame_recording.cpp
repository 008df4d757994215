#include "render/frame_recording.h"

#include <algorithm>

namespace refract::scene {

FrameRecording::FrameRecording(vk::CommandRecorder& recorder, vk::GpuTimer& timer, std::function<bool()> give_way)
    : recorder_(recorder), timer_(timer), give_way_(std::move(give_way)) {
    cmd_ = recorder_.begin();
    timer_.reset(cmd_);
}

void FrameRecording::begin(Pass pass) { timer_.begin(cmd_, pass_names(pass)); }

void FrameRecording::end() { timer_.end(cmd_); }

bool FrameRecording::part(Pass pass) {
    if (!give_way_) return false;
    recorder_.submit_and_wait();
    for (auto& timing : timer_.read()) earlier_ms_.push_back(std::move(timing));
    if (give_way_()) {
        stopped_ = pass;
        return true;
    }
    cmd_ = recorder_.begin();
    timer_.reset(cmd_);
    recorder_.compute_barrier();  // the parts before wrote what the next reads and adds to
    return false;
}

passes::BetweenParts FrameRecording::between_parts(Pass pass) {
    if (!give_way_) return {};
    return [this, pass] {
        end();
        if (part(pass)) return true;
        begin(pass);
        return false;
    };
}

std::vector<std::pair<std::string, double>> FrameRecording::finish() {
    recorder_.to_host_barrier();
    recorder_.submit_and_wait();
    for (auto& timing : timer_.read()) earlier_ms_.push_back(std::move(timing));
    std::vector<std::pair<std::string, double>> per_pass;
    for (const auto& [name, ms] : earlier_ms_) {
        auto same = std::find_if(per_pass.begin(), per_pass.end(), [&](const auto& t) { return t.first == name; });
        if (same == per_pass.end()) per_pass.emplace_back(name, ms);
        else same->second += ms;
    }
    return per_pass;
}

}  // namespace refract::scene
