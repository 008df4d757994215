// The PNG encoder (server/image/png.cpp), which deflates a frame's two halves on two threads and writes
// the chunks by hand: libpng reads every pixel back exactly, at any size down to one pixel, the bytes
// are the same on every run, and a pixel count that is not the size's is refused.
#include <gtest/gtest.h>

#include <cstdint>
#include <random>
#include <stdexcept>
#include <utility>
#include <vector>

#include "image/png.h"

namespace refract {
namespace {

std::vector<uint32_t> noise(uint32_t width, uint32_t height, uint32_t seed) {
    std::mt19937 random(seed);
    std::vector<uint32_t> pixels(size_t{width} * height);
    for (auto& p : pixels) p = static_cast<uint32_t>(random());
    return pixels;
}

// What decode_png gives back for `pixels`: their colour, opaque.
std::vector<uint32_t> opaque(std::vector<uint32_t> pixels) {
    for (auto& p : pixels) p |= 0xff000000u;
    return pixels;
}

TEST(Png, LibpngReadsEveryPixelBack) {
    for (const auto& [width, height] : std::vector<std::pair<uint32_t, uint32_t>>{{1, 1}, {2, 1}, {1, 2}, {7, 5}, {768, 482}}) {
        // Noise (which deflate cannot shrink: stored blocks) and a gradient (which it can).
        std::vector<uint32_t> gradient(size_t{width} * height);
        for (uint32_t y = 0; y < height; ++y)
            for (uint32_t x = 0; x < width; ++x) gradient[size_t{y} * width + x] = (x & 0xffu) | ((y & 0xffu) << 8) | (((x + y) & 0xffu) << 16);
        for (const auto& pixels : {noise(width, height, width * 31 + height), gradient}) {
            uint32_t w = 0, h = 0;
            const std::vector<uint32_t> back = image::decode_png(image::encode_png(pixels, width, height), w, h);
            EXPECT_EQ(w, width);
            EXPECT_EQ(h, height);
            EXPECT_EQ(back, opaque(pixels)) << width << "x" << height;
        }
    }
}

TEST(Png, TheSameFrameIsTheSameBytes) {
    const auto pixels = noise(320, 200, 7);
    const auto png = image::encode_png(pixels, 320, 200);
    for (int i = 0; i < 4; ++i) EXPECT_EQ(image::encode_png(pixels, 320, 200), png);
}

TEST(Png, APixelCountThatIsNotTheSizesIsRefused) {
    const auto pixels = noise(4, 4, 1);
    EXPECT_THROW(image::encode_png(pixels, 4, 5), std::runtime_error);
    EXPECT_THROW(image::encode_png(pixels, 5, 4), std::runtime_error);
    EXPECT_THROW(image::encode_png({}, 0, 0), std::runtime_error);
}

}  // namespace
}  // namespace refract
