#include "scene/render_queue.h"

#include <algorithm>
#include <exception>
#include <iostream>

namespace refract::scene {

const char* to_string(Quality quality) {
    return quality == Quality::interactive ? "interactive" : "still";
}

RenderQueue::RenderQueue(RenderFunction render, RenderQueueOptions options, std::string no_device_reason)
    : render_(std::move(render)),
      options_(std::move(options)),
      no_device_reason_(std::move(no_device_reason)) {
    if (render_) thread_ = std::thread([this] { run(); });
}

RenderQueue::~RenderQueue() {
    stop();
}

std::string RenderQueue::key_of(const FrameRequest& request) {
    std::string key = request.scene_id + "|" + std::to_string(request.document.image.width) + "x" +
                      std::to_string(request.document.image.height) + "|" + to_string(request.options.quality);
    // Viewers with other budgets get frames of other sizes; refinement levels are frames of their own.
    key += '|';  // appended: GCC 12 reports a false -Wrestrict for "|" + std::string (its bug 105329)
    const FrameOptions& options = request.options;
    if (options.quality == Quality::interactive) {
        key += std::to_string(options.budget_ms);
    } else {
        key += std::to_string(options.level);
        if (options.resume_up_to > options.level) key += "-" + std::to_string(options.resume_up_to);
    }
    if (!request.playback.empty()) {
        key += "|play:";
        key += request.playback;
    }
    return key;
}

bool RenderQueue::submit(FrameRequest request, FrameCallback done) {
    if (!render_) {
        FrameOutcome outcome;
        outcome.status = FrameOutcome::Status::no_device;
        outcome.error = no_device_reason_.empty() ? "no usable Vulkan device" : no_device_reason_;
        done(outcome);
        return true;
    }
    std::string key = key_of(request);
    std::unique_lock lock(mutex_);
    if (stopping_) {
        lock.unlock();
        done(FrameOutcome{FrameOutcome::Status::shutting_down, "the daemon is shutting down", 0, nullptr,
                          false});
        return true;
    }

    // A frame of this revision (or newer) with the same size and quality exists: answer with it.
    auto cached = last_frame_.find(request.scene_id);
    if (request.playback.empty() && cached != last_frame_.end() && cached->second.key == key &&
        cached->second.revision >= request.revision) {
        FrameOutcome outcome{
            FrameOutcome::Status::ok, {}, cached->second.revision, cached->second.frame, true};
        lock.unlock();
        done(outcome);
        return true;
    }
    if (waiters_ >= options_.max_waiters) return false;
    ++waiters_;

    // The frame being rendered already covers this revision: wait for it instead of rendering again.
    if (request.playback.empty() && in_flight_ && in_flight_key_ == key && !in_flight_stale_ &&
        in_flight_->request.revision >= request.revision) {
        in_flight_->waiters.push_back(std::move(done));
        return true;
    }
    auto [it, inserted] = pending_.try_emplace(key);
    Pending& pending = it->second;
    if (inserted) {
        pending.request = std::move(request);
        order_.push_back(key);
    } else if (request.revision > pending.request.revision || !request.playback.empty()) {
        pending.request = std::move(request);  // latest wins; the key keeps its place in the round-robin
    }
    pending.waiters.push_back(std::move(done));
    lock.unlock();
    wake_.notify_one();
    return true;
}

std::optional<FrameOutcome> RenderQueue::render_and_wait(FrameRequest request,
                                                         std::chrono::milliseconds timeout) {
    struct Shared {
        std::mutex mutex;
        std::condition_variable ready;
        std::optional<FrameOutcome> outcome;
    };
    auto shared = std::make_shared<Shared>();
    bool accepted = submit(std::move(request), [shared](const FrameOutcome& outcome) {
        {
            std::lock_guard lock(shared->mutex);
            shared->outcome = outcome;
        }
        shared->ready.notify_all();
    });
    if (!accepted) return std::nullopt;
    std::unique_lock lock(shared->mutex);
    if (!shared->ready.wait_for(lock, timeout, [&] { return shared->outcome.has_value(); })) {
        return FrameOutcome{FrameOutcome::Status::timed_out,
                            "the frame was not ready within the request timeout", 0, nullptr, false};
    }
    return *shared->outcome;
}

void RenderQueue::forget_scene(const std::string& scene_id) {
    std::vector<FrameCallback> cancelled;
    {
        std::lock_guard lock(mutex_);
        std::string prefix = scene_id + "|";
        for (auto it = pending_.begin(); it != pending_.end();) {
            if (it->first.compare(0, prefix.size(), prefix) == 0) {
                for (auto& waiter : it->second.waiters) cancelled.push_back(std::move(waiter));
                it = pending_.erase(it);
            } else {
                ++it;
            }
        }
        std::erase_if(order_,
                      [&](const std::string& key) { return key.compare(0, prefix.size(), prefix) == 0; });
        if (in_flight_ && in_flight_key_.compare(0, prefix.size(), prefix) == 0) in_flight_stale_ = true;
        last_frame_.erase(scene_id);
        evictions_.push_back(scene_id);
        waiters_ -= cancelled.size();
    }
    wake_.notify_one();
    FrameOutcome outcome{FrameOutcome::Status::gone, "the scene was deleted", 0, nullptr, false};
    for (auto& waiter : cancelled) waiter(outcome);
}

void RenderQueue::forget_cached_frames() {
    std::lock_guard lock(mutex_);
    last_frame_.clear();
    if (in_flight_) in_flight_stale_ = true;
}

size_t RenderQueue::queued_ahead_of_refinement() const {
    std::lock_guard lock(mutex_);
    return static_cast<size_t>(std::count_if(pending_.begin(), pending_.end(), [](const auto& entry) {
        const FrameOptions& o = entry.second.request.options;
        return o.quality == Quality::interactive || o.level <= 1;
    }));
}

size_t RenderQueue::waiting() const {
    std::lock_guard lock(mutex_);
    return waiters_;
}

void RenderQueue::stop() {
    {
        std::lock_guard lock(mutex_);
        if (stopping_ && !thread_.joinable()) return;
        stopping_ = true;
    }
    wake_.notify_all();
    if (thread_.joinable()) thread_.join();
    std::vector<FrameCallback> cancelled;
    {
        std::lock_guard lock(mutex_);
        for (auto& [key, pending] : pending_)
            for (auto& waiter : pending.waiters) cancelled.push_back(std::move(waiter));
        pending_.clear();
        order_.clear();
        waiters_ = 0;
    }
    FrameOutcome outcome{FrameOutcome::Status::shutting_down, "the daemon is shutting down", 0, nullptr,
                         false};
    for (auto& waiter : cancelled) waiter(outcome);
}

void RenderQueue::read_gauges() {
    try {
        if (options_.after_frame) options_.after_frame();
    } catch (const std::exception& e) {
        std::cerr << "refractd: reading renderer gauges failed: " << e.what() << "\n";
    }
}

void RenderQueue::run() {
    try {
        if (options_.warm_up) options_.warm_up([this] {
                std::lock_guard lock(mutex_);
                return stopping_ || !order_.empty();
            });
    } catch (const std::exception& e) {
        std::cerr << "refractd: warming up the render thread failed: " << e.what() << "\n";
    }
    read_gauges();  // the warm-up may have left scenes resident
    warming_up_ = false;
    for (;;) {
        std::unique_lock lock(mutex_);
        wake_.wait(lock, [&] { return stopping_ || !order_.empty() || !evictions_.empty(); });
        if (stopping_) return;

        // Deleted scenes first: their GPU memory may be what the next frame needs.
        std::deque<std::string> evictions = std::move(evictions_);
        evictions_.clear();
        if (!evictions.empty()) {
            lock.unlock();
            for (const auto& scene_id : evictions) {
                try {
                    if (options_.evict) options_.evict(scene_id);
                } catch (const std::exception& e) {
                    std::cerr << "refractd: evicting " << scene_id << " failed: " << e.what() << "\n";
                }
            }
            read_gauges();
            lock.lock();
        }
        if (order_.empty()) continue;

        // Round-robin: the key waiting longest goes next; edits that arrive while it renders queue anew.
        in_flight_key_ = order_.front();
        order_.pop_front();
        auto node = pending_.extract(in_flight_key_);
        in_flight_ = std::move(node.mapped());
        in_flight_stale_ = false;
        const FrameRequest& request = in_flight_->request;
        lock.unlock();

        FrameOutcome outcome;
        outcome.revision = request.revision;
        try {
            auto frame = std::make_shared<FrameResult>(render_(request));
            frames_rendered_.fetch_add(1);
            if (options_.on_rendered) options_.on_rendered(request, *frame);
            outcome.frame = std::move(frame);
        } catch (const Superseded& e) {
            outcome.status = FrameOutcome::Status::superseded;
            outcome.error = e.what();
        } catch (const RenderError& e) {
            outcome.status = FrameOutcome::Status::unrenderable;
            outcome.error = e.what();
        } catch (const std::exception& e) {
            outcome.status = FrameOutcome::Status::device_error;
            outcome.error = e.what();
        }
        if (outcome.status != FrameOutcome::Status::ok && outcome.status != FrameOutcome::Status::superseded)
            std::cerr << "refractd: frame of " << request.scene_id << " r" << request.revision
                      << " failed: " << outcome.error << "\n";
        read_gauges();

        lock.lock();
        std::vector<FrameCallback> waiters = std::move(in_flight_->waiters);
        if (outcome.frame && !in_flight_stale_ && request.playback.empty())
            last_frame_[request.scene_id] = Rendered{in_flight_key_, outcome.revision, outcome.frame};
        in_flight_.reset();
        waiters_ -= waiters.size();
        lock.unlock();
        for (auto& waiter : waiters) waiter(outcome);
    }
}

}  // namespace refract::scene
