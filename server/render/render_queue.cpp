#include "render/render_queue.h"

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
    if (options.linear) key += "|linear";  // a frame that also holds its radiance answers only those asking for it
    if (!request.playback.empty()) {
        key += "|play:";
        key += request.playback;
    }
    if (!request.view.empty()) {
        key += "|view:";
        key += request.view;
    }
    return key;
}

bool RenderQueue::submit(FrameRequest request, FrameCallback done, Withdrawn withdrawn, Admission admission) {
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

    // A frame of this revision (or newer) with the same view, size and quality exists: answer with it.
    auto cached = last_frame_.find(request.scene_id);
    if (request.playback.empty() && cached != last_frame_.end()) {
        for (const Rendered& rendered : cached->second) {
            if (rendered.key != key || rendered.revision < request.revision) continue;
            FrameOutcome outcome{FrameOutcome::Status::ok, {}, rendered.revision, rendered.frame, true};
            lock.unlock();
            done(outcome);
            return true;
        }
    }
    std::vector<FrameCallback> dropped;
    const bool counted = admission == Admission::bounded;
    if (counted && counted_waiters_ >= options_.max_waiters) drop_withdrawn(dropped);  // clients gone hold no place
    if (counted && counted_waiters_ >= options_.max_waiters) {
        lock.unlock();
        answer(dropped, abandoned_outcome());
        return false;
    }
    ++waiters_;
    if (counted) ++counted_waiters_;
    Waiter waiter{std::move(done), std::move(withdrawn), counted};

    // A frame being rendered already covers this revision: wait for it instead of rendering again.
    for (InFlight& frame : in_flight_) {
        if (request.playback.empty() && frame.key == key && !frame.stale &&
            frame.pending.request.revision >= request.revision) {
            frame.pending.waiters.push_back(std::move(waiter));
            lock.unlock();
            answer(dropped, abandoned_outcome());
            return true;
        }
    }
    auto [it, inserted] = pending_.try_emplace(key);
    Pending& pending = it->second;
    if (inserted) {
        pending.request = std::move(request);
        order_.push_back(key);
    } else if (request.revision > pending.request.revision || !request.playback.empty()) {
        pending.request = std::move(request);  // latest wins; the key keeps its place in the round-robin
    }
    pending.waiters.push_back(std::move(waiter));
    lock.unlock();
    wake_.notify_one();
    answer(dropped, abandoned_outcome());
    return true;
}

std::optional<FrameOutcome> RenderQueue::render_and_wait(FrameRequest request, std::chrono::milliseconds timeout,
                                                         const std::function<bool()>& client_gone) {
    struct Shared {
        std::mutex mutex;
        std::condition_variable ready;
        std::optional<FrameOutcome> outcome;
    };
    auto shared = std::make_shared<Shared>();
    auto withdrawn = std::make_shared<std::atomic<bool>>(false);
    bool accepted = submit(
        std::move(request),
        [shared](const FrameOutcome& outcome) {
            {
                std::lock_guard lock(shared->mutex);
                shared->outcome = outcome;
            }
            shared->ready.notify_all();
        },
        withdrawn);
    if (!accepted) return std::nullopt;
    // A client that hung up is noticed within this interval: its frame is then dropped or abandoned.
    constexpr auto kPoll = std::chrono::milliseconds(50);
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    std::unique_lock lock(shared->mutex);
    while (!shared->outcome) {
        const auto now = std::chrono::steady_clock::now();
        if (now >= deadline || (client_gone && client_gone())) {
            withdrawn->store(true);
            return FrameOutcome{FrameOutcome::Status::timed_out,
                                "the frame was not ready within the request timeout", 0, nullptr, false};
        }
        shared->ready.wait_until(lock, std::min(deadline, now + kPoll));
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
                for (auto& waiter : it->second.waiters) cancelled.push_back(release(waiter));
                it = pending_.erase(it);
            } else {
                ++it;
            }
        }
        std::erase_if(order_,
                      [&](const std::string& key) { return key.compare(0, prefix.size(), prefix) == 0; });
        for (InFlight& frame : in_flight_)
            if (frame.key.compare(0, prefix.size(), prefix) == 0) frame.stale = true;
        last_frame_.erase(scene_id);
        evictions_.push_back(scene_id);
    }
    wake_.notify_one();
    answer(cancelled, FrameOutcome{FrameOutcome::Status::gone, "the scene was deleted", 0, nullptr, false});
}

void RenderQueue::forget_cached_frames() {
    std::lock_guard lock(mutex_);
    last_frame_.clear();
    for (InFlight& frame : in_flight_) frame.stale = true;
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
            for (auto& waiter : pending.waiters) cancelled.push_back(release(waiter));
        pending_.clear();
        order_.clear();
    }
    answer(cancelled, FrameOutcome{FrameOutcome::Status::shutting_down, "the daemon is shutting down", 0, nullptr,
                                   false});
}

void RenderQueue::read_gauges() {
    try {
        if (options_.after_frame) options_.after_frame();
    } catch (const std::exception& e) {
        std::cerr << "refractd: reading renderer gauges failed: " << e.what() << "\n";
    }
}

void RenderQueue::answer(std::vector<FrameCallback>& callbacks, const FrameOutcome& outcome) {
    for (auto& callback : callbacks) callback(outcome);
    callbacks.clear();
}

FrameOutcome RenderQueue::abandoned_outcome() {
    return {FrameOutcome::Status::abandoned, "nobody waits for this frame any more", 0, nullptr, false};
}

FrameCallback RenderQueue::release(Waiter& waiter) {
    --waiters_;
    if (waiter.counted) --counted_waiters_;
    return std::move(waiter.done);
}

void RenderQueue::drop_withdrawn(std::vector<FrameCallback>& dropped) {
    auto drop_from = [&](std::vector<Waiter>& waiters) {
        std::vector<Waiter> kept;
        for (Waiter& waiter : waiters) {
            if (waiter.wanted()) kept.push_back(std::move(waiter));
            else dropped.push_back(release(waiter));
        }
        waiters = std::move(kept);
    };
    for (auto it = pending_.begin(); it != pending_.end();) {
        drop_from(it->second.waiters);
        if (it->second.waiters.empty()) {
            std::erase(order_, it->first);
            it = pending_.erase(it);
            frames_abandoned_.fetch_add(1);
        } else {
            ++it;
        }
    }
    for (InFlight& frame : in_flight_) drop_from(frame.pending.waiters);
}

std::optional<RenderQueue::InFlight> RenderQueue::take_next(const std::vector<std::string>& busy,
                                                            std::vector<FrameCallback>& dropped) {
    drop_withdrawn(dropped);
    // The oldest key of a scene not busy; of the other kind than the last frame taken (played or not)
    // when one waits.
    auto pick = order_.end();
    for (auto key = order_.begin(); key != order_.end(); ++key) {
        const FrameRequest& request = pending_.at(*key).request;
        if (std::find(busy.begin(), busy.end(), request.scene_id) != busy.end()) continue;
        if (pick == order_.end()) pick = key;
        if (request.playback.empty() == last_was_playback_) {
            pick = key;
            break;
        }
    }
    if (pick == order_.end()) return std::nullopt;
    InFlight next;
    next.key = *pick;
    order_.erase(pick);
    next.pending = std::move(pending_.extract(next.key).mapped());
    last_was_playback_ = !next.pending.request.playback.empty();
    return next;
}

bool RenderQueue::between_parts(size_t depth, const std::function<bool()>& requested) {
    // Stops the frame when nobody waits for it any more, or the daemon stops.
    auto abandon = [&] {
        std::lock_guard lock(mutex_);
        InFlight& frame = *std::next(in_flight_.begin(), static_cast<std::ptrdiff_t>(depth));
        const bool wanted = std::any_of(frame.pending.waiters.begin(), frame.pending.waiters.end(),
                                        [](const Waiter& waiter) { return waiter.wanted(); });
        frame.abandoned = stopping_ || !wanted;
        return frame.abandoned;
    };
    if (abandon()) return true;
    if (depth == 0) {
        // The other scenes' frames waiting now, each once; what arrives meanwhile waits for the next part.
        std::unique_lock lock(mutex_);
        std::vector<std::string> busy;
        for (const InFlight& frame : in_flight_) busy.push_back(frame.pending.request.scene_id);
        for (size_t turns = order_.size(); turns > 0 && !stopping_; --turns) {
            const std::optional<bool> rendered = render_next(lock, busy, depth + 1);
            if (!rendered || !*rendered) break;
            lock.lock();
        }
        if (lock.owns_lock()) lock.unlock();
        if (abandon()) return true;
    }
    return requested && requested();
}

std::optional<bool> RenderQueue::render_next(std::unique_lock<std::mutex>& lock, const std::vector<std::string>& busy,
                                             size_t depth) {
    std::vector<FrameCallback> dropped;
    std::optional<InFlight> next = take_next(busy, dropped);
    std::optional<std::list<InFlight>::iterator> frame;
    if (next) frame = in_flight_.insert(in_flight_.end(), std::move(*next));
    lock.unlock();
    answer(dropped, abandoned_outcome());
    if (!frame) return std::nullopt;
    return render_one(*frame, depth);
}

void RenderQueue::defer(std::list<InFlight>::iterator in_flight, std::function<bool()> requested) {
    // It needs what the frame it interrupted holds: it waits, first in line, for that frame's end.
    std::lock_guard lock(mutex_);
    FrameRequest& request = in_flight->pending.request;
    auto [it, inserted] = pending_.try_emplace(in_flight->key);
    if (inserted) {
        request.options.give_way = std::move(requested);
        it->second.request = std::move(request);
        order_.push_front(in_flight->key);
    }
    for (Waiter& waiter : in_flight->pending.waiters) it->second.waiters.push_back(std::move(waiter));
    in_flight_.erase(in_flight);
}

bool RenderQueue::render_one(std::list<InFlight>::iterator in_flight, size_t depth) {
    FrameRequest& request = in_flight->pending.request;
    // The asker's own reason to give way (a refinement step's), asked after the queue's.
    std::function<bool()> requested = std::move(request.options.give_way);
    request.options.give_way = [this, depth, requested] { return between_parts(depth, requested); };

    FrameOutcome outcome;
    outcome.revision = request.revision;
    try {
        auto frame = std::make_shared<FrameResult>(render_(request));
        if (frame->outcome == FrameResult::Outcome::deferred) {
            defer(in_flight, requested);
            return false;
        }
        if (frame->outcome == FrameResult::Outcome::superseded) {
            outcome.status = FrameOutcome::Status::superseded;
            outcome.error = "a newer request came first";
        } else {
            frames_rendered_.fetch_add(1);
            if (options_.on_rendered) options_.on_rendered(request, *frame);
            outcome.frame = std::move(frame);
        }
    } catch (const RenderError& e) {
        outcome.status = FrameOutcome::Status::unrenderable;
        outcome.error = e.what();
    } catch (const std::exception& e) {
        outcome.status = FrameOutcome::Status::device_error;
        outcome.error = e.what();
    }
    if (outcome.status == FrameOutcome::Status::superseded && in_flight->abandoned) {
        if (stopping()) {
            outcome = {FrameOutcome::Status::shutting_down, "the daemon is shutting down", 0, nullptr, false};
        } else {
            outcome = abandoned_outcome();
            frames_abandoned_.fetch_add(1);
        }
    }
    if (outcome.status == FrameOutcome::Status::unrenderable || outcome.status == FrameOutcome::Status::device_error)
        std::cerr << "refractd: frame of " << request.scene_id << " r" << request.revision
                  << " failed: " << outcome.error << "\n";
    read_gauges();

    std::unique_lock lock(mutex_);
    std::vector<FrameCallback> waiters;
    for (Waiter& waiter : in_flight->pending.waiters) waiters.push_back(release(waiter));
    if (outcome.frame && !in_flight->stale && request.playback.empty()) {
        std::deque<Rendered>& kept = last_frame_[request.scene_id];
        std::erase_if(kept, [&](const Rendered& r) { return r.key == in_flight->key; });
        kept.push_front(Rendered{in_flight->key, outcome.revision, outcome.frame});
        if (kept.size() > kCachedViewsPerScene) kept.pop_back();
    }
    in_flight_.erase(in_flight);
    lock.unlock();
    answer(waiters, outcome);
    return true;
}

bool RenderQueue::stopping() const {
    std::lock_guard lock(mutex_);
    return stopping_;
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

        // Round-robin: the key waiting longest goes next; edits that arrive while it renders queue anew.
        render_next(lock, {}, 0);
    }
}

}  // namespace refract::scene
