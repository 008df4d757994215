// Frame encoding: 8-bit RGB PNG (fast settings: a render service pays for encode time on every frame),
// deflated with zlib by hand in two pieces at once, read back through libpng; and float PFM for the
// linear radiance before exposure.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace refract::image {

// `rgba` is width*height packed RGBA8 (alpha ignored). Compression level 1, one filter (SUB), the rows'
// two halves deflated on two threads: the same bytes on any machine.
std::vector<uint8_t> encode_png(std::span<const uint32_t> rgba, uint32_t width, uint32_t height);

// Decodes an 8-bit RGB or RGBA PNG into packed RGBA8 (for tests and tools). Throws std::runtime_error.
std::vector<uint32_t> decode_png(std::span<const uint8_t> png, uint32_t& width, uint32_t& height);

// Writes a colour PFM (little-endian float RGB, rows bottom to top as the format requires).
// `rgba` holds 4 floats per pixel, top row first. Throws std::runtime_error on I/O failure.
void write_pfm(const std::string& path, std::span<const float> rgba, uint32_t width, uint32_t height);

void write_file(const std::string& path, std::span<const uint8_t> bytes);

}  // namespace refract::image
