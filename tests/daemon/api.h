// The daemon's HTTP API as the integration tests call it: scenes, frames, patches and metrics of a
// real refractd, each call checked with GoogleTest's EXPECT so that a failure names the request.
#pragma once

#include <gtest/gtest.h>
#include <httplib.h>

#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "daemon/harness.h"

namespace refract::test {

// Frames small enough for lavapipe on two cores.
inline const nlohmann::json kSmallScene = {{"image", {{"width", 64}, {"height", 64}}},
                                           {"volume", {{"resolution", 32}}},
                                           {"photons", {{"count", 256}}}};

// A frame far heavier than any other: 2^24 photons (the most --max-photons allows) scattering up to 1024
// times in dense white fog (albedo 1) take minutes on two CPU cores and seconds on an H200; a part of them
// (passes::kWorkPart, 2^14) about half a second on the cores.
inline constexpr const char* kHeavyPhotons = "16777216";  // the daemon's --max-photons for it
inline const nlohmann::json kHeavyScene = {{"image", {{"width", 64}, {"height", 64}}},
                                           {"volume", {{"resolution", 32}}},
                                           {"medium", {{"extinction", {50, 50, 50}}, {"scattering", {50, 50, 50}}}},
                                           {"photons", {{"count", 1 << 24}, {"max_bounces", 1024}}}};

inline constexpr const char* kMergePatch = "application/merge-patch+json";

inline bool is_png(const std::string& bytes) {
    return bytes.size() > 8 && bytes.compare(0, 8, "\x89PNG\r\n\x1a\n") == 0;
}

// The width and height a PNG's header states.
inline std::pair<uint32_t, uint32_t> png_size(const std::string& png) {
    auto be32 = [&](size_t at) {
        return (uint32_t(uint8_t(png[at])) << 24) | (uint32_t(uint8_t(png[at + 1])) << 16) |
               (uint32_t(uint8_t(png[at + 2])) << 8) | uint32_t(uint8_t(png[at + 3]));
    };
    return png.size() >= 24 ? std::pair{be32(16), be32(20)} : std::pair{0u, 0u};
}

inline nlohmann::json get_json(httplib::Client& client, const std::string& path, int expected_status = 200) {
    auto res = client.Get(path);
    EXPECT_TRUE(res) << "GET " << path << " failed";
    if (!res) return {};
    EXPECT_EQ(res->status, expected_status) << path << ": " << res->body;
    return nlohmann::json::parse(res->body, nullptr, false);
}

inline std::string create_scene(httplib::Client& client, const std::string& id, const nlohmann::json& document = kSmallScene) {
    auto res = client.Post("/api/scenes?id=" + id, document.dump(), "application/json");
    EXPECT_TRUE(res);
    if (!res) return {};
    EXPECT_EQ(res->status, 201) << res->body;
    return nlohmann::json::parse(res->body).at("id").get<std::string>();
}

// Frame bytes of a scene, with the response for its headers.
inline httplib::Result get_frame(httplib::Client& client, const std::string& id, const std::string& query = "") {
    auto res = client.Get("/api/scenes/" + id + "/frame.png" + query);
    EXPECT_TRUE(res) << "frame of " << id;
    if (res) {
        EXPECT_EQ(res->status, 200) << res->body;
        if (res->status == 200) {
            EXPECT_TRUE(is_png(res->body));
        }
    }
    return res;
}

inline httplib::Result patch(httplib::Client& client, const std::string& id, const nlohmann::json& merge_patch,
                      const httplib::Headers& headers = {}) {
    return client.Patch("/api/scenes/" + id, headers, merge_patch.dump(), kMergePatch);
}

// The value of a metric line ("refract_pass_runs_total{pass=\"view\"}"), 0 when absent.
inline double metric(httplib::Client& client, const std::string& series) {
    auto res = client.Get("/metrics");
    if (!res) return -1;
    std::istringstream lines(res->body);
    std::string line;
    while (std::getline(lines, line)) {
        if (line.compare(0, series.size(), series) == 0 && line.size() > series.size() &&
            line[series.size()] == ' ')
            return std::stod(line.substr(series.size() + 1));
    }
    return 0;
}

inline void expect_alive(Daemon& daemon) {
    ASSERT_TRUE(daemon.running()) << daemon.log();
    auto client = daemon.client();
    auto res = client.Get("/api/health");
    ASSERT_TRUE(res) << daemon.log();
    EXPECT_EQ(res->status, 200);
}

inline void expect_no_validation_errors(Daemon& daemon) {
    auto client = daemon.client();
    nlohmann::json health = get_json(client, "/api/health");
    if (health.contains("validation_errors")) {
        EXPECT_EQ(health["validation_errors"], 0) << daemon.log();
    }
}

}  // namespace refract::test
