// OpenEXR frames (issue 40): a rendered frame's linear radiance written by image::encode_exr and read back
// with OpenEXR itself is the frame to half precision, each value exactly the half it rounds to, with
// its header attributes.
#include <ImfChannelList.h>
#include <ImfDoubleAttribute.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <ImfStdIO.h>
#include <ImfStringAttribute.h>
#include <ImfVecAttribute.h>
#include <half.h>

#include <cmath>
#include <sstream>

#include <nlohmann/json.hpp>

#include "gpu_fixture.h"
#include "image/exr.h"

namespace refract {
namespace {

class ExrTest : public testing::GpuTest {};

TEST_F(ExrTest, AFramesLinearRadianceReadsBackToHalfPrecision) {
    const auto doc = protocol::parse_scene(nlohmann::json{{"image", {{"width", 48}, {"height", 32}}},
                                            {"volume", {{"resolution", 32}}},
                                            {"photons", {{"count", 4096}}}});
    scene::SceneGpu gpu(kit());
    gpu.run(scene::kAllPasses, doc, worlds(doc), nullptr);
    const std::vector<glm::vec4> hdr = gpu.read_hdr();
    image::ExrAttributes attributes;
    attributes.text = {{"refractPhotons", "4096"}};
    attributes.numbers = {{"refractLevel", 1.0}};
    attributes.vectors.emplace_back("cameraPosition", doc.camera.position);
    const std::string exr = image::encode_exr(std::span<const float>(&hdr[0].x, hdr.size() * 4), 48, 32, attributes);

    Imf::StdISStream stream;
    stream.str(exr);
    Imf::InputFile file(stream);
    const Imf::Header& header = file.header();
    const Imath::Box2i window = header.dataWindow();
    ASSERT_EQ(window.max.x - window.min.x + 1, 48);
    ASSERT_EQ(window.max.y - window.min.y + 1, 32);
    for (const char* channel : {"R", "G", "B"}) {
        ASSERT_NE(header.channels().findChannel(channel), nullptr) << channel;
        EXPECT_EQ(header.channels().findChannel(channel)->type, Imf::HALF) << channel;
    }
    EXPECT_EQ(header.typedAttribute<Imf::StringAttribute>("refractPhotons").value(), "4096");
    EXPECT_EQ(header.typedAttribute<Imf::DoubleAttribute>("refractLevel").value(), 1.0);
    const Imath::V3d position = header.typedAttribute<Imf::V3dAttribute>("cameraPosition").value();
    EXPECT_EQ(position, Imath::V3d(doc.camera.position[0], doc.camera.position[1], doc.camera.position[2]));

    std::vector<float> planes(48 * 32 * 3);
    Imf::FrameBuffer buffer;
    const char* names[3] = {"R", "G", "B"};
    for (size_t c = 0; c < 3; ++c)
        buffer.insert(names[c], Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(planes.data() + c * 48 * 32),
                                           sizeof(float), sizeof(float) * 48));
    file.setFrameBuffer(buffer);
    file.readPixels(window.min.y, window.max.y);
    float brightest = 0.0f;
    for (size_t i = 0; i < 48 * 32; ++i)
        for (size_t c = 0; c < 3; ++c) {
            const float linear = hdr[i][static_cast<int>(c)], read = planes[c * 48 * 32 + i];
            ASSERT_EQ(read, static_cast<float>(half(linear))) << "pixel " << i << " channel " << c;
            // Half keeps 11 significant bits: within 2^-11 of the value (or of half's smallest normal).
            ASSERT_LE(std::fabs(read - linear), std::max(std::fabs(linear), 6.1e-5f) / 2048.0f) << "pixel " << i;
            brightest = std::max(brightest, read);
        }
    EXPECT_GT(brightest, 0.01f);  // a frame, not a black image
}

}  // namespace
}  // namespace refract
