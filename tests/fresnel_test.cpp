// Reflection at the object's boundary against the Fresnel equations and Snell's critical angle
// (../shared/OPTICS.md), for photons and for eye rays. Expected values are computed here from the
// textbook amplitude coefficients, independently of shaders/shared/fresnel.h. Every scene's reflecting
// faces are aligned with the grid, so the smoothed shell is stratified: its normal is exact and the
// angle of incidence is the beam's. Tolerances are derived from the photon counts by each check.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <complex>
#include <cstdio>
#include <numbers>

#include <nlohmann/json.hpp>

#include "gpu_fixture.h"
#include "render/transport_inputs.h"

namespace refract {
namespace {

using nlohmann::json;
using shaders::PhotonExit;

constexpr double kPi = std::numbers::pi;
constexpr double kGlass = 1.5;

// Unpolarized reflectance from n1 into n2 at incidence angle `theta` (radians) on the n1 side.
double reflectance(double n1, double n2, double theta) {
    const double s = n1 / n2 * std::sin(theta);
    if (s >= 1.0) return 1.0;
    const double ci = std::cos(theta), ct = std::sqrt(1.0 - s * s);
    const double rs = (n1 * ci - n2 * ct) / (n1 * ci + n2 * ct);
    const double rp = (n2 * ci - n1 * ct) / (n2 * ci + n1 * ct);
    return (rs * rs + rp * rp) / 2.0;
}

// A scene with no fog, floor or absorption, a directional beam and a glass cube of half-side `half`
// reaching past the grid `bounds` wherever the test wants no face.
protocol::SceneDocument glass_scene(const json& patch) {
    json base = {{"light", {{"type", "directional"}, {"intensity", 1.0}}},
                 {"medium", {{"ior", 1.0}, {"extinction", {0, 0, 0}}, {"scattering", {0, 0, 0}}}},
                 {"object", {{"mesh", "cube"}, {"ior", kGlass}, {"extinction", {0, 0, 0}}, {"scattering", {0, 0, 0}}}},
                 {"floor", {{"enabled", false}}},
                 {"image", {{"width", 8}, {"height", 8}}},
                 {"photons", {{"count", 1 << 16}}}};
    base.merge_patch(patch);
    return protocol::parse_scene(base);
}

json bounds(glm::dvec3 lo, glm::dvec3 hi, uint32_t resolution) {
    return {{"resolution", resolution}, {"smoothing", 0.75}, {"bounds", {{"min", {lo.x, lo.y, lo.z}}, {"max", {hi.x, hi.y, hi.z}}}}};
}

// Four standard deviations of a fraction p estimated from n independent photons (each reflects or not
// by its own draw): a correct tracer fails such a check with probability 6e-5.
double binomial_tolerance(double p, double n) { return 4.0 * std::sqrt(std::max(p * (1.0 - p), 1e-12) / n); }

class FresnelTest : public testing::GpuTest {
protected:
    std::vector<PhotonExit> trace(const protocol::SceneDocument& doc) {
        scene::SceneGpu gpu(kit());
        scene::RunOptions options;
        options.record_photon_exits = true;
        options.limit = scene::kAllPasses & ~scene::kView;
        gpu.run(scene::kAllPasses, doc, worlds(doc), nullptr, options);
        return gpu.read_photon_exits();
    }

    // The share of the photons that entered the grid and left it travelling against `axis`.
    double reflected_share(const std::vector<PhotonExit>& exits, glm::dvec3 axis, double* entered = nullptr) {
        double in = 0.0, back = 0.0;
        for (const auto& e : exits) {
            if (e.entry.w != 1.0f) continue;
            ++in;
            if (glm::dot(glm::dvec3(e.direction.x, e.direction.y, e.direction.z), axis) < 0.0) ++back;
        }
        if (entered) *entered = in;
        return back / std::max(in, 1.0);
    }
};

// A beam along +z meets the cube's face z = -1 at normal incidence; the cube's other faces lie outside
// the grid, so the face is the only boundary the photons meet: ((n - 1) / (n + 1))^2 = 4.0% come back.
TEST_F(FresnelTest, PhotonsReflectFourPercentAtNormalIncidence) {
    const auto doc = glass_scene({{"light", {{"direction", {0, 0, 1}}}},
                                  {"volume", bounds({-0.4, -0.4, -1.3}, {0.4, 0.4, -0.5}, 64)}});
    double entered = 0.0;
    const double measured = reflected_share(trace(doc), {0, 0, 1}, &entered);
    const double expected = std::pow((kGlass - 1.0) / (kGlass + 1.0), 2.0);
    std::printf("normal incidence, photons: reflected %.5f, Fresnel %.5f, tolerance %.5f (%.0f photons)\n", measured,
                expected, binomial_tolerance(expected, entered), entered);
    ASSERT_GT(entered, 60000.0);
    EXPECT_NEAR(measured, expected, binomial_tolerance(expected, entered));
}

// A 2 m slab at normal incidence, both faces in the grid: with incoherent multiple reflections and no
// absorption R_slab = 2R / (1 + R) = 7.69% comes back and the rest goes through (R + T = 1: no photon is
// lost or stuck).
TEST_F(FresnelTest, PhotonsThroughASlabReflectTwoROverOnePlusR) {
    const auto doc = glass_scene({{"light", {{"direction", {0, 0, 1}}}},
                                  {"volume", bounds({-0.4, -0.4, -1.3}, {0.4, 0.4, 1.3}, 128)}});
    const auto exits = trace(doc);
    double entered = 0.0, forward = 0.0;
    const double back = reflected_share(exits, {0, 0, 1}, &entered);
    for (const auto& e : exits)
        if (e.entry.w == 1.0f && e.position.w == 1.0f && e.direction.z > 0.0f) ++forward;
    const double r = std::pow((kGlass - 1.0) / (kGlass + 1.0), 2.0), expected = 2.0 * r / (1.0 + r);
    std::printf("slab, photons: reflected %.5f, 2R/(1+R) %.5f, transmitted %.5f, tolerance %.5f\n", back, expected,
                forward / entered, binomial_tolerance(expected, entered));
    ASSERT_GT(entered, 60000.0);
    EXPECT_NEAR(back, expected, binomial_tolerance(expected, entered));
    EXPECT_EQ(back * entered + forward, entered);
}

// Inside glass, a beam meets the face y = 2 of a cube of half-side 2 (the grid holds only the face and
// the glass below it, so photons start in the glass) at theta from its normal. Below the critical
// angle asin(1 / n) = 41.81 degrees a share R(theta) is reflected and the rest leaves along Snell's
// law; above it every photon is reflected.
//
// The margin: the face lies on voxel boundaries, so the smoothed field depends on y alone, and with
// Fresnel on the ray step keeps n sin(theta) across the shell to single precision (ray_step), so a ray
// turns back exactly where n = n1 sin(theta1). What a step can still get wrong is the sign of its
// momentum along grad n, and only within one shortest shell step (1/4 voxel, shell_step_for) of its
// turning point, where n^2 - (n1 sin(theta1))^2, the momentum squared, is below (|grad n| / 4)^2 <=
// (0.27 / 4)^2 (|grad n| peaks at 0.5 / (sqrt(2 pi) 0.75) per voxel): 2.3e-3 in n1 sin(theta1) at
// n = 1, 0.12 degrees. Checked a quarter of a degree either side, where R = 0.57 and 1.
TEST_F(FresnelTest, TotalInternalReflectionBeginsAtTheCriticalAngle) {
    const double critical = std::asin(1.0 / kGlass) * 180.0 / kPi;
    const double margin = 0.25;
    for (const double degrees : {critical - margin, critical + margin}) {
        const double theta = degrees * kPi / 180.0;
        const glm::dvec3 beam(std::sin(theta), std::cos(theta), 0.0);
        const auto doc = glass_scene({{"light", {{"direction", {beam.x, beam.y, beam.z}}}},
                                      {"object", {{"scale", 2.0}}},
                                      {"photons", {{"count", 1 << 15}}},
                                      {"volume", bounds({-1.0, 1.5, -0.25}, {1.0, 2.4, 0.25}, 128)}});
        double in_glass = 0.0, reflected = 0.0, worst_snell = 0.0;
        const double snell = theta < critical * kPi / 180.0 ? std::asin(kGlass * std::sin(theta)) : 0.0;
        for (const auto& e : trace(doc)) {
            // Photons that start in the glass on the grid's floor and meet the face well inside the grid.
            if (e.entry.w != 1.0f || e.entry.y > 1.51f || e.entry.x > 0.3f) continue;
            ++in_glass;
            if (e.direction.y < 0.0f) {
                ++reflected;
            } else {
                const double leaves = std::atan2(double{e.direction.x}, double{e.direction.y});
                worst_snell = std::max(worst_snell, std::abs(leaves - snell) * 180.0 / kPi);
            }
        }
        ASSERT_GT(in_glass, 1000.0);
        const double share = reflected / in_glass, expected = reflectance(kGlass, 1.0, theta);
        std::printf("inside glass at %.2f degrees (critical %.2f): reflected %.4f, Fresnel %.4f, tolerance %.4f; "
                    "transmitted leave within %.3f degrees of Snell\n", degrees, critical, share, expected,
                    binomial_tolerance(expected, in_glass), worst_snell);
        if (expected >= 1.0) {
            EXPECT_EQ(reflected, in_glass);
        } else {
            EXPECT_NEAR(share, expected, binomial_tolerance(expected, in_glass));
            EXPECT_LT(share, 0.7);
        }
    }
}

// Eye rays looking straight down (a 10 degree field of view) at the cube's top face y = 1. The sky is
// the horizon's colour H below the horizon and blends to the zenith's Z above it (view.comp, sky), so a
// pixel whose reflected ray leaves at cos(theta) to the zenith and whose transmitted light ends below
// the horizon is (1 - R_total) H + R_total sky(cos theta), per channel: R_total is measured exactly.
class FresnelViewTest : public FresnelTest {
protected:
    struct Frame {
        std::vector<glm::vec4> hdr;
        shaders::TransportParams params;
    };
    Frame render(const json& volume, const json& medium = json::object(), const scene::RunOptions& options = {}) {
        const auto doc = glass_scene({{"camera", {{"position", {0, 4, 0}}, {"target", {0, 0, 0}}, {"up", {0, 0, -1}},
                                                  {"fov_deg", 10}}},
                                      {"image", {{"width", 16}, {"height", 16}}},
                                      {"volume", volume},
                                      {"medium", medium}});
        scene::SceneGpu gpu(kit());
        gpu.run(scene::kAllPasses, doc, worlds(doc), nullptr, options);
        return {gpu.read_hdr(), gpu.params()};
    }
    // Each pixel's R_total measured from its colour, against `expected`(R at its angle of incidence):
    // the worst difference over pixels and channels.
    template <class Expected>
    double worst_error(const Frame& f, Expected expected, double* mean_measured) {
        const auto& p = f.params;
        const double w = p.image.x, h = p.image.y, tan_half = p.camera_position.w;
        double worst = 0.0, sum = 0.0;
        for (uint32_t y = 0; y < p.image.y; ++y) {
            for (uint32_t x = 0; x < p.image.x; ++x) {
                const double nx = (2.0 * (x + 0.5) / w - 1.0) * tan_half, ny = (1.0 - 2.0 * (y + 0.5) / h) * tan_half;
                const double cos_theta = 1.0 / std::sqrt(1.0 + nx * nx + ny * ny);  // the ray's angle to the face normal
                for (int c = 0; c < 3; ++c) {
                    const double horizon = double{p.sky_horizon[c]}, up = horizon + (double{p.sky_zenith[c]} - horizon) * cos_theta;
                    const double measured = (double{f.hdr[y * p.image.x + x][c]} - horizon) / (up - horizon);
                    worst = std::max(worst, std::abs(measured - expected(std::acos(cos_theta))));
                    sum += measured / 3.0;
                }
            }
        }
        *mean_measured = sum / (w * h);
        return worst;
    }
};

// The glass reaches below the grid, so the transmitted ray leaves the grid inside it, downwards: the
// one face reflects R(theta), 4.0% at normal incidence. The colours are single-precision sums of a
// handful of terms (relative error ~1e-6) over a difference Z - H of about 0.035: 1e-4 in R is ample.
TEST_F(FresnelViewTest, EyeRaysReflectFourPercentAtNormalIncidence) {
    const Frame f = render(bounds({-0.4, 0.5, -0.4}, {0.4, 1.3, 0.4}, 64));
    double mean = 0.0;
    const double worst = worst_error(f, [](double theta) { return reflectance(1.0, kGlass, theta); }, &mean);
    std::printf("normal incidence, eye rays: reflected %.5f (mean over pixels), Fresnel %.5f, worst error %.2e\n", mean,
                reflectance(1.0, kGlass, 0.0), worst);
    EXPECT_LT(worst, 1e-4);
}

// The whole 2 m slab in the grid: eye rays trace the front face's reflection, the back face's and the
// front face's internal reflections (FRESNEL_EYE_REFLECTIONS = 3); the last ray, going down again, keeps
// all its light on the transmitted side. So R + T^2 R = 7.686% comes back at normal incidence, against
// the infinite sum 2R / (1 + R) = 7.692%: T^2 R^3 / (1 - R^2) = 6e-5 short, within the 1e-4 below.
TEST_F(FresnelViewTest, EyeRaysThroughASlabReflectTheFrontAndOneInternalReflection) {
    const Frame f = render(bounds({-0.8, -1.3, -0.8}, {0.8, 1.3, 0.8}, 128));
    double mean = 0.0;
    const double worst = worst_error(
        f,
        [](double theta) {
            const double r = reflectance(1.0, kGlass, theta), t = 1.0 - r;
            return r + t * t * r;
        },
        &mean);
    const double r = reflectance(1.0, kGlass, 0.0);
    std::printf("slab, eye rays: reflected %.5f (mean over pixels), R + T^2 R %.5f, 2R/(1+R) %.5f, worst error %.2e\n",
                mean, r + (1 - r) * (1 - r) * r, 2 * r / (1 + r), worst);
    EXPECT_LT(worst, 1e-4);
    EXPECT_NEAR(mean, 2 * r / (1 + r), 1e-4);
}

// Interactive frames take every reflected eye path straight to the floor or sky
// (FRESNEL_PREVIEW_TRACED_SHARE), dimmed by the medium along its line instead of marched through it. The
// cube's top face lies 0.3 m under the grid's top, in a medium that absorbs kappa per metre and does not
// fade: R(theta) of an eye ray's light reflects up through a = 0.3 / cos(theta) of it to the sky (the
// colour `up`), so the reflected part of a pixel is about R up exp(-2 kappa a), 1e-4 here, and a
// straight path the medium did not dim would be brighter by that part times exp(kappa a) - 1 (0.8 at
// normal incidence). The marched path is thinned in the face's smoothed shell where the straight one
// counts the whole medium: a shell of two voxels (1.25 cm) is 2.5% at kappa = 2; the bound is 10%.
TEST_F(FresnelViewTest, PreviewReflectionsGoStraightDimmedByTheMediumTheyCross) {
    const double kappa = 2.0;
    const json medium = {{"extinction", {kappa, kappa, kappa}}, {"fade", 0}};
    const json volume = bounds({-0.4, 0.5, -0.4}, {0.4, 1.3, 0.4}, 64);
    scene::RunOptions preview;
    preview.traced_reflection_share = FRESNEL_PREVIEW_TRACED_SHARE;
    const Frame marched = render(volume, medium), straight = render(volume, medium, preview);
    const auto& p = marched.params;
    const double w = p.image.x, h = p.image.y, tan_half = p.camera_position.w;
    double worst = 0.0;
    for (uint32_t y = 0; y < p.image.y; ++y)
        for (uint32_t x = 0; x < p.image.x; ++x) {
            const double nx = (2.0 * (x + 0.5) / w - 1.0) * tan_half, ny = (1.0 - 2.0 * (y + 0.5) / h) * tan_half;
            const double cos_theta = 1.0 / std::sqrt(1.0 + nx * nx + ny * ny);
            const double r = reflectance(1.0, kGlass, std::acos(cos_theta));
            const size_t i = y * p.image.x + x;
            for (int c = 0; c < 3; ++c) {
                const double horizon = double{p.sky_horizon[c]}, up = horizon + (double{p.sky_zenith[c]} - horizon) * cos_theta;
                const double reflected = r * up * std::exp(-2.0 * kappa * 0.3 / cos_theta);
                worst = std::max(worst, std::abs(double{straight.hdr[i][c]} - double{marched.hdr[i][c]}) / reflected);
            }
        }
    std::printf("reflected paths through an absorbing medium, straight against marched: worst %.4f of the reflected part\n",
                worst);
    EXPECT_LT(worst, 0.1);
}

// White furnace (OPTICS.md): a lossless object in a uniform environment of radiance L, with no medium or
// floor, leaves every pixel at L whatever its shape and index, if reflection, refraction and total
// internal reflection all conserve energy: a glass sphere, and a tilted cube whose side faces reflect
// totally. Every eye-ray path ends in the environment with its share of the light, and the shares sum
// to 1 at each boundary (R + T = 1, or the whole ray on one side), so the only error is single-precision
// rounding over a few hundred steps (~1e-5): 1e-4 of L.
TEST_F(FresnelViewTest, GlassInAUniformEnvironmentIsAWhiteFurnace) {
    const double L = 0.7;
    for (const json& object : {json{{"mesh", "sphere"}, {"scale", 0.8}},
                               json{{"mesh", "cube"}, {"scale", 0.6}, {"rotation_deg", {30, 40, 0}}}}) {
        json patch = {{"camera", {{"position", {0, 0.3, 4}}, {"target", {0, 0, 0}}, {"fov_deg", 35}}},
                      {"image", {{"width", 48}, {"height", 48}}},
                      {"object", object},
                      {"environment", {{"type", "uniform"}, {"color", {1, 1, 1}}, {"intensity", L}}},
                      {"volume", bounds({-1.2, -1.2, -1.2}, {1.2, 1.2, 1.2}, 96)}};
        const auto doc = glass_scene(patch);
        scene::SceneGpu gpu(kit());
        gpu.run(scene::kAllPasses, doc, worlds(doc), nullptr);
        double worst = 0.0;
        for (const auto& px : gpu.read_hdr())
            for (int c = 0; c < 3; ++c) worst = std::max(worst, std::abs(double{px[c]} - L));
        std::printf("white furnace, %s: worst pixel off L by %.2e\n", object["mesh"].get<std::string>().c_str(), worst);
        EXPECT_LT(worst, 1e-4 * L);
    }
}

// Reflected eye paths gather fog at FRESNEL_REFLECTED_VIEW_STEP times the view step. Their step error is
// the error of a coarser step (itself under the photon noise: interactive frames take twice the step)
// times the few percent of a pixel's light they carry, so the frame moves by far less than two photon
// seeds' frames differ by. The bound, a tenth of that, leaves room for the front reflection at grazing
// angles (R up to 1 at the ball's rim). Measured: 2x moves the frame by 0.3% of the seed difference, and
// even 32x by 1.4%.
TEST_F(FresnelViewTest, ReflectedPathsAtACoarserStepStayWithinThePhotonNoise) {
    const auto doc = protocol::parse_scene({{"image", {{"width", 96}, {"height", 96}}},
                                            {"volume", {{"resolution", 64}}},
                                            {"photons", {{"count", 1 << 14}}}});
    ASSERT_TRUE(doc.object().fresnel);
    auto frame = [&](const protocol::SceneDocument& d, float reflected_view_step) {
        scene::RunOptions options;
        options.reflected_view_step = reflected_view_step;
        scene::SceneGpu gpu(kit());
        gpu.run(scene::kAllPasses, d, worlds(d), nullptr, options);
        return gpu.read_hdr();
    };
    auto reseeded = doc;
    reseeded.photons.seed = doc.photons.seed + 1;
    const auto coarse = frame(doc, FRESNEL_REFLECTED_VIEW_STEP);
    const double step_difference = testing::frame_difference(coarse, frame(doc, 1.0f));
    const double seed_difference =
        testing::frame_difference(coarse, frame(reseeded, FRESNEL_REFLECTED_VIEW_STEP));
    std::printf("[ info ] reflected paths at %.0fx the view step: frames differ by %.3e, two seeds by %.3e\n",
                double{FRESNEL_REFLECTED_VIEW_STEP}, step_difference, seed_difference);
    EXPECT_GT(step_difference, 0.0) << "the reflected paths' step must be the one the frame takes";
    EXPECT_LT(step_difference, 0.1 * seed_difference);
}

// Thin films. The reference: the Airy sum in complex amplitudes (OPTICS.md), r = (r01 + r12 e^(2i delta)) /
// (1 + r01 r12 e^(2i delta)) per polarization, written here independently of fresnel.h's real form, and
// averaged over each channel's band as the protocol defines the channels: blue 400-490, green 490-580,
// red 580-700 nm, evenly weighted (a fine 200-point midpoint rule here; the shaders take 8 points).
double airy(double n0, double n1, double n2, double theta0, double d, double lambda) {
    using C = std::complex<double>;
    const C s0(std::sin(theta0), 0.0);
    const C c0 = std::sqrt(1.0 - s0 * s0), c1 = std::sqrt(1.0 - (n0 / n1) * (n0 / n1) * s0 * s0),
            c2 = std::sqrt(1.0 - (n0 / n2) * (n0 / n2) * s0 * s0);
    const C phase = std::exp(C(0.0, 2.0) * (2.0 * kPi * n1 * d / lambda) * c1);
    auto sum = [&](C r01, C r12) { return std::norm((r01 + r12 * phase) / (1.0 + r01 * r12 * phase)); };
    const C rs01 = (n0 * c0 - n1 * c1) / (n0 * c0 + n1 * c1), rs12 = (n1 * c1 - n2 * c2) / (n1 * c1 + n2 * c2);
    const C rp01 = (n1 * c0 - n0 * c1) / (n1 * c0 + n0 * c1), rp12 = (n2 * c1 - n1 * c2) / (n2 * c1 + n1 * c2);
    return (sum(rs01, rs12) + sum(rp01, rp12)) / 2.0;
}

double band_airy(int channel, double n0, double n1, double n2, double theta0, double d) {
    const double lo[3] = {580.0, 490.0, 400.0}, hi[3] = {700.0, 580.0, 490.0};
    double sum = 0.0;
    for (int k = 0; k < 200; ++k) sum += airy(n0, n1, n2, theta0, d, lo[channel] + (hi[channel] - lo[channel]) * (k + 0.5) / 200.0);
    return sum / 200.0;
}

// How far the shaders' 8-point midpoint rule over a band (width w = 90-120 nm) may stray from the band's
// mean: w^2 / (24 * 8^2) |R''|. R oscillates with the film's phase 4 pi n1 d / lambda between bounds
// (|r01| - |r12|)^2 and (|r01| + |r12|)^2, so |R''| <= (4 pi n1 d / lambda^2)^2 (|r01| + |r12|)^2, largest
// at lambda = 400 nm (the first derivative's term is smaller by lambda / (4 pi n1 d)), and w <= 120 nm.
// Plus 1e-4 for single-precision sums.
double band_tolerance(double n0, double n1, double n2, double d) {
    const double r01 = std::abs((n0 - n1) / (n0 + n1)), r12 = std::abs((n1 - n2) / (n1 + n2));
    const double phase_rate = 4.0 * kPi * n1 * d / (400.0 * 400.0);
    return 120.0 * 120.0 / (24.0 * 64.0) * phase_rate * phase_rate * (r01 + r12) * (r01 + r12) + 1e-4;
}

// Eye rays looking down at a filmed face (the object reaching below the grid, as in the 4% test): per
// channel, R_total is the band-averaged Airy reflectance.
class FilmViewTest : public FresnelViewTest {
protected:
    // R_total per channel at the centre pixels (normal incidence within 0.3 degrees), for a film of index
    // n_film and thickness d on an object of index n_object.
    glm::dvec3 measured(double n_object, double n_film, double d) {
        const auto doc = glass_scene({{"camera", {{"position", {0, 4, 0}}, {"target", {0, 0, 0}}, {"up", {0, 0, -1}},
                                                  {"fov_deg", 10}}},
                                      {"image", {{"width", 16}, {"height", 16}}},
                                      {"object", {{"ior", n_object}, {"film", {{"ior", n_film}, {"top_nm", d}, {"bottom_nm", d}}}}},
                                      {"volume", {{"resolution", 64}, {"smoothing", 0.75}, {"octree_epsilon", 1e-4},
                                                  {"bounds", {{"min", {-0.4, 0.5, -0.4}}, {"max", {0.4, 1.3, 0.4}}}}}}});
        scene::SceneGpu gpu(kit());
        gpu.run(scene::kAllPasses, doc, worlds(doc), nullptr);
        const auto hdr = gpu.read_hdr();
        const auto& p = gpu.params();
        glm::dvec3 r(0.0);
        for (uint32_t y = 7; y <= 8; ++y)
            for (uint32_t x = 7; x <= 8; ++x)
                for (int c = 0; c < 3; ++c) {
                    const double horizon = double{p.sky_horizon[c]}, up = double{p.sky_zenith[c]};
                    r[c] += (double{hdr[y * p.image.x + x][c]} - horizon) / (up - horizon) / 4.0;
                }
        return r;
    }
};

// MgF2 (1.38) a quarter wave thick at 535 nm (the green band's centre) on glass (1.5): at its design
// wavelength ((n0 n2 - n1^2) / (n0 n2 + n1^2))^2 = 1.4% against 4.0% uncoated.
TEST_F(FilmViewTest, QuarterWaveCoatingReflectsAsAiryPredicts) {
    const double n1 = 1.38, n2 = 1.5, design = 535.0, d = design / (4.0 * n1);
    const double quarter_wave = std::pow((n2 - n1 * n1) / (n2 + n1 * n1), 2.0);
    EXPECT_NEAR(airy(1.0, n1, n2, 0.0, d, design), quarter_wave, 1e-12);  // the reference agrees with the formula
    const glm::dvec3 r = measured(n2, n1, d);
    for (int c = 0; c < 3; ++c) {
        const double expected = band_airy(c, 1.0, n1, n2, 0.0, d);
        std::printf("quarter-wave MgF2 on glass, channel %d: reflected %.5f, band-averaged Airy %.5f (at 535 nm %.5f, "
                    "uncoated %.5f)\n", c, r[c], expected, quarter_wave, reflectance(1.0, n2, 0.0));
        EXPECT_NEAR(r[c], expected, band_tolerance(1.0, n1, n2, d));
        EXPECT_LT(r[c], 0.6 * reflectance(1.0, n2, 0.0));
    }
}

// A soap film (1.33) in air, for several thicknesses: an object of index 1.001 under it (a bubble's
// inside is air; the index step only marks where the film is, and reflects 2.5e-7 by itself).
TEST_F(FilmViewTest, SoapFilmColoursFollowAiry) {
    for (const double d : {100.0, 300.0, 500.0}) {
        const glm::dvec3 r = measured(1.001, 1.33, d);
        for (int c = 0; c < 3; ++c) {
            const double expected = band_airy(c, 1.0, 1.33, 1.001, 0.0, d);
            std::printf("soap film %.0f nm, channel %d: reflected %.5f, band-averaged Airy %.5f, tolerance %.5f\n", d, c,
                        r[c], expected, band_tolerance(1.0, 1.33, 1.001, d));
            EXPECT_NEAR(r[c], expected, band_tolerance(1.0, 1.33, 1.001, d));
        }
    }
}

// Photons through a soap film (300 nm, where the channels reflect 4.0, 7.3 and 3.0%): a beam straight
// down onto the filmed face, the object reaching below the grid, the floor under it. The floor map holds
// what the grid changes: each reflected photon's flux is taken from the floor and never returned, each
// transmitted one returns its weight times (1 - R_c) / (1 - P) (P the mean chance). So per channel
// -(floor change) / (entered flux) = R_c. Its noise is that of the transmitted count: the standard
// deviation of R_c is (1 - R_c) sqrt(P / ((1 - P) N)), four of them the tolerance (3e-3 at 2^16 photons,
// a tenth of the channels' spread); the floor's stochastic rounding adds none in expectation.
TEST_F(FresnelTest, PhotonsThroughASoapFilmReflectEachChannelsBandAverage) {
    const double d = 300.0;
    const auto doc = glass_scene({{"light", {{"direction", {0, -1, 0}}}},
                                  {"object", {{"ior", 1.001}, {"film", {{"ior", 1.33}, {"top_nm", d}, {"bottom_nm", d}}}}},
                                  {"floor", {{"enabled", true}, {"height", -1.0}}},
                                  {"volume", {{"resolution", 64}, {"smoothing", 0.75}, {"octree_epsilon", 1e-4},
                                              {"bounds", {{"min", {-0.4, 0.5, -0.4}}, {"max", {0.4, 1.3, 0.4}}}}}}});
    scene::SceneGpu gpu(kit());
    scene::RunOptions options;
    options.limit = scene::kAllPasses & ~scene::kView;
    const auto stats = gpu.run(scene::kAllPasses, doc, worlds(doc), nullptr, options);
    const double entered = static_cast<double>(stats.photons_entered);
    ASSERT_GT(entered, 60000.0);
    const auto map = gpu.read_floor_map();
    const double side = static_cast<double>(gpu.params().floor_map.z) / gpu.floor_map_side();
    double mean = 0.0;
    for (int c = 0; c < 3; ++c) mean += band_airy(c, 1.0, 1.33, 1.001, 0.0, d) / 3.0;
    for (int c = 0; c < 3; ++c) {
        double change = 0.0;
        for (const auto& texel : map) change += double{texel[c]} * side * side;
        const double measured = -change / (entered * double{gpu.params().photon_flux[c]});
        const double expected = band_airy(c, 1.0, 1.33, 1.001, 0.0, d);
        const double tolerance = 4.0 * (1.0 - expected) * std::sqrt(mean / ((1.0 - mean) * entered));
        std::printf("soap film %.0f nm, photons, channel %d: reflected %.5f, band-averaged Airy %.5f, tolerance %.5f\n", d,
                    c, measured, expected, tolerance);
        EXPECT_NEAR(measured, expected, tolerance);
    }
}

// A Maxwell fish-eye of n0 = 3 in air has no shell inside (n rises from 1.5 at its surface to 3 at its
// centre) but meets the air with a step at its surface: a narrow beam along its axis comes back like a
// slab's, 2R / (1 + R) with R = ((1.5 - 1) / (1.5 + 1))^2 (the front face and, after the graded
// inside, the back face, both met near normal incidence: a 0.5-degree spot 3.2 m before the lens is
// 2.8 cm wide there, two degrees). With Fresnel off nothing comes back; a Luneburg lens, whose surface
// is index-matched in air, and an imported grid never reflect.
TEST_F(FresnelTest, AGradedFieldReflectsAtItsOuterBoundaryOnly) {
    json patch = {{"light", {{"type", "spot"}, {"position", {0, 0, -4}}, {"direction", {0, 0, 1}}, {"cone_deg", 0.5}}},
                  {"object", {{"mesh", "sphere"}, {"scale", 0.8}, {"index_field", "maxwell"}, {"maxwell_n0", 3.0}}},
                  {"volume", bounds({-1, -1, -1}, {1, 1, 1}, 96)}};
    const auto doc = glass_scene(patch);
    ASSERT_TRUE(scene::fresnel_reflects(doc));
    double entered = 0.0;
    const double measured = reflected_share(trace(doc), {0, 0, 1}, &entered);
    const double r = std::pow((kGlass - 1.0) / (kGlass + 1.0), 2.0), expected = 2.0 * r / (1.0 + r);
    std::printf("Maxwell n0 = 3, axial beam: reflected %.5f, 2R/(1+R) %.5f, tolerance %.5f (%.0f photons)\n", measured,
                expected, binomial_tolerance(expected, entered), entered);
    ASSERT_GT(entered, 60000.0);
    EXPECT_NEAR(measured, expected, binomial_tolerance(expected, entered));

    patch["object"]["fresnel"] = false;
    EXPECT_EQ(reflected_share(trace(glass_scene(patch)), {0, 0, 1}), 0.0);
    patch["object"]["fresnel"] = true;
    patch["object"]["maxwell_n0"] = 2.0;  // surface index 1: matched
    EXPECT_FALSE(scene::fresnel_reflects(glass_scene(patch)));
    patch["object"]["index_field"] = "luneburg";
    EXPECT_FALSE(scene::fresnel_reflects(glass_scene(patch)));
    patch["medium"] = {{"ior", 1.33}};  // a Luneburg lens in water would cross the midpoint inside
    EXPECT_FALSE(scene::fresnel_reflects(glass_scene(patch)));
}

}  // namespace
}  // namespace refract
