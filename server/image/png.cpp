#include "image/png.h"

#include <png.h>

#include <cstdio>
#include <cstring>
#include <fstream>
#include <memory>
#include <stdexcept>

namespace refract::image {
namespace {

void on_png_error(png_structp png, png_const_charp message) {
    // libpng must not return from its error callback: unwind with an exception instead of longjmp.
    (void)png;
    throw std::runtime_error(std::string("libpng: ") + message);
}

void on_png_warning(png_structp, png_const_charp) {}

void append_bytes(png_structp png, png_bytep data, png_size_t length) {
    auto* out = static_cast<std::vector<uint8_t>*>(png_get_io_ptr(png));
    out->insert(out->end(), data, data + length);
}

struct ReadCursor {
    std::span<const uint8_t> data;
    size_t offset = 0;
};

void read_bytes(png_structp png, png_bytep data, png_size_t length) {
    auto* cursor = static_cast<ReadCursor*>(png_get_io_ptr(png));
    if (cursor->offset + length > cursor->data.size()) throw std::runtime_error("libpng: truncated PNG");
    std::memcpy(data, cursor->data.data() + cursor->offset, length);
    cursor->offset += length;
}

}  // namespace

std::vector<uint8_t> encode_png(std::span<const uint32_t> rgba, uint32_t width, uint32_t height) {
    if (rgba.size() != size_t{width} * height) throw std::runtime_error("encode_png: pixel count mismatch");
    png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, on_png_error, on_png_warning);
    if (!png) throw std::runtime_error("libpng: cannot create write struct");
    png_infop info = png_create_info_struct(png);
    std::vector<uint8_t> out;
    out.reserve(size_t{width} * height);
    try {
        if (!info) throw std::runtime_error("libpng: cannot create info struct");
        png_set_write_fn(png, &out, append_bytes, nullptr);
        png_set_IHDR(png, info, width, height, 8, PNG_COLOR_TYPE_RGB, PNG_INTERLACE_NONE,
                     PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
        png_set_compression_level(png, 1);
        png_set_filter(png, PNG_FILTER_TYPE_BASE, PNG_FILTER_SUB);
        png_write_info(png, info);
        std::vector<uint8_t> row(size_t{width} * 3);
        for (uint32_t y = 0; y < height; ++y) {
            for (uint32_t x = 0; x < width; ++x) {
                const uint32_t p = rgba[size_t{y} * width + x];
                row[3 * x] = static_cast<uint8_t>(p & 0xffu);
                row[3 * x + 1] = static_cast<uint8_t>((p >> 8) & 0xffu);
                row[3 * x + 2] = static_cast<uint8_t>((p >> 16) & 0xffu);
            }
            png_write_row(png, row.data());
        }
        png_write_end(png, nullptr);
    } catch (...) {
        png_destroy_write_struct(&png, &info);
        throw;
    }
    png_destroy_write_struct(&png, &info);
    return out;
}

std::vector<uint32_t> decode_png(std::span<const uint8_t> data, uint32_t& width, uint32_t& height) {
    png_structp png = png_create_read_struct(PNG_LIBPNG_VER_STRING, nullptr, on_png_error, on_png_warning);
    if (!png) throw std::runtime_error("libpng: cannot create read struct");
    png_infop info = png_create_info_struct(png);
    std::vector<uint32_t> pixels;
    try {
        if (!info) throw std::runtime_error("libpng: cannot create info struct");
        ReadCursor cursor{data, 0};
        png_set_read_fn(png, &cursor, read_bytes);
        png_read_info(png, info);
        width = png_get_image_width(png, info);
        height = png_get_image_height(png, info);
        if (png_get_bit_depth(png, info) != 8) throw std::runtime_error("decode_png: only 8-bit PNGs");
        const auto type = png_get_color_type(png, info);
        if (type != PNG_COLOR_TYPE_RGB && type != PNG_COLOR_TYPE_RGB_ALPHA)
            throw std::runtime_error("decode_png: only RGB or RGBA PNGs");
        const size_t channels = type == PNG_COLOR_TYPE_RGB ? 3 : 4;
        std::vector<uint8_t> row(size_t{width} * channels);
        pixels.resize(size_t{width} * height);
        for (uint32_t y = 0; y < height; ++y) {
            png_read_row(png, row.data(), nullptr);
            for (uint32_t x = 0; x < width; ++x) {
                const uint8_t* p = &row[x * channels];
                pixels[size_t{y} * width + x] = uint32_t{p[0]} | (uint32_t{p[1]} << 8) | (uint32_t{p[2]} << 16) | 0xff000000u;
            }
        }
    } catch (...) {
        png_destroy_read_struct(&png, &info, nullptr);
        throw;
    }
    png_destroy_read_struct(&png, &info, nullptr);
    return pixels;
}

void write_pfm(const std::string& path, std::span<const float> rgba, uint32_t width, uint32_t height) {
    if (rgba.size() != size_t{width} * height * 4) throw std::runtime_error("write_pfm: pixel count mismatch");
    std::ofstream out(path, std::ios::binary);
    if (!out) throw std::runtime_error("cannot write " + path);
    out << "PF\n" << width << " " << height << "\n-1.0\n";  // negative scale: little-endian
    std::vector<float> row(size_t{width} * 3);
    for (uint32_t y = height; y-- > 0;) {
        for (uint32_t x = 0; x < width; ++x)
            for (uint32_t c = 0; c < 3; ++c) row[3 * x + c] = rgba[(size_t{y} * width + x) * 4 + c];
        out.write(reinterpret_cast<const char*>(row.data()), static_cast<std::streamsize>(row.size() * sizeof(float)));
    }
    if (!out) throw std::runtime_error("write failed: " + path);
}

void write_file(const std::string& path, std::span<const uint8_t> bytes) {
    std::ofstream out(path, std::ios::binary);
    if (!out) throw std::runtime_error("cannot write " + path);
    out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
    if (!out) throw std::runtime_error("write failed: " + path);
}

}  // namespace refract::image
