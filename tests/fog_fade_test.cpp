// The fog's box boundary (medium.fade): the medium's density falls smoothly to 0 at the grid's faces, so
// the lit fog's box no longer shows as a hard edge. Measured as the box's edge contrast in a frame, against
// the step the fade's smoothstep allows; and the density's parameters as the host derives them.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include <glm/glm.hpp>
#include <nlohmann/json.hpp>

#include "gpu_fixture.h"
#include "passes/grid_geometry.h"
#include "render/renderer.h"
#include "render/transport_inputs.h"

namespace refract {
namespace {

using nlohmann::json;
using protocol::SceneDocument;

class FogFadeTest : public refract::testing::GpuTest {};

double luminance(const glm::vec4& c) {
    return 0.2126 * static_cast<double>(c.r) + 0.7152 * static_cast<double>(c.g) + 0.0722 * static_cast<double>(c.b);
}

// Fog (sigma_s = sigma_t = 0.05 / m, isotropic) filling the grid box [-1, 1]^3 (64^3 voxels, h = 1/32 m),
// lit from straight above by a directional light, and seen face-on from 60 m away: a nearly orthographic
// view, in which every eye ray through the front face crosses the box's whole depth and one just beside
// it crosses none, so without a fade the box's side faces are a step of the full contrast between one
// pixel and the next (the perspective spreads it over about 1.5 pixels). The object is the medium itself
// (its index and coefficients), below the rows measured. Its light then never bends: the direct light in
// closed form is all of it, so the frame has no photon noise.
json fog_box_scene(double fade) {
    const json sigma = {0.05, 0.05, 0.05}, isotropic = {{"model", "isotropic"}, {"g", 0}};
    return {
        {"camera", {{"position", {0.0, 0.0, 60.0}}, {"target", {0.0, 0.0, 0.0}}, {"fov_deg", 1.34}}},
        {"image", {{"width", 128}, {"height", 64}}},
        {"light", {{"type", "directional"}, {"direction", {0.0, -1.0, 0.0}}, {"intensity", 10.0}}},
        {"object", {{"mesh", "sphere"}, {"position", {0.0, -0.7, 0.0}}, {"scale", 0.2}, {"ior", 1.0},
                    {"extinction", sigma}, {"scattering", sigma}, {"phase", isotropic}}},
        {"medium", {{"ior", 1.0}, {"extinction", sigma}, {"scattering", sigma}, {"phase", isotropic}, {"fade", fade}}},
        {"volume", {{"resolution", 64}, {"bounds", {{"min", {-1, -1, -1}}, {"max", {1, 1, 1}}}}}},
        {"photons", {{"count", 1 << 14}, {"seed", 3}}},
        {"floor", {{"enabled", false}}},
    };
}

struct EdgeContrast {
    double contrast;   // the plateau's luminance over the background's
    double left, right;  // the largest step between neighbouring pixels across each side face, over the contrast
};

// The mean luminance of the middle rows (|y| < 0.35 m: neither the object nor the top and bottom faces'
// fade), column by column; the plateau is the middle columns' mean, the background the outer five's.
EdgeContrast edge_contrast(const std::vector<glm::vec4>& hdr, uint32_t width, uint32_t height) {
    std::vector<double> column(width, 0.0);
    const uint32_t first = height / 2 - 8, last = height / 2 + 8;
    for (uint32_t y = first; y < last; ++y)
        for (uint32_t x = 0; x < width; ++x) column[x] += luminance(hdr[size_t{y} * width + x]) / (last - first);
    double plateau = 0.0, background = 0.0;
    for (uint32_t x = width / 2 - 10; x < width / 2 + 10; ++x) plateau += column[x] / 20.0;
    for (uint32_t x = 0; x < 5; ++x) background += (column[x] + column[width - 1 - x]) / 10.0;
    EdgeContrast e{plateau - background, 0.0, 0.0};
    for (uint32_t x = 0; x + 1 < width; ++x) {
        const double step = std::abs(column[x + 1] - column[x]) / e.contrast;
        double& side = x < width / 2 ? e.left : e.right;
        side = std::max(side, step);
    }
    return e;
}

// The derived bound. An eye ray parallel to a side face at distance s from it (s < the fade w) meets the
// density S(s / w) (S the smoothstep 3u^2 - 2u^3) except within s of the front and back faces, where the
// nearer face's fade takes over; over the box's depth D its density integrates to
// I(s) = 2 int_0^s S(u / w) du + (D - 2 s) S(s / w), against I = D - w on the plateau. dI/ds =
// (D - 2 s) S'(s / w) / w is largest at s = w / 2, where it is (D - w) 1.5 / w: the profile, relative to
// the plateau, rises by at most 1.5 / w per metre. In an optically thin medium (here 0.1 across the box)
// a pixel's luminance is affine in I, so neighbouring pixels differ by at most 1.5 p / w of the contrast,
// p the pixel's width (taken at the front face, the widest the step can be); the medium's 10% optical
// depth bends that affine relation by at most 5%, and the perspective (rays diverge by 1/60) only blurs.
TEST_F(FogFadeTest, BoxEdgeContrastIsTheStepTheFadesSmoothstepLeaves) {
    constexpr double kFade = 0.25;  // metres: 8 voxels
    scene::SceneGpu gpu(kit());
    const SceneDocument today = protocol::parse_scene(fog_box_scene(0.0));
    gpu.run(scene::kAllPasses, today, worlds(today), nullptr);
    const auto& p = gpu.params();
    const EdgeContrast hard = edge_contrast(gpu.read_hdr(), p.image.x, p.image.y);

    const SceneDocument faded = protocol::parse_scene(fog_box_scene(kFade));
    gpu.run(scene::kAllPasses, faded, worlds(faded), nullptr);
    const EdgeContrast soft = edge_contrast(gpu.read_hdr(), p.image.x, p.image.y);

    const double aspect = static_cast<double>(p.image.x) / p.image.y;
    const double pixel = 2.0 * aspect * static_cast<double>(p.camera_position.w) * 59.0 / p.image.x;  // metres at the front face
    const double bound = 1.5 * pixel / kFade * 1.05;
    std::printf("  box edge contrast (largest pixel step / contrast): no fade %.3f | %.3f, fade %.2f m %.3f | %.3f "
                "(bound %.3f); contrast %.4f and %.4f\n",
                hard.left, hard.right, kFade, soft.left, soft.right, bound, hard.contrast, soft.contrast);
    ASSERT_GT(hard.contrast, 0.01);
    ASSERT_GT(soft.contrast, 0.01);
    // Without a fade the side faces are a step of most of the contrast: the measure sees the edge.
    EXPECT_GT(hard.left, 0.5);
    EXPECT_GT(hard.right, 0.5);
    EXPECT_LE(soft.left, bound);
    EXPECT_LE(soft.right, bound);
    // The fade thins only the margin: the plateau keeps the medium's (D - w) / D of the unfaded contrast,
    // within 2%.
    EXPECT_NEAR(soft.contrast / hard.contrast, (2.0 - kFade) / 2.0, 0.02);
}

// The density as the transport receives it: in voxels, at most a quarter of the grid's shortest side,
// none for a medium that neither scatters nor absorbs, and the bottom face left dense where the floor
// lies inside the grid.
TEST(FogFade, ParametersAreTheFadeInVoxelsClampedAndTheFloorHidesTheBottomFace) {
    const passes::GridGeometry grid{glm::vec3(-1.0f), 1.0f / 32.0f, {64, 64, 48}};
    auto fade_of = [&](const json& patch) {
        const SceneDocument d = protocol::apply_merge_patch(SceneDocument{}, patch);
        return scene::make_transport_params(d, grid, scene::TransportOptions{}).front().medium_fade;
    };
    const glm::vec4 standard = fade_of(json::object());
    EXPECT_FLOAT_EQ(standard.x, static_cast<float>(SceneDocument{}.medium.fade * 32.0));
    EXPECT_LT(standard.y, -1e29f);  // the default floor (y = -1) lies on the grid's bottom face
    EXPECT_FLOAT_EQ(fade_of({{"medium", {{"fade", 0.1}}}}).x, 3.2f);
    EXPECT_FLOAT_EQ(fade_of({{"medium", {{"fade", 1e4}}}}).x, 12.0f);  // a quarter of 48 voxels
    EXPECT_EQ(fade_of({{"medium", {{"fade", 0}}}}).x, 0.0f);
    EXPECT_EQ(fade_of({{"medium", {{"extinction", {0, 0, 0}}, {"scattering", {0, 0, 0}}}}}).x, 0.0f);
    EXPECT_EQ(fade_of({{"floor", {{"height", -1.5}}}}).y, 0.0f);
    EXPECT_EQ(fade_of({{"floor", {{"enabled", false}}}}).y, 0.0f);
}

}  // namespace
}  // namespace refract
