// What the HTTP and WebSocket front ends share: the store, the render queue, the metrics, the device
// description, and the few answers both give the same way (auth, health, frame headers).
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "http/daemon_config.h"
#include "http/metrics.h"
#include "render/render_queue.h"
#include "store/store.h"

namespace refract::http {

// The device as /api/health reports it; `error` set (and the rest empty) when no device could be used.
struct DeviceStatus {
    std::string name, type, driver_name, driver_info, api_version;
    std::string error;
    bool validation = false;
};

// The state both front ends borrow; it owns nothing but the device description and the gauges.
class Service {
public:
    Service(const DaemonConfig& config, scene::Store& store, scene::RenderQueue& queue, Metrics& metrics,
            DeviceStatus device);

    const DaemonConfig& config() const { return config_; }
    scene::Store& store() { return store_; }
    scene::RenderQueue& queue() { return queue_; }
    Metrics& metrics() { return metrics_; }

    // True when no token is configured or `authorization` is "Bearer <token>" or `token_param` is the token.
    bool authorized(const std::string& authorization, const std::string& token_param) const;

    // The body of GET /api/health.
    nlohmann::json health() const;
    // The gauges of GET /metrics, read now.
    Gauges gauges() const;

    // Written by the render thread after each frame; read by health and metrics.
    std::atomic<size_t> scenes_resident{0};
    std::atomic<int64_t> device_bytes{0};
    std::atomic<size_t> validation_errors{0};
    // Open WebSocket sessions, counted by the sessions themselves.
    std::atomic<size_t> ws_sessions{0};

private:
    // The gauges, with why the store could not be read (empty when it could).
    Gauges read_gauges(std::string& store_error) const;

    const DaemonConfig& config_;
    scene::Store& store_;
    scene::RenderQueue& queue_;
    Metrics& metrics_;
    DeviceStatus device_;
    std::chrono::steady_clock::time_point started_ = std::chrono::steady_clock::now();
};

// The HTTP status that answers a store's failure: the one place where the store's reasons become
// statuses (404 not found, 409 for a conflict with what is stored, 412 for a stale If-Match, 503 when
// retrying may help, ...). The API's routes answer every StoreError with it and the error's message;
// the WebSocket endpoint refuses an upgrade whose scene it cannot look up with 503 whatever the failure,
// and tells an open session only the message.
int http_status(scene::StoreFailure failure);

// Parses a request's JSON, refusing nesting deeper than any scene document needs (a deep body would
// otherwise cost stack in every recursive consumer). Throws nlohmann::json::exception or
// std::invalid_argument.
nlohmann::json parse_json_document(const std::string& text);
// The text of a JSON body or message. Never throws: bytes that are not UTF-8 (a raw path, a token quoted
// from a bad OBJ or from a parser's error) become U+FFFD. Every JSON the daemon writes goes through here.
std::string dump_json(const nlohmann::json& value);

// Pass names of a set, in pipeline order ("voxelize", "index_field", ...).
std::vector<std::string> pass_list(scene::PassSet passes);
// Names joined by commas (the X-Refract-Voxelized header: object names hold no comma).
std::string comma_list(const std::vector<std::string>& names);
// {pass: ms} for every timing of a frame.
nlohmann::json timings_json(const scene::FrameResult& frame);
// The Server-Timing header value of a frame ("voxelize;dur=1.2, view;dur=3.4").
std::string server_timing(const scene::FrameResult& frame);
// Parses an If-Match value ("3", "\"3\"", W/"3"); nullopt for "*" or absent; throws on garbage.
std::optional<uint64_t> parse_if_match(const std::string& value);

}  // namespace refract::http
