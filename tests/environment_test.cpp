// Environment maps and environment light (../shared/OPTICS.md, "Environment light"): decoding uploads
// and refusing hostile ones, the document's environment fields, and on the GPU a uniform environment's
// irradiance on an open floor (pi L) and fluence in thin fog (4 pi L), and where a marked direction of
// a map appears in the frame. Expected values come from the formulas, computed here; tolerances from
// the photon counts.
#include <gtest/gtest.h>

#include <ImfRgbaFile.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <numbers>
#include <optional>
#include <sstream>

#include <nlohmann/json.hpp>

#include "gpu_fixture.h"
#include "image/environment_map.h"
#include "passes/environment_light.h"
#include "render/transport_inputs.h"

namespace refract {
namespace {

using nlohmann::json;
constexpr double kPi = std::numbers::pi;

image::EnvironmentMap constant_map(uint32_t width, uint32_t height, float value) {
    return {width, height, std::vector<float>(size_t{width} * height * 3, value)};
}

// An OpenEXR file of `map`'s pixels (alpha 1), written by the OpenEXR library and read back as bytes.
std::string exr_bytes(const image::EnvironmentMap& map) {
    const auto path = std::filesystem::temp_directory_path() / ("refract_env_" + std::to_string(::getpid()) + ".exr");
    {
        std::vector<Imf::Rgba> pixels;
        for (size_t i = 0; i < size_t{map.width} * map.height; ++i)
            pixels.emplace_back(map.rgb[3 * i], map.rgb[3 * i + 1], map.rgb[3 * i + 2], 1.0f);
        Imf::RgbaOutputFile file(path.c_str(), static_cast<int>(map.width), static_cast<int>(map.height), Imf::WRITE_RGBA);
        file.setFrameBuffer(pixels.data(), 1, map.width);
        file.writePixels(static_cast<int>(map.height));
    }
    std::ifstream in(path, std::ios::binary);
    std::ostringstream bytes;
    bytes << in.rdbuf();
    std::filesystem::remove(path);
    return bytes.str();
}

// The message decode_environment refuses `bytes` with ("" if it accepts them).
std::string refusal(const std::string& bytes) {
    try {
        image::decode_environment(bytes);
    } catch (const image::EnvironmentError& e) {
        return e.what();
    }
    return "";
}

TEST(EnvironmentMapTest, RadianceAndOpenExrFilesDecodeToTheirPixels) {
    image::EnvironmentMap map = constant_map(16, 8, 0.5f);
    map.rgb[3 * (3 * 16 + 5)] = 12.0f;  // red of pixel (5, 3)
    for (const std::string& bytes : {image::encode_hdr(map), exr_bytes(map)}) {
        const image::EnvironmentMap decoded = image::decode_environment(bytes);
        ASSERT_EQ(decoded.width, 16u);
        ASSERT_EQ(decoded.height, 8u);
        // RGBE keeps 8 bits of mantissa, half floats 11: both within 1%.
        EXPECT_NEAR(decoded.rgb[3 * (3 * 16 + 5)], 12.0f, 0.12f);
        EXPECT_NEAR(decoded.rgb[3 * (3 * 16 + 5) + 1], 0.5f, 0.005f);
        EXPECT_NEAR(decoded.rgb[0], 0.5f, 0.005f);
    }
}

TEST(EnvironmentMapTest, HostileFilesAreRefusedWithTheReason) {
    const image::EnvironmentMap map = constant_map(64, 32, 1.0f);
    const std::string hdr = image::encode_hdr(map);
    EXPECT_NE(refusal("P6\n64 32\n255\n").find("not a Radiance .hdr"), std::string::npos);
    EXPECT_NE(refusal(hdr.substr(0, hdr.size() / 2)).find("truncated"), std::string::npos);
    const std::string exr = exr_bytes(map);
    EXPECT_NE(refusal(exr.substr(0, exr.size() / 2)), "");
    EXPECT_NE(refusal(exr.substr(0, 4) + std::string(200, '\x7f')).find("OpenEXR"), std::string::npos);
    // A header claiming 100k x 100k pixels is refused on its header: 30 GB were never allocated.
    const std::string huge = "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 100000 +X 100000\n" + std::string(64, '\0');
    EXPECT_NE(refusal(huge).find("between 1 x 1 and 8192 x 4096"), std::string::npos) << refusal(huge);
    // The same in an OpenEXR header: a small file's data and display windows widened to 100k x 100k.
    std::string huge_exr = exr;
    for (const std::string attribute : {"dataWindow", "displayWindow"}) {
        const size_t at = huge_exr.find(attribute + std::string(1, '\0') + "box2i");
        ASSERT_NE(at, std::string::npos) << attribute;
        const int32_t corner = 99999;  // xMax, yMax after xMin, yMin and the attribute's size
        for (size_t k : {2u, 3u})
            std::memcpy(&huge_exr[at + attribute.size() + 7 + 4 + 4 * k], &corner, sizeof corner);
    }
    EXPECT_NE(refusal(huge_exr).find("8192"), std::string::npos) << refusal(huge_exr);
    for (float bad : {std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity(), -1.0f}) {
        image::EnvironmentMap poisoned = map;
        poisoned.rgb[3 * (7 * 64 + 9) + 2] = bad;
        EXPECT_NE(refusal(exr_bytes(poisoned)).find("pixel (9, 7)"), std::string::npos) << bad;
    }
}

std::string le32(uint32_t value) {
    std::string out(4, '\0');
    for (size_t i = 0; i < 4; ++i) out[i] = static_cast<char>((value >> (8 * i)) & 0xff);
    return out;
}

std::string exr_attribute(const std::string& name, const std::string& type, const std::string& value,
                          std::optional<uint32_t> declared = std::nullopt) {
    return name + '\0' + type + '\0' + le32(declared.value_or(static_cast<uint32_t>(value.size()))) + value;
}

// `exr` (written by the library) with `attributes` inserted before its first one.
std::string with_attributes(const std::string& exr, const std::string& attributes) {
    return exr.substr(0, 8) + attributes + exr.substr(8);
}

TEST(EnvironmentMapTest, OpenExrHeadersAreBoundedBeforeTheLibraryReadsThem) {
    const image::EnvironmentMap map = constant_map(64, 32, 1.0f);
    const std::string exr = exr_bytes(map);
    // The library takes a declared size at its word and allocates it: 2 GiB for this string, 16 GiB for
    // the preview, and again for each string of the vector.
    const std::string bomb = with_attributes(exr, exr_attribute("comment", "string", "abc", 0x7fffffff));
    EXPECT_NE(refusal(bomb).find("'comment' declares 2147483647 bytes"), std::string::npos) << refusal(bomb);
    const std::string present = with_attributes(exr, exr_attribute("comment", "string", "abc", 1000));
    EXPECT_NE(refusal(present.substr(0, 8 + 30)).find("truncated"), std::string::npos) << refusal(present.substr(0, 38));
    const std::string preview = with_attributes(exr, exr_attribute("preview", "preview", le32(65535) + le32(65535)));
    EXPECT_NE(refusal(preview).find("does not hold the pixels"), std::string::npos) << refusal(preview);
    const std::string strings =
        with_attributes(exr, exr_attribute("multiView", "stringvector", le32(0x7fffffff) + "left"));
    EXPECT_NE(refusal(strings).find("'multiView'"), std::string::npos) << refusal(strings);
    std::string many;
    for (int i = 0; i < 300; ++i) many += exr_attribute(std::string("a").append(std::to_string(i)), "int", le32(0));
    EXPECT_NE(refusal(with_attributes(exr, many)).find("more than 256 attributes"), std::string::npos);
    const std::string long_name = with_attributes(exr, exr_attribute(std::string(40, 'n'), "int", le32(0)));
    EXPECT_NE(refusal(long_name).find("longer than 31"), std::string::npos) << refusal(long_name);
    // A thousand channels of a full-size image: 2^35 samples in the library's line buffers.
    std::string channels;
    for (int i = 0; i < 1000; ++i) {
        channels.append("c").append(std::to_string(i)).append(1, '\0');
        channels.append(le32(1)).append(4, '\0').append(le32(1)).append(le32(1));
    }
    channels += '\0';
    const std::string wide = exr_attribute("channels", "chlist", channels) +
                             exr_attribute("dataWindow", "box2i", le32(0) + le32(0) + le32(8191) + le32(4095));
    // After the library's last attribute (they are sorted by name), so that these override its own.
    const size_t end = exr.find(std::string("screenWindowWidth") + '\0') + 18 + 6 + 4 + 4;
    const std::string wide_exr = exr.substr(0, end) + wide + exr.substr(end);
    EXPECT_NE(refusal(wide_exr).find("1000 channels of 8192 x 4096"), std::string::npos) << refusal(wide_exr);
    // Tiles of one pixel over 8192 x 4096: 256 MiB of tile offsets, of which the file holds none.
    std::string tiled = with_attributes(exr, exr_attribute("tiles", "tiledesc", le32(1) + le32(1) + std::string(1, '\0')) +
                                                 exr_attribute("dataWindow", "box2i", le32(0) + le32(0) + le32(8191) + le32(4095)));
    tiled[5] = 0x02;  // the version's tiled flag
    EXPECT_NE(refusal(tiled).find("tile offsets are missing"), std::string::npos) << refusal(tiled);
    EXPECT_NE(refusal(exr.substr(0, 4) + le32(2) + std::string("x", 1)).find("truncated"), std::string::npos);

    const image::EnvironmentSize size = image::environment_size(exr);
    EXPECT_EQ(size.width, 64u);
    EXPECT_EQ(size.height, 32u);
    EXPECT_EQ(size.decoded_bytes(), 64u * 32 * 3 * sizeof(float));
}

// A Radiance file of `height` rows of `width` pixels: the first `rle_rows` run-length encoded, then
// `flat_pixels` flat RGBE pixels.
std::string mixed_hdr(uint32_t width, uint32_t height, uint32_t rle_rows, size_t flat_pixels) {
    std::string file = "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y " + std::to_string(height) + " +X " +
                       std::to_string(width) + "\n";
    for (uint32_t row = 0; row < rle_rows; ++row) {
        file += {2, 2, static_cast<char>(width >> 8), static_cast<char>(width & 0xff)};
        for (char value : {'\x80', '\x80', '\x80', '\x81'}) file += {static_cast<char>(128 + width), value};
    }
    for (size_t pixel = 0; pixel < flat_pixels; ++pixel) file += "\x80\x80\x80\x81";
    return file;
}

TEST(EnvironmentMapTest, RadianceFilesAreRefusedWhenAnyMixOfRowsEndsEarly) {
    // A flat scanline after run-length encoded ones makes stb_image decode the whole image again, flat,
    // from there: it needs width x height flat pixels, not just the rows left.
    constexpr uint32_t kWidth = 16, kHeight = 6;
    for (uint32_t rle_rows = 0; rle_rows <= kHeight; ++rle_rows) {
        const std::string complete = mixed_hdr(kWidth, kHeight, rle_rows, rle_rows == kHeight ? 0 : kWidth * kHeight);
        EXPECT_EQ(refusal(complete), "") << rle_rows;
        if (rle_rows > 0 && rle_rows < kHeight) {
            const std::string rows_left = mixed_hdr(kWidth, kHeight, rle_rows, size_t{kWidth} * (kHeight - rle_rows));
            EXPECT_NE(refusal(rows_left).find("truncated"), std::string::npos) << rle_rows;
        }
        for (size_t cut = 1; cut < 40; cut += 3)
            EXPECT_NE(refusal(complete.substr(0, complete.size() - cut)), "") << rle_rows << " " << cut;
    }
    const std::string wrong_length = "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 1 +X 16\n" + std::string("\x02\x02\x00\x11", 4);
    EXPECT_NE(refusal(wrong_length + std::string(64, '\x81')).find("length"), std::string::npos);
    const image::EnvironmentSize size = image::environment_size(mixed_hdr(kWidth, kHeight, kHeight, 0));
    EXPECT_EQ(size.width, kWidth);
    EXPECT_EQ(size.height, kHeight);
}

TEST(EnvironmentMapTest, TheBuiltInSkyHasASunAboveTheHorizon) {
    const auto sky = image::built_in_environment("sky-sun");
    ASSERT_TRUE(sky);
    EXPECT_EQ(sky, image::built_in_environment("sky-sun"));  // made once
    EXPECT_EQ(image::built_in_environment("no-such"), nullptr);
    ASSERT_EQ(sky->width, 256u);
    ASSERT_EQ(sky->height, 128u);
    // The sun: 30 degrees up (row 128 / 3 = 42) at azimuth 90 degrees (column 64).
    EXPECT_GT(sky->rgb[3 * (42 * 256 + 64)], 1000.0f);
    EXPECT_LT(sky->rgb[3 * (100 * 256 + 64)], 1.0f);
}

// A uniform sky of radiance L gives an up-facing surface pi L (Lambert), whatever the map's size, also when
// a row straddles the horizon (an odd height); the ground half adds nothing; a sun disc at elevation e adds
// its radiance times its solid angle times sin(e).
TEST(EnvironmentMapTest, HorizontalIrradianceIsTheCosineWeightedUpperHemisphere) {
    for (const uint32_t height : {4u, 33u, 128u}) {
        image::EnvironmentMap map{2 * height, height, {}};
        for (uint32_t row = 0; row < height; ++row)
            for (uint32_t column = 0; column < map.width; ++column) {
                const bool sky = row + 0.5 < height / 2.0;
                map.rgb.insert(map.rgb.end(), {sky ? 2.0f : 9.0f, sky ? 1.0f : 9.0f, 0.0f});
            }
        // With an odd height the middle row is half sky, half ground: fill it with the sky's radiance.
        if (height % 2 == 1)
            for (uint32_t column = 0; column < map.width; ++column) {
                float* rgb = &map.rgb[3 * ((height / 2) * size_t{map.width} + column)];
                rgb[0] = 2.0f, rgb[1] = 1.0f;
            }
        const auto irradiance = image::horizontal_irradiance(map);
        EXPECT_NEAR(irradiance[0], 2.0 * std::numbers::pi, 1e-9) << height;
        EXPECT_NEAR(irradiance[1], std::numbers::pi, 1e-9) << height;
        EXPECT_EQ(irradiance[2], 0.0);
    }
    // The built-in sky's sun (2000 W/(m^2 sr) red over a 2.5 degree disc, 30 degrees up) adds its radiance times
    // its solid angle times sin(30 deg) to a sky no brighter than 0.75 in red; the disc drawn with 1.4 degree
    // pixels by their centres covers between half and twice its true solid angle.
    const auto irradiance = image::horizontal_irradiance(*image::built_in_environment("sky-sun"));
    const double sun = 2000.0 * 2.0 * std::numbers::pi * (1.0 - std::cos(2.5 * std::numbers::pi / 180.0)) * 0.5;
    EXPECT_GT(irradiance[0], 0.5 * sun);
    EXPECT_LT(irradiance[0], 2.0 * sun + 0.75 * std::numbers::pi);
}

TEST(EnvironmentProtocolTest, ImageEnvironmentsNeedANameAndARotationInRange) {
    const auto doc = protocol::parse_scene(
        {{"environment", {{"type", "image"}, {"image", "sky-sun"}, {"rotation_deg", 45.0}, {"intensity", 2.0}}}});
    EXPECT_EQ(doc.environment.type, protocol::EnvironmentKind::image);
    EXPECT_EQ(doc.environment.image, "sky-sun");
    EXPECT_EQ(protocol::parse_scene(protocol::to_json(doc)), doc);
    auto pointer_of = [](const json& j) {
        try {
            protocol::parse_scene(j);
        } catch (const protocol::ValidationError& e) {
            return e.pointer();
        }
        return std::string("accepted");
    };
    // The edit that set only the type is blamed for the missing name.
    EXPECT_EQ(pointer_of({{"environment", {{"type", "image"}}}}), "/environment/type");
    EXPECT_EQ(pointer_of({{"environment", {{"type", "image"}, {"image", "a/b"}}}}), "/environment/image");
    EXPECT_EQ(pointer_of({{"environment", {{"rotation_deg", 400.0}}}}), "/environment/rotation_deg");
    EXPECT_EQ(pointer_of({{"environment", {{"rotation_deg", "north"}}}}), "/environment/rotation_deg");
    // A merge patch back to the sky keeps the image's name, unused.
    const auto sky = protocol::apply_merge_patch(doc, {{"environment", {{"type", "sky"}}}});
    EXPECT_EQ(sky.environment.type, protocol::EnvironmentKind::sky);
    EXPECT_EQ(sky.environment.image, "sky-sun");
}

TEST(EnvironmentLightTest, AUniformEnvironmentsTablesHoldItsRadianceAndPower) {
    auto doc = protocol::parse_scene({{"environment", {{"type", "uniform"}, {"color", {1, 1, 1}}, {"intensity", 0.5}}},
                                      {"floor", {{"enabled", false}}}});
    const auto open = passes::make_environment_light(scene::environment_source(doc, nullptr));
    EXPECT_NEAR(open.sampled, 4.0 * kPi * 0.5, 1e-9);  // the whole sphere
    EXPECT_NEAR(open.floor_irradiance.g, kPi * 0.5, 1e-5);
    doc.floor.enabled = true;
    EXPECT_NEAR(passes::make_environment_light(scene::environment_source(doc, nullptr)).sampled, 2.0 * kPi * 0.5, 1e-9);  // the upper half
    doc.environment.lights = false;  // a backdrop only: the map stays, its power goes
    const auto backdrop = passes::make_environment_light(scene::environment_source(doc, nullptr));
    EXPECT_FALSE(backdrop.lights());
    EXPECT_EQ(backdrop.width, 1u);
    EXPECT_EQ(backdrop.floor_irradiance.g, 0.0f);
    doc.environment.lights = true;
    doc.environment.type = protocol::EnvironmentKind::sky;
    EXPECT_FALSE(passes::make_environment_light(scene::environment_source(doc, nullptr)).lights());
}

// A scene with nothing in it to see but the environment: no fog, an index-matched object without
// extinction, the light off.
protocol::SceneDocument open_scene(const json& patch) {
    json base = {{"light", {{"type", "directional"}, {"intensity", 0.0}}},
                 {"medium", {{"ior", 1.0}, {"extinction", {0, 0, 0}}, {"scattering", {0, 0, 0}}}},
                 {"object", {{"ior", 1.0}, {"extinction", {0, 0, 0}}, {"scattering", {0, 0, 0}}, {"scale", 0.5}}},
                 {"volume", {{"resolution", 32}, {"bounds", {{"min", {-1, -1, -1}}, {"max", {1, 1, 1}}}}}},
                 {"image", {{"width", 16}, {"height", 16}}},
                 {"photons", {{"count", 1 << 18}}}};
    base.merge_patch(patch);
    return protocol::parse_scene(base);
}

class EnvironmentGpuTest : public testing::GpuTest {};

// A uniform environment of radiance L over the open floor: irradiance pi L (the closed form), and the
// photons' floor map of what the grid changes stays at zero, since nothing in the grid stops or bends
// them (each takes its flux away where it would land and adds it where it lands: the same texels).
TEST_F(EnvironmentGpuTest, UniformEnvironmentLightsTheOpenFloorToPiL) {
    constexpr double kRadiance = 0.5;
    const auto doc = open_scene({{"environment", {{"type", "uniform"}, {"color", {1, 1, 1}}, {"intensity", kRadiance}}},
                                 {"floor", {{"enabled", true}, {"height", -1.0}}}});
    scene::SceneGpu gpu(kit());
    gpu.run(scene::kAllPasses, doc, worlds(doc), nullptr);
    EXPECT_EQ(gpu.params().environment.z, doc.photons.count);  // every photon from the environment
    const auto irradiance = gpu.read_floor_irradiance();
    const auto change = gpu.read_floor_map();
    double sum = 0.0, squares = 0.0;
    for (size_t i = 0; i < irradiance.size(); ++i) {
        sum += static_cast<double>(irradiance[i].g);
        squares += static_cast<double>(change[i].g) * static_cast<double>(change[i].g);
    }
    const double texels = static_cast<double>(irradiance.size());
    // The closed form, bar the map's rounding (below): float precision.
    std::printf("open floor: irradiance %.6f W/m^2 against pi L = %.6f\n", sum / texels, kPi * kRadiance);
    EXPECT_NEAR(sum / texels, kPi * kRadiance, 1e-3 * kPi * kRadiance);
    // The map's fixed point rounds each splat up or down, by under one unit (variance at most 1/4):
    // even if every photon landed in the map, a texel would take 2 (taken and added) x 4 (bilinear)
    // x N / texels splats, so the change's RMS stays below sqrt(2 N / texels) units.
    const auto& params = gpu.params();
    const double texel_side = static_cast<double>(params.floor_map.z) / gpu.floor_map_side();
    const double unit = static_cast<double>(params.photon_flux.w) /
                        (static_cast<double>(params.stepping.w) * texel_side * texel_side);
    EXPECT_LT(std::sqrt(squares / texels), unit * std::sqrt(2.0 * doc.photons.count / texels)) << "unit " << unit;
}

// A uniform environment of radiance L with the floor off: fluence 4 pi L everywhere (OPTICS.md), here
// in fog thin enough (optical depth across the grid 0.004) to take photon deposits and change little.
// The mean over a ball of radius rho is the photons' track length in it over its volume: a photon
// crosses it with probability p = (rho / R)^2 (R: the disc's radius), along a chord of mean 4 rho / 3
// and mean square 2 rho^2, so its relative standard deviation is (3 sqrt(2) / 4) / sqrt(N p).
TEST_F(EnvironmentGpuTest, UniformEnvironmentGivesFluenceFourPiLInThinFog) {
    constexpr double kRadiance = 0.5, kSigma = 0.001;
    const auto doc = open_scene({{"environment", {{"type", "uniform"}, {"color", {1, 1, 1}}, {"intensity", kRadiance}}},
                                 {"medium", {{"extinction", {kSigma, kSigma, kSigma}}, {"scattering", {kSigma, kSigma, kSigma}}}},
                                 {"floor", {{"enabled", false}}}});
    scene::SceneGpu gpu(kit());
    gpu.run(scene::kAllPasses, doc, worlds(doc), nullptr);
    const auto& grid = gpu.grid();
    const glm::dvec3 centre = 0.5 * (glm::dvec3(grid.origin) + glm::dvec3(grid.max_corner()));
    const double side = static_cast<double>(grid.max_corner().x - grid.origin.x);
    const double rho = 0.4 * side, disc = static_cast<double>(gpu.params().environment_frame.z);
    const auto radiance = gpu.read_radiance();
    double sum = 0.0, count = 0.0;
    for (uint32_t z = 0; z < grid.dims.z; ++z)
        for (uint32_t y = 0; y < grid.dims.y; ++y)
            for (uint32_t x = 0; x < grid.dims.x; ++x) {
                const glm::dvec3 p = glm::dvec3(grid.origin) + (glm::dvec3(x, y, z) + 0.5) * static_cast<double>(grid.voxel_size);
                if (glm::length(p - centre) > rho) continue;
                sum += static_cast<double>(radiance[(size_t{z} * grid.dims.y + y) * grid.dims.x + x].g);
                ++count;
            }
    const double mean = sum / count;
    const double p = (rho / disc) * (rho / disc);
    const double relative_sigma = 3.0 * std::sqrt(2.0) / 4.0 / std::sqrt(static_cast<double>(doc.photons.count) * p);
    // Photons reach the ball through at most half the grid's diagonal of fog: exp(-kSigma d) within 0.2%.
    const double attenuation = kSigma * 0.5 * std::sqrt(3.0) * side;
    const double expected = 4.0 * kPi * kRadiance;
    std::printf("thin fog: fluence %.5f W/m^2 against 4 pi L = %.5f, sigma %.5f (%.0f voxels)\n", mean, expected,
                expected * relative_sigma, count);
    EXPECT_NEAR(mean, expected * (1.0 - 0.5 * attenuation), expected * (4.0 * relative_sigma + 0.5 * attenuation))
        << "relative sigma " << relative_sigma;
}

// A dark map with one bright texel: the frame shows it where the camera's projection of that texel's
// centre falls, and a rotation of the environment moves it there too.
TEST_F(EnvironmentGpuTest, AMarkedDirectionAppearsWhereTheCameraSaysIt) {
    constexpr uint32_t kWidth = 64, kHeight = 32, kU = 20, kV = 13;
    image::EnvironmentMap map = constant_map(kWidth, kHeight, 0.01f);
    for (int c = 0; c < 3; ++c) map.rgb[3 * (kV * kWidth + kU) + static_cast<size_t>(c)] = 100.0f;
    for (double rotation : {0.0, 30.0}) {
        const double theta = kPi * (kV + 0.5) / kHeight, phi = 2.0 * kPi * (kU + 0.5) / kWidth + rotation * kPi / 180.0;
        const glm::dvec3 towards(std::sin(theta) * std::cos(phi), std::cos(theta), std::sin(theta) * std::sin(phi));
        const glm::dvec3 eye(0.0, 0.0, 0.0);
        const auto doc = open_scene({{"environment", {{"type", "image"}, {"image", "marked"}, {"rotation_deg", rotation}}},
                                     {"floor", {{"enabled", false}}},
                                     {"camera", {{"position", {eye.x, eye.y, eye.z}},
                                                 {"target", {towards.x, towards.y, towards.z}},
                                                 {"fov_deg", 40.0}}},
                                     {"image", {{"width", 64}, {"height", 64}}}});
        scene::SceneGpu gpu(kit());
        gpu.run(scene::kAllPasses, doc, worlds(doc), nullptr, {}, &map);
        const auto hdr = gpu.read_hdr();
        double sx = 0.0, sy = 0.0, weight = 0.0;
        for (uint32_t y = 0; y < 64; ++y)
            for (uint32_t x = 0; x < 64; ++x)
                if (hdr[y * 64 + x].g > 50.0f) {
                    sx += x + 0.5;
                    sy += y + 0.5;
                    ++weight;
                }
        ASSERT_GT(weight, 0.0) << "rotation " << rotation;
        // The camera looks straight at the texel's centre: it lies at the frame's centre, and the texel
        // (5.6 degrees across, 14 pixels at 40 degrees over 64) covers many pixels around it.
        EXPECT_NEAR(sx / weight, 32.0, 1.0) << "rotation " << rotation;
        EXPECT_NEAR(sy / weight, 32.0, 1.0) << "rotation " << rotation;
        EXPECT_GT(weight, 20.0);
    }
}

// The same texel seen in a mirror: the flat top face of a cube of index 4 (its other faces outside the
// grid; the face on a voxel boundary, so its smoothed shell's normal is exactly +y) reflects the camera's
// central ray, tilted 45 degrees down, into the texel's direction, so the texel appears at the frame's
// centre, weighted by the face's Fresnel reflectance at 45 degrees.
TEST_F(EnvironmentGpuTest, AMarkedDirectionAppearsWhereItsMirrorImageShouldBe) {
    constexpr uint32_t kWidth = 64, kHeight = 32, kU = 20, kV = 8;
    image::EnvironmentMap map = constant_map(kWidth, kHeight, 0.01f);
    for (int c = 0; c < 3; ++c) map.rgb[3 * (kV * kWidth + kU) + static_cast<size_t>(c)] = 100.0f;
    const double theta = kPi * (kV + 0.5) / kHeight, phi = 2.0 * kPi * (kU + 0.5) / kWidth;
    const glm::dvec3 towards(std::sin(theta) * std::cos(phi), std::cos(theta), std::sin(theta) * std::sin(phi));
    const glm::dvec3 looking(towards.x, -towards.y, towards.z);  // the mirror image about the face
    const glm::dvec3 eye = -2.0 * looking;                           // looking at the face's point (0, 0, 0)
    const auto doc = open_scene({{"environment", {{"type", "image"}, {"image", "marked"}}},
                                 {"floor", {{"enabled", false}}},
                                 {"object", {{"mesh", "cube"}, {"ior", 4.0}, {"scale", 2.0}, {"position", {0, -2, 0}}}},
                                 {"volume", {{"resolution", 64}, {"bounds", {{"min", {-1, -1, -1}}, {"max", {1, 0.5, 1}}}}}},
                                 {"camera", {{"position", {eye.x, eye.y, eye.z}}, {"target", {0, 0, 0}}, {"fov_deg", 40.0}}},
                                 {"image", {{"width", 64}, {"height", 64}}}});
    scene::SceneGpu gpu(kit());
    gpu.run(scene::kAllPasses, doc, worlds(doc), nullptr, {}, &map);
    const double incidence = std::acos(std::abs(looking.y));
    const double ct = std::sqrt(1.0 - std::pow(std::sin(incidence) / 4.0, 2.0)), ci = std::cos(incidence);
    const double rs = (ci - 4.0 * ct) / (ci + 4.0 * ct), rp = (4.0 * ci - ct) / (4.0 * ci + ct);
    const double reflected = 100.0 * (rs * rs + rp * rp) / 2.0;
    const auto hdr = gpu.read_hdr();
    double sx = 0.0, sy = 0.0, weight = 0.0;
    for (uint32_t y = 0; y < 64; ++y)
        for (uint32_t x = 0; x < 64; ++x)
            if (static_cast<double>(hdr[y * 64 + x].g) > 0.5 * reflected) {
                sx += x + 0.5;
                sy += y + 0.5;
                ++weight;
            }
    ASSERT_GT(weight, 20.0) << "reflected radiance " << reflected;
    EXPECT_NEAR(sx / weight, 32.0, 1.0);
    EXPECT_NEAR(sy / weight, 32.0, 1.0);
}

}  // namespace
}  // namespace refract
