#include "http/metrics.h"

#include <sstream>
#include <vector>

#include "render/invalidation.h"

namespace refract::http {

namespace {

std::vector<std::string> split_path(const std::string& path) {
    std::vector<std::string> parts;
    size_t start = 1;
    while (start <= path.size()) {
        size_t end = path.find('/', start);
        if (end == std::string::npos) end = path.size();
        parts.push_back(path.substr(start, end - start));
        start = end + 1;
    }
    return parts;
}

// Label values need backslash, quote and newline escaped.
std::string label(const std::string& value) {
    std::string out;
    for (char c : value) {
        if (c == '\\' || c == '"') out += '\\';
        if (c == '\n') {
            out += "\\n";
            continue;
        }
        out += c;
    }
    return out;
}

}  // namespace

std::string route_of(const std::string& path) {
    if (path == "/metrics") return "/metrics";
    if (path.rfind("/api/", 0) != 0) return "static";
    std::vector<std::string> p = split_path(path);
    // p[0] == "api"
    if (p.size() == 2 && (p[1] == "health" || p[1] == "scenes" || p[1] == "meshes" || p[1] == "examples"))
        return "/api/" + p[1];
    if (p.size() == 3 && p[1] == "scenes") return "/api/scenes/{id}";
    if (p.size() == 3 && (p[1] == "meshes" || p[1] == "examples")) return "/api/" + p[1] + "/{name}";
    if (p.size() == 4 && p[1] == "scenes" && (p[3] == "frame.png" || p[3] == "index-field" || p[3] == "ws"))
        return "/api/scenes/{id}/" + p[3];
    return "other";
}

double pass_ms(const scene::PassTiming& timing) {
    return timing.gpu_ms > 0.0 ? timing.gpu_ms : timing.host_ms;
}

void Metrics::record_request(const std::string& method, const std::string& route, int status) {
    std::lock_guard lock(mutex_);
    ++requests_[{method, route, status}];
    if (status >= 400) ++errors_[route];
}

void Metrics::record_frame(const scene::FrameResult& frame) {
    std::lock_guard lock(mutex_);
    ++frames_;
    for (scene::PassSet bit = 1; bit <= scene::kToneMap; bit <<= 1) {
        if ((frame.rerun & bit) != 0) ++pass_runs_[scene::pass_names(bit)];
    }
    for (const auto& timing : frame.timings) {
        double ms = pass_ms(timing);
        Histogram& h = pass_durations_[timing.name];
        size_t bucket = 0;
        while (bucket < kBucketsMs.size() && ms > kBucketsMs[bucket]) ++bucket;
        if (bucket < kBucketsMs.size()) ++h.buckets[bucket];
        ++h.count;
        h.sum += ms;
    }
}

void Metrics::record_ws_message(bool rejected) {
    std::lock_guard lock(mutex_);
    ++ws_messages_;
    if (rejected) ++ws_rejected_;
}

std::string Metrics::prometheus_text(const Gauges& gauges) const {
    std::ostringstream out;
    std::lock_guard lock(mutex_);

    out << "# HELP refract_requests_total HTTP requests answered, by method, route and status.\n"
        << "# TYPE refract_requests_total counter\n";
    for (const auto& [key, count] : requests_) {
        const auto& [method, route, status] = key;
        out << "refract_requests_total{method=\"" << label(method) << "\",route=\"" << label(route)
            << "\",status=\"" << status << "\"} " << count << "\n";
    }
    out << "# HELP refract_errors_total HTTP requests answered with a status of 400 or more, by route.\n"
        << "# TYPE refract_errors_total counter\n";
    for (const auto& [route, count] : errors_)
        out << "refract_errors_total{route=\"" << label(route) << "\"} " << count << "\n";

    out << "# HELP refract_frames_total Frames rendered (a frame shared by several waiters counts once).\n"
        << "# TYPE refract_frames_total counter\n"
        << "refract_frames_total " << frames_ << "\n";
    out << "# HELP refract_pass_runs_total Times each pass ran.\n"
        << "# TYPE refract_pass_runs_total counter\n";
    for (const auto& [pass, count] : pass_runs_)
        out << "refract_pass_runs_total{pass=\"" << label(pass) << "\"} " << count << "\n";

    out << "# HELP refract_pass_duration_ms Duration of each pass that ran (GPU time where measured).\n"
        << "# TYPE refract_pass_duration_ms histogram\n";
    for (const auto& [pass, h] : pass_durations_) {
        uint64_t cumulative = 0;
        for (size_t i = 0; i < kBucketsMs.size(); ++i) {
            cumulative += h.buckets[i];
            out << "refract_pass_duration_ms_bucket{pass=\"" << label(pass) << "\",le=\"" << kBucketsMs[i]
                << "\"} " << cumulative << "\n";
        }
        out << "refract_pass_duration_ms_bucket{pass=\"" << label(pass) << "\",le=\"+Inf\"} " << h.count
            << "\n"
            << "refract_pass_duration_ms_sum{pass=\"" << label(pass) << "\"} " << h.sum << "\n"
            << "refract_pass_duration_ms_count{pass=\"" << label(pass) << "\"} " << h.count << "\n";
    }

    out << "# HELP refract_ws_messages_total WebSocket messages received, and those rejected.\n"
        << "# TYPE refract_ws_messages_total counter\n"
        << "refract_ws_messages_total " << ws_messages_ << "\n"
        << "# TYPE refract_ws_rejected_total counter\n"
        << "refract_ws_rejected_total " << ws_rejected_ << "\n";

    out << "# HELP refract_scenes Scene documents stored.\n# TYPE refract_scenes gauge\n"
        << "refract_scenes " << gauges.scenes << "\n"
        << "# HELP refract_scenes_resident Scenes whose GPU state is resident.\n# TYPE "
           "refract_scenes_resident gauge\n"
        << "refract_scenes_resident " << gauges.scenes_resident << "\n"
        << "# HELP refract_device_memory_bytes Device memory held by the renderer.\n"
        << "# TYPE refract_device_memory_bytes gauge\n"
        << "refract_device_memory_bytes " << gauges.device_bytes << "\n"
        << "# HELP refract_render_waiting Requests waiting for a frame.\n# TYPE refract_render_waiting "
           "gauge\n"
        << "refract_render_waiting " << gauges.render_waiting << "\n"
        << "# HELP refract_frames_abandoned_total Frames nobody waited for any more: dropped before they "
           "rendered, or stopped at a part.\n# TYPE refract_frames_abandoned_total counter\n"
        << "refract_frames_abandoned_total " << gauges.frames_abandoned << "\n"
        << "# HELP refract_ws_sessions Open WebSocket sessions.\n# TYPE refract_ws_sessions gauge\n"
        << "refract_ws_sessions " << gauges.ws_sessions << "\n"
        << "# HELP refract_store_quarantined_files Stored scene files found unreadable at start and kept aside.\n"
        << "# TYPE refract_store_quarantined_files gauge\n"
        << "refract_store_quarantined_files " << gauges.quarantined_files << "\n"
        << "# HELP refract_uptime_seconds Seconds since the daemon started.\n# TYPE refract_uptime_seconds "
           "gauge\n"
        << "refract_uptime_seconds " << gauges.uptime_s << "\n";
    return out.str();
}

}  // namespace refract::http
