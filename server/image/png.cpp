#include "image/png.h"

#include <png.h>
#include <zlib.h>

#include <cstdio>
#include <cstring>
#include <fstream>
#include <future>
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

void put_u32(std::vector<uint8_t>& out, uint32_t v) {
    out.insert(out.end(), {static_cast<uint8_t>(v >> 24), static_cast<uint8_t>(v >> 16), static_cast<uint8_t>(v >> 8),
                           static_cast<uint8_t>(v)});
}

// A PNG chunk: its length, type and data, and the CRC of type and data.
void append_chunk(std::vector<uint8_t>& out, const char* type, std::span<const uint8_t> data) {
    put_u32(out, static_cast<uint32_t>(data.size()));
    const size_t typed = out.size();
    out.insert(out.end(), type, type + 4);
    out.insert(out.end(), data.begin(), data.end());
    put_u32(out, static_cast<uint32_t>(crc32(0L, out.data() + typed, static_cast<uInt>(out.size() - typed))));
}

// Rows [first, last) as PNG scanlines (filter SUB: each byte less the one a pixel to its left), deflated
// raw at level 1: the piece of the zlib stream they make, with the Adler-32 and length of the scanlines.
// A piece that is not the last ends on a sync flush, so that the next piece's blocks follow it.
struct Piece {
    std::vector<uint8_t> deflated;
    uLong adler = 1;
    size_t length = 0;
};

Piece deflate_rows(std::span<const uint32_t> rgba, uint32_t width, uint32_t first, uint32_t last, bool final) {
    const size_t stride = 1 + size_t{width} * 3;
    std::vector<uint8_t> lines(stride * (last - first));
    for (uint32_t y = first; y < last; ++y) {
        uint8_t* line = lines.data() + stride * (y - first);
        line[0] = 1;  // SUB
        uint32_t left = 0;
        for (uint32_t x = 0; x < width; ++x) {
            const uint32_t p = rgba[size_t{y} * width + x];
            for (int c = 0; c < 3; ++c)
                line[1 + 3 * x + static_cast<uint32_t>(c)] = static_cast<uint8_t>((p >> (8 * c)) - (left >> (8 * c)));
            left = p;
        }
    }
    Piece piece;
    piece.length = lines.size();
    piece.adler = adler32(1L, lines.data(), static_cast<uInt>(lines.size()));
    z_stream stream{};
    if (deflateInit2(&stream, 1, Z_DEFLATED, -15, 8, Z_DEFAULT_STRATEGY) != Z_OK)
        throw std::runtime_error("zlib: cannot start deflate");
    piece.deflated.resize(deflateBound(&stream, static_cast<uLong>(lines.size())) + 16);
    stream.next_in = lines.data();
    stream.avail_in = static_cast<uInt>(lines.size());
    stream.next_out = piece.deflated.data();
    stream.avail_out = static_cast<uInt>(piece.deflated.size());
    const int result = deflate(&stream, final ? Z_FINISH : Z_SYNC_FLUSH);
    const bool whole = final ? result == Z_STREAM_END : result == Z_OK && stream.avail_in == 0;
    piece.deflated.resize(stream.total_out);
    deflateEnd(&stream);
    if (!whole) throw std::runtime_error("zlib: deflate did not finish");
    return piece;
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
    if (width == 0 || height == 0) throw std::runtime_error("encode_png: empty image");
    // The rows in two pieces, the second deflated on a thread of its own: on two cores the device is idle
    // while a frame encodes, and the encode of a full-size preview is a tenth of its frame. Always two
    // (one for a single row), whatever the machine, so that a frame's bytes do not depend on it.
    const uint32_t split = height / 2;
    auto second = std::async(std::launch::async, [&] { return deflate_rows(rgba, width, split, height, true); });
    Piece first = deflate_rows(rgba, width, 0, split, false);
    const Piece last = second.get();

    std::vector<uint8_t> idat;
    idat.reserve(2 + first.deflated.size() + last.deflated.size() + 4);
    idat.push_back(0x78);  // zlib: deflate, 32 KiB window
    idat.push_back(0x01);  // fastest compression, no preset dictionary; (0x78 << 8 | 0x01) % 31 == 0
    idat.insert(idat.end(), first.deflated.begin(), first.deflated.end());
    idat.insert(idat.end(), last.deflated.begin(), last.deflated.end());
    put_u32(idat, static_cast<uint32_t>(adler32_combine(first.adler, last.adler, static_cast<z_off_t>(last.length))));

    std::vector<uint8_t> header;
    put_u32(header, width);
    put_u32(header, height);
    header.insert(header.end(), {8, 2, 0, 0, 0});  // 8 bits, RGB, deflate, adaptive filters, no interlace
    std::vector<uint8_t> out = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
    out.reserve(8 + 25 + idat.size() + 12 + 12);
    append_chunk(out, "IHDR", header);
    append_chunk(out, "IDAT", idat);
    append_chunk(out, "IEND", {});
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
