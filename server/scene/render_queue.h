// The render queue: the daemon's one render thread, the only caller of the Renderer (and so of Vulkan).
// Requests name a scene revision; the thread takes the newest pending revision per frame key, round-robin
// over keys, renders it once, and hands that frame to every waiter for that revision or an older one.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "protocol/scene_document.h"
#include "scene/renderer.h"

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
    };
    Status status = Status::ok;
    std::string error;
    uint64_t revision = 0;  // the revision rendered, >= the revision asked for
    std::shared_ptr<const FrameResult> frame;
    bool cached = false;  // answered from the last frame of this scene: no pass ran for it
};

using FrameCallback = std::function<void(const FrameOutcome&)>;

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
    // for a frame already rendered). Returns false, without calling `done`, when the queue is full.
    bool submit(FrameRequest request, FrameCallback done);
    // Blocking form for HTTP handlers: nullopt when the queue is full; a `timed_out` outcome on timeout.
    std::optional<FrameOutcome> render_and_wait(FrameRequest request, std::chrono::milliseconds timeout);

    // The scene is gone: fails its waiters, forgets its cached frame and drops its GPU state.
    void forget_scene(const std::string& scene_id);
    // An asset changed without a new revision (mesh re-upload): no cached frame may answer any more.
    void forget_cached_frames();
    // Fails every waiter and joins the render thread. Idempotent.
    void stop();

    size_t waiting() const;
    // Requests queued behind the frame being rendered (all scenes) that a refinement level gives way to:
    // all but other refinement levels (still frames past level 1), which take their turns whole, so
    // that two scenes refining at once both progress.
    size_t queued_ahead_of_refinement() const;
    uint64_t frames_rendered() const { return frames_rendered_.load(); }
    // Whether the render thread is still in its warm-up (RenderQueueOptions::warm_up), which ends when it
    // is done or a request arrives: a readiness signal for whatever sends users to this daemon.
    bool warming_up() const { return warming_up_.load(); }

private:
    struct Pending {
        FrameRequest request;
        std::vector<FrameCallback> waiters;
    };
    struct Rendered {
        std::string key;
        uint64_t revision = 0;
        std::shared_ptr<const FrameResult> frame;
    };

    static std::string key_of(const FrameRequest& request);
    void run();
    void read_gauges();  // options_.after_frame, its failure logged

    RenderFunction render_;
    RenderQueueOptions options_;
    std::string no_device_reason_;

    mutable std::mutex mutex_;
    std::condition_variable wake_;
    bool stopping_ = false;
    std::map<std::string, Pending> pending_;  // by frame key
    std::deque<std::string> order_;           // keys with pending work, oldest first (round-robin)
    std::optional<Pending> in_flight_;        // the frame being rendered; late waiters for it join here
    std::string in_flight_key_;
    bool in_flight_stale_ = false;                // its scene was forgotten or an asset changed meanwhile
    std::map<std::string, Rendered> last_frame_;  // by scene id: its newest frame, answers repeats
    std::deque<std::string> evictions_;
    size_t waiters_ = 0;
    std::atomic<uint64_t> frames_rendered_{0};
    std::atomic<bool> warming_up_{true};
    std::thread thread_;
};

const char* to_string(Quality quality);

}  // namespace refract::scene
