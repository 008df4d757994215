// Fuzzes the environment upload's decoder (image::decode_environment: Radiance .hdr through stb_image,
// OpenEXR through the OpenEXR library, after our header and scanline checks). Invariants: only
// EnvironmentError is thrown; an accepted map is within the size limits, holds 3 floats per pixel, every
// one finite and not negative; an accepted .hdr re-encodes and decodes to the same size.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>

#include "fuzz_check.h"
#include "image/environment_map.h"

using namespace refract::image;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    const std::string bytes(reinterpret_cast<const char*>(data), size);
    EnvironmentMap map;
    try {
        map = decode_environment(bytes);
    } catch (const EnvironmentError&) {
        return 0;
    }
    REFRACT_FUZZ_CHECK(map.width >= 1 && map.width <= kMaxEnvironmentWidth);
    REFRACT_FUZZ_CHECK(map.height >= 1 && map.height <= kMaxEnvironmentHeight);
    REFRACT_FUZZ_CHECK(map.rgb.size() == size_t{map.width} * map.height * 3);
    for (float value : map.rgb) REFRACT_FUZZ_CHECK(std::isfinite(value) && value >= 0.0f);
    const EnvironmentMap again = decode_environment(encode_hdr(map));
    REFRACT_FUZZ_CHECK(again.width == map.width && again.height == map.height);
    return 0;
}
