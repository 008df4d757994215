// Equirectangular environment maps: decoding uploads (Radiance .hdr through stb_image, OpenEXR through
// the OpenEXR library), with the limits a service needs, and the built-in environments that ship with
// Refract (generated here, so the default install downloads nothing).
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace refract::image {

// Linear RGB radiance (W/(m^2 sr)), rows top to bottom. Row v spans polar angle theta in
// [pi v / H, pi (v + 1) / H] from +y (the zenith); column u spans azimuth phi in [2 pi u / W,
// 2 pi (u + 1) / W], the direction (sin theta cos phi, cos theta, sin theta sin phi).
struct EnvironmentMap {
    uint32_t width = 0, height = 0;
    std::vector<float> rgb;  // 3 floats per pixel, row by row
};

// The largest map accepted: 8192 x 4096 (32 Mpixels, 384 MiB as floats, a 16k-wide map's detail is
// lost at any radiance-grid resolution Refract renders). Checked on the header, before any pixel is read.
inline constexpr uint32_t kMaxEnvironmentWidth = 8192;
inline constexpr uint32_t kMaxEnvironmentHeight = 4096;

// An upload that is not a usable environment; the message says why, for the user.
class EnvironmentError : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

// Decodes a Radiance .hdr ("#?RADIANCE" / "#?RGBE") or OpenEXR file, told apart by their first bytes.
// Throws EnvironmentError for another format, a header over the limits, a truncated or corrupt file,
// and any pixel that is NaN, infinite or negative.
EnvironmentMap decode_environment(std::string_view bytes);

// A map's size as its header declares it.
struct EnvironmentSize {
    uint32_t width = 0, height = 0;
    // The host memory the decoded map takes (EnvironmentMap::rgb).
    uint64_t decoded_bytes() const { return uint64_t{width} * height * 3 * sizeof(float); }
};

// The size `bytes` declare, from the header alone (checked as decode_environment checks headers), so a
// caller can tell what decoding would take before anything is allocated. Throws EnvironmentError.
EnvironmentSize environment_size(std::string_view bytes);

// The irradiance (W/m^2, RGB) the map at intensity 1 gives a surface facing up: its radiance times the
// cosine from the zenith over the upper hemisphere, each row weighted by its exact cosine-weighted solid
// angle, so a uniform map of radiance L gives pi L. Rotation about the vertical does not change it; what a
// client compares lights with when it balances an environment against them.
std::array<double, 3> horizontal_irradiance(const EnvironmentMap& map);

// Writes `map` as an uncompressed Radiance .hdr (RGBE); for tests and tools.
std::string encode_hdr(const EnvironmentMap& map);

// The environments every install has, by name ("sky-sun": a clear sky with a sun 30 degrees up).
std::vector<std::string> built_in_environment_names();
// The built-in environment `name`, made once: the same pointer every time, so a renderer holding it never
// sees it change; nullptr for any other name.
std::shared_ptr<const EnvironmentMap> built_in_environment(std::string_view name);

}  // namespace refract::image
