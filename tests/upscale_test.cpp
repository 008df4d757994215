// The view upscale (issue 37, passes/view_upscale.h): an interactive frame traced smaller than its viewer
// is sent at the viewer's size, the light its eye rays gathered interpolated and the floor or sky where
// they end found again for every pixel. At the traced size it is the traced frame; at the viewer's size
// its floor is the still frame's there, where the traced frame scaled up blurs the checker and the lit
// disc's rim; and the renderer sends interactive frames at the viewer's size.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include <nlohmann/json.hpp>

#include "gpu_fixture.h"
#include "image/png.h"
#include "render/renderer.h"

namespace refract {
namespace {

using nlohmann::json;
using protocol::SceneDocument;

class UpscaleTest : public testing::GpuTest {};

SceneDocument document(const json& patch) { return protocol::parse_scene(patch); }

// The 8-bit channel c of an RGBA8 pixel.
int channel(uint32_t rgba, int c) { return static_cast<int>((rgba >> (8 * c)) & 0xffu); }

// Linear radiance bilinearly scaled from w x h to W x H, pixel centres on pixel centres (the client's
// way of showing a smaller frame).
std::vector<glm::vec4> bilinear(const std::vector<glm::vec4>& in, uint32_t w, uint32_t h, uint32_t W, uint32_t H) {
    std::vector<glm::vec4> out(size_t{W} * H);
    const auto sample_at = [](uint32_t to, uint32_t from, uint32_t n) {  // where pixel `to` falls among n
        return std::clamp((to + 0.5) * from / n - 0.5, 0.0, from - 1.0);
    };
    for (uint32_t Y = 0; Y < H; ++Y)
        for (uint32_t X = 0; X < W; ++X) {
            const double fx = sample_at(X, w, W), fy = sample_at(Y, h, H);
            const auto x0 = static_cast<uint32_t>(fx), y0 = static_cast<uint32_t>(fy);
            const uint32_t x1 = std::min(x0 + 1, w - 1), y1 = std::min(y0 + 1, h - 1);
            const auto ax = static_cast<float>(fx - x0), ay = static_cast<float>(fy - y0);
            auto at = [&](uint32_t x, uint32_t y) { return in[size_t{y} * w + x]; };
            out[size_t{Y} * W + X] = (1 - ay) * ((1 - ax) * at(x0, y0) + ax * at(x1, y0)) +
                                     ay * ((1 - ax) * at(x0, y1) + ax * at(x1, y1));
        }
    return out;
}

// Relative RMSE of a frame's rgb against a reference's, over the pixels where the reference is not black.
double relative_rmse(const std::vector<glm::vec4>& a, const std::vector<glm::vec4>& reference) {
    double sum = 0.0, norm = 0.0;
    for (size_t i = 0; i < a.size(); ++i)
        for (int c = 0; c < 3; ++c) {
            const double d = static_cast<double>(a[i][c]) - static_cast<double>(reference[i][c]);
            sum += d * d;
            norm += static_cast<double>(reference[i][c] * reference[i][c]);
        }
    return std::sqrt(sum / std::max(norm, 1e-30));
}

// Every pixel traced (no adaptive interpolation), the upscale to the traced size itself evaluates each
// straight ray's floor or sky where the viewing pass did: the same frame, up to the float rounding of
// where the floor point lies (the march's end against the plane's intersection), which moves no pixel by
// more than one 8-bit level. The default scene: fog, a glass sphere (its rays bend: all gathered), a spot
// on a checker floor.
TEST_F(UpscaleTest, AtTheTracedSizeItIsTheTracedFrame) {
    const uint32_t w = 97, h = 75;
    const SceneDocument doc = document({{"image", {{"width", w}, {"height", h}}},
                                        {"volume", {{"resolution", 48}}},
                                        {"photons", {{"count", 1 << 14}}}});
    scene::RunOptions options = scene::run_options_for(scene::Quality::interactive);
    options.adaptive_view = false;
    options.view_ends = true;
    scene::SceneGpu gpu(kit());
    gpu.run(scene::kAllPasses, doc, worlds(doc), nullptr, options);
    ASSERT_TRUE(gpu.has_view_ends());
    gpu.upscale(w, h);
    const auto hdr = gpu.read_hdr();
    const auto ldr = gpu.read_ldr();
    const auto up_hdr = gpu.read_viewer_hdr();
    const auto up_ldr = gpu.read_viewer_ldr();
    ASSERT_EQ(up_hdr.size(), hdr.size());
    double worst = 0.0;
    for (size_t i = 0; i < hdr.size(); ++i)
        for (int c = 0; c < 3; ++c) {
            EXPECT_LE(std::abs(channel(up_ldr[i], c) - channel(ldr[i], c)), 1) << "pixel " << i;
            worst = std::max(worst, std::abs(static_cast<double>(up_hdr[i][c] - hdr[i][c])) /
                                        std::max(1e-3, static_cast<double>(hdr[i][c])));
        }
    std::printf("upscaled to its own size: largest relative difference %.2e\n", worst);
    EXPECT_LT(worst, 1e-3);
    EXPECT_LT(relative_rmse(up_hdr, hdr), 1e-5);
}

// Without fog, the floor a viewer sees is all end: the frame traced at a quarter of the viewer's side and
// upscaled is the still frame of the viewer's size (level 1: pixel centres, the footprint of the
// viewer's pixels, which filters the checker and the spot's rim), where the same traced frame scaled up
// bilinearly is the blurred, stair-stepped picture a client would show.
TEST_F(UpscaleTest, TheFloorAtTheViewersSizeIsTheStillFrames) {
    const json scene = {{"camera", {{"position", {0.0, 1.2, 4.0}}, {"target", {0.0, -0.8, -2.0}}, {"fov_deg", 50}}},
                        {"lights", {{"spot", {{"type", "spot"}, {"position", {0.5, 3.0, 0.0}}, {"direction", {0.0, -1.0, -0.3}},
                                              {"cone_deg", 25}, {"intensity", 20.0}}}}},
                        {"objects", {{"object", {{"position", {0.0, 0.0, 8.0}}, {"scale", 0.2}}}}},
                        {"medium", {{"extinction", {0, 0, 0}}, {"scattering", {0, 0, 0}}}},
                        {"floor", {{"enabled", true}, {"height", -1.0}, {"checker", true}, {"checker_size", 0.25}}},
                        {"volume", {{"resolution", 32}}},
                        {"photons", {{"count", 4096}}}};
    const uint32_t w = 48, h = 32, W = 192, H = 128;
    json traced = scene, viewer = scene;
    traced["image"] = {{"width", w}, {"height", h}};
    viewer["image"] = {{"width", W}, {"height", H}};
    scene::SceneGpu still(kit()), preview(kit());
    const SceneDocument still_doc = document(viewer), preview_doc = document(traced);
    still.run(scene::kAllPasses, still_doc, worlds(still_doc), nullptr);
    scene::RunOptions options = scene::run_options_for(scene::Quality::interactive);
    options.view_ends = true;
    preview.run(scene::kAllPasses, preview_doc, worlds(preview_doc), nullptr, options);
    preview.upscale(W, H);
    const auto reference = still.read_hdr();
    const double upscaled = relative_rmse(preview.read_viewer_hdr(), reference);
    const double scaled_up = relative_rmse(bilinear(preview.read_hdr(), w, h, W, H), reference);
    std::printf("against the still at %ux%u: upscaled %.2e, scaled up bilinearly %.3f\n", W, H, upscaled, scaled_up);
    EXPECT_LT(upscaled, 1e-4);
    EXPECT_GT(scaled_up, 0.05);
}

// The renderer sends an interactive frame at the viewer's size whatever size its budget traced, and keeps
// the traced rays' ends so that an exposure edit (tone map only) is upscaled again.
TEST_F(UpscaleTest, InteractiveFramesComeAtTheViewersSize) {
    scene::Renderer renderer(context());
    const SceneDocument doc = document({{"image", {{"width", 320}, {"height", 200}}}, {"volume", {{"resolution", 48}}}});
    scene::Assets no_assets;
    scene::FrameOptions options{scene::Quality::interactive};
    options.budget_ms = 10.0;  // a budget no frame of 320 x 200 meets here: traced smaller
    const scene::FrameResult frame = renderer.render("a", doc, no_assets, options);
    EXPECT_EQ(frame.width, 320u);
    EXPECT_EQ(frame.height, 200u);
    EXPECT_LT(frame.traced_width, 320u);
    EXPECT_TRUE(std::any_of(frame.timings.begin(), frame.timings.end(), [](const auto& t) { return t.name == "upscale"; }));
    uint32_t png_width = 0, png_height = 0;
    image::decode_png(frame.png, png_width, png_height);
    EXPECT_EQ(png_width, 320u);
    EXPECT_EQ(png_height, 200u);
    const SceneDocument brighter = protocol::apply_merge_patch(doc, {{"image", {{"exposure", 1.0}}}});
    const scene::FrameResult toned = renderer.render("a", brighter, no_assets, options);
    EXPECT_EQ(toned.rerun, scene::kToneMap);
    EXPECT_EQ(toned.width, 320u);
    EXPECT_EQ(toned.traced_width, frame.traced_width);
    EXPECT_NE(toned.png, frame.png);
}

}  // namespace
}  // namespace refract
