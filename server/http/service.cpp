#include "http/service.h"

#include <charconv>
#include <cstdio>
#include <set>
#include <sstream>

#include "render/invalidation.h"

namespace refract::http {

namespace {

// Compares without an early exit, so the time taken says nothing about where a guess went wrong.
bool equal_constant_time(const std::string& given, const std::string& expected) {
    if (expected.empty()) return false;
    unsigned diff = given.size() == expected.size() ? 0u : 1u;
    for (size_t i = 0; i < given.size(); ++i)
        diff |= static_cast<unsigned>(static_cast<unsigned char>(given[i]) ^
                                      static_cast<unsigned char>(expected[i % expected.size()]));
    return diff == 0;
}

}  // namespace

Service::Service(const DaemonConfig& config, scene::Store& store, scene::RenderQueue& queue,
                 Metrics& metrics, DeviceStatus device)
    : config_(config), store_(store), queue_(queue), metrics_(metrics), device_(std::move(device)) {}

bool Service::authorized(const std::string& authorization, const std::string& token_param) const {
    if (config_.token.empty()) return true;
    constexpr std::string_view bearer = "Bearer ";
    if (authorization.size() > bearer.size() && authorization.compare(0, bearer.size(), bearer) == 0 &&
        equal_constant_time(authorization.substr(bearer.size()), config_.token))
        return true;
    return !token_param.empty() && equal_constant_time(token_param, config_.token);
}

Gauges Service::gauges() const {
    std::string ignored;
    return read_gauges(ignored);
}

Gauges Service::read_gauges(std::string& store_error) const {
    Gauges g;
    try {
        g.scenes = store_.size();
    } catch (const scene::StoreError& e) {
        // A shared store's database is away: health says so instead of failing, so that a proxy keeps
        // sending requests here and each gets the 503 and its reason.
        store_error = e.what();
    }
    g.scenes_resident = scenes_resident.load();
    g.device_bytes = device_bytes.load();
    g.render_waiting = queue_.waiting();
    g.frames_abandoned = queue_.frames_abandoned();
    g.ws_sessions = ws_sessions.load();
    g.quarantined_files = store_.quarantined().size();
    g.uptime_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - started_).count();
    return g;
}

nlohmann::json Service::health() const {
    std::string store_error;
    Gauges g = read_gauges(store_error);
    nlohmann::json device = nullptr;
    if (device_.error.empty()) {
        device = {{"name", device_.name},
                  {"type", device_.type},
                  {"driver_name", device_.driver_name},
                  {"driver_info", device_.driver_info},
                  {"api_version", device_.api_version}};
    }
    nlohmann::json health = {
        {"status", device_.error.empty() && store_.quarantined().empty() && store_error.empty() ? "ok" : "degraded"},
        {"version", REFRACT_VERSION},
        {"device", device},
        {"uptime_s", g.uptime_s},
        {"scenes", g.scenes},
        {"scenes_resident", g.scenes_resident},
        {"device_bytes", g.device_bytes},
        {"render_waiting", g.render_waiting},
        {"frames_rendered", queue_.frames_rendered()},
        {"frames_abandoned", queue_.frames_abandoned()},
        {"warming_up", queue_.warming_up()},
        {"ws_port", config_.effective_ws_port()},
        {"ws_sessions", g.ws_sessions},
        {"limits",
         {{"max_scenes", config_.max_scenes},
          {"max_body", config_.max_body},
          {"max_queue", config_.max_queue},
          {"max_resolution", config_.max_resolution},
          {"max_photons", config_.max_photons},
          {"max_image", config_.max_image},
          {"request_timeout_s", config_.request_timeout_s}}},
        {"auth", !config_.token.empty()},
    };
    if (!device_.error.empty()) health["device_error"] = device_.error;
    if (!store_error.empty()) health["store_error"] = store_error;
    if (!store_.quarantined().empty()) {
        nlohmann::json files = nlohmann::json::array();
        for (const auto& file : store_.quarantined())
            files.push_back({{"scene", file.scene_id}, {"path", file.path}, {"error", file.error}});
        health["quarantined"] = files;
    }
    if (device_.validation) health["validation_errors"] = validation_errors.load();
    return health;
}

int http_status(scene::StoreFailure failure) {
    using Failure = scene::StoreFailure;
    switch (failure) {
        case Failure::invalid:
            return 400;
        case Failure::not_found:
            return 404;
        // The request collides with the store's state, which the client can change (pick another id,
        // delete the scenes that name the asset) or cannot (revisions used up): 409 either way.
        case Failure::taken:
        case Failure::in_use:
        case Failure::out_of_revisions:
            return 409;
        case Failure::stale_revision:
            return 412;  // the If-Match precondition failed
        case Failure::too_large:
            return 413;
        case Failure::broken:
            return 500;
        case Failure::unavailable:
            return 503;
    }
    return 500;  // not reached: every failure is named above (-Wswitch says when one is added)
}

nlohmann::json parse_json_document(const std::string& text) {
    constexpr int kMaxDepth = 16;
    using Event = nlohmann::json::parse_event_t;
    // The keys of each object being read: a repeated key would silently keep only its last value.
    std::vector<std::set<std::string>> keys;
    return nlohmann::json::parse(text, [&keys](int depth, Event event, nlohmann::json& parsed) {
        if (depth > kMaxDepth)
            throw std::invalid_argument("JSON nested deeper than " + std::to_string(kMaxDepth) + " levels");
        if (event == Event::object_start) keys.emplace_back();
        if (event == Event::object_end) keys.pop_back();
        if (event == Event::key && !keys.back().insert(parsed.get<std::string>()).second)
            throw std::invalid_argument("JSON object has the key \"" + parsed.get<std::string>() + "\" twice");
        return true;
    });
}

std::string dump_json(const nlohmann::json& value) {
    return value.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
}

std::vector<std::string> pass_list(scene::PassSet passes) {
    std::vector<std::string> names;
    for (scene::PassSet bit = 1; bit <= scene::kToneMap; bit <<= 1) {
        if ((passes & bit) != 0) names.push_back(scene::pass_names(bit));
    }
    return names;
}

std::string comma_list(const std::vector<std::string>& names) {
    std::string out;
    for (const auto& name : names) {
        if (!out.empty()) out += ',';
        out += name;
    }
    return out;
}

nlohmann::json timings_json(const scene::FrameResult& frame) {
    nlohmann::json timings = nlohmann::json::object();
    for (const auto& timing : frame.timings) timings[timing.name] = pass_ms(timing);
    return timings;
}

std::string server_timing(const scene::FrameResult& frame) {
    std::string header;
    for (const auto& timing : frame.timings) {
        char dur[32];
        std::snprintf(dur, sizeof dur, "%.3f", pass_ms(timing));
        if (!header.empty()) header += ", ";
        header += timing.name + ";dur=" + dur;
    }
    return header;
}

std::optional<uint64_t> parse_if_match(const std::string& value) {
    std::string_view v = value;
    while (!v.empty() && v.front() == ' ') v.remove_prefix(1);
    while (!v.empty() && v.back() == ' ') v.remove_suffix(1);
    if (v.empty() || v == "*") return std::nullopt;
    if (v.substr(0, 2) == "W/") v.remove_prefix(2);
    if (v.size() >= 2 && v.front() == '"' && v.back() == '"') v = v.substr(1, v.size() - 2);
    uint64_t revision = 0;
    auto [rest, error] = std::from_chars(v.data(), v.data() + v.size(), revision);
    if (error != std::errc() || rest != v.data() + v.size() || v.empty())
        throw std::invalid_argument("If-Match must be a scene revision ETag such as \"3\" (or *)");
    return revision;
}

}  // namespace refract::http
