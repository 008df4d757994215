// Multiple scattering (photon random walks, photons.max_bounces) against references computed here:
// phase sampling against the phase functions it inverts, today's frames at 0 bounces, energy in a
// closed box, a slab's diffuse reflectance and transmittance against a CPU Monte Carlo written below,
// and the diffusion limit far from a point source. Tolerances are derived beside each check.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <numeric>
#include <random>
#include <vector>

#include "gpu_fixture.h"
#include "phase.h"
#include "render/renderer.h"

namespace refract {
namespace {

using nlohmann::json;
using shaders::PhotonExit;

constexpr double kPi = 3.14159265358979323846;

// ---------------------------------------------------------------------------------------------------
// Phase sampling (phase.h): a histogram of phase_sample_cos against the phase function's own mass in
// each bin (Simpson's rule over phase_value, which the sampler never calls).
TEST(PhaseSampling, DrawsEachPhaseFunction) {
    constexpr int kBins = 40;
    constexpr int kSamples = 400000;
    const std::pair<uint32_t, float> cases[] = {
        {PHASE_ISOTROPIC_ID, 0.0f}, {PHASE_HG_ID, 0.0f},      {PHASE_HG_ID, 1e-6f},
        {PHASE_HG_ID, 0.3f},        {PHASE_HG_ID, -0.5f},     {PHASE_HG_ID, 0.8f},
        {PHASE_HG_ID, 0.99f},       {PHASE_SCHLICK_ID, 0.0f}, {PHASE_SCHLICK_ID, 0.6f},
        {PHASE_SCHLICK_ID, -0.9f},  {PHASE_SCHLICK_ID, 0.99f}};
    for (const auto& [model, g] : cases) {
        std::vector<double> counts(size_t{kBins}, 0.0);
        // A stratified xi: each sample inverts the distribution at its own quantile, so the histogram is
        // the distribution's own up to the bin edges (no noise but the stratification's 1/kSamples).
        double mean_cos = 0.0;
        for (int i = 0; i < kSamples; ++i) {
            const float xi = (static_cast<float>(i) + 0.5f) / kSamples;
            const float mu = shaders::phase_sample_cos(model, g, xi);
            ASSERT_TRUE(mu >= -1.0f && mu <= 1.0f)
                << "model " << model << " g " << g << " xi " << xi << ": " << mu;
            counts[std::min(size_t{kBins - 1}, static_cast<size_t>((mu + 1.0f) * 0.5f * kBins))] += 1.0;
            mean_cos += static_cast<double>(mu);
        }
        mean_cos /= kSamples;
        double worst = 0.0;
        for (int b = 0; b < kBins; ++b) {
            const double lo = -1.0 + 2.0 * b / kBins, hi = lo + 2.0 / kBins;
            double mass = 0.0;
            // Simpson on each bin, fine enough for the sharpest peak: g = 0.99 narrows it to (1 - g)^2 / 2g
            // = 5e-5 in mu, 16 steps of 0.05 / 2^14.
            constexpr int kSteps = 1 << 14;
            for (int k = 0; k <= kSteps; ++k) {
                const double w = (k == 0 || k == kSteps) ? 1.0 : (k % 2 ? 4.0 : 2.0);
                mass += w * static_cast<double>(shaders::phase_value(
                                model, static_cast<float>(lo + (hi - lo) * k / kSteps), g));
            }
            mass *= (hi - lo) / (3.0 * kSteps) * 2.0 * kPi;  // the azimuth's 2 pi
            // Float rounding of mu near a bin edge moves a sample across it: a few samples per edge at
            // float's 6e-8 relative spacing times the density (at most kSamples x 2 pi p_max x 1.2e-7).
            const double tolerance = 4.0 / kSamples + 1e-6 * mass;
            const double share = counts[static_cast<size_t>(b)] / kSamples;
            worst = std::max(worst, std::abs(share - mass) / (tolerance + 1e-3 * mass));
            EXPECT_NEAR(share, mass, tolerance + 1e-3 * mass)
                << "model " << model << " g " << g << " bin " << b;
        }
        // The mean cosine of Henyey-Greenstein is g.
        if (model == PHASE_HG_ID) {
            EXPECT_NEAR(mean_cos, static_cast<double>(g), 2e-3);
        }
        std::printf("phase model %u g %.2f: mean cos %.4f, worst bin at %.2f of its tolerance\n", model,
                    static_cast<double>(g), mean_cos, worst);
    }
}

// ---------------------------------------------------------------------------------------------------
class ScatteringTest : public testing::GpuTest {
protected:
    struct Run {
        std::unique_ptr<scene::SceneGpu> gpu;
        std::vector<PhotonExit> exits;
        scene::RunStats stats;
    };

    Run photons(const protocol::SceneDocument& doc, bool exits = true) {
        Run r;
        r.gpu = std::make_unique<scene::SceneGpu>(kit());
        scene::RunOptions options;
        options.record_photon_exits = exits;
        options.limit = scene::kAllPasses & ~scene::kView;
        r.stats = r.gpu->run(scene::kAllPasses, doc, worlds(doc), nullptr, options);
        if (exits) r.exits = r.gpu->read_photon_exits();
        return r;
    }

    // Sum over the radiance grid of coefficient x fluence x voxel volume (W): the power a coefficient
    // takes from the light (absorbed for sigma_a, scattered for sigma_s).
    static double integral(const scene::SceneGpu& gpu, double coefficient) {
        const double h = gpu.grid().voxel_size;
        double sum = 0.0;
        for (const auto& v : gpu.read_radiance()) sum += static_cast<double>(v.r);
        return coefficient * sum * h * h * h;
    }

    // The slab's reflectance and transmittance against cpu_slab for each optical thickness and albedo.
    void check_slab(const char* what, double g, const nlohmann::json& phase);
};

// A homogeneous medium filling the grid up to its faces (no fade), index-matched everywhere (n = 1,
// straight lines): the object is the medium's twin, so coverage changes nothing.
json homogeneous(double extinction, double scattering, const json& phase, uint32_t bounces) {
    const json k = {extinction, extinction, extinction}, s = {scattering, scattering, scattering};
    return {{"medium", {{"ior", 1.0}, {"extinction", k}, {"scattering", s}, {"phase", phase}, {"fade", 0}}},
            {"object", {{"ior", 1.0}, {"extinction", k}, {"scattering", s}, {"phase", phase}}},
            {"floor", {{"enabled", false}}},
            {"image", {{"width", 8}, {"height", 8}}},
            {"photons", {{"max_bounces", bounces}}}};
}

// ---------------------------------------------------------------------------------------------------
// 0 bounces is today's transport, operation for operation (the walk is compiled out): frames hashed
// byte for byte against the same scenes rendered by the tree before random walks (07b9ff5: Fresnel
// reflection and thin films, which changed the frames of f1e490e; `refract
// render SCENE --hdr F.pfm [--quality interactive]` on lavapipe, Mesa 22.3 (Debian 12), FNV-1a 64 of
// the PFM's pixel data). Another device rounds differently: there the frames are only checked to
// repeat. A deliberate change to the frames regenerates the hashes the same way. Since then these changes
// moved them, none in what sets 0 bounces apart from the walks: the B-spline voxelizer (9a21bed, every
// scene's index field), eye rays taking faint reflections straight (FRESNEL_EYE_TRACED_SHARE), and the
// lattice's imprint taken out (docs/rendering.md, "Ring moire in caustics": the isotropic gradient, the
// photons' first shell step after a leaf, eye rays crossing unlit fog in whole view steps), and reflected eye
// paths gathering fog at twice the view step (FRESNEL_REFLECTED_VIEW_STEP; FresnelViewTest bounds what it
// moves against the photon noise; the absorbing scene, without fog, keeps its hashes), each the same
// with and without walks, the adaptive density estimate of interactive frames (radiance_spread.comp:
// the interactive hashes only; ViewTest.AdaptiveDensityKeepsTheGridsTotalAndQuietsSparsePhotons tests it),
// and the floor's checker and spot rims box-filtered over each pixel's footprint (the scenes with a floor;
// ViewTest.CheckerFloorIsBoxFilteredOverThePixelsFootprint, ViewTest.SpotRimOnTheFloorIsBoxFiltered...),
// and the medium fading at the grid's faces (medium.fade, on by default: the scenes with fog, default,
// ball_lens_fog and dispersion; FogFadeTest measures the box's edge, and
// ViewTest.SingleScatteringInAFadingMediumMatchesTheAirlightIntegral the light), where the default scene
// with a fade of 0 kept the hashes from before the fade, byte for byte, and still frames depositing
// sampled as interactive ones do (run_options_for: the still hashes of the scenes whose photons deposit,
// all but the absorbing one; EnergyTest.StillFramesDepositSampledWithinThePhotonNoise bounds what it moves
// against the photon noise), and reflected eye paths taken straight dimmed by the medium they cross
// (the still hashes of the scenes with fog, where faint reflections go straight; every interactive hash,
// since interactive frames take every reflection straight: FRESNEL_PREVIEW_TRACED_SHARE,
// FresnelViewTest.PreviewReflectionsGoStraightDimmedByTheMediumTheyCross), and the voxels the direct
// light's edge crosses taking its fluence once, at the mean of the points of theirs it reaches
// (direct_light.comp: the still hashes of the scenes with fog, the default's interactive ones; at most one
// level of an 8-bit pixel in the examples; EnergyTest.DirectLightMatchesPhotons), and the adaptive
// spread's shares summed as three box sums (radiance_spread.comp: the same terms in another order, every
// interactive hash but the absorbing scene's, which has no fog to spread), and the floor's shadow taken
// away in closed form where the photons' straight paths meet the object (direct_light.comp,
// DIRECT_MODE_FLOOR_SHADOW: the hashes of the scenes with a floor, default and absorbing; FloorShadowTest
// checks its mean against the photons' removals), and still frames filtering the floor that bent eye paths
// reach over where their neighbours' rays land (view.comp, neighbour_footprint: the still hashes of the
// scenes with a checker floor, default and absorbing; ViewTest.CheckerSeenThroughGlassIsFilteredOver...),
// and interactive frames spreading a lone floor hit to its neighbours (radiance_spread.comp: the
// interactive hashes of the scenes with a floor; ViewTest.FloorSpreadReachesOutFromLoneHitsAndKeeps...),
// and the floor's closed form taking each light's light through the medium, with photons tracing only
// the part of the emitter whose rays may meet the object (medium_transmittance, emit_photon_ray: the
// hashes of the scenes with a floor, default and absorbing; EnergyTest.ExtinctionFollowsBeerLambert,
// FloorShadowTest, EnergyTest.DirectLightMatchesPhotons), and the floor map read from a storage buffer
// and interpolated in the shader, no longer sampled from an image (eye_ray_ends.glsl, floor_map_at: the
// hashes of the scenes with a floor, default and absorbing; the same interpolation rounded otherwise, at
// most one level of an 8-bit pixel in 490 of the default's 370,000), and eye rays gathering through unlit
// fog rather than crossing it in cells of a lit pyramid (view.comp: the same zeros gathered, transmittance
// multiplied step by step rather than over the cell, so rounded otherwise: the still hashes of the scenes
// with fog, the ball lens's interactive one; in the ball lens example at 512^2, 424 pixels one 8-bit level
// apart, and 7 grazing rays at the ball's rim that enter the glass elsewhere by a rounding), and previews
// stepping a voxel of their own radiance grid through fog, not two lattice voxels (transport_inputs in
// frame_inputs.cpp: the interactive hashes of the scenes with fog; 0.36 8-bit RMS in the ball lens in fog
// at 256^2, its difference from the still the same), and every grid the transport reads (index field,
// coverage, volumes, fluence) interpolated in the shader from eight image loads, no longer by the sampler
// (trilinear.glsl: the same interpolation, rounded otherwise: every hash; photon and eye paths that graze
// glass go another way by a rounding, so the examples differ at glass outlines (the prism: 190 pixels
// over 10 levels) and by photon noise elsewhere, each within two seeds' difference but the prism's
// outline: ball lens 0.12 RMS against seeds' 0.16, two lamps 0.34 against 0.35, gallery 0.86 against 2.5),
// and lavapipe from Mesa 25.0 (bookworm-backports, scripts/install-deps.sh) instead of 22.3: the same
// shaders, a few values rounded otherwise (the default scene's still hashes; at 256^2, 29 of its 65,536
// pixels, in six small clusters on the checker floor, at most 3.4e-4 apart relative).
// The hashes are the frames of this tree on the lavapipe scripts/install-deps.sh installs.
uint64_t fnv1a_pfm_order(const std::vector<glm::vec4>& hdr, uint32_t width, uint32_t height) {
    uint64_t h = 0xcbf29ce484222325ull;
    for (uint32_t y = height; y-- > 0;)
        for (uint32_t x = 0; x < width; ++x)
            for (int c = 0; c < 3; ++c) {
                const float v = hdr[size_t{y} * width + x][c];
                const auto* bytes = reinterpret_cast<const unsigned char*>(&v);
                for (size_t i = 0; i < sizeof v; ++i) h = (h ^ bytes[i]) * 0x100000001b3ull;
            }
    return h;
}

TEST_F(ScatteringTest, ZeroBouncesRendersTodaysFramesByteForByte) {
    const json small = {{"image", {{"width", 96}, {"height", 96}}},
                        {"photons", {{"count", 16384}, {"max_bounces", 0}}},
                        {"volume", {{"resolution", 48}}}};
    json absorbing =
        json::parse(R"({"camera":{"position":[0.3,1.6,4.6],"target":[0.1,-0.35,0.0],"fov_deg":40},
        "image":{"exposure":-1},"light":{"type":"spot","position":[-1.8,4.2,-1.6],"direction":[1.8,-4.7,1.6],
        "color":[1.0,0.97,0.92],"intensity":45,"cone_deg":28},"object":{"mesh":"cube","scale":0.55,"position":[0.0,-0.2,0.0],
        "rotation_deg":[30,40,10],"ior":1.5,"extinction":[0.15,2.2,2.8],"scattering":[0.0,0.0,0.0]},
        "medium":{"extinction":[0.0,0.0,0.0],"scattering":[0.0,0.0,0.0]},"volume":{"smoothing":1.0,"margin":0.25},
        "floor":{"enabled":true,"height":-1.15,"albedo":[0.85,0.85,0.85],"checker":true,"checker_size":0.4}})");
    json ball_lens = json::parse(R"({"camera":{"position":[0.4,0.9,5.2],"target":[0.4,0.0,0.0],"fov_deg":42},
        "image":{"exposure":0},"light":{"type":"spot","position":[-2.2,0.0,0.0],"direction":[1,0,0],"color":[1.0,0.95,0.85],
        "intensity":110,"cone_deg":9},"object":{"mesh":"sphere","scale":0.6,"ior":1.5,"extinction":[0.02,0.02,0.02],
        "scattering":[0.0,0.0,0.0]},"medium":{"extinction":[0.25,0.25,0.25],"scattering":[0.24,0.24,0.24],
        "phase":{"model":"henyey-greenstein","g":0.2}},"volume":{"smoothing":0.75,"bounds":{"min":[-2.5,-2.6,-1.6],
        "max":[3.2,2.6,1.6]}},"floor":{"enabled":false}})");
    json dispersion = ball_lens;
    dispersion.merge_patch(
        json::parse(R"({"camera":{"position":[1.0,0.35,2.6],"target":[1.0,0.0,0.0],"fov_deg":40},
        "light":{"color":[1.0,1.0,1.0]},"object":{"ior":1.6,"abbe":6}})"));
    struct Case {
        const char* name;
        json doc;
        uint64_t still, interactive;
    };
    Case cases[] = {{"default", json::object(), 0xc3fc0bb3fd9cb893ull, 0x221ba4a8ddddc3c1ull},
                    {"default without fade", json::parse(R"({"medium": {"fade": 0}})"), 0xab6c1168fe4452a2ull,
                     0x7275dfd2099c1225ull},
                    {"absorbing", absorbing, 0x78c5ce0257409dddull, 0x7bb1cff56f730d27ull},
                    {"ball_lens_fog", ball_lens, 0x42a1a3936f7b403eull, 0xa24b7718fda01c95ull},
                    {"dispersion", dispersion, 0xec28b15d6787f07dull, 0x7c8f5c982a045032ull}};
    for (auto& c : cases) {
        c.doc.merge_patch(small);
        const auto doc = protocol::parse_scene(c.doc);
        for (const auto quality : {scene::Quality::still, scene::Quality::interactive}) {
            uint64_t hashes[2];
            for (auto& hash : hashes) {
                scene::SceneGpu gpu(kit());
                gpu.run(scene::kAllPasses, doc, worlds(doc), nullptr, scene::run_options_for(quality));
                hash = fnv1a_pfm_order(gpu.read_hdr(), gpu.width(), gpu.height());
            }
            const bool still = quality == scene::Quality::still;
            std::printf("%s (%s): frame hash %016llx\n", c.name, still ? "still" : "interactive",
                        static_cast<unsigned long long>(hashes[0]));
            EXPECT_EQ(hashes[0], hashes[1]) << c.name;
            if (context().is_cpu_device()) {
                EXPECT_EQ(hashes[0], still ? c.still : c.interactive)
                    << c.name << " on " << context().info().driver_info
                    << " (pinned for scripts/install-deps.sh's lavapipe)";
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------------
// Energy in a closed box: a directional beam into a 2 m cube of scattering medium (side optical depth
// 4), every wall absorbing what leaves. With a cap of b bounces, what the photons carry splits into:
// escaped (the exits' flux), absorbed (the integral of sigma_a x fluence) and the light scattered a
// (b+1)-th time, which the photon pass does not follow (the viewing pass turns its last order into single
// scattering): the integral of sigma_s x the order-b fluence. Walks capped at b and at b - 1 coincide up
// to the b-th collision (same random streams, same draws), so that fluence is their difference, nearly
// free of noise. At 0 bounces this is Beer-Lambert (emitted = escaped + integral of sigma_t x fluence).
TEST_F(ScatteringTest, EnergyIsConservedInAClosedBox) {
    const double E = 2.0, sigma_t = 2.0;
    for (const double albedo : {1.0, 0.9}) {
        const double sigma_s = albedo * sigma_t, sigma_a = sigma_t - sigma_s;
        double previous_fluence = 0.0;  // integral of fluence of the run capped one bounce lower
        for (const uint32_t bounces : {0u, 1u, 7u, 8u, 63u, 64u}) {
            json patch = homogeneous(sigma_t, sigma_s, {{"model", "isotropic"}}, bounces);
            patch.merge_patch(
                {{"light", {{"type", "directional"}, {"direction", {0, -1, 0}}, {"intensity", E}}},
                 {"photons", {{"count", 1 << 16}}},
                 {"volume", {{"resolution", 32}, {"bounds", {{"min", {-1, -1, -1}}, {"max", {1, 1, 1}}}}}}});
            const auto run = photons(protocol::parse_scene(patch));
            const double photon_flux = static_cast<double>(run.gpu->params().photon_flux.w);
            double emitted = 0.0, escaped = 0.0, stopped = 0.0;
            uint64_t most_bounces = 0, all_bounces = 0;
            for (const auto& e : run.exits) {
                if (e.entry.w != 1.0f) continue;
                emitted += photon_flux;
                all_bounces += static_cast<uint64_t>(e.weight.w);
                const double carried =
                    photon_flux * static_cast<double>(e.weight.r + e.weight.g + e.weight.b) / 3.0;
                (e.position.w == 1.0f ? escaped : stopped) += carried;
                most_bounces = std::max(most_bounces, static_cast<uint64_t>(e.weight.w));
            }
            const double fluence = integral(*run.gpu, 1.0);
            const double absorbed = sigma_a * fluence;
            const double dropped = bounces == 0 ? sigma_s * fluence : sigma_s * (fluence - previous_fluence);
            previous_fluence = fluence;
            if (bounces == 7 || bounces == 63) continue;  // only the lower run of a pair
            const double balance = escaped + absorbed + dropped;
            std::printf(
                "closed box, albedo %.2f, %u bounces (most taken %llu): emitted %.5f W, escaped %.5f, "
                "absorbed "
                "%.5f, scattered past the cap %.5f, stopped with %.2e: balance %+.4f%%\n",
                albedo, bounces, static_cast<unsigned long long>(most_bounces), emitted, escaped, absorbed,
                dropped, stopped, 100.0 * (balance / emitted - 1.0));
            EXPECT_NEAR(emitted, E * 4.0, 1e-4 * E);  // every photon enters the top face: irradiance x area
            EXPECT_LE(most_bounces, bounces);
            EXPECT_EQ(run.stats.photon_scatterings, all_bounces);  // the benchmarks' bounces per photon
            // The issue's 1%: the escaped flux's own noise (at most the beam's flux times 1 / sqrt(2^16),
            // 0.4%, and less since most photons escape with their whole weight) fits well inside it, and
            // the closed-form direct light at voxel centres differs from the voxel mean of exp(-sigma_t
            // y) by (sigma_t h)^2 / 24 = 0.07%.
            EXPECT_NEAR(balance, emitted, 0.01 * emitted);
            // Non-absorbing: nothing is lost but what leaves and what scatters past the cap.
            if (albedo == 1.0) {
                EXPECT_LT(stopped, 1e-3 * emitted);
            }
        }
    }
}

// The same box with the medium fading over 0.3 m (4.8 voxels) at its faces (medium.fade), at 0 bounces:
// photons and the closed-form direct light thin out alike, so Beer-Lambert still balances, emitted =
// escaped + the integral of sigma_t x density x fluence, the density taken at voxel centres as the
// transport defines it (TransportParams::medium_fade), within the same 1% (the voxel's mean density
// differs from its centre's by at most h^2 / 24 x 6 / w^2 = 1% in the margin, and by as much of either
// sign across it; measured 0.2%). Light that runs down the thin fog along the side faces goes deep:
// the same integral without the density is twice the light.
TEST_F(ScatteringTest, EnergyIsConservedInAClosedBoxWhoseMediumFades) {
    const double E = 2.0, sigma_t = 2.0;
    json patch = homogeneous(sigma_t, sigma_t, {{"model", "isotropic"}}, 0);
    patch.merge_patch({{"light", {{"type", "directional"}, {"direction", {0, -1, 0}}, {"intensity", E}}},
                       {"photons", {{"count", 1 << 16}}},
                       {"medium", {{"fade", 0.3}}},
                       {"volume", {{"resolution", 32}, {"bounds", {{"min", {-1, -1, -1}}, {"max", {1, 1, 1}}}}}}});
    const auto run = photons(protocol::parse_scene(patch));
    const auto& p = run.gpu->params();
    ASSERT_EQ(p.radiance_grid.w, 1u);
    const double photon_flux = static_cast<double>(p.photon_flux.w);
    double emitted = 0.0, escaped = 0.0;
    for (const auto& e : run.exits) {
        if (e.entry.w != 1.0f) continue;
        emitted += photon_flux;
        if (e.position.w == 1.0f) escaped += photon_flux * static_cast<double>(e.weight.r + e.weight.g + e.weight.b) / 3.0;
    }
    const double fade = static_cast<double>(p.medium_fade.x), bottom = static_cast<double>(p.medium_fade.y);
    ASSERT_GT(fade, 4.0);
    const glm::dvec3 dims(p.grid_dims.x, p.grid_dims.y, p.grid_dims.z);
    const auto radiance = run.gpu->read_radiance();
    double faded = 0.0, uniform = 0.0;
    for (uint32_t z = 0; z < p.grid_dims.z; ++z)
        for (uint32_t y = 0; y < p.grid_dims.y; ++y)
            for (uint32_t x = 0; x < p.grid_dims.x; ++x) {
                const glm::dvec3 c = glm::dvec3(x, y, z) + 0.5;
                const glm::dvec3 below = c - glm::dvec3(0.0, bottom, 0.0), above = dims - c;
                const double nearest = std::min({below.x, below.y, below.z, above.x, above.y, above.z});
                const double u = std::clamp(nearest / fade, 0.0, 1.0);
                const double fluence = static_cast<double>(radiance[(size_t{z} * p.grid_dims.y + y) * p.grid_dims.x + x].r);
                faded += u * u * (3.0 - 2.0 * u) * fluence;
                uniform += fluence;
            }
    const double h = run.gpu->grid().voxel_size;
    const double balance = escaped + sigma_t * faded * h * h * h, without = escaped + sigma_t * uniform * h * h * h;
    std::printf("closed box, fading medium: emitted %.5f W, escaped %.5f, extinguished %.5f: balance %+.4f%% "
                "(%+.4f%% without the density)\n",
                emitted, escaped, balance - escaped, 100.0 * (balance / emitted - 1.0), 100.0 * (without / emitted - 1.0));
    EXPECT_NEAR(emitted, E * 4.0, 1e-4 * E);
    EXPECT_NEAR(balance, emitted, 0.01 * emitted);
    EXPECT_GT(without / emitted - 1.0, 0.5);
}

// Interactive frames take at most kInteractiveBounces of the document's bounces; a frame that takes
// more (the still frame after a drag, on the same resident scene) retraces its photons with all of them,
// though nothing else about the photons changed.
TEST_F(ScatteringTest, InteractiveFramesCapTheBounces) {
    EXPECT_EQ(scene::run_options_for(scene::Quality::interactive).bounce_cap, scene::kInteractiveBounces);
    EXPECT_EQ(scene::run_options_for(scene::Quality::still).bounce_cap, protocol::kMaxBounces);
    json patch = homogeneous(8.0, 8.0, {{"model", "isotropic"}}, 64);
    patch.merge_patch(
        {{"light", {{"type", "directional"}, {"direction", {0, -1, 0}}, {"intensity", 1.0}}},
         {"photons", {{"count", 4096}}},
         {"volume", {{"resolution", 32}, {"bounds", {{"min", {-1, -1, -1}}, {"max", {1, 1, 1}}}}}}});
    const auto doc = protocol::parse_scene(patch);
    scene::SceneGpu gpu(kit());
    for (const uint32_t cap : {scene::kInteractiveBounces, protocol::kMaxBounces}) {
        auto options = scene::run_options_for(scene::Quality::still);
        options.bounce_cap = cap;
        options.record_photon_exits = true;
        options.limit = scene::kAllPasses & ~scene::kView;
        const auto stats = gpu.run(scene::kView, doc, worlds(doc), nullptr, options);
        EXPECT_TRUE(stats.ran & scene::kPhotons) << "cap " << cap;
        float most = 0.0f;
        for (const auto& e : gpu.read_photon_exits()) most = std::max(most, e.weight.w);
        std::printf("bounce cap %u: at most %.0f bounces of the document's 64\n", cap,
                    static_cast<double>(most));
        // A cube of side optical depth 16 keeps nearly every photon scattering past 4 bounces.
        EXPECT_EQ(static_cast<uint32_t>(most), std::min(cap, 64u));
    }
}

// ---------------------------------------------------------------------------------------------------
// An independent reference for the slab: analog Monte Carlo on the CPU, in double precision, with its
// own Henyey-Greenstein inversion (the usual form of OPTICS.md): a photon enters the top face of the box
// [lo, hi] going down, flies exp(sigma_t) free paths, is absorbed with probability 1 - albedo at each
// collision or scatters, and is tallied by the face it leaves through (the bottom only once scattered:
// diffuse transmittance).
struct SlabTally {
    double reflected = 0.0, transmitted = 0.0;        // fractions of the photons
    double se_reflected = 0.0, se_transmitted = 0.0;  // their standard errors
};

// One layer of the slab: its extinction (per metre) and albedo.
struct Layer {
    double sigma_t, albedo;
};

// The slab is `above` over y = split and `below` under it (the same layer twice: one homogeneous slab).
SlabTally cpu_slab(glm::dvec3 lo, glm::dvec3 hi, Layer above, Layer below, double split, double g,
                   int photons, uint32_t seed) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> uniform(0.0, 1.0);
    int up = 0, down = 0;
    for (int i = 0; i < photons; ++i) {
        glm::dvec3 p(lo.x + (hi.x - lo.x) * uniform(rng), hi.y, lo.z + (hi.z - lo.z) * uniform(rng));
        glm::dvec3 d(0.0, -1.0, 0.0);
        for (bool scattered = false;; scattered = true) {
            // A free path: an optical depth, spent layer by layer along d until it runs out or the photon
            // leaves the box.
            double depth = -std::log(1.0 - uniform(rng));
            bool left = false;
            double albedo = 0.0;
            for (;;) {
                const bool upper = p.y > split || (p.y == split && d.y > 0.0);
                const Layer& layer = upper ? above : below;
                double exit = 1e300;
                for (int a = 0; a < 3; ++a) {
                    if (d[a] > 0.0) exit = std::min(exit, (hi[a] - p[a]) / d[a]);
                    if (d[a] < 0.0) exit = std::min(exit, (lo[a] - p[a]) / d[a]);
                }
                double to_split = 1e300;
                if (upper && d.y < 0.0) to_split = (p.y - split) / -d.y;
                if (!upper && d.y > 0.0) to_split = (split - p.y) / d.y;
                const double run = std::min(exit, to_split);
                if (depth < layer.sigma_t * run) {
                    p += d * (depth / layer.sigma_t);
                    albedo = layer.albedo;
                    break;
                }
                depth -= layer.sigma_t * run;
                if (exit <= to_split) {
                    const glm::dvec3 q = p + d * exit;
                    const double to_top = hi.y - q.y, to_bottom = q.y - lo.y;
                    const double to_side = std::min({q.x - lo.x, hi.x - q.x, q.z - lo.z, hi.z - q.z});
                    if (to_top < to_side && to_top <= to_bottom) {
                        ++up;
                    } else if (to_bottom < to_side && scattered) {
                        ++down;
                    }
                    left = true;
                    break;
                }
                p += d * to_split;
                p.y = split;
            }
            if (left) break;
            if (uniform(rng) >= albedo) break;
            double mu;
            const double xi = uniform(rng);
            if (g == 0.0) {
                mu = 2.0 * xi - 1.0;
            } else {
                const double f = (1.0 - g * g) / (1.0 - g + 2.0 * g * xi);
                mu = (1.0 + g * g - f * f) / (2.0 * g);
            }
            const double phi = 2.0 * kPi * uniform(rng);
            // A frame around d.
            const glm::dvec3 a = std::abs(d.x) < 0.9 ? glm::dvec3(1, 0, 0) : glm::dvec3(0, 1, 0);
            const glm::dvec3 u = glm::normalize(glm::cross(d, a)), v = glm::cross(d, u);
            const double sine = std::sqrt(std::max(0.0, 1.0 - mu * mu));
            d = glm::normalize(mu * d + sine * (std::cos(phi) * u + std::sin(phi) * v));
        }
    }
    SlabTally t;
    const double n = photons;
    t.reflected = up / n;
    t.transmitted = down / n;
    t.se_reflected = std::sqrt(t.reflected * (1.0 - t.reflected) / n);
    t.se_transmitted = std::sqrt(t.transmitted * (1.0 - t.transmitted) / n);
    return t;
}

// Diffuse reflectance and transmittance of a plane-parallel slab (1 m thick, 4 m wide: the whole grid)
// under a collimated beam at normal incidence, n = 1 everywhere, against cpu_slab on the same box (its
// sides absorb what reaches them, as the grid's do). Transmittance is diffuse: the unscattered beam
// (exp(-tau)) is left out.
// The GPU's tallies of the same box: each photon's weight where it left, by face (the bottom only once
// scattered), with standard errors from the photons' own spread.
SlabTally gpu_slab(const std::vector<PhotonExit>& exits, glm::dvec3 lo, glm::dvec3 hi) {
    double sum[2] = {0, 0}, sum_sq[2] = {0, 0}, n = 0;
    for (const auto& e : exits) {
        if (e.entry.w != 1.0f) continue;
        n += 1.0;
        if (e.position.w != 1.0f) continue;
        const glm::dvec3 q(glm::vec3(e.position));
        const double w = static_cast<double>(e.weight.r + e.weight.g + e.weight.b) / 3.0;
        const double to_top = hi.y - q.y, to_bottom = q.y - lo.y;
        const double to_side = std::min({q.x - lo.x, hi.x - q.x, q.z - lo.z, hi.z - q.z});
        const int face = to_top < to_side && to_top <= to_bottom ? 0 : to_bottom < to_side ? 1 : -1;
        if (face < 0 || (face == 1 && e.weight.w == 0.0f)) continue;
        sum[face] += w;
        sum_sq[face] += w * w;
    }
    SlabTally t;
    t.reflected = sum[0] / n;
    t.transmitted = sum[1] / n;
    t.se_reflected = std::sqrt((sum_sq[0] / n - t.reflected * t.reflected) / n);
    t.se_transmitted = std::sqrt((sum_sq[1] / n - t.transmitted * t.transmitted) / n);
    return t;
}

// R and T within `systematic` (relative) plus 4 standard errors of the difference, which keep a false
// failure below 1e-4 per comparison.
void compare_slab(const char* what, const SlabTally& gpu, const SlabTally& cpu, double systematic,
                  double steps) {
    const double tol_r = systematic * cpu.reflected + 4.0 * std::hypot(gpu.se_reflected, cpu.se_reflected);
    const double tol_t =
        systematic * cpu.transmitted + 4.0 * std::hypot(gpu.se_transmitted, cpu.se_transmitted);
    std::printf("%s: R %.4f vs CPU %.4f (tolerance %.4f), T %.4f vs %.4f (%.4f); %.1f steps per photon\n",
                what, gpu.reflected, cpu.reflected, tol_r, gpu.transmitted, cpu.transmitted, tol_t, steps);
    EXPECT_NEAR(gpu.reflected, cpu.reflected, tol_r) << what;
    EXPECT_NEAR(gpu.transmitted, cpu.transmitted, tol_t) << what;
}

void ScatteringTest::check_slab(const char* what, double g, const json& phase) {
    constexpr int kPhotons = 1 << 16;
    for (const double tau : {0.5, 2.0, 8.0})
        for (const double albedo : {0.5, 0.9, 0.99}) {
            json patch = homogeneous(tau, albedo * tau, phase, protocol::kMaxBounces);
            patch.merge_patch(
                {{"light", {{"type", "directional"}, {"direction", {0, -1, 0}}, {"intensity", 1.0}}},
                 {"photons", {{"count", kPhotons}}},
                 {"volume",
                  {{"resolution", 64}, {"bounds", {{"min", {-2, -0.5, -2}}, {"max", {2, 0.5, 2}}}}}}});
            const auto run = photons(protocol::parse_scene(patch));
            const auto& grid = run.gpu->grid();
            const glm::dvec3 lo(grid.origin), hi(grid.max_corner());
            ASSERT_NEAR(hi.y - lo.y, 1.0, 1e-6);
            const SlabTally cpu = cpu_slab(lo, hi, {tau, albedo}, {tau, albedo}, 0.0, g, kPhotons, 7);
            char what_case[96];
            std::snprintf(what_case, sizeof what_case, "slab %s, tau %.1f, albedo %.2f", what, tau, albedo);
            // Both sample the same process exactly (a homogeneous medium: the walk's free paths are exact
            // exponentials, the CPU's too), so they differ by noise, plus float rounding of positions
            // (1e-7 of a path) and the walk's cap (1024 bounces: at albedo 0.99 a weight of 0.99^1024 =
            // 3e-5 would be left). 2% is the issue's allowance for anything systematic.
            compare_slab(what_case, gpu_slab(run.exits, lo, hi), cpu, 0.02,
                         run.stats.mean_steps_per_photon());
        }
}

TEST_F(ScatteringTest, SlabOfIsotropicScatterersMatchesMonteCarlo) {
    check_slab("isotropic", 0.0, {{"model", "isotropic"}});
}

TEST_F(ScatteringTest, SlabOfHenyeyGreensteinScatterersMatchesMonteCarlo) {
    check_slab("HG g=0.8", 0.8, {{"model", "henyey-greenstein"}, {"g", 0.8}});
}

// Where scattering changes and n does not (an index-matched object), the octree's leaves span the change:
// free paths must still see it. Two layers: thin fog (optical thickness 0.5, albedo 0.99) over a dense
// layer (8, albedo 0.9), the lower half of the grid filled by an index-matched cube (no smoothing: its
// faces lie on voxel boundaries, so coverage is 0 or 1 per voxel and the interface is one voxel of
// trilinear ramp), against cpu_slab with a sharp interface.
TEST_F(ScatteringTest, LayeredSlabWhereOnlyScatteringChangesMatchesMonteCarlo) {
    constexpr int kPhotons = 1 << 16;
    const Layer fog{1.0, 0.99}, dense{16.0, 0.9};
    const json phase = {{"model", "isotropic"}};
    json patch = homogeneous(fog.sigma_t, fog.sigma_t * fog.albedo, phase, protocol::kMaxBounces);
    patch.merge_patch(
        {{"object",
          {{"mesh", "cube"},
           {"scale", 2.5},
           {"position", {0, -2.5, 0}},
           {"extinction", {dense.sigma_t, dense.sigma_t, dense.sigma_t}},
           {"scattering", json::array({dense.sigma_t * dense.albedo, dense.sigma_t * dense.albedo,
                                       dense.sigma_t * dense.albedo})}}},
         {"light", {{"type", "directional"}, {"direction", {0, -1, 0}}, {"intensity", 1.0}}},
         {"photons", {{"count", kPhotons}}},
         {"volume",
          {{"resolution", 64},
           {"smoothing", 0.0},
           {"bounds", {{"min", {-2, -0.5, -2}}, {"max", {2, 0.5, 2}}}}}}});
    const auto run = photons(protocol::parse_scene(patch));
    const glm::dvec3 lo(run.gpu->grid().origin), hi(run.gpu->grid().max_corner());
    const SlabTally cpu = cpu_slab(lo, hi, fog, dense, 0.0, 0.0, kPhotons, 11);
    // The interface: one voxel (h = 1/16 m) where the GPU's coefficient ramps linearly between the
    // layers, symmetric about the CPU's sharp step (the same optical depth across it). It moves
    // collisions within that voxel by at most h / 2, against the dense layer's mean free path of h: the
    // share of light turned there is what changes, bounded by the collisions in that voxel (1 - e^-1
    // of what reaches it) times the half of them that move, times the layers' albedo difference and
    // direction: 3% of R and T as a systematic allowance, beside the noise.
    compare_slab("layered slab", gpu_slab(run.exits, lo, hi), cpu, 0.03, run.stats.mean_steps_per_photon());
}

// ---------------------------------------------------------------------------------------------------
// The infinite-medium limit: an isotropic point source of power P in a weakly absorbing, strongly
// scattering medium (albedo 0.99, isotropic phase). Far from the source (r >> 1 / sigma_t) diffusion
// theory gives fluence P exp(-sigma_eff r) / (4 pi D r), D = 1 / (3 (sigma_a + sigma_s')), sigma_eff =
// sqrt(sigma_a / D) (OPTICS.md); and whatever the theory, energy conservation (Gauss's theorem) says the
// net flux through the sphere of radius r is what the source emits less what is absorbed inside it:
// 4 pi r^2 F_r(r) = P - integral over r' < r of sigma_a fluence. That checks the directional store's
// net flux vector, the beam half of its split, for light scattered many times.
TEST_F(ScatteringTest, FluenceFarFromAPointSourceFollowsDiffusion) {
    const double sigma_s = 32.0, sigma_a = 0.32, sigma_t = sigma_s + sigma_a, intensity = 1.0;
    const double power = 4.0 * kPi * intensity;
    json patch = homogeneous(sigma_t, sigma_s, {{"model", "isotropic"}}, protocol::kMaxBounces);
    patch.merge_patch(
        {{"light", {{"type", "point"}, {"position", {0, 0, 0}}, {"intensity", intensity}}},
         {"photons", {{"count", 1 << 15}}},
         {"volume", {{"resolution", 64}, {"bounds", {{"min", {-1, -1, -1}}, {"max", {1, 1, 1}}}}}}});
    const auto run = photons(protocol::parse_scene(patch), false);
    const auto& grid = run.gpu->grid();
    const double h = grid.voxel_size;
    const auto radiance = run.gpu->read_radiance();
    const auto flux = run.gpu->read_flux();
    // Shells one voxel thick: mean fluence, radial net flux and radius of the voxels whose centres lie in
    // each, and what the voxels inside them absorb.
    constexpr double kFrom = 0.25, kTo = 0.5;
    const auto shells = static_cast<size_t>(std::ceil(kTo / h)) + 1;
    std::vector<double> phi(shells, 0.0), radial(shells, 0.0), radius(shells, 0.0), count(shells, 0.0),
        absorbed(shells, 0.0);
    const auto dims = grid.dims;
    for (uint32_t z = 0; z < dims.z; ++z)
        for (uint32_t y = 0; y < dims.y; ++y)
            for (uint32_t x = 0; x < dims.x; ++x) {
                const size_t i = (size_t{z} * dims.y + y) * dims.x + x;
                const glm::dvec3 c = glm::dvec3(grid.origin) + h * (glm::dvec3(x, y, z) + 0.5);
                const double r = glm::length(c);
                const auto s = static_cast<size_t>(r / h + 0.5);
                if (s >= shells) continue;
                const auto fluence = static_cast<double>(radiance[i].r);
                phi[s] += fluence;
                radial[s] += glm::dot(glm::dvec3(glm::vec3(flux[i])), c / r);
                radius[s] += r;
                count[s] += 1.0;
                absorbed[s] += sigma_a * fluence * h * h * h;
            }
    // Least squares of ln(r fluence) against r over the far shells; the slope's standard error from the
    // residuals.
    std::vector<double> rs, ys;
    std::vector<double>
        gauss;  // the ratio of the radial flux through each shell to P less what is absorbed inside
    double inside = 0.0;
    for (size_t s = 0; s < shells; ++s) {
        const double r = radius[s] / count[s], mean_phi = phi[s] / count[s];
        if (r >= kFrom && r <= kTo) {
            rs.push_back(r);
            ys.push_back(std::log(r * mean_phi));
            gauss.push_back(4.0 * kPi * r * r * (radial[s] / count[s]) /
                            (power - inside - 0.5 * absorbed[s]));
        }
        inside += absorbed[s];
    }
    const double n = static_cast<double>(rs.size());
    const double mr = std::accumulate(rs.begin(), rs.end(), 0.0) / n,
                 my = std::accumulate(ys.begin(), ys.end(), 0.0) / n;
    double sxx = 0.0, sxy = 0.0;
    for (size_t k = 0; k < rs.size(); ++k) {
        sxx += (rs[k] - mr) * (rs[k] - mr);
        sxy += (rs[k] - mr) * (ys[k] - my);
    }
    const double slope = sxy / sxx;
    double residual = 0.0;
    for (size_t k = 0; k < rs.size(); ++k) residual += std::pow(ys[k] - my - slope * (rs[k] - mr), 2);
    const double slope_se = std::sqrt(residual / (n - 2.0) / sxx);
    const double D = 1.0 / (3.0 * sigma_t), sigma_eff = std::sqrt(sigma_a / D);
    // Transport theory's own asymptotic decay for isotropic scattering: kappa = k sigma_t with
    // c atanh(k) / k = 1 (albedo c), by bisection; diffusion is its expansion for small 1 - c.
    const double c = sigma_s / sigma_t;
    double k_lo = 1e-9, k_hi = 1.0 - 1e-12;
    for (int i = 0; i < 200; ++i) {
        const double k = 0.5 * (k_lo + k_hi);
        (c * std::atanh(k) / k > 1.0 ? k_hi : k_lo) = k;
    }
    const double kappa_transport = 0.5 * (k_lo + k_hi) * sigma_t;
    // Tolerance on the decay constant, term by term:
    //  - diffusion against transport: |kappa_transport - sigma_eff| (computed above);
    //  - the walls (1 m away, absorbing): their image source changes ln(fluence) by about
    //    exp(-2 sigma_eff (1 - r)), and the slope by twice sigma_eff times that, at most at kTo;
    //  - the unscattered and few-times scattered light near the source decays as exp(-sigma_t r): its
    //    share of the fluence at kFrom, exp(-(sigma_t - sigma_eff) kFrom), times sigma_t;
    //  - noise: 4 standard errors of the fitted slope.
    const double tolerance = std::abs(kappa_transport - sigma_eff) +
                             2.0 * sigma_eff * std::exp(-2.0 * sigma_eff * (1.0 - kTo)) +
                             sigma_t * std::exp(-(sigma_t - sigma_eff) * kFrom) + 4.0 * slope_se;
    const double gauss_mean =
        std::accumulate(gauss.begin(), gauss.end(), 0.0) / static_cast<double>(gauss.size());
    double gauss_var = 0.0;
    for (const double g : gauss) gauss_var += (g - gauss_mean) * (g - gauss_mean);
    const double gauss_se =
        std::sqrt(gauss_var / (static_cast<double>(gauss.size()) - 1.0) / static_cast<double>(gauss.size()));
    std::printf(
        "diffusion: decay %.4f /m against sigma_eff %.4f (transport %.4f), tolerance %.4f (slope SE %.4f); "
        "%.1f steps per photon\n",
        -slope, sigma_eff, kappa_transport, tolerance, slope_se, run.stats.mean_steps_per_photon());
    std::printf("diffusion: radial net flux / (P - absorbed inside) = %.4f mean over %zu shells (SE %.4f):",
                gauss_mean, gauss.size(), gauss_se);
    for (const double g : gauss) std::printf(" %.3f", g);
    std::printf("\n");
    EXPECT_NEAR(-slope, sigma_eff, tolerance);
    // The net flux: shells one voxel thick sample the sphere's area with their voxels (a lattice error of
    // about h / r, under 1/8, that averages out over the shells' many orientations to well under 1%); the
    // absorbed power inside r counts half the shell's own (second order in h). 3% plus 4 standard errors
    // of the shells' mean.
    EXPECT_NEAR(gauss_mean, 1.0, 0.03 + 4.0 * gauss_se);
}

}  // namespace
}  // namespace refract
