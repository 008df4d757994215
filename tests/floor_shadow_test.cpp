// The floor's shadow in closed form (transport.h, DIRECT_MODE_FLOOR_SHADOW): where the straight rays to
// a floor-map cell meet the object, the light's photons take nothing away from the floor there and the
// direct-light pass takes away what they would have on average. That changes which part of the floor
// map is random, not its expectation: the map's mean over photon seeds must be the one of the estimator
// where every photon takes its own flux away (the direct light left to the photons, which flags no
// cell), and its noise in the shadow must fall. Checked for a spot light (photons uniform in solid angle
// over its cone) and a directional one (uniform over a rectangle), each through the default scene's
// glass ball in fog at a light drag's photon count, and for the spot in clear air. Likewise photons
// traced only along the rays that may meet the object, against photons over the whole emitter.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include <nlohmann/json.hpp>

#include "gpu_fixture.h"
#include "render/scene_gpu.h"

namespace refract {
namespace {

using nlohmann::json;
using protocol::SceneDocument;

constexpr int kSeeds = 8;

struct FloorMaps {
    std::vector<std::vector<double>> change;  // per seed, per texel: the map's channel mean (W/m^2)
    std::vector<double> unobstructed;         // per texel: the analytic irradiance the map changes
    uint32_t side = 0;
    uint32_t traced = 0;  // the light's photons traced (of the last seed)
};

double channel_mean(const glm::vec4& v) {
    return (static_cast<double>(v.r) + static_cast<double>(v.g) + static_cast<double>(v.b)) / 3.0;
}

// How the floor map is estimated: the shadow in closed form or by every photon's removal, photons over
// the whole emitter or only its part whose rays may meet the object (RunOptions::photon_part).
struct Estimator {
    bool closed_form_shadow = true;
    bool photon_part = true;
};

class FloorShadowTest : public testing::GpuTest {
protected:
    static FloorMaps floor_maps(const json& j, Estimator estimator);
    static void expect_same_mean(const FloorMaps& a, const FloorMaps& b, const char* what);
    static void expect_same_mean_and_quieter_shadow(const json& scene, const char* light);
};

FloorMaps FloorShadowTest::floor_maps(const json& j, Estimator estimator) {
    FloorMaps maps;
    // Seeds of their own for each estimator, so that the two means are independent.
    const uint32_t first_seed =
        (estimator.closed_form_shadow ? 0u : 100u) + (estimator.photon_part ? 0u : 200u);
    for (int seed = 1; seed <= kSeeds; ++seed) {
        SceneDocument doc = protocol::parse_scene(j);
        doc.photons.seed = static_cast<uint32_t>(seed) + first_seed;
        scene::SceneGpu gpu(kit());
        scene::RunOptions options;
        // The direct light's pass is what flags the shadow's cells: without it every photon takes its
        // own flux away, the estimator before this one.
        options.direct_light = estimator.closed_form_shadow;
        options.photon_part = estimator.photon_part;
        gpu.run(scene::kAllPasses, doc, worlds(doc), nullptr, options);
        const auto change = gpu.read_floor_map();
        const auto irradiance = gpu.read_floor_irradiance();
        maps.side = gpu.floor_map_side();
        maps.traced = gpu.light_params().front().photon_info.x;
        std::vector<double> mean(change.size());
        maps.unobstructed.assign(change.size(), 0.0);
        for (size_t i = 0; i < change.size(); ++i) {
            mean[i] = channel_mean(change[i]);
            maps.unobstructed[i] = channel_mean(irradiance[i]) - mean[i];
        }
        maps.change.push_back(std::move(mean));
    }
    return maps;
}

// Mean and variance over the seeds of the sum of `values` over texels `texels`.
struct Moments {
    double mean = 0.0, variance = 0.0;
};
Moments moments(const std::vector<std::vector<double>>& per_seed, const std::vector<size_t>& texels) {
    std::vector<double> sums;
    for (const auto& map : per_seed) {
        double sum = 0.0;
        for (size_t i : texels) sum += map[i];
        sums.push_back(sum);
    }
    Moments m;
    for (double s : sums) m.mean += s / kSeeds;
    for (double s : sums) m.variance += (s - m.mean) * (s - m.mean) / (kSeeds - 1);
    return m;
}

// (difference of the two estimators' means)^2 over its estimated variance: a squared Welch t.
double squared_t(const Moments& a, const Moments& b) {
    return (a.mean - b.mean) * (a.mean - b.mean) / ((a.variance + b.variance) / kSeeds);
}

void FloorShadowTest::expect_same_mean(const FloorMaps& a_maps, const FloorMaps& b_maps, const char* what) {
    ASSERT_EQ(a_maps.side, b_maps.side);
    const uint32_t side = a_maps.side, block = std::max(1u, side / 16);

    // The same expectation, block by block: blocks of block^2 texels, each a squared t of the two
    // estimators' seed means. Under the same mean each follows a t distribution of about 7-14 degrees of
    // freedom (8 seeds a side): E[t^2] = v / (v - 2), at most 1.4, and the mean over 100 blocks or more
    // has a standard deviation under 0.3 (E[t^4] = 3 v^2 / ((v - 2)(v - 4)) at v = 7): 3 is five of them
    // above. A bias in the closed form's integral along the shadow's rim would show in the rim's blocks.
    double t2_sum = 0.0;
    size_t blocks = 0;
    std::vector<size_t> all;
    for (uint32_t by = 0; by < side; by += block)
        for (uint32_t bx = 0; bx < side; bx += block) {
            std::vector<size_t> texels;
            for (uint32_t y = by; y < std::min(side, by + block); ++y)
                for (uint32_t x = bx; x < std::min(side, bx + block); ++x) texels.push_back(size_t{y} * side + x);
            all.insert(all.end(), texels.begin(), texels.end());
            const Moments a = moments(a_maps.change, texels), b = moments(b_maps.change, texels);
            if (a.variance + b.variance <= 0.0) continue;  // no photon reached it in either
            t2_sum += squared_t(a, b);
            ++blocks;
        }
    const double total_t2 = squared_t(moments(a_maps.change, all), moments(b_maps.change, all));
    std::printf("%s: %zu blocks, mean t^2 %.2f; whole map t^2 %.2f\n", what, blocks,
                t2_sum / static_cast<double>(blocks), total_t2);
    ASSERT_GE(blocks, 100u);
    EXPECT_LT(t2_sum / static_cast<double>(blocks), 3.0);
    EXPECT_LT(total_t2, 16.0);  // four standard deviations
}

void FloorShadowTest::expect_same_mean_and_quieter_shadow(const json& scene, const char* light) {
    const FloorMaps closed = floor_maps(scene, {}),
                    photons = floor_maps(scene, {.closed_form_shadow = false});
    expect_same_mean(closed, photons, light);

    // Quieter in the shadow: texels the spot lights (a quarter of its brightest or more) whose light the
    // object takes mostly away (the photons' mean change under minus half of it). There the closed form
    // replaces the random removals, so the seed-to-seed variance, summed over those texels, must fall.
    const double brightest = *std::max_element(photons.unobstructed.begin(), photons.unobstructed.end());
    double closed_variance = 0.0, photons_variance = 0.0;
    size_t shadowed = 0;
    for (size_t i = 0; i < photons.unobstructed.size(); ++i) {
        const double lit = photons.unobstructed[i];
        const Moments p = moments(photons.change, {i});
        if (lit < 0.25 * brightest || p.mean > -0.5 * lit) continue;
        ++shadowed;
        photons_variance += p.variance;
        closed_variance += moments(closed.change, {i}).variance;
    }
    std::printf("%s: %zu texels in the shadow, variance there %.3g with the closed form against %.3g (%.2fx)\n", light,
                shadowed, closed_variance, photons_variance, closed_variance / photons_variance);
    ASSERT_GE(shadowed, 50u);
    EXPECT_LT(closed_variance, photons_variance);
}

const json kBase = {{"image", {{"width", 8}, {"height", 8}}},
                    {"volume", {{"resolution", 48}}},
                    {"photons", {{"count", 4096}}}};

TEST_F(FloorShadowTest, ASpotLightsShadowKeepsItsMeanAndLosesItsRemovalNoise) {
    expect_same_mean_and_quieter_shadow(kBase, "spot");
}

TEST_F(FloorShadowTest, ADirectionalLightsShadowKeepsItsMeanAndLosesItsRemovalNoise) {
    json scene = kBase;
    scene["light"] = {{"type", "directional"}, {"direction", {0.3, -1.0, -0.2}}, {"intensity", 3.0}};
    expect_same_mean_and_quieter_shadow(scene, "directional");
}

// A light's photons only along the rays that may meet the object (emit_photon_ray; the others go straight,
// their light in closed form): the floor map's mean is the whole emitter's photons', block by block, from
// fewer photons traced (the part's share of the document's count), and where the object changes the
// floor (its caustic and shadow: texels the whole emitter's photons change by a tenth of the brightest
// light or more) the variance is theirs, to the seeds' spread: the same photons land there (stratified
// over the part rather than the whole emitter: 1.15x measured, a count that is no power of two).
TEST_F(FloorShadowTest, PhotonsOnlyWhereTheObjectMayBendThemKeepTheFloorsMean) {
    json directional = kBase;
    directional["light"] = {{"type", "directional"}, {"direction", {0.3, -1.0, -0.2}}, {"intensity", 3.0}};
    for (const auto& [scene, light] : {std::pair{kBase, "spot"}, std::pair{directional, "directional"}}) {
        const FloorMaps part = floor_maps(scene, {}), whole = floor_maps(scene, {.photon_part = false});
        expect_same_mean(part, whole, light);
        const double brightest = *std::max_element(whole.unobstructed.begin(), whole.unobstructed.end());
        double part_variance = 0.0, whole_variance = 0.0;
        size_t changed = 0;
        for (size_t i = 0; i < whole.unobstructed.size(); ++i) {
            if (std::abs(moments(whole.change, {i}).mean) < 0.1 * brightest) continue;
            ++changed;
            whole_variance += moments(whole.change, {i}).variance;
            part_variance += moments(part.change, {i}).variance;
        }
        std::printf(
            "%s: %u photons traced of %u; %zu texels the object changes, variance there %.3g from the part "
            "against %.3g (%.2fx)\n",
            light, part.traced, whole.traced, changed, part_variance, whole_variance,
            part_variance / whole_variance);
        ASSERT_GE(changed, 50u);
        EXPECT_LT(part.traced, whole.traced * 9 / 10);
        EXPECT_LT(part_variance, 1.5 * whole_variance);
        EXPECT_GT(part_variance, whole_variance / 1.5);
    }
}

// Without fog the light is not in closed form (nothing scatters it), but the floor's shadow still is:
// the light map's runs are traced for it alone.
TEST_F(FloorShadowTest, InClearAirTheShadowKeepsItsMeanAndLosesItsRemovalNoise) {
    json scene = kBase;
    scene["medium"] = {{"extinction", {0.0, 0.0, 0.0}}, {"scattering", {0.0, 0.0, 0.0}}};
    expect_same_mean_and_quieter_shadow(scene, "clear air");
}

}  // namespace
}  // namespace refract
