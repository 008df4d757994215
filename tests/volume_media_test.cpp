// Volumes through the transport (issue 39, point 3): OpenVDB grids written here, exported as the daemon
// exports them, resampled into the medium field and crossed by photons and eye rays. Known answers: the
// transmittance through a linear ramp of density against exp(-its integral), a volume of constant
// density against the homogeneous fog of the same coefficients, and a volume that only scatters in a
// uniform environment against that environment's radiance (the white furnace); what a volume emits along
// an eye ray against the integral of L_e e^-tau, and on the floor against the inverse-square integral over
// the volume; the blackbody's colour against the CIE's Planckian locus. REFRACT_VOLUME_PNG_DIR set: each test
// writes its frames there to be looked at.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <numbers>
#include <nlohmann/json.hpp>
#include <string>

#include "gpu_fixture.h"
#include "image/png.h"
#include "render/blackbody.h"
#include "render/medium_field.h"
#include "render/renderer.h"
#include "volume/builtin_volumes.h"
#include "volume/vdb_reader.h"
#include "volume/vdb_samples.h"

namespace refract {
namespace {

using nlohmann::json;

class VolumeMediaTest : public testing::GpuTest {
protected:
    static void save(const scene::SceneGpu& gpu, const std::string& name) {
        const char* dir = std::getenv("REFRACT_VOLUME_PNG_DIR");
        if (dir == nullptr) return;
        image::write_file(std::string(dir) + "/" + name + ".png", image::encode_png(gpu.read_ldr(), gpu.width(), gpu.height()));
    }
};

// The ramp: voxels of 5 cm, index x 0..19 (world x 0 to 0.95 m at their centres), y and z -10..9, density
// 0.5 + 0.1 i. Trilinear between centres, the density along a line through it is piecewise linear, and
// its integral is the voxels' sum times the voxel: 0.05 (20 x 0.5 + 0.1 x 190) = 1.45.
constexpr double kRampVoxel = 0.05, kRampDepth = 1.45, kRampMost = 2.4;
constexpr double kRampExtinction = 1.0;  // per metre per unit density

scene::Densities ramp() {
    const std::string file = test::ramp_box_vdb({0, -10, -10}, {19, 9, 9}, kRampVoxel, 0.5f, 0.1f);
    return {{"ramp", {std::make_shared<const volume::DensityGrid>(volume::export_density(file, "density", {}))}}};
}

// The ramp alone in a box of clear medium, seen along x and lit along x; the one object a speck of
// the medium itself, out of the way.
protocol::SceneDocument ramp_scene() {
    return protocol::parse_scene(json::parse(R"({
        "camera": {"position": [-3, 0, 0], "target": [0, 0, 0], "up": [0, 1, 0], "fov_deg": 30},
        "image": {"width": 16, "height": 16},
        "light": {"type": "directional", "direction": [1, 0, 0], "intensity": 1},
        "object": {"position": [1.3, 0.6, 0.6], "scale": 0.05, "ior": 1.0, "extinction": [0, 0, 0],
                   "scattering": [0, 0, 0]},
        "medium": {"extinction": [0, 0, 0], "scattering": [0, 0, 0], "fade": 0},
        "volumes": {"ramp": {"asset": "ramp", "extinction": [1, 1, 1], "scattering": [0, 0, 0]}},
        "volume": {"resolution": 48, "bounds": {"min": [-0.5, -0.75, -0.75], "max": [1.5, 0.75, 0.75]}},
        "photons": {"count": 16384},
        "floor": {"enabled": false},
        "environment": {"type": "uniform", "color": [1, 1, 1], "lights": false}})"));
}

// How far the optical depth may be off: the field holds the ramp at the lattice's voxel h, so each of the
// ramp's two ends (where the density drops from its most to 0 within a grid voxel) may be smeared by up to
// half a voxel of the densest value: sigma rho_max h in all.
double depth_tolerance(const scene::SceneGpu& gpu) {
    return kRampExtinction * kRampMost * static_cast<double>(gpu.grid().voxel_size);
}

TEST_F(VolumeMediaTest, EyeRaysThroughALinearRampSeeExpOfItsIntegral) {
    const protocol::SceneDocument document = ramp_scene();
    scene::SceneGpu gpu(kit());
    gpu.run(scene::kAllPasses, document, worlds(document), nullptr, scene::run_options_for(scene::Quality::still), nullptr,
            ramp());
    save(gpu, "eye_rays_through_a_ramp");
    const std::vector<glm::vec4> hdr = gpu.read_hdr();
    // The middle four pixels look through the ramp's middle (within 15 cm of the axis, at 1 degree to it):
    // the backdrop of radiance 1 times the transmittance.
    for (uint32_t y : {7u, 8u})
        for (uint32_t x : {7u, 8u}) {
            const glm::vec4 pixel = hdr[y * 16 + x];
            std::printf("optical depth through the ramp, pixel (%u, %u): eye ray %.4f, exact %.4f (tolerance %.4f)\n", x, y,
                        -std::log(static_cast<double>(pixel.g)), kRampExtinction * kRampDepth, depth_tolerance(gpu));
            for (int c = 0; c < 3; ++c) {
                const double depth = -std::log(static_cast<double>(pixel[c]));
                EXPECT_NEAR(depth, kRampExtinction * kRampDepth, depth_tolerance(gpu)) << x << ", " << y << " channel " << c;
            }
        }
    // Past the ramp's side (the corner pixels) the backdrop shows unattenuated.
    EXPECT_NEAR(hdr[0][0], 1.0f, 1e-5f);
}

TEST_F(VolumeMediaTest, PhotonsThroughALinearRampKeepExpOfItsIntegral) {
    const protocol::SceneDocument document = ramp_scene();
    scene::SceneGpu gpu(kit());
    scene::RunOptions options = scene::run_options_for(scene::Quality::still);
    options.record_photon_exits = true;
    gpu.run(scene::kAllPasses, document, worlds(document), nullptr, options, nullptr, ramp());
    // Photons that crossed the ramp within 0.3 m of its axis (its y, z span +-0.5 m): each keeps exp(-tau).
    double sum = 0.0;
    uint32_t crossed = 0;
    for (const shaders::PhotonExit& exit : gpu.read_photon_exits()) {
        if (exit.entry.w != 1.0f || std::abs(exit.entry.y) > 0.3f || std::abs(exit.entry.z) > 0.3f) continue;
        sum += static_cast<double>(exit.weight.g);
        ++crossed;
    }
    ASSERT_GT(crossed, 1000u);
    const double depth = -std::log(sum / crossed);
    std::printf("optical depth through the ramp: photons %.4f, exact %.4f (tolerance %.4f)\n", depth,
                kRampExtinction * kRampDepth, depth_tolerance(gpu));
    EXPECT_NEAR(depth, kRampExtinction * kRampDepth, depth_tolerance(gpu));
}

// A Gaussian blob of density, exp(-r^2 / 2 s^2), in voxels of `voxel` metres from -half to half - 1 an
// axis, as the volume member "blob".
scene::Densities gaussian_blob(double s, double voxel, int half) {
    volume::DensityGrid blob;
    blob.index_to_world = {voxel, 0, 0, 0, 0, voxel, 0, 0, 0, 0, voxel, 0};
    for (int ox = -half; ox < half; ox += 8)
        for (int oy = -half; oy < half; oy += 8)
            for (int oz = -half; oz < half; oz += 8) {
                volume::DensityLeaf leaf;
                leaf.origin = {ox, oy, oz};
                for (size_t i = 0; i < volume::kLeafVoxels; ++i) {
                    const glm::dvec3 x = glm::dvec3(ox + static_cast<int>(i / 64), oy + static_cast<int>(i / 8 % 8), oz + static_cast<int>(i % 8)) * voxel;
                    leaf.values[i] = static_cast<float>(std::exp(-glm::dot(x, x) / (2.0 * s * s)));
                }
                blob.leaves.push_back(leaf);
            }
    return {{"blob", {std::make_shared<const volume::DensityGrid>(blob)}}};
}

// A Gaussian blob of density, exp(-r^2 / 2 s^2) with s = 0.2 m in voxels of 2 cm, crossed along x by eye
// rays and by photons: a ray at distance b from its centre sees the optical depth sigma s sqrt(2 pi)
// exp(-b^2 / 2 s^2). The estimate smooths the blob three times, each exact for a linear density and off by
// at most |rho''| (along each axis, <= rho / s^2) times a point otherwise: the grid's trilinear
// interpolation h_g^2 / 8 an axis, the field voxel's mean of 2^3 samples (h / 4 off its centre) h^2 / 32,
// and the field's trilinear interpolation h^2 / 8 (the steps' midpoints add h^2 / 24 along the ray, less
// than these). So the depth may be off by sigma s sqrt(2 pi) 3 (h_g^2 / 8 + h^2 / 32 + h^2 / 8) / s^2, which
// the tolerance is.
TEST_F(VolumeMediaTest, EyeRaysAndPhotonsThroughAGaussianBlobSeeExpOfItsIntegral) {
    constexpr double kS = 0.2, kVoxel = 0.02, kSigma = 2.0;
    const scene::Densities densities = gaussian_blob(kS, kVoxel, 64);
    const protocol::SceneDocument document = protocol::parse_scene(json::parse(R"({
        "camera": {"position": [-3, 0, 0], "target": [0, 0, 0], "up": [0, 1, 0], "fov_deg": 20},
        "image": {"width": 33, "height": 33},
        "light": {"type": "directional", "direction": [1, 0, 0], "intensity": 1},
        "object": {"position": [0.9, 0.9, 0.9], "scale": 0.03, "ior": 1.0, "extinction": [0, 0, 0], "scattering": [0, 0, 0]},
        "medium": {"extinction": [0, 0, 0], "scattering": [0, 0, 0], "fade": 0},
        "volumes": {"blob": {"asset": "blob", "extinction": [2, 2, 2], "scattering": [0, 0, 0]}},
        "volume": {"resolution": 48, "bounds": {"min": [-1, -1, -1], "max": [1, 1, 1]}},
        "photons": {"count": 65536},
        "floor": {"enabled": false},
        "environment": {"type": "uniform", "color": [1, 1, 1], "lights": false}})"));
    scene::SceneGpu gpu(kit());
    scene::RunOptions options = scene::run_options_for(scene::Quality::still);
    options.record_photon_exits = true;
    gpu.run(scene::kAllPasses, document, worlds(document), nullptr, options, nullptr, densities);
    save(gpu, "gaussian_blob");
    const double h = static_cast<double>(gpu.grid().voxel_size);
    const double width = kS * std::sqrt(2.0 * std::numbers::pi);
    const double tolerance = kSigma * width * 3.0 * (kVoxel * kVoxel / 8.0 + h * h / 32.0 + h * h / 8.0) / (kS * kS);
    // The middle pixel looks along the axis through the centre.
    const double eye = -std::log(static_cast<double>(gpu.read_hdr()[16 * 33 + 16].g));
    // Photons entering within 10 cm of the axis, each against the exact transmittance at its own distance
    // (they do not scatter: every weight is its path's transmittance, no noise).
    double sum = 0.0, exact = 0.0;
    uint32_t crossed = 0;
    for (const shaders::PhotonExit& exit : gpu.read_photon_exits()) {
        const double b = std::hypot(static_cast<double>(exit.entry.y), static_cast<double>(exit.entry.z));
        if (exit.entry.w != 1.0f || b > 0.1) continue;
        sum += static_cast<double>(exit.weight.g);
        exact += std::exp(-kSigma * width * std::exp(-b * b / (2.0 * kS * kS)));
        ++crossed;
    }
    ASSERT_GT(crossed, 200u);
    const double photons = -std::log(sum / crossed), photons_exact = -std::log(exact / crossed);
    std::printf("optical depth through a Gaussian blob: eye ray %.4f, exact %.4f; photons %.4f, exact %.4f (%u; "
                "tolerance %.4f)\n",
                eye, kSigma * width, photons, photons_exact, crossed, tolerance);
    EXPECT_NEAR(eye, kSigma * width, tolerance);
    EXPECT_NEAR(photons, photons_exact, tolerance);
}

// The medium field's extinction (any channel, per metre) at voxel point p, as the shaders read it
// (transport_common.glsl: field_point, medium_block, brick_fetch): the field point clamped to texel
// centres, its block's brick, and the atlas filtered trilinearly between texel centres.
double field_extinction(const scene::MediumField& field, glm::dvec3 p) {
    const scene::MediumFieldLayout& layout = field.layout;
    const glm::dvec3 dims(layout.dims.x, layout.dims.y, layout.dims.z);
    const glm::dvec3 f = glm::clamp(p / static_cast<double>(layout.step), glm::dvec3(0.5), dims - 0.5);
    const glm::uvec3 blocks = (glm::uvec3(layout.dims.x, layout.dims.y, layout.dims.z) + (scene::kMediumFieldBlock - 1)) /
                              scene::kMediumFieldBlock;
    const glm::uvec3 b = glm::min(glm::uvec3(f), glm::uvec3(layout.dims.x, layout.dims.y, layout.dims.z) - 1u) /
                         scene::kMediumFieldBlock;
    const uint32_t brick = field.blocks[(b.z * blocks.y + b.y) * blocks.x + b.x].x;
    if (brick == MEDIUM_NO_BRICK) return 0.0;
    const glm::uvec3 atlas_bricks(layout.bricks.x, layout.bricks.y, layout.bricks.z);
    const glm::uvec3 at(brick % atlas_bricks.x, brick / atlas_bricks.x % atlas_bricks.y, brick / (atlas_bricks.x * atlas_bricks.y));
    const glm::ivec3 size(atlas_bricks * scene::kMediumBrickSide);
    const glm::dvec3 u = glm::dvec3(at * scene::kMediumBrickSide) + 1.0 + (f - glm::dvec3(b * scene::kMediumFieldBlock)) - 0.5;
    const glm::ivec3 low(glm::floor(u));
    const glm::dvec3 w = u - glm::dvec3(low);
    double value = 0.0;
    for (int c = 0; c < 8; ++c) {
        const glm::ivec3 corner = glm::clamp(low + glm::ivec3(c & 1, (c >> 1) & 1, c >> 2), glm::ivec3(0), size - 1);
        const double weight = ((c & 1) ? w.x : 1.0 - w.x) * ((c & 2) ? w.y : 1.0 - w.y) * ((c & 4) ? w.z : 1.0 - w.z);
        value += weight * static_cast<double>(field.extinction[static_cast<size_t>((corner.z * size.y + corner.y) * size.x + corner.x)].g);
    }
    return value;
}

// Eye rays' transmittance through the volumes is unbiased for the field they read (issue 39, point 3:
// residual ratio tracking). A blob about as wide as a field voxel (s = 6 cm, voxels of 6.25 cm) makes the field
// curve within each voxel, where a march by the midpoint rule is off by its curvature. The middle pixel's
// ray crosses it obliquely; its transmittance over 192 seeds (each its own tracking stream) has a mean
// within 4 standard errors of exp(-tau), tau the field's integral along the ray, taken here from the very
// field the shaders read (resample_volumes) by the trapezoid rule at a thousandth of a voxel. The same
// integral by the midpoint rule over the field's interpolation cells (the steps the march takes, and
// what the frames showed before tracking) is off by more than that: the test tells the two apart.
TEST_F(VolumeMediaTest, EyeRaysTransmittanceIsUnbiasedForTheFieldTheyRead) {
    constexpr double kS = 0.06, kVoxel = 0.02;
    const scene::Densities densities = gaussian_blob(kS, kVoxel, 32);
    json j = json::parse(R"({
        "camera": {"position": [-2.4, -1.3, -0.9], "target": [0.03, -0.02, 0.05], "up": [0, 1, 0], "fov_deg": 20},
        "image": {"width": 33, "height": 33},
        "light": {"type": "directional", "direction": [1, 0, 0], "intensity": 0},
        "object": {"position": [0.9, 0.9, 0.9], "scale": 0.03, "ior": 1.0, "extinction": [0, 0, 0], "scattering": [0, 0, 0]},
        "medium": {"extinction": [0, 0, 0], "scattering": [0, 0, 0], "fade": 0},
        "volumes": {"blob": {"asset": "blob", "extinction": [12, 12, 12], "scattering": [0, 0, 0]}},
        "volume": {"resolution": 32, "bounds": {"min": [-1, -1, -1], "max": [1, 1, 1]}},
        "photons": {"count": 4096},
        "floor": {"enabled": false},
        "environment": {"type": "uniform", "color": [1, 1, 1], "lights": false}})");
    constexpr int kSeeds = 192;
    double sum = 0.0, squares = 0.0;
    scene::SceneGpu gpu(kit());
    for (int seed = 1; seed <= kSeeds; ++seed) {
        j["photons"]["seed"] = seed;
        const protocol::SceneDocument document = protocol::parse_scene(j);
        gpu.run(scene::kAllPasses, document, worlds(document), nullptr, scene::run_options_for(scene::Quality::still),
                nullptr, densities);
        const double t = static_cast<double>(gpu.read_hdr()[16 * 33 + 16].g);
        sum += t;
        squares += t * t;
    }
    const double mean = sum / kSeeds;
    const double error = std::sqrt(std::max(squares / kSeeds - mean * mean, 0.0) / (kSeeds - 1));

    const protocol::SceneDocument document = protocol::parse_scene(j);
    const passes::GridGeometry& grid = gpu.grid();
    const scene::MediumField field = scene::resample_volumes(grid, document.volumes, densities);
    const glm::dvec3 eye(-2.4, -1.3, -0.9), target(0.03, -0.02, 0.05);
    const glm::dvec3 d = glm::normalize(target - eye);
    const glm::dvec3 start = (eye - glm::dvec3(grid.origin)) / static_cast<double>(grid.voxel_size);
    const glm::dvec3 dims(grid.dims.x, grid.dims.y, grid.dims.z);
    // The ray's span inside the lattice (voxels along d).
    double t0 = 0.0, t1 = 1e30;
    for (int a = 0; a < 3; ++a) {
        const double lo = (0.0 - start[a]) / d[a], hi = (dims[a] - start[a]) / d[a];
        t0 = std::max(t0, std::min(lo, hi));
        t1 = std::min(t1, std::max(lo, hi));
    }
    ASSERT_LT(t0, t1);
    const double h = static_cast<double>(grid.voxel_size);
    auto sigma = [&](double t) { return field_extinction(field, start + t * d); };
    double exact = 0.0;
    const int fine = static_cast<int>((t1 - t0) * 1000.0);
    for (int i = 0; i < fine; ++i) {
        const double a = t0 + (t1 - t0) * i / fine, b = t0 + (t1 - t0) * (i + 1) / fine;
        exact += 0.5 * (sigma(a) + sigma(b)) * (b - a) * h;
    }
    // The midpoint rule over the interpolation cells: steps end where the ray crosses a plane of texel centres.
    std::vector<double> ends{t0, t1};
    for (int a = 0; a < 3; ++a)
        for (double plane = 0.5; plane < dims[a]; plane += 1.0) {
            const double t = (plane * field.layout.step - start[a]) / d[a];
            if (t > t0 && t < t1) ends.push_back(t);
        }
    std::sort(ends.begin(), ends.end());
    double midpoint = 0.0;
    for (size_t i = 0; i + 1 < ends.size(); ++i) midpoint += sigma(0.5 * (ends[i] + ends[i + 1])) * (ends[i + 1] - ends[i]) * h;
    std::printf("eye rays through a narrow blob, %d seeds: transmittance %.5f (standard error %.5f), exp(-tau) %.5f "
                "(tau %.4f); the midpoint rule's %.5f\n",
                kSeeds, mean, error, std::exp(-exact), exact, std::exp(-midpoint));
    EXPECT_NEAR(mean, std::exp(-exact), 4.0 * error + 1e-5);
    EXPECT_GT(std::abs(std::exp(-midpoint) - std::exp(-exact)), 4.0 * error);  // what tracking is tested against
}

// A volume of density 1 filling the lattice with the fog's coefficients is that fog: its frame differs
// from the fog's by no more than two seeds of the volume differ (photons carry all light in both: the
// closed-form direct light knows only the homogeneous medium, so the volume's frame is the noisier), with
// single scattering and with photons' random walks of up to 4 bounces alike. No floor: its closed form
// takes the light through the homogeneous medium at every pixel, through the volumes by the photons' map,
// whose texels blur the spot's rim.
TEST_F(VolumeMediaTest, AConstantDensityVolumeIsTheHomogeneousFogOfItsCoefficients) {
    // 10 cm voxels from -2 m to 2 m: beyond the lattice on every side, so it is 1 throughout it.
    const scene::Densities densities{
        {"cloud", {std::make_shared<const volume::DensityGrid>(
                      volume::export_density(test::ramp_box_vdb({-20, -20, -20}, {19, 19, 19}, 0.1, 1.0f, 0.0f), "density", {}))}}};
    scene::RunOptions options = scene::run_options_for(scene::Quality::still);
    options.direct_light = false;
    for (const uint32_t bounces : {0u, 4u}) {
        SCOPED_TRACE(bounces);
        json fog = json::parse(R"({
            "image": {"width": 64, "height": 64, "exposure": 2}, "floor": {"enabled": false},
            "object": {"position": [1.3, 1.0, 1.3], "scale": 0.05, "ior": 1.0, "extinction": [0.6, 0.6, 0.6],
                       "scattering": [0.5, 0.5, 0.5], "phase": {"model": "henyey-greenstein", "g": 0.3}},
            "medium": {"extinction": [0.6, 0.6, 0.6], "scattering": [0.5, 0.5, 0.5],
                       "phase": {"model": "henyey-greenstein", "g": 0.3}, "fade": 0},
            "volume": {"resolution": 40, "bounds": {"min": [-1.5, -1.2, -1.5], "max": [1.5, 1.5, 1.5]}},
            "photons": {"count": 131072}})");
        fog["photons"]["max_bounces"] = bounces;
        json cloud = fog;
        for (const char* part : {"medium", "object"}) {
            cloud[part]["extinction"] = {0, 0, 0};
            cloud[part]["scattering"] = {0, 0, 0};
        }
        cloud["volumes"] = {{"cloud", {{"asset", "cloud"}, {"extinction", {0.6, 0.6, 0.6}}, {"scattering", {0.5, 0.5, 0.5}},
                                       {"phase", {{"model", "henyey-greenstein"}, {"g", 0.3}}}}}};
        char suffix[32];
        std::snprintf(suffix, sizeof suffix, "_%u_bounces", bounces);
        auto frame = [&](const json& j, const scene::Densities& with, const std::string& name) {
            const protocol::SceneDocument document = protocol::parse_scene(j);
            scene::SceneGpu gpu(kit());
            gpu.run(scene::kAllPasses, document, worlds(document), nullptr, options, nullptr, with);
            save(gpu, name + suffix);
            return gpu.read_hdr();
        };
        json cloud_seed = cloud;
        cloud_seed["photons"]["seed"] = 2;
        const auto fog_frame = frame(fog, {}, "fog");
        const auto volume = frame(cloud, densities, "constant_volume");
        const auto other_volume = frame(cloud_seed, densities, "constant_volume_other_seed");
        const double noise = testing::frame_difference(volume, other_volume);
        const double apart = testing::frame_difference(fog_frame, other_volume);
        std::printf("%u bounces: constant volume against fog %.4g, two seeds of the volume %.4g\n", bounces,
                    apart, noise);
        EXPECT_LT(apart, 1.5 * noise);
    }
}

// The white furnace for media (issue 39): a volume that scatters all it meets (extinction = scattering, a
// ramp of density 0.1 to 2.5 times 2 per metre, optical depths up to about 4 across it) in a uniform
// environment of radiance L that lights the scene, with photons' random walks of up to 64 bounces (none
// reached them here: the frames of 64 and 256 were the same), is in equilibrium: every pixel shows L.
// Past the volume the backdrop is L to rounding. Through it a pixel is L plus photon noise, which two
// seeds measure: sigma = RMS(a - b) / sqrt(2). A bias would show as a deviation from L beyond it: the
// frame's RMS deviation stays within 1.5 sigma (the constant-volume test's allowance), and its mean over
// the volume's pixels within 4 standard errors of the mean, sigma / sqrt(pixels).
TEST_F(VolumeMediaTest, ANonAbsorbingVolumeInAUniformEnvironmentIsAWhiteFurnace) {
    const double L = 0.7;
    const scene::Densities densities{
        {"ramp", {std::make_shared<const volume::DensityGrid>(
                     volume::export_density(test::ramp_box_vdb({-6, -6, -6}, {5, 5, 5}, 0.1, 1.3f, 0.2f), "density", {}))}}};
    auto frame = [&](uint32_t seed) {
        json j = json::parse(R"({
            "camera": {"position": [0, 0.2, 4], "target": [0, 0, 0], "fov_deg": 30},
            "image": {"width": 32, "height": 32},
            "light": {"type": "point", "position": [0, 3, 0], "intensity": 0},
            "object": {"position": [1.1, 1.1, 1.1], "scale": 0.03, "ior": 1.0, "extinction": [0, 0, 0],
                       "scattering": [0, 0, 0]},
            "medium": {"extinction": [0, 0, 0], "scattering": [0, 0, 0], "fade": 0},
            "volumes": {"ramp": {"asset": "ramp", "extinction": [2, 2, 2], "scattering": [2, 2, 2]}},
            "volume": {"resolution": 48, "bounds": {"min": [-1.2, -1.2, -1.2], "max": [1.2, 1.2, 1.2]}},
            "photons": {"count": 524288, "max_bounces": 64},
            "floor": {"enabled": false},
            "environment": {"type": "uniform", "color": [1, 1, 1], "intensity": 0.7, "lights": true}})");
        j["photons"]["seed"] = seed;
        const protocol::SceneDocument document = protocol::parse_scene(j);
        scene::SceneGpu gpu(kit());
        gpu.run(scene::kAllPasses, document, worlds(document), nullptr, scene::run_options_for(scene::Quality::still),
                nullptr, densities);
        save(gpu, "white_furnace_seed_" + std::to_string(seed));
        return gpu.read_hdr();
    };
    const auto a = frame(1), b = frame(2);
    double seed_squares = 0.0, deviation_squares = 0.0, deviation_sum = 0.0, backdrop_worst = 0.0;
    size_t through = 0;
    for (size_t i = 0; i < a.size(); ++i) {  // one channel: grey transport, the three are the same
        const double x = a[i].g, y = b[i].g;
        if (x == y) {  // no photon noise: the ray missed the volume
            backdrop_worst = std::max(backdrop_worst, std::abs(x - L));
            continue;
        }
        seed_squares += (x - y) * (x - y);
        deviation_squares += (x - L) * (x - L);
        deviation_sum += x - L;
        ++through;
    }
    ASSERT_GT(through, a.size() / 4);  // the volume covers a good part of the frame
    const double sigma = std::sqrt(seed_squares / static_cast<double>(through) / 2.0);
    const double rms = std::sqrt(deviation_squares / static_cast<double>(through));
    const double mean = deviation_sum / static_cast<double>(through);
    std::printf("white furnace: backdrop off L by %.1e; through the volume (%zu pixels) RMS off L %.4f, "
                "photon noise %.4f, mean off L %+.5f (standard error %.5f)\n",
                backdrop_worst, through, rms, sigma, mean, sigma / std::sqrt(static_cast<double>(through)));
    EXPECT_LT(backdrop_worst, 1e-4 * L);
    EXPECT_LT(rms, 1.5 * sigma);
    EXPECT_LT(std::abs(mean), 4.0 * sigma / std::sqrt(static_cast<double>(through)));
}

// A box of 20^3 voxels of 5 cm (1 m along x, the view's axis), density 1 and an emission grid of 1
// throughout, as two grids.
scene::Densities emitting_box() {
    auto grid = [](const std::string& name) {
        return std::make_shared<const volume::DensityGrid>(
            volume::export_density(test::ramp_box_vdb({0, -10, -10}, {19, 9, 9}, kRampVoxel, 1.0f, 0.0f, name), name, {}));
    };
    return {{"box", {grid("density"), grid("flame")}}};
}

// Emission alone (issue 39, point 4): through a box of emitted radiance L_e per metre and extinction
// sigma, each eye ray gathers the integral of L_e e^(-sigma s) over its depth l, L_e (1 - e^(-sigma l)) /
// sigma (L_e l without extinction), against a black backdrop. As for the ramp, each of the box's two faces
// may be smeared by half a lattice voxel: L_e h in all.
TEST_F(VolumeMediaTest, AnEmittingVolumeShowsTheIntegralOfItsEmissionAlongEachRay) {
    const glm::dvec3 colour(1.0, 0.5, 0.25);
    const double intensity = 2.0, depth = 1.0;
    for (const double sigma : {0.0, 2.0}) {
        SCOPED_TRACE(sigma);
        json j = json::parse(R"({
            "camera": {"position": [-3, 0, 0], "target": [0, 0, 0], "up": [0, 1, 0], "fov_deg": 30},
            "image": {"width": 16, "height": 16},
            "light": {"type": "directional", "direction": [1, 0, 0], "intensity": 0},
            "object": {"position": [1.3, 0.6, 0.6], "scale": 0.05, "ior": 1.0, "extinction": [0, 0, 0],
                       "scattering": [0, 0, 0]},
            "medium": {"extinction": [0, 0, 0], "scattering": [0, 0, 0], "fade": 0},
            "volumes": {"box": {"asset": "box", "scattering": [0, 0, 0],
                                "emission": {"grid": "flame", "color": [1, 0.5, 0.25], "intensity": 2}}},
            "volume": {"resolution": 48, "bounds": {"min": [-0.5, -0.75, -0.75], "max": [1.5, 0.75, 0.75]}},
            "floor": {"enabled": false},
            "environment": {"type": "uniform", "color": [0, 0, 0], "lights": false}})");
        j["volumes"]["box"]["extinction"] = {sigma, sigma, sigma};
        const protocol::SceneDocument document = protocol::parse_scene(j);
        scene::SceneGpu gpu(kit());
        gpu.run(scene::kAllPasses, document, worlds(document), nullptr, scene::run_options_for(scene::Quality::still),
                nullptr, emitting_box());
        save(gpu, sigma > 0.0 ? "emission_absorbed" : "emission_alone");
        const std::vector<glm::vec4> hdr = gpu.read_hdr();
        const double along = sigma > 0.0 ? (1.0 - std::exp(-sigma * depth)) / sigma : depth;
        const double tolerance = intensity * static_cast<double>(gpu.grid().voxel_size);
        for (uint32_t y : {7u, 8u})
            for (uint32_t x : {7u, 8u})
                for (int c = 0; c < 3; ++c) {
                    const double expected = intensity * colour[c] * along;
                    if (x == 7 && y == 7)
                        std::printf("emission, sigma %.0f, channel %d: eye ray %.4f, exact %.4f (tolerance %.4f)\n", sigma, c,
                                    static_cast<double>(hdr[y * 16 + x][c]), expected, tolerance);
                    EXPECT_NEAR(hdr[y * 16 + x][c], expected, tolerance) << x << ", " << y << " channel " << c;
                }
        EXPECT_EQ(hdr[0], glm::vec4(0.0f, 0.0f, 0.0f, hdr[0].w));  // the black backdrop beside it
    }
}

// Emission lights the scene (issue 39, point 4): photons leave a small emitting box 0.6 m above the floor
// in proportion to what it emits (4 pi L_e per unit volume, uniformly in direction), and the floor beneath
// takes the irradiance E(x) = integral of L_e cos(theta) / r^2 over the box. Compared as the mean over the
// map's texels within 0.3 m of the point below the box: the photons landing there are counted exactly
// enough that their mean is off by 1 / sqrt(hits) relative at one standard deviation; allowed 4 of them.
TEST_F(VolumeMediaTest, AnEmittingVolumeLightsTheFloorByTheInverseSquareLaw) {
    const double intensity = 3.0, height = 0.6;
    // 4^3 voxels of 5 cm, placed to fill [-0.1, 0.1] x [0.5, 0.7] x [-0.1, 0.1].
    auto grid = [](const std::string& name) {
        return std::make_shared<const volume::DensityGrid>(
            volume::export_density(test::ramp_box_vdb({0, 0, 0}, {3, 3, 3}, kRampVoxel, 1.0f, 0.0f, name), name, {}));
    };
    const scene::Densities densities{{"lamp", {grid("density"), grid("flame")}}};
    const protocol::SceneDocument document = protocol::parse_scene(json::parse(R"({
        "camera": {"position": [0, 2, 3], "target": [0, 0, 0], "fov_deg": 40},
        "image": {"width": 32, "height": 32},
        "light": {"type": "point", "position": [0, 3, 0], "intensity": 0},
        "object": {"position": [0.8, 0.9, 0.8], "scale": 0.03, "ior": 1.0, "extinction": [0, 0, 0],
                   "scattering": [0, 0, 0]},
        "medium": {"extinction": [0, 0, 0], "scattering": [0, 0, 0], "fade": 0},
        "volumes": {"lamp": {"asset": "lamp", "position": [-0.075, 0.525, -0.075], "extinction": [0, 0, 0],
                             "scattering": [0, 0, 0], "emission": {"grid": "flame", "intensity": 3}}},
        "volume": {"resolution": 48, "bounds": {"min": [-1, -0.05, -1], "max": [1, 1, 1]}},
        "photons": {"count": 262144},
        "floor": {"enabled": true, "height": 0, "checker": false},
        "environment": {"type": "uniform", "color": [0, 0, 0], "lights": false}})"));
    scene::SceneGpu gpu(kit());
    gpu.run(scene::kAllPasses, document, worlds(document), nullptr, scene::run_options_for(scene::Quality::still), nullptr,
            densities);
    save(gpu, "emission_on_the_floor");
    const auto& params = gpu.params();
    EXPECT_EQ(params.volume_emission.x, document.photons.count);  // the light is off: every photon from the box
    const auto irradiance = gpu.read_floor_irradiance();
    const uint32_t side = gpu.floor_map_side();
    const double texel = static_cast<double>(params.floor_map.z) / side;
    // The box by 10^3 pieces: E at a floor point.
    auto exact = [&](double x, double z) {
        double e = 0.0;
        constexpr int kPieces = 10;
        const double piece = 0.2 / kPieces;
        for (int i = 0; i < kPieces; ++i)
            for (int j = 0; j < kPieces; ++j)
                for (int k = 0; k < kPieces; ++k) {
                    const glm::dvec3 r = glm::dvec3(-0.1 + (i + 0.5) * piece, 0.5 + (j + 0.5) * piece, -0.1 + (k + 0.5) * piece) -
                                         glm::dvec3(x, 0.0, z);
                    const double r2 = glm::dot(r, r);
                    e += intensity * (r.y / std::sqrt(r2)) / r2 * piece * piece * piece;
                }
        return e;
    };
    double measured = 0.0, expected = 0.0, solid_angle = 0.0;
    int texels = 0;
    for (uint32_t j = 0; j < side; ++j)
        for (uint32_t i = 0; i < side; ++i) {
            const double x = static_cast<double>(params.floor_map.x) + (i + 0.5) * texel;
            const double z = static_cast<double>(params.floor_map.y) + (j + 0.5) * texel;
            if (x * x + z * z > 0.3 * 0.3) continue;
            measured += static_cast<double>(irradiance[j * side + i].g);
            expected += exact(x, z);
            solid_angle += height / std::pow(x * x + z * z + height * height, 1.5) * texel * texel;
            ++texels;
        }
    ASSERT_GT(texels, 20) << "the floor map does not reach below the box";
    measured /= texels;
    expected /= texels;
    const double hits = static_cast<double>(document.photons.count) * solid_angle / (4.0 * std::numbers::pi);
    std::printf("floor below an emitting box: irradiance %.4f W/m^2, exact %.4f (%d texels, about %.0f photons, "
                "tolerance %.4f)\n",
                measured, expected, texels, hits, 4.0 * expected / std::sqrt(hits));
    EXPECT_NEAR(measured, expected, 4.0 * expected / std::sqrt(hits));
}

// A volume written by OpenVDB from a function renders as the same function given procedurally (issue
// 39): the built-in smoke and flame (closed forms and noise), written to .vdb files by OpenVDB and read
// back as the daemon reads uploads, are the same grids value for value, and a frame of the flame in its
// soot renders byte for byte the same from either.
TEST_F(VolumeMediaTest, AVolumeWrittenByOpenVdbRendersAsTheSameFunctionGivenProcedurally) {
    scene::Densities procedural, written;
    for (const auto& [asset, grid] : {std::pair{"builtin.smoke", "density"}, std::pair{"builtin.flame", "density"},
                                      std::pair{"builtin.flame", "temperature"}}) {
        SCOPED_TRACE(std::string(asset) + " " + grid);
        const auto original = volume::builtin_density(asset, grid);
        ASSERT_TRUE(original);
        const volume::DensityGrid read = volume::export_density(test::vdb_of(*original, grid), grid, {});
        // OpenVDB keeps leaves in its own order: compared by origin.
        auto by_origin = [](std::vector<volume::DensityLeaf> leaves) {
            std::sort(leaves.begin(), leaves.end(), [](const auto& a, const auto& b) { return a.origin < b.origin; });
            return leaves;
        };
        EXPECT_EQ(read.index_to_world, original->index_to_world);
        EXPECT_EQ(by_origin(read.leaves), by_origin(original->leaves));
        if (std::string(asset) == "builtin.flame") {
            auto& grids = std::string(grid) == "density" ? procedural["fire"].density : procedural["fire"].emission;
            grids = original;
            (std::string(grid) == "density" ? written["fire"].density : written["fire"].emission) =
                std::make_shared<const volume::DensityGrid>(read);
        }
    }
    const protocol::SceneDocument document = protocol::parse_scene(json::parse(R"({
        "camera": {"position": [0, 0.3, 1.6], "target": [0, 0.22, 0], "fov_deg": 35},
        "image": {"width": 32, "height": 32},
        "light": {"type": "point", "position": [0, 2, 0], "intensity": 0},
        "object": {"position": [0.4, 0.1, 0.3], "scale": 0.03, "ior": 1.0, "extinction": [0, 0, 0], "scattering": [0, 0, 0]},
        "medium": {"extinction": [0.1, 0.1, 0.1], "scattering": [0.1, 0.1, 0.1], "fade": 0},
        "volumes": {"fire": {"asset": "builtin.flame", "extinction": [4, 4, 4], "scattering": [1, 1, 1],
                             "emission": {"temperature_grid": "temperature", "intensity": 4}}},
        "volume": {"resolution": 48, "bounds": {"min": [-0.5, -0.05, -0.5], "max": [0.5, 0.6, 0.5]}},
        "photons": {"count": 16384},
        "floor": {"enabled": true, "height": 0},
        "environment": {"type": "uniform", "color": [0, 0, 0], "lights": false}})"));
    auto frame = [&](const scene::Densities& grids) {
        scene::SceneGpu gpu(kit());
        gpu.run(scene::kAllPasses, document, worlds(document), nullptr, scene::run_options_for(scene::Quality::still),
                nullptr, grids);
        return gpu.read_ldr();
    };
    const auto from_function = frame(procedural);
    EXPECT_EQ(frame(written), from_function);
    EXPECT_NE(std::count(from_function.begin(), from_function.end(), from_function.front()),
              static_cast<std::ptrdiff_t>(from_function.size()));  // not one flat colour: the flame shows
}

// Memory follows the content (issue 39, point 5): the medium field keeps bricks only where volumes reach.
// The built-in smoke (0.5 x 1.2 x 0.5 m) in a lattice of 256 voxels over 4 m keeps the lattice's own
// voxel and takes under a fiftieth of a dense field's memory; the same smoke blown up 8 times coarsens the
// field until its bricks fit kMaxMediumBricks; the memory estimate is the field's.
TEST(MediumField, KeepsBricksOnlyWhereVolumesReach) {
    const passes::GridGeometry lattice = passes::fit_grid(glm::vec3(-2.0f), glm::vec3(2.0f), 256);
    std::map<std::string, protocol::DensityVolume> volumes{{"plume", {}}};
    volumes["plume"].asset = "builtin.smoke";
    const scene::Densities densities{{"plume", {volume::builtin_density("builtin.smoke", "density"), nullptr}}};
    const scene::MediumFieldLayout layout = scene::plan_medium_field(lattice, volumes, densities);
    const scene::MediumField field = scene::resample_volumes(lattice, volumes, densities);
    const uint64_t dense = lattice.dims.count() * 2 * sizeof(glm::vec4);
    std::printf("smoke in a 256^3 lattice: step %u, %u bricks planned, %u kept, %.1f MiB against %.1f MiB dense\n",
                layout.step, layout.brick_count, field.layout.brick_count,
                static_cast<double>(scene::medium_field_bytes(field.layout)) / 1048576.0, static_cast<double>(dense) / 1048576.0);
    EXPECT_EQ(layout.step, 1u);
    EXPECT_GT(field.layout.brick_count, 0u);
    EXPECT_LE(field.layout.brick_count, layout.brick_count);
    EXPECT_LT(scene::medium_field_bytes(field.layout), dense / 50);
    EXPECT_LE(scene::medium_field_bytes(field.layout), scene::medium_field_bytes(layout));
    volumes["plume"].scale = 8.0;
    const scene::MediumFieldLayout big = scene::plan_medium_field(lattice, volumes, densities);
    std::printf("smoke 8 times as large: step %u, %u bricks\n", big.step, big.brick_count);
    EXPECT_GT(big.step, 1u);
    EXPECT_LE(big.brick_count, scene::kMaxMediumBricks);
}

// Each empty block of the map names the largest aligned cube of blocks around it that holds no brick (its
// span k: rays cross that cube in one step), checked against the map itself: the cube of 2^k holds no
// brick, and the cube of 2^(k+1) holds one (or would pass the field's every face).
TEST(MediumField, EmptyBlocksNameTheLargestEmptyCubeAroundThem) {
    const passes::GridGeometry lattice = passes::fit_grid(glm::vec3(-2.0f), glm::vec3(2.0f), 256);
    std::map<std::string, protocol::DensityVolume> volumes{{"plume", {}}};
    volumes["plume"].asset = "builtin.smoke";
    volumes["plume"].position = {0.7, -0.4, 0.2};
    const scene::Densities densities{{"plume", {volume::builtin_density("builtin.smoke", "density"), nullptr}}};
    const scene::MediumField field = scene::resample_volumes(lattice, volumes, densities);
    const glm::ivec3 dims(static_cast<int>(field.layout.dims.x), static_cast<int>(field.layout.dims.y),
                          static_cast<int>(field.layout.dims.z));
    const glm::ivec3 blocks = (dims + static_cast<int>(scene::kMediumFieldBlock) - 1) / static_cast<int>(scene::kMediumFieldBlock);
    auto at = [&](glm::ivec3 b) { return field.blocks[static_cast<size_t>((b.z * blocks.y + b.y) * blocks.x + b.x)]; };
    auto cube_holds_brick = [&](glm::ivec3 b, uint32_t k) {
        const glm::ivec3 lo = (b >> static_cast<int>(k)) << static_cast<int>(k), hi = glm::min(lo + (1 << k), blocks);
        for (int z = lo.z; z < hi.z; ++z)
            for (int y = lo.y; y < hi.y; ++y)
                for (int x = lo.x; x < hi.x; ++x)
                    if (at({x, y, z}).x != MEDIUM_NO_BRICK) return true;
        return false;
    };
    size_t empty = 0, spanning = 0;
    for (int z = 0; z < blocks.z; ++z)
        for (int y = 0; y < blocks.y; ++y)
            for (int x = 0; x < blocks.x; ++x) {
                const glm::uvec2 block = at({x, y, z});
                if (block.x != MEDIUM_NO_BRICK) continue;
                ++empty;
                spanning += block.y > 0 ? 1 : 0;
                ASSERT_FALSE(cube_holds_brick({x, y, z}, block.y)) << x << ", " << y << ", " << z;
                if ((1 << (block.y + 1)) < 2 * std::max({blocks.x, blocks.y, blocks.z})) {
                    ASSERT_TRUE(cube_holds_brick({x, y, z}, block.y + 1)) << x << ", " << y << ", " << z;
                }
            }
    std::printf("smoke in a 256^3 lattice: %u bricks, %zu empty blocks, %zu of them in spans of 2^3 blocks or more\n",
                field.layout.brick_count, empty, spanning);
    EXPECT_GT(spanning, empty / 2);  // most empty blocks lie in cubes of 2^3 blocks or more
}

// The blackbody's colour against the CIE 1931 chromaticities of the Planckian locus (CIE 15:2004: the
// illuminant A at 2856 K, x 0.44757, y 0.40745; 6500 K, x 0.3135, y 0.3237), within the colour-matching
// fit's own error against the tabulated functions (about 0.002 in x and y); its brightness 1 at the
// reference and rising with the temperature; red before green before blue when warm; 0 at 0 K.
TEST(Blackbody, FollowsThePlanckianLocus) {
    const glm::dvec3 a = scene::blackbody_xyY(2856.0), d = scene::blackbody_xyY(6500.0);
    std::printf("blackbody chromaticity: 2856 K (%.4f, %.4f), 6500 K (%.4f, %.4f)\n", a.x, a.y, d.x, d.y);
    EXPECT_NEAR(a.x, 0.44757, 0.002);
    EXPECT_NEAR(a.y, 0.40745, 0.002);
    EXPECT_NEAR(d.x, 0.3135, 0.002);
    EXPECT_NEAR(d.y, 0.3237, 0.002);
    EXPECT_NEAR(scene::blackbody_xyY(scene::kBlackbodyReferenceKelvin).z, 1.0, 1e-9);
    EXPECT_GT(scene::blackbody_xyY(2000.0).z, 1.0);
    EXPECT_GT(scene::blackbody_xyY(3000.0).z, scene::blackbody_xyY(2000.0).z);
    const glm::dvec3 warm = scene::blackbody_rgb(1500.0);
    EXPECT_GT(warm.r, warm.g);
    EXPECT_GT(warm.g, warm.b);
    EXPECT_EQ(scene::blackbody_rgb(0.0), glm::dvec3(0.0));
    EXPECT_EQ(scene::blackbody_rgb(-5.0), glm::dvec3(0.0));
}

}  // namespace
}  // namespace refract
