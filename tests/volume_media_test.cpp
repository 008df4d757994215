// Volumes through the transport (issue 39, point 3): OpenVDB grids written here, exported as the daemon
// exports them, resampled into the medium field and crossed by photons and eye rays. Known answers: the
// transmittance through a linear ramp of density against exp(-its integral), a volume of constant
// density against the homogeneous fog of the same coefficients, and a volume that only scatters in a
// uniform environment against that environment's radiance (the white furnace). REFRACT_VOLUME_PNG_DIR set: each test
// writes its frames there to be looked at.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "gpu_fixture.h"
#include "image/png.h"
#include "render/medium_field.h"
#include "render/renderer.h"
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
    return {{"ramp", std::make_shared<const volume::DensityGrid>(volume::export_density(file, "density", {}))}};
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

// A volume of density 1 filling the lattice with the fog's coefficients is that fog: its frame differs
// from the fog's by no more than two seeds of the fog differ (photons carry all light in both: the
// closed-form direct light knows only the homogeneous medium), with single scattering and with photons'
// random walks of up to 4 bounces alike.
TEST_F(VolumeMediaTest, AConstantDensityVolumeIsTheHomogeneousFogOfItsCoefficients) {
    // 10 cm voxels from -2 m to 2 m: beyond the lattice on every side, so it is 1 throughout it.
    const scene::Densities densities{
        {"cloud", std::make_shared<const volume::DensityGrid>(
                      volume::export_density(test::ramp_box_vdb({-20, -20, -20}, {19, 19, 19}, 0.1, 1.0f, 0.0f), "density", {}))}};
    scene::RunOptions options = scene::run_options_for(scene::Quality::still);
    options.direct_light = false;
    for (const uint32_t bounces : {0u, 4u}) {
        SCOPED_TRACE(bounces);
        json fog = json::parse(R"({
            "image": {"width": 64, "height": 64, "exposure": 2},
            "object": {"position": [1.3, 1.0, 1.3], "scale": 0.05, "ior": 1.0, "extinction": [0.6, 0.6, 0.6],
                       "scattering": [0.5, 0.5, 0.5], "phase": {"model": "henyey-greenstein", "g": 0.3}},
            "medium": {"extinction": [0.6, 0.6, 0.6], "scattering": [0.5, 0.5, 0.5],
                       "phase": {"model": "henyey-greenstein", "g": 0.3}, "fade": 0},
            "volume": {"resolution": 40, "bounds": {"min": [-1.5, -1.2, -1.5], "max": [1.5, 1.5, 1.5]}},
            "photons": {"count": 131072}})");
        fog["photons"]["max_bounces"] = bounces;
        json fog_seed = fog;
        fog_seed["photons"]["seed"] = 2;
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
        const auto fog_frame = frame(fog, {}, "fog");
        const auto other_fog = frame(fog_seed, {}, "fog_other_seed");
        const auto volume = frame(cloud, densities, "constant_volume");
        const double noise = testing::frame_difference(fog_frame, other_fog);
        const double apart = testing::frame_difference(volume, other_fog);
        std::printf("%u bounces: constant volume against fog %.4g, two seeds of fog %.4g\n", bounces, apart, noise);
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
        {"ramp", std::make_shared<const volume::DensityGrid>(
                     volume::export_density(test::ramp_box_vdb({-6, -6, -6}, {5, 5, 5}, 0.1, 1.3f, 0.2f), "density", {}))}};
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

}  // namespace
}  // namespace refract
