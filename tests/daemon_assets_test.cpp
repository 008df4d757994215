// Hostile uploads against a real refractd (issue 35): every upload is bounded before anything is
// allocated for it, decoded assets are held within --max-host-memory, and uploaded assets can be deleted
// (refused while a scene uses them, for good once done). Memory is read as the daemon's VmRSS.
#include <numbers>
#include <gtest/gtest.h>

#include <cstdint>
#include <algorithm>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "daemon/harness.h"

namespace refract::test {
namespace {

using nlohmann::json;
constexpr int64_t kMiB = int64_t{1} << 20;

const json kSmallScene = {{"image", {{"width", 32}, {"height", 32}}},
                          {"volume", {{"resolution", 32}}},
                          {"photons", {{"count", 256}}}};


std::string le32(uint32_t value) {
    std::string out(4, '\0');
    for (size_t i = 0; i < 4; ++i) out[i] = static_cast<char>((value >> (8 * i)) & 0xff);
    return out;
}

std::string exr_attribute(const std::string& name, const std::string& type, const std::string& value) {
    return name + '\0' + type + '\0' + le32(static_cast<uint32_t>(value.size())) + value;
}

// A 350-byte OpenEXR file (issue 35's was 332), valid but for its first attribute: a string declared 2^31 - 1 bytes long, of
// which 3 are present. The library allocates the declared size before it reads a byte of it.
std::string exr_string_bomb() {
    std::string file = std::string("\x76\x2f\x31\x01", 4) + le32(2);
    file += "comment";
    file += '\0';
    file += "string";
    file += '\0';
    file += le32(0x7fffffff) + "abc";
    std::string channels;
    for (const char* c : {"B", "G", "R"}) channels += std::string(c) + '\0' + le32(1) + std::string(4, '\0') + le32(1) + le32(1);
    channels += '\0';
    const std::string window = le32(0) + le32(0) + le32(0) + le32(0);
    file += exr_attribute("channels", "chlist", channels);
    file += exr_attribute("compression", "compression", std::string(1, '\0'));
    file += exr_attribute("dataWindow", "box2i", window);
    file += exr_attribute("displayWindow", "box2i", window);
    file += exr_attribute("lineOrder", "lineOrder", std::string(1, '\0'));
    file += exr_attribute("pixelAspectRatio", "float", le32(0x3f800000));
    file += exr_attribute("screenWindowCenter", "v2f", std::string(8, '\0'));
    file += exr_attribute("screenWindowWidth", "float", le32(0x3f800000));
    file += '\0';
    file += le32(static_cast<uint32_t>(file.size() + 8)) + le32(0);  // the one line's offset
    return file;
}

// A Radiance file of one colour, every scanline run-length encoded: about 520 bytes a row at 8192 wide.
std::string constant_rle_hdr(uint32_t width, uint32_t height, unsigned char exponent) {
    std::string row = {2, 2, static_cast<char>(width >> 8), static_cast<char>(width & 0xff)};
    const unsigned char rgbe[4] = {128, 128, 128, exponent};
    for (unsigned char value : rgbe) {
        for (uint32_t left = width; left > 0;) {
            const uint32_t run = std::min<uint32_t>(left, 127);
            row += static_cast<char>(128 + run);
            row += static_cast<char>(value);
            left -= run;
        }
    }
    std::string file = "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y " + std::to_string(height) + " +X " +
                       std::to_string(width) + "\n";
    file.reserve(file.size() + row.size() * height);
    for (uint32_t y = 0; y < height; ++y) file += row;
    return file;
}

json get_json(httplib::Client& client, const std::string& path) {
    auto res = client.Get(path);
    if (!res || res->status != 200) {
        ADD_FAILURE() << "GET " << path << ": " << (res ? res->body : "no answer");
        return json();
    }
    return json::parse(res->body);
}

std::vector<std::string> environment_names(httplib::Client& client) {
    std::vector<std::string> names;
    const json listed = get_json(client, "/api/environments");
    for (const auto& entry : listed["environments"]) names.push_back(entry["name"]);
    return names;
}

bool has(const std::vector<std::string>& names, const std::string& name) {
    return std::find(names.begin(), names.end(), name) != names.end();
}

TEST(DaemonAssetsTest, AnOpenExrHeaderDeclaringTwoGigabytesIsRefusedWithoutAllocatingThem) {
    TempDir dir;
    Daemon daemon(dir.path() / "data");
    auto client = daemon.client();
    ASSERT_EQ(client.Post("/api/scenes?id=kept", kSmallScene.dump(), "application/json")->status, 201);
    ASSERT_EQ(client.Put("/api/environments/good", constant_rle_hdr(64, 32, 128), "image/vnd.radiance")->status, 201);

    const std::string bomb = exr_string_bomb();
    ASSERT_LT(bomb.size(), 400u);
    // The warm-up builds the default scene and compiles pipelines meanwhile (~110 MiB): measured after it.
    ASSERT_TRUE(daemon.wait_until_warm()) << daemon.log();
    const int64_t before = daemon.rss_bytes();
    for (int i = 0; i < 3; ++i) {
        auto put = client.Put("/api/environments/bomb", bomb, "image/x-exr");
        ASSERT_TRUE(put);
        EXPECT_EQ(put->status, 400) << put->body;
        EXPECT_NE(put->body.find("declares 2147483647 bytes"), std::string::npos) << put->body;
    }
    const int64_t growth = daemon.rss_bytes() - before;
    std::printf("RSS %lld MiB before, grew by %lld KiB after 3 uploads\n", static_cast<long long>(before / kMiB),
                static_cast<long long>(growth / 1024));
    // Allocated, each upload's 2 GiB would show (and stay: issue 35 saw +2.1 GB per upload).
    EXPECT_LT(growth, 64 * kMiB);
    ASSERT_TRUE(daemon.running());
    EXPECT_EQ(client.Get("/api/scenes/kept")->status, 200);
    const auto names = environment_names(client);
    EXPECT_TRUE(has(names, "good"));
    EXPECT_FALSE(has(names, "bomb"));
}

TEST(DaemonAssetsTest, DecodedEnvironmentsStayWithinTheHostMemoryBudget) {
    TempDir dir;
    Daemon daemon(dir.path() / "data", {"--max-host-memory", "256M"});
    auto client = daemon.client();
    // Measured after the warm-up, which grows the process by ~110 MiB (the default scene, pipelines): taken
    // before it, the warm-up counted against the budget (CI: +353 MiB, of which the maps' share was ~240).
    ASSERT_TRUE(daemon.wait_until_warm()) << daemon.log();
    const int64_t before = daemon.rss_bytes();

    // 8192 x 4096 decodes to 384 MiB, over the whole budget: refused on its header, nothing decoded.
    const std::string largest = constant_rle_hdr(8192, 4096, 129);
    ASSERT_LT(largest.size(), size_t{3} << 20);
    for (int i = 0; i < 6; ++i) {
        auto put = client.Put("/api/environments/large-" + std::to_string(i), largest, "image/vnd.radiance");
        ASSERT_TRUE(put);
        EXPECT_EQ(put->status, 413) << put->body;
        EXPECT_NE(put->body.find("--max-host-memory"), std::string::npos) << put->body;
    }
    const int64_t after_refused = daemon.rss_bytes();
    // Nothing decoded: one decode is 384 MiB. What grows is the bodies received (3 MiB each, on the
    // server's threads, whose allocator arenas keep what they held).
    if (!daemon_sanitized()) {
        EXPECT_LT(after_refused - before, 128 * kMiB);
    }

    // 4096 x 2048 decodes to 96 MiB: all six are stored, at most two stay decoded (192 MiB of the 256).
    const std::string map = constant_rle_hdr(4096, 2048, 129);
    for (int i = 0; i < 6; ++i) {
        auto put = client.Put("/api/environments/map-" + std::to_string(i), map, "image/vnd.radiance");
        ASSERT_TRUE(put);
        ASSERT_EQ(put->status, 201) << put->body;
    }
    const int64_t after = daemon.rss_bytes();
    std::printf("RSS %lld MiB before, %lld MiB after six refused 8192 x 4096, %lld MiB after six 4096 x 2048\n",
                static_cast<long long>(before / kMiB), static_cast<long long>(after_refused / kMiB),
                static_cast<long long>(after / kMiB));
    // The budget plus one map: the cache holds two maps (192 MiB); of each decode's temporaries
    // (stb_image's floats and the map, 96 MiB each) the allocator may keep up to one map's worth in a
    // worker thread's arena (measured after the warm-up: +197 MiB, flat from the second upload on). Kept, the
    // six maps alone would take 576 MiB.
    if (!daemon_sanitized()) {
        EXPECT_LT(after - before, 256 * kMiB + 96 * kMiB);
    }

    ASSERT_TRUE(daemon.running());
    const json listed = get_json(client, "/api/environments");
    size_t maps = 0;
    for (const auto& entry : listed["environments"]) {
        if (entry["name"].get<std::string>().rfind("map-", 0) != 0) continue;
        ++maps;
        EXPECT_EQ(entry["width"], 4096);
        EXPECT_EQ(entry["height"], 2048);
    }
    EXPECT_EQ(maps, 6u);
    EXPECT_FALSE(has(environment_names(client), "large-0"));
}

// One environment's entry tells a client how brightly it lights the scene at intensity 1: a uniform map of
// radiance 0.5 (RGBE 128,128,128 at exponent 128) gives an up-facing surface pi / 2.
TEST(DaemonAssetsTest, AnEnvironmentsEntryStatesItsIrradianceOnAnUpwardSurface) {
    TempDir dir;
    Daemon daemon(dir.path() / "data");
    auto client = daemon.client();
    ASSERT_EQ(client.Put("/api/environments/studio", constant_rle_hdr(64, 32, 128), "image/vnd.radiance")->status, 201);
    const json studio = get_json(client, "/api/environments/studio");
    EXPECT_EQ(studio["width"], 64);
    EXPECT_EQ(studio["built_in"], false);
    for (size_t c = 0; c < 3; ++c) EXPECT_NEAR(studio["irradiance"][c].get<double>(), std::numbers::pi / 2, 1e-6);
    const json sky = get_json(client, "/api/environments/sky-sun");
    EXPECT_EQ(sky["built_in"], true);
    EXPECT_GT(sky["irradiance"][0].get<double>(), studio["irradiance"][0].get<double>());
    for (const char* path : {"/api/environments/nothing", "/api/environments/..%2Fscenes", "/api/environments/a%00b"}) {
        auto missing = client.Get(path);
        ASSERT_TRUE(missing) << path;
        EXPECT_EQ(missing->status, 404) << path << ": " << missing->body;
        EXPECT_TRUE(json::parse(missing->body).contains("error")) << missing->body;
    }
    ASSERT_TRUE(daemon.running());
}

TEST(DaemonAssetsTest, AssetsAreDeletedOnlyWhenNoSceneUsesThemAndStayDeleted) {
    TempDir dir;
    const auto data = dir.path() / "data";
    {
        Daemon daemon(data);
        auto client = daemon.client();
        ASSERT_EQ(client.Put("/api/environments/studio", constant_rle_hdr(64, 32, 128), "image/vnd.radiance")->status,
                  201);
        ASSERT_EQ(client.Put("/api/meshes/tetra", kTetrahedronObj, "text/plain")->status, 201);
        json scene = kSmallScene;
        scene["environment"] = {{"type", "image"}, {"image", "studio"}};
        scene["objects"] = {{"object", {{"mesh", "upload:tetra"}}}};
        ASSERT_EQ(client.Post("/api/scenes?id=user", scene.dump(), "application/json")->status, 201);
        ASSERT_EQ(client.Post("/api/scenes?id=other", kSmallScene.dump(), "application/json")->status, 201);
        const std::vector<float> values(8, 1.2f);
        auto grid = client.Put("/api/scenes/other/index-field?nx=2&ny=2&nz=2&min=0,0,0&max=1,1,1",
                               std::string(reinterpret_cast<const char*>(values.data()), values.size() * sizeof(float)),
                               "application/octet-stream");
        ASSERT_EQ(grid->status, 200) << grid->body;

        for (const char* path : {"/api/environments/studio", "/api/meshes/tetra"}) {
            auto refused = client.Delete(path);
            ASSERT_TRUE(refused);
            EXPECT_EQ(refused->status, 409) << path << ": " << refused->body;
            EXPECT_EQ(json::parse(refused->body)["scenes"], json({"user"})) << refused->body;
        }
        auto grid_refused = client.Delete("/api/scenes/other/index-field");
        EXPECT_EQ(grid_refused->status, 409) << grid_refused->body;
        EXPECT_EQ(json::parse(grid_refused->body)["scenes"], json({"other"}));
        EXPECT_EQ(client.Delete("/api/environments/sky-sun")->status, 405);
        EXPECT_EQ(client.Delete("/api/environments/nothing")->status, 404);
        EXPECT_EQ(client.Delete("/api/meshes/nothing")->status, 404);
        EXPECT_EQ(client.Delete("/api/scenes/user/index-field")->status, 404);

        const std::string patch =
            json({{"environment", {{"type", "sky"}}}, {"objects", {{"object", {{"mesh", "sphere"}}}}}}).dump();
        ASSERT_EQ(client.Patch("/api/scenes/user", patch, "application/merge-patch+json")->status, 200);
        const std::string uniform = json({{"objects", {{"object", {{"index_field", "uniform"}}}}}}).dump();
        ASSERT_EQ(client.Patch("/api/scenes/other", uniform, "application/merge-patch+json")->status, 200);
        for (const char* path : {"/api/environments/studio", "/api/meshes/tetra", "/api/scenes/other/index-field"}) {
            auto deleted = client.Delete(path);
            ASSERT_TRUE(deleted);
            EXPECT_EQ(deleted->status, 204) << path << ": " << deleted->body;
            EXPECT_EQ(client.Delete(path)->status, 404) << path;
        }
    }
    Daemon restarted(data);
    auto client = restarted.client();
    EXPECT_FALSE(has(environment_names(client), "studio"));
    EXPECT_TRUE(get_json(client, "/api/meshes")["meshes"].empty());
    for (const char* path : {"/api/environments/studio", "/api/meshes/tetra", "/api/scenes/other/index-field"})
        EXPECT_EQ(client.Delete(path)->status, 404) << path;
    EXPECT_EQ(client.Get("/api/scenes/user")->status, 200);
    EXPECT_EQ(client.Get("/api/scenes/other")->status, 200);
}

}  // namespace
}  // namespace refract::test
