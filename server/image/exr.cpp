#include "image/exr.h"

#include <ImfChannelList.h>
#include <ImfDoubleAttribute.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfOutputFile.h>
#include <ImfStdIO.h>
#include <ImfStringAttribute.h>
#include <ImfVecAttribute.h>
#include <half.h>

#include <sstream>
#include <stdexcept>

namespace refract::image {

ExrAttributes frame_attributes(const protocol::SceneDocument& document, uint32_t level, uint64_t photons,
                               uint64_t revision) {
    ExrAttributes a;
    // 64-bit counts as text: EXR's integer attribute is 32 bits.
    a.text = {{"software", "Refract " REFRACT_VERSION}, {"refractPhotons", std::to_string(photons)}};
    if (revision) a.text.emplace_back("refractRevision", std::to_string(revision));
    a.numbers = {{"refractLevel", level}, {"refractExposure", document.image.exposure},
                 {"cameraFovDeg", document.camera.fov_deg}};
    a.vectors = {{"cameraPosition", document.camera.position},
                 {"cameraTarget", document.camera.target},
                 {"cameraUp", document.camera.up}};
    return a;
}

std::string encode_exr(std::span<const float> rgba, uint32_t width, uint32_t height, const ExrAttributes& attributes) {
    const size_t pixels = size_t{width} * height;
    if (rgba.size() != pixels * 4) throw std::runtime_error("encode_exr: the pixels are not width x height x 4 floats");
    Imf::Header header(static_cast<int>(width), static_cast<int>(height));
    header.compression() = Imf::ZIP_COMPRESSION;
    for (const char* channel : {"R", "G", "B"}) header.channels().insert(channel, Imf::Channel(Imf::HALF));
    for (const auto& [name, value] : attributes.text) header.insert(name, Imf::StringAttribute(value));
    for (const auto& [name, value] : attributes.numbers) header.insert(name, Imf::DoubleAttribute(value));
    for (const auto& [name, v] : attributes.vectors) header.insert(name, Imf::V3dAttribute(Imath::V3d(v[0], v[1], v[2])));
    // Planar half channels: OpenEXR converts nothing, so what it writes is exactly these halves.
    std::vector<half> planes(pixels * 3);
    for (size_t i = 0; i < pixels; ++i)
        for (size_t c = 0; c < 3; ++c) planes[c * pixels + i] = half(rgba[i * 4 + c]);
    Imf::FrameBuffer buffer;
    const char* names[3] = {"R", "G", "B"};
    for (size_t c = 0; c < 3; ++c)
        buffer.insert(names[c], Imf::Slice(Imf::HALF, reinterpret_cast<char*>(planes.data() + c * pixels), sizeof(half),
                                           sizeof(half) * width));
    Imf::StdOSStream stream;
    {
        Imf::OutputFile file(stream, header);
        file.setFrameBuffer(buffer);
        file.writePixels(static_cast<int>(height));
    }
    return stream.str();
}

}  // namespace refract::image
