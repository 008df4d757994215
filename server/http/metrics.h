// The daemon's counters and histograms, served as Prometheus text at GET /metrics.
// Thread-safe: HTTP threads record requests, the render thread records frames.
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <mutex>
#include <string>
#include <tuple>

#include "render/renderer.h"

namespace refract::http {

// Values read at scrape time from the parts that own them.
struct Gauges {
    size_t scenes = 0;
    size_t scenes_resident = 0;
    int64_t device_bytes = 0;
    size_t render_waiting = 0;
    uint64_t frames_abandoned = 0;
    size_t ws_sessions = 0;
    size_t quarantined_files = 0;
    double uptime_s = 0.0;
};

// The route pattern of a request path, so that labels stay few ("/api/scenes/{id}", "static", ...).
std::string route_of(const std::string& path);

// The milliseconds a pass took as reported to clients and metrics: GPU time where measured, else host time.
double pass_ms(const scene::PassTiming& timing);

class Metrics {
public:
    void record_request(const std::string& method, const std::string& route, int status);
    // One rendered frame: counts it, each pass that ran, and each pass's duration.
    void record_frame(const scene::FrameResult& frame);
    void record_ws_message(bool rejected);

    std::string prometheus_text(const Gauges& gauges) const;

private:
    static constexpr std::array<double, 14> kBucketsMs = {0.5, 1,   2,   5,    10,   25,   50,
                                                          100, 250, 500, 1000, 2500, 5000, 10000};
    struct Histogram {
        std::array<uint64_t, kBucketsMs.size()> buckets{};  // non-cumulative counts per bucket
        uint64_t count = 0;
        double sum = 0.0;
    };

    mutable std::mutex mutex_;
    std::map<std::tuple<std::string, std::string, int>, uint64_t> requests_;  // (method, route, status)
    std::map<std::string, uint64_t> errors_;                                  // by route, status >= 400
    std::map<std::string, uint64_t> pass_runs_;
    std::map<std::string, Histogram> pass_durations_;
    uint64_t frames_ = 0;
    uint64_t ws_messages_ = 0;
    uint64_t ws_rejected_ = 0;
};

}  // namespace refract::http
