// Temporal reuse (issue 37, render/temporal_history.h): a still camera's jittered samples accumulate to
// the refined still's bytes; a known camera motion reprojects a known pattern, and what the motion
// uncovers takes the new samples alone; the history starts over on edits that are not camera, light or
// exposure moves; a viewer's interactive frames come at its full size, starting from the still before.
#include <cmath>
#include <cstring>

#include <nlohmann/json.hpp>

#include "gpu_fixture.h"
#include "image/png.h"
#include "passes/transport_params.h"
#include "render/renderer.h"
#include "render/temporal_history.h"
#include "render/transport_inputs.h"

namespace refract {
namespace {

using nlohmann::json;
using protocol::SceneDocument;

class TemporalTest : public testing::GpuTest {
protected:
    // Samples (radiance, inverse depth) in a buffer the temporal pass reads.
    static vk::Buffer upload(const std::vector<glm::vec4>& samples) {
        vk::Buffer buffer(context(), samples.size() * sizeof(glm::vec4), VK_BUFFER_USAGE_STORAGE_BUFFER_BIT,
                          vk::MemoryUse::upload, "test samples");
        buffer.write(samples.data(), samples.size() * sizeof(glm::vec4));
        return buffer;
    }
};

SceneDocument scene_of(const json& patch) {
    json base = {{"image", {{"width", 48}, {"height", 32}}}, {"volume", {{"resolution", 32}}}, {"photons", {{"count", 4096}}}};
    base.merge_patch(patch);
    return protocol::parse_scene(base);
}

TEST_F(TemporalTest, AStillCameraAccumulatesToTheRefinedStillsBytes) {
    const SceneDocument doc = scene_of(json::object());
    scene::SceneGpu refined(kit()), frames(kit());
    refined.run(scene::kAllPasses, doc, worlds(doc), nullptr);
    frames.run(scene::kAllPasses, doc, worlds(doc), nullptr);
    scene::TemporalHistory history(kit());
    history.add(frames.hdr_buffer(), 48, 32, doc, true);
    for (uint32_t s = 1; s < scene::kMaxViewSamples; ++s) {
        scene::RunOptions refine;
        refine.view_sample = s;
        refined.run(scene::kView | scene::kToneMap, doc, worlds(doc), nullptr, refine);
        scene::RunOptions jittered;
        jittered.view_jitter = history.next_jitter();
        ASSERT_EQ(jittered.view_jitter, s);
        frames.run(scene::kView | scene::kToneMap, doc, worlds(doc), nullptr, jittered);
        history.add(frames.hdr_buffer(), 48, 32, doc, true);
    }
    const auto expected = refined.read_hdr();
    const auto accumulated = history.read_radiance();
    ASSERT_EQ(accumulated.size(), expected.size());
    size_t differing = 0;
    for (size_t i = 0; i < expected.size(); ++i)
        differing += std::memcmp(&expected[i], &accumulated[i], 3 * sizeof(float)) != 0;
    EXPECT_EQ(differing, 0u);
    EXPECT_EQ(accumulated[0].w, static_cast<float>(scene::kMaxViewSamples));
    EXPECT_EQ(history.read_ldr(), refined.read_ldr());
}

// A camera looking down -z at the plane z = 0, whose radiance is linear in x and y there: bilinear
// reprojection reproduces a linear function exactly, so a history reprojected right matches the
// pattern to float rounding, and one left in place is off by the gradient times the motion.
struct PlaneView {
    SceneDocument doc;
    shaders::TemporalCamera camera;
};

PlaneView plane_view(double x, double y, uint32_t width, uint32_t height) {
    const SceneDocument doc = scene_of({{"image", {{"width", width}, {"height", height}}},
                                        {"camera", {{"position", {x, y, 5.0}}, {"target", {x, y, 0.0}}, {"up", {0, 1, 0}}}}});
    return {doc, scene::pinhole_camera(doc.camera)};
}

glm::vec3 pattern(glm::vec3 point) { return glm::vec3(0.5f + 0.1f * point.x, 0.5f + 0.1f * point.y, 0.25f); }

// What the camera sees of the plane at sub-pixel offset `jitter`; pixels with x below `near_columns`
// see instead a red square 2.5 m from the eye.
std::vector<glm::vec4> plane_samples(const PlaneView& view, glm::vec2 jitter, uint32_t near_columns = 0) {
    const auto& c = view.camera;
    const uint32_t width = view.doc.image.width, height = view.doc.image.height;
    std::vector<glm::vec4> samples(size_t{width} * height);
    for (uint32_t y = 0; y < height; ++y)
        for (uint32_t x = 0; x < width; ++x) {
            const glm::vec2 q = glm::vec2(x, y) + 0.5f + jitter;
            const float aspect = static_cast<float>(width) / static_cast<float>(height);
            const glm::vec2 ndc = glm::vec2((2.0f * q.x / static_cast<float>(width) - 1.0f) * aspect,
                                            1.0f - 2.0f * q.y / static_cast<float>(height)) * c.position.w;
            const glm::vec3 d = glm::normalize(glm::vec3(c.forward) + ndc.x * glm::vec3(c.right) + ndc.y * glm::vec3(c.up));
            const float t = -c.position.z / d.z;
            samples[size_t{y} * width + x] =
                x < near_columns ? glm::vec4(0.9f, 0.1f, 0.1f, 1.0f / (0.5f * t)) : glm::vec4(pattern(glm::vec3(c.position) + t * d), 1.0f / t);
        }
    return samples;
}

TEST_F(TemporalTest, AKnownCameraMotionReprojectsAKnownPatternAndWhatItUncoversTakesTheNewSamples) {
    const PlaneView before = plane_view(0.0, 0.0, 64, 48), after = plane_view(0.3, 0.1, 64, 48);
    scene::TemporalHistory history(kit());
    history.add(upload(plane_samples(before, passes::view_sample_offset(history.next_jitter()))), 64, 48, before.doc, true);
    const uint32_t near_columns = 8;
    const auto now = plane_samples(after, passes::view_sample_offset(history.next_jitter()), near_columns);
    history.add(upload(now), 64, 48, after.doc, true);
    const auto blended = history.read_radiance();
    const auto centred = plane_samples(after, glm::vec2(0.0f));  // the pattern at the pixel centres
    double worst_kept = 0.0, worst_in_place = 0.0;
    size_t uncovered_blended = 0, kept = 0;
    for (uint32_t y = 0; y < 48; ++y)
        for (uint32_t x = 0; x < 64; ++x) {
            const size_t i = size_t{y} * 64 + x;
            if (x < near_columns) {
                // Nearer than anything the history saw there: disoccluded, the new sample alone.
                uncovered_blended += glm::vec3(blended[i]) != glm::vec3(now[i]) || blended[i].w != 1.0f;
                continue;
            }
            if (blended[i].w < 2.0f) continue;  // outside the view before: nothing to reproject
            // The image's edge: its samples' neighbourhood is one-sided there, and the clamp may move a
            // history the jitter put outside it.
            if (x == 63 || y == 0 || y == 47) continue;
            ++kept;
            // The history at the pixel centre and the sample at its jittered point, averaged.
            const glm::vec3 expected = 0.5f * (glm::vec3(centred[i]) + glm::vec3(now[i]));
            worst_kept = std::max(worst_kept, static_cast<double>(glm::length(glm::vec3(blended[i]) - expected)));
            const glm::vec3 in_place = pattern(glm::vec3(0.0f)) + glm::vec3(centred[i]) - pattern(glm::vec3(0.3f, 0.1f, 0.0f));
            worst_in_place = std::max(worst_in_place, static_cast<double>(glm::length(0.5f * (in_place + glm::vec3(now[i])) - expected)));
        }
    EXPECT_GT(kept, size_t{64 * 48 / 2});
    EXPECT_EQ(uncovered_blended, 0u);
    // Float rounding of directions and depths (about 1e-6 relative) times the pattern's scale.
    EXPECT_LT(worst_kept, 1e-4);
    // Left in place the history would be off by half the gradient times the motion: 0.5 x 0.1 x |(0.3, 0.1)|.
    EXPECT_GT(worst_in_place, 0.01);
}

TEST_F(TemporalTest, TheHistoryStartsOverOnEditsThatAreNotCameraLightOrExposureMoves) {
    const SceneDocument doc = scene_of(json::object());
    std::vector<glm::vec4> sky(48 * 32, glm::vec4(0.2f, 0.3f, 0.4f, 0.0f));
    const vk::Buffer samples = upload(sky);
    scene::TemporalHistory history(kit());
    auto counted = [&](const SceneDocument& shown, bool view_ran = true) {
        history.add(samples, 48, 32, shown, view_ran);
        return history.read_radiance()[16 * 48 + 24].w;  // a pixel in the middle
    };
    EXPECT_EQ(counted(doc), 1.0f);
    EXPECT_EQ(counted(doc), 2.0f);
    // A moved camera reprojects the sky's directions through bilinear weights: counts to float rounding.
    EXPECT_NEAR(counted(protocol::apply_merge_patch(doc, {{"camera", {{"position", {0.1, 1.0, 5.0}}}}})), 3.0f, 1e-5f);
    const SceneDocument lit = protocol::apply_merge_patch(doc, {{"light", {{"position", {-2, 3, 1}}}}});
    EXPECT_NEAR(counted(lit), 4.0f, 1e-5f);  // at kMovingHistorySamples while anything moves
    // Nothing moved since: counting on towards kStillHistorySamples.
    const SceneDocument exposed = protocol::apply_merge_patch(lit, {{"image", {{"exposure", 1.0}}}});
    EXPECT_NEAR(counted(exposed), 5.0f, 1e-5f);
    EXPECT_NEAR(counted(exposed, false), 5.0f, 1e-5f);  // re-toned only
    EXPECT_EQ(counted(protocol::apply_merge_patch(doc, {{"medium", {{"extinction", {0.3, 0.3, 0.3}}}}})), 1.0f);
    EXPECT_EQ(counted(protocol::apply_merge_patch(doc, {{"object", {{"ior", 1.3}}}})), 1.0f);
    EXPECT_EQ(counted(protocol::apply_merge_patch(doc, {{"object", {{"ior", 1.3}}}})), 2.0f);
}

TEST_F(TemporalTest, AViewersInteractiveFramesComeAtItsSizeStartingFromTheStillBefore) {
    const SceneDocument doc = scene_of({{"image", {{"width", 96}, {"height", 64}}}});
    scene::Renderer renderer(context()), fresh(context());
    const scene::Assets none;
    renderer.render("a", doc, none);
    scene::FrameOptions interactive{scene::Quality::interactive};
    interactive.history = "viewer";
    // An exposure edit re-tones the history the still seeded: the still's bytes at the new exposure.
    const auto exposed = protocol::apply_merge_patch(doc, {{"image", {{"exposure", 1.0}}}});
    const scene::FrameResult toned = renderer.render("a", exposed, none, interactive);
    EXPECT_EQ(toned.rerun, scene::kToneMap);
    EXPECT_EQ(toned.png, fresh.render("b", exposed, none).png);
    // A camera drag's frames: the viewer's size, whatever size the budget traces.
    for (double x : {0.05, 0.1, 0.15}) {
        const scene::FrameResult moved =
            renderer.render("a", protocol::apply_merge_patch(exposed, {{"camera", {{"position", {x, 1.0, 5.0}}}}}), none, interactive);
        EXPECT_EQ(moved.width, 96u);
        EXPECT_EQ(moved.height, 64u);
        uint32_t width = 0, height = 0;
        image::decode_png(moved.png, width, height);
        EXPECT_EQ(width, 96u);
    }
}

}  // namespace
}  // namespace refract
