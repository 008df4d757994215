// refractd: the long-running Refract render daemon. Wires the scene store, the render thread (the only
// Vulkan user), the HTTP API and the WebSocket endpoint together, and stops cleanly on SIGINT/SIGTERM.
#include <pthread.h>
#include <sys/resource.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <iostream>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "http/api_server.h"
#include "http/daemon_config.h"
#include "http/examples.h"
#include "http/metrics.h"
#include "http/service.h"
#include "http/stop_deadline.h"
#include "http/ws_server.h"
#include "mesh/mesh.h"
#include "render/render_queue.h"
#include "render/renderer.h"
#include "store/pg_scene_store.h"
#include "store/scene_store.h"
#include "vk/context.h"

using namespace refract;

namespace {

// The scene a first start creates: the default document's glass sphere, made smaller and lifted off the
// floor so that its caustic lands beside it, seen from above and to the side so that a new user sees
// the object and what it does to the light in the first frame.
const nlohmann::json kFirstScene = {
    {"camera", {{"position", {2.2, 2.0, 5.0}}, {"target", {-0.5, -0.6, 0.0}}, {"fov_deg", 38}}},
    {"object", {{"position", {0.0, 0.2, 0.0}}, {"scale", 0.6}}}};

// How many stored scenes the render thread prepares (pipelines, then volumes) before it takes requests.
constexpr size_t kWarmUpScenes = 4;

// Signals are taken by sigwait (wait_for_stop_signal) only: blocked before any thread starts, so that
// all inherit the mask. A client gone mid-write is an error code, not a death (SIGPIPE ignored).
sigset_t block_stop_signals() {
    sigset_t stop_signals;
    sigemptyset(&stop_signals);
    sigaddset(&stop_signals, SIGINT);
    sigaddset(&stop_signals, SIGTERM);
    pthread_sigmask(SIG_BLOCK, &stop_signals, nullptr);
    std::signal(SIGPIPE, SIG_IGN);
    return stop_signals;
}

// Every connection holds a descriptor: allow as many as the hard limit does (the soft one is often 1024).
void raise_open_file_limit() {
    rlimit files{};
    if (getrlimit(RLIMIT_NOFILE, &files) == 0 && files.rlim_cur < files.rlim_max) {
        files.rlim_cur = files.rlim_max;
        setrlimit(RLIMIT_NOFILE, &files);
    }
}

// The embedded file store in --data-dir, or the shared PostgreSQL store of --store; on a first start
// (no scene yet), with the scene kFirstScene describes.
std::unique_ptr<scene::Store> open_store(const http::DaemonConfig& config) {
    protocol::Limits limits{config.max_resolution, config.max_photons, config.max_image};
    mesh::MeshLimits mesh_limits;
    mesh_limits.max_bytes = config.max_body;
    std::unique_ptr<scene::Store> store;
    if (config.store.empty())
        store =
            std::make_unique<scene::SceneStore>(config.data_dir, limits, mesh_limits, config.max_host_memory);
    else
        store =
            std::make_unique<scene::PgSceneStore>(config.store, limits, mesh_limits, config.max_host_memory);
    if (store->size() == 0) {
        try {
            store->create("default", kFirstScene);
        } catch (const scene::StoreError& e) {
            // Replicas sharing a store start together: one of them creates the scene.
            if (e.failure() != scene::StoreFailure::taken) throw;
        }
    }
    return store;
}

// The Vulkan device and the renderer on it, or (all empty but `status.error`) why there is none.
struct Device {
    http::DeviceStatus status;
    std::unique_ptr<vk::Context> context;
    std::unique_ptr<scene::Renderer> renderer;
};

// A daemon without a device still serves documents; health says why frames cannot render.
Device open_device(const http::DaemonConfig& config) {
    Device device;
    try {
        vk::ContextOptions options;
        options.device_name = config.device;
        // Its warm-up renders what first frames need before it takes requests, compiling those pipelines
        // (as it always did the transport passes' variants): the rest wait until a frame uses them.
        options.compile_on_first_use = true;
        device.context = std::make_unique<vk::Context>(vk::options_from_environment(options));
        const vk::DeviceInfo& info = device.context->info();
        device.status = {info.name,
                         info.type,
                         info.driver_name,
                         info.driver_info,
                         info.api_version,
                         {},
                         device.context->validation_enabled()};
        scene::RendererOptions renderer_options;
        renderer_options.max_resident_scenes = config.max_scenes;
        renderer_options.device_memory_budget = static_cast<int64_t>(config.max_device_memory);
        device.renderer = std::make_unique<scene::Renderer>(*device.context, renderer_options);
    } catch (const std::exception& e) {
        device.status.error = e.what();
        device.renderer.reset();
        device.context.reset();
        std::fprintf(stderr, "refractd: no usable Vulkan device, frames will fail: %s\n", e.what());
    }
    return device;
}

// While the first viewer's page loads, in the order its first frames need them: the pipelines of the
// stored scenes' interactive frames (a few scenes; they share most pipelines), then the same scenes'
// volumes (Renderer::prepare: most of a first frame's work; within the memory budget, evicting nothing),
// then the still frames' pipelines, then those of each example's first preview when it is loaded into the
// first of them (Renderer::warm_up_load: lavapipe compiles those again for a load's coarser lattice,
// 0.5-1.5 s of the first load of most examples on two cores; loaded over another example, one may take
// another lattice divisor and still compile some). `default` first: the client opens it when
// the address names no scene. Each step stops when a request waits, which then renders what is left. A
// scene or example that cannot render now says so when asked for a frame.
void warm_up(scene::Renderer& renderer, const scene::Store& store, const scene::Assets& assets,
             const http::DaemonConfig& config, const std::function<bool()>& waiting) {
    std::vector<scene::SceneSnapshot> scenes = store.list();
    std::stable_partition(scenes.begin(), scenes.end(),
                          [](const scene::SceneSnapshot& snapshot) { return snapshot.id == "default"; });
    scenes.resize(std::min(scenes.size(), kWarmUpScenes));
    const std::vector<std::function<void(const scene::SceneSnapshot&)>> steps = {
        [&](const scene::SceneSnapshot& s) {
            renderer.warm_up(s.document, assets, scene::Quality::interactive);
        },
        [&](const scene::SceneSnapshot& s) { renderer.prepare(s.id, s.document, assets, waiting); },
        [&](const scene::SceneSnapshot& s) { renderer.warm_up(s.document, assets, scene::Quality::still); },
    };
    for (const auto& step : steps)
        for (const auto& snapshot : scenes) {
            if (waiting()) return;
            try {
                step(snapshot);
            } catch (const scene::RenderError&) {
            }
        }
    const protocol::Limits limits{config.max_resolution, config.max_photons, config.max_image};
    const protocol::SceneDocument shown = scenes.empty() ? protocol::parse_scene(kFirstScene) : scenes.front().document;
    const std::vector<std::string> examples = http::list_examples(config.examples_dir);
    const auto start = std::chrono::steady_clock::now();
    size_t warmed = 0;
    for (const auto& name : examples) {
        if (waiting()) return;
        const http::ExampleFile example = http::read_example(config.examples_dir, name);
        try {
            if (example.status != 200) continue;
            renderer.warm_up_load(shown, protocol::parse_scene(example.document, limits), assets);
            ++warmed;
        } catch (const protocol::ValidationError&) {
            // Over this daemon's limits: loading it says so.
        } catch (const scene::RenderError&) {
            // Not renderable here (an upload it names is missing): loading it says why.
        }
    }
    if (!examples.empty())
        std::fprintf(stderr, "refractd: warmed up loading %zu of %zu examples in %.1f s\n", warmed, examples.size(),
                     std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
}

// What the render queue's thread does with the device: render a frame, evict a scene, warm up, and
// report after each frame (to the service once `service` points at it: the warm-up runs before). Without
// a renderer, none of it: every frame fails with the device's error.
struct RenderQueueSetup {
    scene::RenderFunction render;
    scene::RenderQueueOptions options;
};

RenderQueueSetup render_queue_setup(const http::DaemonConfig& config, Device& device,
                                    const scene::Store& store, const scene::Assets& assets,
                                    http::Metrics& metrics, std::atomic<http::Service*>& service) {
    RenderQueueSetup setup;
    setup.options.max_waiters = config.max_queue;
    if (!device.renderer) return setup;
    scene::Renderer& renderer = *device.renderer;
    vk::Context& context = *device.context;
    setup.render = [&](const scene::FrameRequest& request) {
        return renderer.render(request.scene_id, request.document, assets, request.options);
    };
    setup.options.evict = [&](const std::string& scene_id) { renderer.evict(scene_id); };
    setup.options.on_rendered = [&](const scene::FrameRequest&, const scene::FrameResult& frame) {
        metrics.record_frame(frame);
    };
    setup.options.warm_up = [&](const std::function<bool()>& waiting) {
        warm_up(renderer, store, assets, config, waiting);
    };
    setup.options.after_frame = [&] {
        http::Service* published = service.load();
        if (!published) return;
        published->scenes_resident.store(renderer.resident_scenes());
        published->device_bytes.store(context.allocated_bytes());
        published->validation_errors.store(context.validation_error_count());
    };
    return setup;
}

// The start-up line, and a loud warning when anyone on the network may use the daemon.
void announce(const http::DaemonConfig& config, const http::DeviceStatus& device, const scene::Store& store) {
    // lavapipe's thread setting (split_cpu_dispatches_finely), where it is the device: the value as set,
    // which lavapipe reads (a value it cannot read leaves its own default).
    const char* threads = device.driver_name == "llvmpipe" ? std::getenv("LP_NUM_THREADS") : nullptr;
    std::fprintf(stderr, "refractd %s: http://%s:%u  ws://%s:%u  device: %s%s%s  data: %s  scenes: %zu\n",
                 REFRACT_VERSION, config.bind.c_str(), unsigned{config.port}, config.bind.c_str(),
                 unsigned{config.effective_ws_port()}, device.error.empty() ? device.name.c_str() : "none",
                 threads ? ", LP_NUM_THREADS=" : "", threads ? threads : "",
                 config.store.empty() ? config.data_dir.c_str() : store.location().c_str(), store.size());
    if (!http::is_loopback(config.bind) && config.token.empty())
        std::fprintf(
            stderr,
            "refractd: WARNING: OPEN TO THE NETWORK: listening on %s with no token (--open): anyone who "
            "reaches this address can read, edit and delete every scene\n",
            config.bind.c_str());
}

void wait_for_stop_signal(const sigset_t& stop_signals) {
    int signal_number = 0;
    sigwait(&stop_signals, &signal_number);
    std::fprintf(stderr, "refractd: %s received, stopping\n", signal_number == SIGINT ? "SIGINT" : "SIGTERM");
}

int run(const http::DaemonConfig& config) {
    const sigset_t stop_signals = block_stop_signals();
    raise_open_file_limit();
    std::unique_ptr<scene::Store> store_owner = open_store(config);
    scene::Store& store = *store_owner;
    Device device = open_device(config);

    http::Metrics metrics;
    // Where the render thread publishes gauges, built after the queue: atomic, as its warm-up runs meanwhile.
    std::atomic<http::Service*> service_ptr = nullptr;
    scene::Assets assets = store.assets();
    RenderQueueSetup setup = render_queue_setup(config, device, store, assets, metrics, service_ptr);
    scene::RenderQueue queue(setup.render, setup.options, device.status.error);
    http::Service service(config, store, queue, metrics, device.status);
    service_ptr = &service;
    // On every way out, the render thread stops before the service it publishes to is gone.
    struct StopQueue {
        scene::RenderQueue& queue;
        ~StopQueue() { queue.stop(); }
    } stop_queue{queue};
    if (device.context) service.device_bytes.store(device.context->allocated_bytes());

    // Another replica's deletions and mesh, environment and volume uploads reach this daemon's render queue as its own
    // do (the routes tell the queue of those made here; telling it twice costs nothing).
    scene::Subscription forget = store.on_change([&queue](const scene::StoreEvent& event) {
        if (event.kind == scene::StoreEvent::Kind::deleted) queue.forget_scene(event.name);
        if (event.kind == scene::StoreEvent::Kind::mesh || event.kind == scene::StoreEvent::Kind::environment ||
            event.kind == scene::StoreEvent::Kind::volume || event.kind == scene::StoreEvent::Kind::missed)
            queue.forget_cached_frames();
    });

    http::WsServer ws(service);
    // WebSocket upgrades on the HTTP port go to the same endpoint (one port suffices behind a proxy).
    http::ApiServer api(service, [&ws](http::UpgradePtr upgrade) { ws.adopt(std::move(upgrade)); });
    api.bind();
    ws.start();
    std::thread http_thread([&] { api.serve(); });
    announce(config, device.status, store);
    wait_for_stop_signal(stop_signals);

    // The render thread first: the frame it is on stops at its next part (acknowledged edits are durable
    // already), and every waiter is answered "shutting down", so that no HTTP worker waits on a frame.
    // Then the listeners (WebSocket first, as its sessions on the HTTP port close on that port's threads),
    // and the HTTP workers are joined. A step that outlasts --stop-timeout (a pipeline the driver compiles
    // within one part, on a loaded machine) ends the process there: what it would have finished is frames.
    http::StopDeadline deadline(std::chrono::seconds(config.stop_timeout_s), [](const std::string& step) {
        std::fprintf(stderr, "refractd: stopped without waiting longer for %s (past --stop-timeout)\n",
                     step.c_str());
        std::_Exit(0);
    });
    deadline.step("the render thread (its frame in progress, or a step of its warm-up)");
    queue.stop();
    deadline.step("the WebSocket sessions");
    ws.stop();
    deadline.step("the HTTP workers");
    api.stop();
    http_thread.join();
    deadline.step("the device");
    device.renderer.reset();
    device.context.reset();
    std::fprintf(stderr, "refractd: stopped\n");
    return 0;
}

}  // namespace

int main(int argc, char** argv) {
    http::DaemonConfig defaults;
    defaults.web_root = REFRACT_WEB_ROOT;
    defaults.examples_dir = REFRACT_EXAMPLES_DIR;
    try {
        http::CommandLine command_line =
            http::parse_command_line(std::vector<std::string>(argv + 1, argv + argc), defaults);
        if (command_line.help) {
            std::cout << http::usage_text(defaults);
            return 0;
        }
        vk::split_cpu_dispatches_finely(std::thread::hardware_concurrency());
        return run(command_line.config);
    } catch (const http::ConfigError& e) {
        std::fprintf(stderr, "refractd: %s\n", e.what());
        return 2;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "refractd: %s\n", e.what());
        return 1;
    }
}
