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

SceneDocument document(const json& patch) { return protocol::parse_scene(patch); }

class UpscaleTest : public testing::GpuTest {
protected:
    // `scene` as a still frame of W x H in `still`, and as an interactive frame traced at w x h in
    // `preview`, upscaled to W x H; the still's document.
    SceneDocument still_and_preview(const json& scene, glm::uvec2 traced, glm::uvec2 viewer, bool adaptive,
                                    scene::SceneGpu& still, scene::SceneGpu& preview) {
        json traced_scene = scene, viewer_scene = scene;
        traced_scene["image"] = {{"width", traced.x}, {"height", traced.y}};
        viewer_scene["image"] = {{"width", viewer.x}, {"height", viewer.y}};
        const SceneDocument still_doc = document(viewer_scene), preview_doc = document(traced_scene);
        still.run(scene::kAllPasses, still_doc, worlds(still_doc), nullptr);
        scene::RunOptions options = scene::run_options_for(scene::Quality::interactive);
        options.adaptive_view = adaptive;
        options.view_ends = true;
        preview.run(scene::kAllPasses, preview_doc, worlds(preview_doc), nullptr, options);
        preview.upscale(viewer.x, viewer.y);
        return still_doc;
    }
};

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

// The pixels of a W x H view of `doc` whose centre's ray passes within `fraction` of the angular radius
// of its (spherical) object's disc around the object's centre.
std::vector<bool> object_disc(const SceneDocument& doc, uint32_t W, uint32_t H, double fraction) {
    const auto vec = [](const protocol::Vec3& v) { return glm::dvec3(v[0], v[1], v[2]); };
    const glm::dvec3 eye = vec(doc.camera.position), centre = vec(doc.object().position);
    const glm::dvec3 forward = glm::normalize(vec(doc.camera.target) - eye);
    const glm::dvec3 right = glm::normalize(glm::cross(forward, vec(doc.camera.up)));
    const glm::dvec3 up = glm::cross(right, forward);
    const double tan_half = std::tan(glm::radians(doc.camera.fov_deg) * 0.5);
    const glm::dvec3 to_centre = glm::normalize(centre - eye);
    const double disc = fraction * std::asin(doc.object().scale / glm::length(centre - eye));
    std::vector<bool> inside(size_t{W} * H);
    for (uint32_t y = 0; y < H; ++y)
        for (uint32_t x = 0; x < W; ++x) {
            const double u = (2.0 * (x + 0.5) / W - 1.0) * tan_half * W / H,
                         v = (1.0 - 2.0 * (y + 0.5) / H) * tan_half;
            const glm::dvec3 d = glm::normalize(forward + u * right + v * up);
            inside[size_t{y} * W + x] = std::acos(std::clamp(glm::dot(d, to_centre), -1.0, 1.0)) <= disc;
        }
    return inside;
}

// A glass ball over a checker floor, no fog: what the glass shows is the floor's or the sky's.
json ball_over_checker() {
    return {{"camera", {{"position", {0.0, 0.6, 3.0}}, {"target", {0.0, 0.0, 0.0}}, {"fov_deg", 40}}},
            {"objects", {{"object", {{"position", {0.0, 0.0, 0.0}}, {"scale", 0.8}}}}},
            {"medium", {{"extinction", {0, 0, 0}}, {"scattering", {0, 0, 0}}}},
            {"floor", {{"enabled", true}, {"height", -1.0}, {"checker", true}, {"checker_size", 0.2}}},
            {"volume", {{"resolution", 64}}},
            {"photons", {{"count", 4096}}}};
}

// The pixels of `image` where `mask` is `keep`.
std::vector<glm::vec4> where(const std::vector<glm::vec4>& image, const std::vector<bool>& mask, bool keep) {
    std::vector<glm::vec4> kept;
    for (size_t i = 0; i < image.size(); ++i)
        if (mask[i] == keep) kept.push_back(image[i]);
    return kept;
}

// Every pixel traced (no adaptive interpolation), the upscale to the traced size itself evaluates each
// straight ray's floor or sky where the viewing pass did: the same frame, up to the float rounding of
// where the floor point lies (the march's end against the plane's intersection), which moves no pixel by
// more than one 8-bit level. The default scene: fog, a glass sphere, a spot on a checker floor. Through
// the sphere the upscale filters the checker by how far apart the traced rays' last legs land, which a
// preview's viewing pass does not (its footprint is the straight cone's; the next test's subject), and
// keeps what a bent ray saw where it falls back on it in half precision: the comparison leaves out the
// sphere's disc to 1.6 of its radius, where rays graze the octree's finest cells around the glass.
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
    const std::vector<bool> sphere = object_disc(doc, w, h, 1.6);
    double worst = 0.0;
    for (size_t i = 0; i < hdr.size(); ++i)
        for (int c = 0; c < 3 && !sphere[i]; ++c) {
            EXPECT_LE(std::abs(channel(up_ldr[i], c) - channel(ldr[i], c)), 1) << "pixel " << i;
            worst = std::max(worst, std::abs(static_cast<double>(up_hdr[i][c] - hdr[i][c])) /
                                        std::max(1e-3, static_cast<double>(hdr[i][c])));
        }
    std::printf("upscaled to its own size: largest relative difference %.2e\n", worst);
    EXPECT_LT(worst, 1e-3);
    EXPECT_LT(relative_rmse(where(up_hdr, sphere, false), where(hdr, sphere, false)), 1e-5);
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
    scene::SceneGpu still(kit()), preview(kit());
    still_and_preview(scene, {w, h}, {W, H}, true, still, preview);
    const auto reference = still.read_hdr();
    const double upscaled = relative_rmse(preview.read_viewer_hdr(), reference);
    const double scaled_up = relative_rmse(bilinear(preview.read_hdr(), w, h, W, H), reference);
    std::printf("against the still at %ux%u: upscaled %.2e, scaled up bilinearly %.3f\n", W, H, upscaled, scaled_up);
    EXPECT_LT(upscaled, 1e-4);
    EXPECT_GT(scaled_up, 0.05);
}

// Through the glass the viewer sees the floor along the traced rays' last legs, interpolated between the
// traced pixels as rays (where each leaves the glass, and its direction) and followed again for each of
// the viewer's pixels to the floor or the sky: inside the ball's disc (away from its rim, where
// neighbouring rays take different ways through the glass and the pixel keeps what its traced neighbours
// saw) the upscaled frame is at most a quarter as far from the still of the viewer's size as the traced
// frame scaled up bilinearly, which is what the upscale did there before it followed legs. The ball
// shows the horizon upside down; where the legs were followed only between traced pixels that all saw
// the floor (or all the sky), that line kept the traced pixels' light, and this came to 0.30 of the
// bilinear frame's distance.
TEST_F(UpscaleTest, ThroughGlassTheFloorIsFollowedAlongTheRaysLastLegs) {
    json scene = ball_over_checker();
    scene["lights"] = {
        {"sun", {{"type", "directional"}, {"direction", {0.3, -1.0, -0.2}}, {"intensity", 2.0}}}};
    const uint32_t w = 60, h = 40, W = 240, H = 160;
    scene::SceneGpu still(kit()), preview(kit());
    const SceneDocument still_doc = still_and_preview(scene, {w, h}, {W, H}, false, still, preview);
    // The sphere's disc, its inner 80%: the rays that cross the glass well inside its rim.
    const std::vector<bool> sphere = object_disc(still_doc, W, H, 0.8);
    const auto reference = where(still.read_hdr(), sphere, true);
    ASSERT_GT(reference.size(), size_t{W} * H / 20);
    const double followed = relative_rmse(where(preview.read_viewer_hdr(), sphere, true), reference);
    const double blurred =
        relative_rmse(where(bilinear(preview.read_hdr(), w, h, W, H), sphere, true), reference);
    std::printf(
        "inside the sphere (%zu pixels) against the still at %ux%u: upscaled %.3f, scaled up bilinearly "
        "%.3f\n",
        reference.size(), W, H, followed, blurred);
    EXPECT_LT(followed, 0.25 * blurred);
}

// A light drag's eye rays are the still frame's before it: with that still's ends kept at the viewer's
// size (RunOptions::still_ends), each viewer pixel takes its own end from them, its own ray or last leg
// out of the glass and the transmittance to it, and from the traced pixels only the light gathered before
// it. Away from the sphere, where every traced ray went straight, that is what the traced pixels' ends
// give (no fog here: nothing gathered, all transmitted). Around its outline and rim, which the traced
// pixels hold at a quarter of the viewer's size, the frame of a moved light is then within a tenth as
// close to a still of that light (8-bit RMSE) as the same preview tracing every pixel at the viewer's
// size, where the traced pixels' own ends leave it at least half as far again.
TEST_F(UpscaleTest, ALightDragTakesEachViewerPixelsEyeRayFromTheStill) {
    json scene = ball_over_checker();
    const uint32_t w = 60, h = 40, W = 240, H = 160;
    const auto sized = [&](json s, uint32_t width, uint32_t height) {
        s["image"] = {{"width", width}, {"height", height}};
        return document(s);
    };
    const SceneDocument still_doc = sized(scene, W, H);
    scene::SceneGpu gpu(kit());
    scene::RunOptions still = scene::run_options_for(scene::Quality::still);
    still.still_ends = true;
    gpu.run(scene::kAllPasses, still_doc, worlds(still_doc), nullptr, still);
    ASSERT_TRUE(gpu.has_still_ends(W, H));
    EXPECT_FALSE(gpu.has_still_ends(w, h));

    scene["lights"] = {{"light", {{"position", {-1.5, 3.0, 1.5}}}}};
    const SceneDocument moved = sized(scene, w, h);
    scene::RunOptions preview = scene::run_options_for(scene::Quality::interactive);
    preview.view_ends = true;
    gpu.run(scene::kPhotons | scene::kView | scene::kToneMap, moved, worlds(moved), nullptr, preview);
    gpu.upscale(W, H, false);
    const auto traced_ends = gpu.read_viewer_ldr();
    gpu.upscale(W, H, true);
    const auto still_ends = gpu.read_viewer_ldr();
    preview.adaptive_view = false;
    preview.view_ends = false;
    const SceneDocument moved_whole = sized(scene, W, H);
    scene::SceneGpu whole(kit());
    whole.run(scene::kAllPasses, moved_whole, worlds(moved_whole), nullptr, preview);
    const auto whole_ldr = whole.read_ldr();
    scene["photons"] = {{"count", 1 << 18}};
    const SceneDocument moved_still = sized(scene, W, H);
    scene::SceneGpu reference(kit());
    reference.run(scene::kAllPasses, moved_still, worlds(moved_still), nullptr);
    const auto reference_ldr = reference.read_ldr();

    const std::vector<bool> near_sphere = object_disc(still_doc, W, H, 1.6),
                            inner = object_disc(still_doc, W, H, 0.85),
                            outer = object_disc(still_doc, W, H, 1.1);
    int apart = 0;
    double own = 0.0, traced = 0.0, every = 0.0;
    size_t rim = 0;
    for (size_t i = 0; i < still_ends.size(); ++i)
        for (int c = 0; c < 3; ++c) {
            if (!near_sphere[i])
                apart = std::max(apart, std::abs(channel(still_ends[i], c) - channel(traced_ends[i], c)));
            if (!outer[i] || inner[i]) continue;
            own += std::pow(channel(still_ends[i], c) - channel(reference_ldr[i], c), 2);
            traced += std::pow(channel(traced_ends[i], c) - channel(reference_ldr[i], c), 2);
            every += std::pow(channel(whole_ldr[i], c) - channel(reference_ldr[i], c), 2);
            rim += c == 0;
        }
    const auto rmse = [&](double sum) { return std::sqrt(sum / (3.0 * static_cast<double>(rim))); };
    std::printf(
        "the sphere's rim (%zu pixels) against a still of the moved light: %.2f with the still's ends, "
        "%.2f with the traced pixels', %.2f tracing every pixel\n",
        rim, rmse(own), rmse(traced), rmse(every));
    EXPECT_LE(apart, 1);
    EXPECT_LT(rmse(own), 1.1 * rmse(every));
    EXPECT_GT(rmse(traced), 1.5 * rmse(every));
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
