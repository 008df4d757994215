// The render queue: the daemon's one render thread, the only caller of the Renderer (and so of Vulkan).
// Requests name a scene revision; the thread takes the newest pending revision per frame key, round-robin
// over keys, renders it once, and hands that frame to every waiter for that revision or an older one.
// Every frame runs in parts (RunOptions::give_way): between two parts of one scene's frame the thread
// renders the other scenes' waiting frames, so a heavy frame delays them by one part, not by all of it;
// and a frame nobody waits for any more (its clients gone or timed out, or the daemon stopping) is
// abandoned at its next part.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <list>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "protocol/scene_document.h"
#include "render/renderer.h"

namespace refract::scene {

// What a waiter asks for: a scene at (at least) a revision, with the image size and quality of the frame.
struct FrameRequest {
    std::string scene_id;
    uint64_t revision = 0;
    protocol::SceneDocument document;  // the document at `revision`, image size already overridden
    FrameOptions options;  // quality, frame-time budget, refinement level
    // Non-empty for a frame of an animation played into a viewer: its document is not the stored
    // revision's, so it is keyed by this tag, never answered from or kept as the scene's cached frame,
    // and shared with no other waiter.
    std::string playback;
    // Non-empty for a viewer's own camera (protocol::View; the document's camera already replaced by it):
    // frames are keyed by it, so that viewers of one scene who look from different places get frames of
    // their own. Empty: the document's camera (followers of the scene's camera share their frames).
    std::string view;
};

// What a waiter gets. `frame` is set on success; otherwise `status` says why and `error` in words.
struct FrameOutcome {
    enum class Status {
        ok,
        unrenderable,   // RenderError: the document names something unusable (unknown mesh, ...)
        device_error,   // the renderer failed (Vulkan error)
        no_device,      // the daemon runs without a usable device
        gone,           // the scene was deleted while waiting
        timed_out,      // not ready within the caller's timeout
        shutting_down,  // the daemon is stopping
        superseded,     // a refinement step gave way to newer work (FrameOptions::give_way); no frame
        abandoned,      // every waiter withdrew (RenderQueue::submit's `withdrawn`) before it was done
    };
    Status status = Status::ok;
    std::string error;
    uint64_t revision = 0;  // the revision rendered, >= the revision asked for
    std::shared_ptr<const FrameResult> frame;
    bool cached = false;  // answered from the last frame of this scene: no pass ran for it
};

using FrameCallback = std::function<void(const FrameOutcome&)>;
// Set by a waiter that no longer wants its frame (its client went away, its timeout passed): a frame with
// no waiter left is dropped before it renders, or abandoned at its next part.
using Withdrawn = std::shared_ptr<std::atomic<bool>>;

// Whether RenderQueueOptions::max_waiters may refuse a request: `bounded` ones (HTTP requests) count
// against it; a caller that keeps at most one request queued and is itself bounded in number (a
// WebSocket session) submits `one_per_caller`, never refused: a session refused while others are
// answered would retry behind them and could wait forever.
enum class Admission { bounded, one_per_caller };

// Does the rendering; the daemon binds it to Renderer::render. Runs only on the render thread.
using RenderFunction = std::function<FrameResult(const FrameRequest&)>;

struct RenderQueueOptions {
    size_t max_waiters = 64;  // requests waiting for a frame, all scenes together; more are refused
    // Drops a scene's GPU state (on the render thread); may be empty.
    std::function<void(const std::string& scene_id)> evict;
    // Sees every rendered frame once (metrics); runs on the render thread; may be empty.
    std::function<void(const FrameRequest&, const FrameResult&)> on_rendered;
    // Reads renderer gauges after the warm-up and after each frame and eviction (render thread); may be empty.
    std::function<void()> after_frame;
    // Runs once on the render thread before it takes any request (Renderer::warm_up); requests queue
    // meanwhile, and `waiting` says whether one has (or the queue is stopping), so that it can leave the
    // rest to first use. May be empty.
    std::function<void(const std::function<bool()>& waiting)> warm_up;
};

class RenderQueue {
public:
    // `render` empty: no usable device; every request fails with `no_device_reason`.
    RenderQueue(RenderFunction render, RenderQueueOptions options, std::string no_device_reason = {});
    ~RenderQueue();
    RenderQueue(const RenderQueue&) = delete;
    RenderQueue& operator=(const RenderQueue&) = delete;

    // Queues a request; `done` runs exactly once, on the render thread (or at once, on the caller's thread,
    // for a frame already rendered; `abandoned` once `withdrawn` is set). Returns false, without calling
    // `done`, when the queue is full (waiters that withdrew no longer count).
    bool submit(FrameRequest request, FrameCallback done, Withdrawn withdrawn = {},
                Admission admission = Admission::bounded);
    // Blocking form for HTTP handlers: nullopt when the queue is full; a `timed_out` outcome on timeout or
    // when `client_gone` (asked every few tens of milliseconds) says the asker left. Either withdraws it.
    std::optional<FrameOutcome> render_and_wait(FrameRequest request, std::chrono::milliseconds timeout,
                                                const std::function<bool()>& client_gone = {});

    // The scene is gone: fails its waiters, forgets its cached frame and drops its GPU state.
    void forget_scene(const std::string& scene_id);
    // An asset changed without a new revision (mesh re-upload): no cached frame may answer any more.
    void forget_cached_frames();
    // Fails every waiter and joins the render thread; the frame being rendered is abandoned at its next
    // part. Idempotent.
    void stop();

    size_t waiting() const;
    // Requests queued behind the frame being rendered (all scenes) that a refinement level gives way to:
    // all but other refinement levels (still frames past level 1), which take their turns whole, so
    // that two scenes refining at once both progress.
    size_t queued_ahead_of_refinement() const;
    uint64_t frames_rendered() const { return frames_rendered_.load(); }
    // Frames nobody waited for any more: dropped before they rendered, or stopped at a part.
    uint64_t frames_abandoned() const { return frames_abandoned_.load(); }
    // Whether the render thread is still in its warm-up (RenderQueueOptions::warm_up), which ends when it
    // is done or a request arrives: a readiness signal for whatever sends users to this daemon.
    bool warming_up() const { return warming_up_.load(); }

private:
    struct Waiter {
        FrameCallback done;
        Withdrawn withdrawn;  // may be empty: wanted until answered
        bool counted = true;  // against max_waiters (Admission::bounded)
        bool wanted() const { return !withdrawn || !withdrawn->load(); }
    };
    struct Pending {
        FrameRequest request;
        std::vector<Waiter> waiters;
    };
    struct Rendered {
        std::string key;
        uint64_t revision = 0;
        std::shared_ptr<const FrameResult> frame;
    };
    // Views whose newest frame each scene keeps (last_frame_): viewers of one scene looking from
    // different places (or at different sizes) each find theirs.
    static constexpr size_t kCachedViewsPerScene = 4;
    // A frame on the render thread's stack: the one taken from the queue, and the other scenes' frames it
    // renders between its parts (at most one at a time: those do not nest further).
    struct InFlight {
        std::string key;
        Pending pending;
        bool stale = false;      // its scene was forgotten or an asset changed meanwhile
        bool abandoned = false;  // it stopped at a part because nobody waits for it (or the daemon stops)
    };

    static std::string key_of(const FrameRequest& request);
    void run();
    // The next key to render, removed from the queue with its request, or nullopt: round-robin, except
    // that a played frame and other work alternate (an edit waits for one played frame at most), and
    // that keys of `busy` scenes are passed over. Drops waiters that withdrew, and requests left with
    // none. Under mutex_; `dropped` collects the callbacks to answer `abandoned` once it is released.
    std::optional<InFlight> take_next(const std::vector<std::string>& busy, std::vector<FrameCallback>& dropped);
    // Renders what `in_flight` asks and answers its waiters; `depth` 0 for a frame taken by the loop, 1
    // for one rendered between the parts of another. False when the frame was deferred: it is queued
    // again, first, and the frame it interrupted goes on.
    bool render_one(std::list<InFlight>::iterator in_flight, size_t depth);
    // Queues a deferred frame again, first, with its asker's own reason to give way (`requested`).
    void defer(std::list<InFlight>::iterator in_flight, std::function<bool()> requested);
    // Takes the next frame (take_next, passing over `busy` scenes) and renders it at `depth`. `lock` holds
    // mutex_ on entry and not on return. nullopt when there was none; else what render_one returned.
    std::optional<bool> render_next(std::unique_lock<std::mutex>& lock, const std::vector<std::string>& busy,
                                    size_t depth);
    // Asked between two parts of the frame at `depth`: whether it stops there (superseded). Renders the
    // other scenes' waiting frames first when `depth` is 0.
    bool between_parts(size_t depth, const std::function<bool()>& requested);
    // Takes the waiters that withdrew out of every request (under mutex_), and the requests left without
    // one out of the queue; their callbacks go to `dropped`.
    void drop_withdrawn(std::vector<FrameCallback>& dropped);
    // A waiter leaves the counts (under mutex_); its callback, to be answered.
    FrameCallback release(Waiter& waiter);
    void read_gauges();  // options_.after_frame, its failure logged
    bool stopping() const;
    // Calls each callback with `outcome` (never under mutex_) and empties the list.
    static void answer(std::vector<FrameCallback>& callbacks, const FrameOutcome& outcome);
    static FrameOutcome abandoned_outcome();

    RenderFunction render_;
    RenderQueueOptions options_;
    std::string no_device_reason_;

    mutable std::mutex mutex_;
    std::condition_variable wake_;
    bool stopping_ = false;
    std::map<std::string, Pending> pending_;  // by frame key
    std::deque<std::string> order_;           // keys with pending work, oldest first (round-robin)
    // The frames being rendered, outermost first; late waiters for one join it there.
    std::list<InFlight> in_flight_;
    bool last_was_playback_ = false;              // the last frame taken was a played one (take_next)
    // By scene id: the newest frame of each of its last kCachedViewsPerScene keys, newest first; answers repeats.
    std::map<std::string, std::deque<Rendered>> last_frame_;
    std::deque<std::string> evictions_;
    size_t waiters_ = 0;          // all waiters
    size_t counted_waiters_ = 0;  // those of Admission::bounded
    std::atomic<uint64_t> frames_rendered_{0};
    std::atomic<uint64_t> frames_abandoned_{0};
    std::atomic<bool> warming_up_{true};
    std::thread thread_;
};

const char* to_string(Quality quality);

}  // namespace refract::scene
