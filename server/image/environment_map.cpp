#include "image/environment_map.h"

#include <ImfArray.h>
#include <ImfHeader.h>
#include <ImfIO.h>
#include <ImfRgbaFile.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <numbers>
#include <optional>

#define STB_IMAGE_IMPLEMENTATION
#define STBI_ONLY_HDR
#define STBI_NO_STDIO
#include <stb_image.h>

namespace refract::image {
namespace {

void check_size(int64_t width, int64_t height) {
    if (width < 1 || height < 1 || width > kMaxEnvironmentWidth || height > kMaxEnvironmentHeight)
        throw EnvironmentError("the map is " + std::to_string(width) + " x " + std::to_string(height) +
                               " pixels; environments must be between 1 x 1 and " +
                               std::to_string(kMaxEnvironmentWidth) + " x " + std::to_string(kMaxEnvironmentHeight));
}

void check_pixels(const EnvironmentMap& map) {
    for (size_t i = 0; i < map.rgb.size(); ++i) {
        const float value = map.rgb[i];
        if (!std::isfinite(value) || value < 0.0f) {
            const size_t pixel = i / 3;
            throw EnvironmentError("pixel (" + std::to_string(pixel % map.width) + ", " +
                                   std::to_string(pixel / map.width) + ") is " + std::to_string(value) +
                                   "; radiance must be finite and not negative");
        }
    }
}

bool starts_with(std::string_view bytes, std::string_view prefix) { return bytes.substr(0, prefix.size()) == prefix; }
bool is_hdr(std::string_view bytes) { return starts_with(bytes, "#?RADIANCE\n") || starts_with(bytes, "#?RGBE\n"); }
bool is_exr(std::string_view bytes) { return starts_with(bytes, std::string_view("\x76\x2f\x31\x01", 4)); }
constexpr const char* kNotAnEnvironment = "not a Radiance .hdr (#?RADIANCE) or OpenEXR file";

// stb_image reads past the end of a Radiance file as zeros, so a truncated upload would decode as a map
// with a black bottom. Its scanlines are walked here first, the way stb_image decodes them, and a file
// that ends early is refused. A scanline not marked run-length encoded sends stb_image back to the first
// row, decoding the whole image again as flat RGBE from there: that takes 4 bytes per pixel of the image
// from where that scanline starts, whatever the rows before it held.
void check_hdr_complete(std::string_view bytes, uint32_t width, uint32_t height) {
    size_t at = bytes.find("\n\n");
    if (at == std::string_view::npos) throw EnvironmentError("the Radiance header has no end");
    at = bytes.find('\n', at + 2);  // the resolution line
    if (at == std::string_view::npos) throw EnvironmentError("the Radiance header has no resolution line");
    ++at;
    auto need = [&](size_t count) {
        if (bytes.size() - at < count) throw EnvironmentError("the Radiance file is truncated");
    };
    const size_t flat_image = 4 * size_t{width} * height;
    if (width < 8 || width >= 32768) {
        need(flat_image);
        return;
    }
    for (uint32_t row = 0; row < height; ++row) {
        need(4);
        const auto byte = [&](size_t i) { return static_cast<unsigned char>(bytes[at + i]); };
        if (byte(0) != 2 || byte(1) != 2 || (byte(2) & 0x80) != 0) {
            need(flat_image);
            return;
        }
        if ((uint32_t{byte(2)} << 8 | byte(3)) != width)
            throw EnvironmentError("a Radiance scanline's length is not the image's width");
        at += 4;
        for (int channel = 0; channel < 4; ++channel) {
            for (uint32_t filled = 0; filled < width;) {
                need(1);
                const uint32_t count = byte(0);
                const bool run = count > 128;
                const uint32_t length = run ? count - 128 : count;
                if (length == 0 || filled + length > width) throw EnvironmentError("a Radiance scanline is corrupt");
                need(run ? 2 : 1 + length);
                at += run ? 2 : 1 + length;
                filled += length;
            }
        }
    }
}

// The size a Radiance header declares, read by stb_image without allocating any pixel.
EnvironmentSize hdr_size(std::string_view bytes) {
    if (bytes.size() > static_cast<size_t>(std::numeric_limits<int>::max()))
        throw EnvironmentError("the file is larger than 2 GiB");
    int width = 0, height = 0, channels = 0;
    if (!stbi_info_from_memory(reinterpret_cast<const stbi_uc*>(bytes.data()), static_cast<int>(bytes.size()), &width,
                               &height, &channels))
        throw EnvironmentError(std::string("unreadable Radiance header: ") + stbi_failure_reason());
    check_size(width, height);
    return {static_cast<uint32_t>(width), static_cast<uint32_t>(height)};
}

EnvironmentMap decode_hdr(std::string_view bytes) {
    const EnvironmentSize size = hdr_size(bytes);
    EnvironmentMap map{size.width, size.height, {}};
    check_hdr_complete(bytes, map.width, map.height);
    const auto* data = reinterpret_cast<const stbi_uc*>(bytes.data());
    const int length = static_cast<int>(bytes.size());
    int width = 0, height = 0, channels = 0;
    float* pixels = stbi_loadf_from_memory(data, length, &width, &height, &channels, 3);
    if (pixels == nullptr) throw EnvironmentError(std::string("corrupt Radiance file: ") + stbi_failure_reason());
    map.rgb.assign(pixels, pixels + size_t{map.width} * map.height * 3);
    stbi_image_free(pixels);
    return map;
}

// The OpenEXR library allocates what a header declares before it reads it: a string attribute declared
// 2^31 - 1 bytes long took 2 GiB for a 332-byte upload, a preview declared 65535 x 65535 would take
// 16 GiB. So the header is walked here first (magic, version, then attributes: name\0 type\0 int32 size,
// value, up to an empty name) and every size is held against the bytes actually present and the bounds
// below; the library reads only a header that passed.
constexpr size_t kMaxExrAttributes = 256;
constexpr uint64_t kMaxExrAttributeBytes = uint64_t{1} << 20;
constexpr uint64_t kMaxExrHeaderBytes = uint64_t{4} << 20;
// Samples decoded at most: RGBA at the largest size (the library's line buffers hold every channel).
constexpr uint64_t kMaxExrSamples = uint64_t{kMaxEnvironmentWidth} * kMaxEnvironmentHeight * 4;

constexpr uint32_t kExrTiled = 0x200, kExrLongNames = 0x400, kExrDeep = 0x800, kExrMultiPart = 0x1000;

// Little-endian reads within a header; every read is checked against the end first.
class ExrReader {
public:
    ExrReader(std::string_view bytes, size_t at) : bytes_(bytes), at_(at) {}
    size_t at() const { return at_; }
    size_t left() const { return bytes_.size() - at_; }
    void need(uint64_t count, const std::string& what) const {
        if (left() < count) throw EnvironmentError("the OpenEXR header is truncated in " + what);
    }
    uint32_t u32(const std::string& what) {
        need(4, what);
        uint32_t value = 0;
        for (int i = 3; i >= 0; --i) value = value << 8 | static_cast<unsigned char>(bytes_[at_ + static_cast<size_t>(i)]);
        at_ += 4;
        return value;
    }
    int32_t i32(const std::string& what) { return static_cast<int32_t>(u32(what)); }
    uint8_t u8(const std::string& what) {
        need(1, what);
        return static_cast<uint8_t>(bytes_[at_++]);
    }
    // A NUL-terminated name of at most `longest` characters ("" for the NUL that ends a list).
    std::string_view name(size_t longest, const std::string& what) {
        const size_t end = bytes_.find('\0', at_);
        if (end == std::string_view::npos) throw EnvironmentError("the OpenEXR header is truncated in " + what);
        if (end - at_ > longest)
            throw EnvironmentError("an OpenEXR " + what + " is longer than " + std::to_string(longest) + " characters");
        const std::string_view text = bytes_.substr(at_, end - at_);
        at_ = end + 1;
        return text;
    }
    void skip(uint64_t count, const std::string& what) {
        need(count, what);
        at_ += static_cast<size_t>(count);
    }

private:
    std::string_view bytes_;
    size_t at_;
};

struct ExrLayout {
    int64_t width = 0, height = 0;
};

// The channel list's channels, each checked to be whole; their count.
uint64_t exr_channels(ExrReader value) {
    uint64_t channels = 0;
    while (!value.name(255, "channel name").empty()) {
        value.skip(16, "a channel");  // pixel type, pLinear and 3 reserved bytes, x and y sampling
        ++channels;
    }
    return channels;
}

ExrLayout check_exr_header(std::string_view bytes) {
    ExrReader in(bytes, 4);  // past the magic number
    const uint32_t version = in.u32("the version");
    if ((version & 0xff) != 2) throw EnvironmentError("unsupported OpenEXR version " + std::to_string(version & 0xff));
    if ((version & (kExrDeep | kExrMultiPart)) != 0)
        throw EnvironmentError("multi-part and deep OpenEXR files are not environments: save a single-part image");
    const size_t longest_name = (version & kExrLongNames) != 0 ? 255 : 31;
    std::optional<ExrLayout> layout;
    uint64_t channels = 0;
    uint32_t tile_width = 0, tile_height = 0;
    for (size_t count = 0;; ++count) {
        const std::string_view name = in.name(longest_name, "attribute name");
        if (name.empty()) break;
        if (count == kMaxExrAttributes)
            throw EnvironmentError("the OpenEXR header has more than " + std::to_string(kMaxExrAttributes) + " attributes");
        const std::string attribute = "attribute '" + std::string(name) + "'";
        const std::string_view type = in.name(longest_name, "attribute type");
        const int32_t size = in.i32(attribute);
        if (size < 0) throw EnvironmentError("the OpenEXR " + attribute + " has a negative size");
        if (static_cast<uint64_t>(size) > kMaxExrAttributeBytes)
            throw EnvironmentError("the OpenEXR " + attribute + " declares " + std::to_string(size) +
                                   " bytes, over the limit of " + std::to_string(kMaxExrAttributeBytes));
        in.need(static_cast<uint64_t>(size), attribute + " (it declares " + std::to_string(size) + " bytes)");
        ExrReader value(bytes.substr(0, in.at() + static_cast<size_t>(size)), in.at());
        if (type == "box2i" && name == "dataWindow") {
            const int64_t x_min = value.i32(attribute), y_min = value.i32(attribute);
            const int64_t x_max = value.i32(attribute), y_max = value.i32(attribute);
            layout = ExrLayout{x_max - x_min + 1, y_max - y_min + 1};
        } else if (type == "chlist" && name == "channels") {
            channels = exr_channels(value);
        } else if (type == "tiledesc" && name == "tiles") {
            tile_width = value.u32(attribute);
            tile_height = value.u32(attribute);
        } else if (type == "preview") {
            // Its pixels are allocated from the two sides before they are read.
            const uint64_t width = value.u32(attribute), height = value.u32(attribute);
            if (value.left() % 4 != 0 || width * height != value.left() / 4)
                throw EnvironmentError("the OpenEXR " + attribute + " does not hold the pixels it declares");
        } else if (type == "stringvector") {
            while (value.left() > 0) {
                const int32_t length = value.i32(attribute);
                if (length < 0) throw EnvironmentError("the OpenEXR " + attribute + " holds a string of negative size");
                value.skip(static_cast<uint64_t>(length), attribute);
            }
        }
        in.skip(static_cast<uint64_t>(size), attribute);
        if (in.at() > kMaxExrHeaderBytes)
            throw EnvironmentError("the OpenEXR header is over the limit of " + std::to_string(kMaxExrHeaderBytes) +
                                   " bytes");
    }
    if (!layout) throw EnvironmentError("the OpenEXR header has no dataWindow");
    check_size(layout->width, layout->height);
    if (channels == 0) throw EnvironmentError("the OpenEXR header lists no channels");
    const uint64_t samples = static_cast<uint64_t>(layout->width * layout->height) * channels;
    if (samples > kMaxExrSamples)
        throw EnvironmentError("the OpenEXR image holds " + std::to_string(channels) + " channels of " +
                               std::to_string(layout->width) + " x " + std::to_string(layout->height) +
                               " pixels; at most " + std::to_string(kMaxExrSamples) + " samples are decoded");
    if ((version & kExrTiled) != 0) {
        // The library allocates the tile offset table (8 bytes a tile, more for mipmap levels) from the
        // tile size: the file must hold at least the offsets of its full-resolution level.
        if (tile_width == 0 || tile_height == 0 || tile_width > kMaxEnvironmentWidth ||
            tile_height > kMaxEnvironmentHeight)
            throw EnvironmentError("the OpenEXR tiles are " + std::to_string(tile_width) + " x " +
                                   std::to_string(tile_height) + " pixels; tiles must fit an environment");
        const uint64_t tiles = (static_cast<uint64_t>(layout->width) + tile_width - 1) / tile_width *
                               ((static_cast<uint64_t>(layout->height) + tile_height - 1) / tile_height);
        if (8 * tiles > in.left()) throw EnvironmentError("the OpenEXR file is truncated: its tile offsets are missing");
    }
    return *layout;
}

// The upload as an OpenEXR input stream (the library reads from files or streams, never from memory).
class MemoryStream : public Imf::IStream {
public:
    explicit MemoryStream(std::string_view bytes) : Imf::IStream("upload"), bytes_(bytes) {}
    bool read(char c[], int n) override {
        if (n < 0 || bytes_.size() - at_ < static_cast<size_t>(n)) throw EnvironmentError("the OpenEXR file is truncated");
        std::memcpy(c, bytes_.data() + at_, static_cast<size_t>(n));
        at_ += static_cast<size_t>(n);
        return at_ < bytes_.size();
    }
    uint64_t tellg() override { return at_; }
    void seekg(uint64_t position) override {
        if (position > bytes_.size()) throw EnvironmentError("the OpenEXR file is truncated");
        at_ = position;
    }

private:
    std::string_view bytes_;
    size_t at_ = 0;
};

EnvironmentMap decode_exr(std::string_view bytes) {
    // The library reads the header and allocates the line-offset table in the file's constructor, before
    // check_size could look: its own sanity check refuses larger data windows there.
    static const bool limited = [] {
        Imf::Header::setMaxImageSize(static_cast<int>(kMaxEnvironmentWidth), static_cast<int>(kMaxEnvironmentHeight));
        return true;
    }();
    (void)limited;
    check_exr_header(bytes);
    try {
        MemoryStream stream(bytes);
        Imf::RgbaInputFile file(stream);
        const Imath::Box2i window = file.dataWindow();
        const int64_t width = int64_t{window.max.x} - window.min.x + 1, height = int64_t{window.max.y} - window.min.y + 1;
        check_size(width, height);
        EnvironmentMap map{static_cast<uint32_t>(width), static_cast<uint32_t>(height), {}};
        Imf::Array2D<Imf::Rgba> pixels(height, width);
        const size_t row_stride = static_cast<size_t>(width);
        file.setFrameBuffer(&pixels[0][0] - window.min.x - window.min.y * static_cast<ptrdiff_t>(row_stride), 1, row_stride);
        file.readPixels(window.min.y, window.max.y);
        map.rgb.reserve(size_t{map.width} * map.height * 3);
        for (int64_t y = 0; y < height; ++y)
            for (int64_t x = 0; x < width; ++x) {
                const Imf::Rgba& p = pixels[y][x];
                map.rgb.insert(map.rgb.end(), {float(p.r), float(p.g), float(p.b)});
            }
        return map;
    } catch (const EnvironmentError&) {
        throw;
    } catch (const std::exception& e) {
        throw EnvironmentError(std::string("corrupt OpenEXR file: ") + e.what());
    }
}

// A clear sky: blue at the zenith paling to the horizon, a darker ground below it, and a sun disc of
// angular radius 2.5 degrees, 30 degrees above the horizon at azimuth 90 degrees (towards +z), bright
// enough (about ten times the sky's irradiance on the ground) to cast sharp caustics.
EnvironmentMap sky_sun() {
    constexpr uint32_t kWidth = 256, kHeight = 128;
    constexpr double kPi = std::numbers::pi;
    const double sun_theta = kPi / 3.0, sun_phi = kPi / 2.0, sun_radius = 2.5 * kPi / 180.0;
    const double sun[3] = {std::sin(sun_theta) * std::cos(sun_phi), std::cos(sun_theta),
                           std::sin(sun_theta) * std::sin(sun_phi)};
    EnvironmentMap map{kWidth, kHeight, {}};
    map.rgb.reserve(size_t{kWidth} * kHeight * 3);
    for (uint32_t v = 0; v < kHeight; ++v) {
        const double theta = kPi * (v + 0.5) / kHeight;
        for (uint32_t u = 0; u < kWidth; ++u) {
            const double phi = 2.0 * kPi * (u + 0.5) / kWidth;
            const double d[3] = {std::sin(theta) * std::cos(phi), std::cos(theta), std::sin(theta) * std::sin(phi)};
            const double up = d[1];
            double rgb[3];
            if (up >= 0.0) {
                const double t = std::pow(1.0 - up, 3.0);  // 0 at the zenith, 1 at the horizon
                const double zenith[3] = {0.10, 0.22, 0.55}, horizon[3] = {0.75, 0.80, 0.85};
                for (int c = 0; c < 3; ++c) rgb[c] = zenith[c] + (horizon[c] - zenith[c]) * t;
            } else {
                const double ground[3] = {0.16, 0.14, 0.12};
                for (int c = 0; c < 3; ++c) rgb[c] = ground[c];
            }
            const double cos_to_sun = d[0] * sun[0] + d[1] * sun[1] + d[2] * sun[2];
            if (cos_to_sun > std::cos(sun_radius)) {
                const double disc[3] = {2000.0, 1800.0, 1500.0};
                for (int c = 0; c < 3; ++c) rgb[c] = disc[c];
            }
            for (double c : rgb) map.rgb.push_back(static_cast<float>(c));
        }
    }
    return map;
}

}  // namespace

EnvironmentMap decode_environment(std::string_view bytes) {
    EnvironmentMap map;
    if (is_hdr(bytes)) map = decode_hdr(bytes);
    else if (is_exr(bytes)) map = decode_exr(bytes);
    else throw EnvironmentError(kNotAnEnvironment);
    check_pixels(map);
    return map;
}

EnvironmentSize environment_size(std::string_view bytes) {
    if (is_hdr(bytes)) return hdr_size(bytes);
    if (!is_exr(bytes)) throw EnvironmentError(kNotAnEnvironment);
    const ExrLayout layout = check_exr_header(bytes);
    return {static_cast<uint32_t>(layout.width), static_cast<uint32_t>(layout.height)};
}

std::array<double, 3> horizontal_irradiance(const EnvironmentMap& map) {
    std::array<double, 3> irradiance{};
    const double dphi = 2.0 * std::numbers::pi / map.width;
    for (uint32_t row = 0; row < map.height; ++row) {
        const double theta0 = std::numbers::pi * row / map.height;
        const double theta1 = std::min(std::numbers::pi * (row + 1) / map.height, std::numbers::pi / 2);
        if (theta0 >= theta1) break;
        // The integral of cos(theta) sin(theta) over the row's polar span.
        const double weight = 0.5 * (std::pow(std::sin(theta1), 2) - std::pow(std::sin(theta0), 2)) * dphi;
        for (uint32_t column = 0; column < map.width; ++column)
            for (size_t c = 0; c < 3; ++c)
                irradiance[c] += weight * static_cast<double>(map.rgb[3 * (size_t{row} * map.width + column) + c]);
    }
    return irradiance;
}

std::string encode_hdr(const EnvironmentMap& map) {
    std::string out = "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y " + std::to_string(map.height) + " +X " +
                      std::to_string(map.width) + "\n";
    for (size_t pixel = 0; pixel < size_t{map.width} * map.height; ++pixel) {
        const float* rgb = &map.rgb[3 * pixel];
        const float largest = std::max({rgb[0], rgb[1], rgb[2]});
        if (largest < 1e-32f) {
            out.append(4, '\0');
            continue;
        }
        int exponent = 0;
        const float mantissa = std::frexp(largest, &exponent) * 256.0f / largest;
        for (int c = 0; c < 3; ++c) out.push_back(static_cast<char>(static_cast<unsigned char>(rgb[c] * mantissa)));
        out.push_back(static_cast<char>(exponent + 128));
    }
    return out;
}

std::vector<std::string> built_in_environment_names() { return {"sky-sun"}; }

std::shared_ptr<const EnvironmentMap> built_in_environment(std::string_view name) {
    static const auto sky_sun_map = std::make_shared<const EnvironmentMap>(sky_sun());
    return name == "sky-sun" ? sky_sun_map : nullptr;
}

}  // namespace refract::image
