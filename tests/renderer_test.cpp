// The renderer's bookkeeping: which passes an edit invalidates, reuse of resident state, eviction
// under the memory budget, and unrenderable scenes leaving others untouched.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "scene/passes.h"
#include "scene/renderer.h"
#include "vk/context.h"

namespace refract {
namespace {

using nlohmann::json;
using protocol::SceneDocument;
using namespace scene;

// Small scenes: the point here is bookkeeping, not pictures.
SceneDocument small(const json& patch = json::object()) {
    json base = {{"image", {{"width", 32}, {"height", 32}}},
                 {"volume", {{"resolution", 32}}},
                 {"photons", {{"count", 1024}}}};
    base.merge_patch(patch);
    return protocol::parse_scene(base);
}

TEST(Invalidation, EachEditRerunsExactlyWhatDependsOnIt) {
    const SceneDocument before = small();
    const struct {
        const char* what;
        json patch;
        PassSet expected;
    } cases[] = {
        {"camera", {{"camera", {{"position", {1, 1, 4}}}}}, kView},
        {"image size", {{"image", {{"width", 64}}}}, kView},
        {"exposure", {{"image", {{"exposure", 1.0}}}}, kView},
        {"object scattering", {{"object", {{"scattering", {0.01, 0.01, 0.01}}}}}, kView},
        {"phase", {{"medium", {{"phase", {{"model", "isotropic"}, {"g", 0.0}}}}}}, kView},
        {"floor look", {{"floor", {{"albedo", {0.5, 0.5, 0.5}}}}}, kView},
        {"light", {{"light", {{"position", {-2, 3, 1}}}}}, kPhotons | kView},
        {"photon count", {{"photons", {{"count", 2048}}}}, kPhotons | kView},
        {"extinction", {{"object", {{"extinction", {0.5, 0.5, 0.5}}}}}, kPhotons | kView},
        {"floor height", {{"floor", {{"height", -1.2}}}}, kPhotons | kView},
        {"octree epsilon", {{"volume", {{"octree_epsilon", 0.01}}}}, kOctree | kPhotons | kView},
        {"dispersion", {{"object", {{"abbe", 30}}}}, kOctree | kPhotons | kView},
        {"ior", {{"object", {{"ior", 1.33}}}}, kIndexField | kOctree | kPhotons | kView},
        {"index field kind", {{"object", {{"index_field", "luneburg"}}}}, kIndexField | kOctree | kPhotons | kView},
        {"mesh", {{"object", {{"mesh", "torus"}}}}, kAllPasses},
        {"object position", {{"object", {{"position", {0.1, 0, 0}}}}}, kAllPasses},
        {"resolution", {{"volume", {{"resolution", 48}}}}, kAllPasses},
        {"smoothing", {{"volume", {{"smoothing", 1.0}}}}, kAllPasses},
        {"nothing", json::object(), 0},
    };
    for (const auto& c : cases) {
        const SceneDocument after = protocol::apply_merge_patch(before, c.patch);
        EXPECT_EQ(pass_names(passes_invalidated(before, after)), pass_names(c.expected)) << c.what;
    }
    // Photons deposit only where something scatters: fog appearing in a clear scene, or the last of it
    // going, reruns them; changing how much it scatters does not.
    const json clear = {{"medium", {{"scattering", {0, 0, 0}}}}, {"object", {{"scattering", {0, 0, 0}}}}};
    const SceneDocument clear_scene = protocol::apply_merge_patch(before, clear);
    EXPECT_EQ(pass_names(passes_invalidated(clear_scene, before)), pass_names(kPhotons | kView));
    EXPECT_EQ(pass_names(passes_invalidated(before, clear_scene)), pass_names(kPhotons | kView));
}

class RendererTest : public ::testing::Test {
protected:
    void SetUp() override { context = std::make_unique<vk::Context>(vk::options_from_environment({})); }
    void TearDown() override { EXPECT_EQ(context->validation_error_count(), 0u) << context->last_validation_message(); }
    std::unique_ptr<vk::Context> context;
    Assets no_assets;
};

TEST_F(RendererTest, ResidentStateIsReusedAndOnlyStalePassesRun) {
    Renderer renderer(*context);
    const SceneDocument doc = small();
    EXPECT_EQ(renderer.render("a", doc, no_assets).rerun, kAllPasses);
    const auto camera = protocol::apply_merge_patch(doc, {{"camera", {{"position", {1, 1, 4}}}}});
    const FrameResult moved = renderer.render("a", camera, no_assets);
    EXPECT_EQ(moved.rerun, kView);
    ASSERT_EQ(moved.timings.size(), 2u);  // view and encode
    EXPECT_EQ(moved.timings[0].name, "view");
    const auto light = protocol::apply_merge_patch(camera, {{"light", {{"intensity", 5.0}}}});
    EXPECT_EQ(renderer.render("a", light, no_assets).rerun, kPhotons | kView);
    EXPECT_FALSE(renderer.render("a", light, no_assets).png.empty());
}

// Interactive frames deposit photons into a coarser radiance grid. With 4096 photons and a 32-pixel
// image the interactive document is the still one (nothing to halve or quarter), so only the grid's
// resolution differs: switching quality must still rerun photons and view, and the still frame after
// an interactive one must be the first still frame to the byte.
TEST_F(RendererTest, SwitchingQualityRerunsPhotonsIntoTheRightGrid) {
    Renderer renderer(*context);
    const SceneDocument doc = small({{"photons", {{"count", 4096}}}});
    const FrameResult still = renderer.render("a", doc, no_assets, Quality::still);
    const FrameResult interactive = renderer.render("a", doc, no_assets, Quality::interactive);
    EXPECT_EQ(interactive.rerun, kPhotons | kView);
    EXPECT_NE(interactive.png, still.png);
    const FrameResult again = renderer.render("a", doc, no_assets, Quality::still);
    EXPECT_EQ(again.rerun, kPhotons | kView);
    EXPECT_EQ(again.png, still.png);
    EXPECT_EQ(renderer.render("a", doc, no_assets, Quality::still).rerun, 0u);
}

// Extinction that differs by channel switches the resident scene from grey to coloured transport (a
// per-channel radiance grid appears), dispersion to dispersive transport (three paths per photon
// sample), and back: each frame must equal a fresh scene's frame of the same document, so nothing of
// another kind of transport is left behind.
TEST_F(RendererTest, SwitchingBetweenGreyColouredAndDispersiveTransportMatchesFreshScenes) {
    const SceneDocument grey = small({{"photons", {{"count", 4096}}}});
    const SceneDocument coloured =
        protocol::apply_merge_patch(grey, {{"medium", {{"extinction", {0.2, 0.3, 0.5}}}}});
    const SceneDocument dispersive = protocol::apply_merge_patch(grey, {{"object", {{"abbe", 20}}}});
    Renderer resident(*context);
    const FrameResult first = resident.render("a", grey, no_assets);
    const FrameResult switched = resident.render("a", coloured, no_assets);
    EXPECT_EQ(switched.rerun, kPhotons | kView);
    const FrameResult dispersed = resident.render("a", dispersive, no_assets);
    EXPECT_EQ(dispersed.rerun, kOctree | kPhotons | kView);
    const FrameResult back = resident.render("a", grey, no_assets);
    EXPECT_EQ(back.png, first.png);
    Renderer fresh(*context);
    EXPECT_EQ(fresh.render("b", coloured, no_assets).png, switched.png);
    EXPECT_EQ(fresh.render("c", dispersive, no_assets).png, dispersed.png);
    EXPECT_NE(switched.png, first.png);
    EXPECT_NE(dispersed.png, first.png);
    // Dragging a dispersive scene: sampled deposits into the coarse grid, adaptive pixels, three paths.
    const FrameResult dragged = fresh.render("c", dispersive, no_assets, Quality::interactive);
    EXPECT_EQ(dragged.rerun, kPhotons | kView);
    EXPECT_FALSE(dragged.png.empty());
}

TEST_F(RendererTest, MemoryBudgetDropsTheLeastRecentlyUsedScene) {
    const SceneDocument doc = small();
    RendererOptions options;
    // Room for one 32^3 scene but not two: one and a half times what one scene holds, as measured.
    int64_t one_scene = 0;
    {
        const int64_t before = context->allocated_bytes();
        Renderer measure(*context);
        measure.render("first", doc, no_assets);
        one_scene = context->allocated_bytes() - before;
    }
    ASSERT_GT(one_scene, 0);
    options.device_memory_budget = context->allocated_bytes() + one_scene * 3 / 2;
    Renderer renderer(*context, options);
    renderer.render("first", doc, no_assets);
    EXPECT_EQ(renderer.resident_scenes(), 1u);
    renderer.render("second", doc, no_assets);
    EXPECT_EQ(renderer.resident_scenes(), 1u);
    // "first" was dropped: rendering it again rebuilds everything.
    EXPECT_EQ(renderer.render("first", doc, no_assets).rerun, kAllPasses);
    // A scene that cannot fit even alone is refused with a reason.
    const auto huge = protocol::apply_merge_patch(doc, {{"volume", {{"resolution", 256}}}});
    EXPECT_THROW(renderer.render("huge", huge, no_assets), RenderError);
}

TEST_F(RendererTest, UnrenderableSceneLeavesOtherScenesResident) {
    Renderer renderer(*context);
    const SceneDocument doc = small();
    renderer.render("good", doc, no_assets);
    const auto missing = protocol::apply_merge_patch(doc, {{"object", {{"mesh", "upload:nowhere"}}}});
    EXPECT_THROW(renderer.render("good", missing, no_assets), RenderError);
    EXPECT_EQ(renderer.resident_scenes(), 1u);
    // The resident state is still the good scene's: an unchanged document reruns nothing.
    EXPECT_EQ(renderer.render("good", doc, no_assets).rerun, 0u);
}

}  // namespace
}  // namespace refract
