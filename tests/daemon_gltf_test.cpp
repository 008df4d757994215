// glTF scenes and OpenEXR frames against a real refractd (issue 40): a .glb posted as a scene renders the
// frame of the document written by hand for it; its export imports back to the same document and frame;
// hostile files are refused with the glTF path named and leave no scene and no mesh behind; frame.exr is
// half-float radiance with the frame's metadata.
#include <gtest/gtest.h>

#include <ImfChannelList.h>
#include <ImfDoubleAttribute.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <ImfStdIO.h>
#include <ImfStringAttribute.h>
#include <ImfVecAttribute.h>

#include <algorithm>
#include <cmath>
#include <numbers>

#include "daemon/api.h"
#include "daemon/harness.h"
#include "gltf/gltf_builder.h"
#include "mesh/mesh.h"

namespace refract::test {
namespace {

using nlohmann::json;

constexpr const char* kGlb = "model/gltf-binary";

class DaemonGltf : public ::testing::Test {
protected:
    static void SetUpTestSuite() {
        dir_ = new TempDir();
        daemon_ = new Daemon(dir_->path() / "data");
    }
    static void TearDownTestSuite() {
        delete daemon_;
        delete dir_;
    }
    httplib::Client client() { return daemon_->client(); }

    static TempDir* dir_;
    static Daemon* daemon_;
};
TempDir* DaemonGltf::dir_ = nullptr;
Daemon* DaemonGltf::daemon_ = nullptr;

// A turned, scaled built-in cube and a tetrahedron of the file's own, a spot light straight down, a
// camera; the scene's extras.refract keeps frames tiny.
GltfBuilder two_glasses() {
    GltfBuilder b;
    const double s15 = std::sin(std::numbers::pi / 12), c15 = std::cos(std::numbers::pi / 12), h = std::sqrt(0.5);
    b.gltf["materials"] = {{{"extensions",
                             {{"KHR_materials_transmission", {{"transmissionFactor", 1.0}}},
                              {"KHR_materials_ior", {{"ior", 1.6}}},
                              {"KHR_materials_volume",
                               {{"thicknessFactor", 1.0}, {"attenuationDistance", 1.0}, {"attenuationColor", {0.5, 1.0, 1.0}}}}}}}};
    const mesh::Mesh cube = mesh::make_cube();
    b.add_node({{"name", "glass"}, {"mesh", b.add_mesh("cube", cube.positions, cube.triangles, 0)},
                {"translation", {0.2, 0.0, 0.0}}, {"rotation", {0.0, s15, 0.0, c15}}, {"scale", {0.5, 0.5, 0.5}}});
    const std::vector<glm::vec3> tetra = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    b.add_node({{"name", "tetra"}, {"mesh", b.add_mesh("tetra-d", tetra, {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}}, 0)},
                {"translation", {-0.8, -0.5, 0.0}}});
    b.gltf["extensionsUsed"] = {"KHR_lights_punctual", "KHR_materials_transmission", "KHR_materials_ior", "KHR_materials_volume"};
    b.gltf["extensions"]["KHR_lights_punctual"]["lights"] = {
        {{"type", "spot"}, {"intensity", 20.0 * 683.0}, {"spot", {{"innerConeAngle", 0.3}, {"outerConeAngle", 25.0 * std::numbers::pi / 180.0}}}}};
    b.add_node({{"name", "lamp"}, {"translation", {0.0, 3.0, 0.0}}, {"rotation", {-h, 0.0, 0.0, h}},
                {"extensions", {{"KHR_lights_punctual", {{"light", 0}}}}}});
    b.gltf["cameras"] = {{{"type", "perspective"}, {"perspective", {{"yfov", 35.0 * std::numbers::pi / 180.0}, {"aspectRatio", 1.0}, {"znear", 0.1}}}}};
    b.add_node({{"name", "eye"}, {"camera", 0}, {"translation", {0.0, 0.5, 5.0}}});
    b.gltf["scenes"][0]["extras"]["refract"] = {{"image", {{"width", 32}, {"height", 32}}},
                                                {"volume", {{"resolution", 32}}},
                                                {"photons", {{"count", 256}}}};
    return b;
}

// What two_glasses() means, written by hand.
const json kHandWritten = json::parse(R"({
  "camera": {"position": [0, 0.5, 5], "target": [0, 0.5, 4], "up": [0, 1, 0], "fov_deg": 35},
  "image": {"width": 32, "height": 32}, "volume": {"resolution": 32}, "photons": {"count": 256},
  "lights": {"lamp": {"type": "spot", "position": [0, 3, 0], "direction": [0, -1, 0], "intensity": 20, "cone_deg": 25}},
  "objects": {
    "glass": {"mesh": "cube", "position": [0.2, 0, 0], "rotation_deg": [0, 30, 0], "scale": 0.5, "ior": 1.6,
              "extinction": [0.69314718056, 0, 0], "scattering": [0, 0, 0]},
    "tetra": {"mesh": "upload:tetra-d", "position": [-0.8, -0.5, 0], "ior": 1.6,
              "extinction": [0.69314718056, 0, 0], "scattering": [0, 0, 0]}}
})");

std::string frame(httplib::Client& c, const std::string& id) {
    auto res = get_frame(c, id);
    return res ? res->body : std::string();
}

TEST_F(DaemonGltf, AnImportedSceneRendersTheHandWrittenDocumentsFrame) {
    auto c = client();
    auto res = c.Post("/api/scenes?id=imported", two_glasses().glb(), kGlb);
    ASSERT_TRUE(res);
    ASSERT_EQ(res->status, 201) << res->body;
    const json answer = json::parse(res->body);
    EXPECT_EQ(answer["meshes"], json::array({"tetra-d"}));
    EXPECT_FALSE(answer["warnings"].empty());  // the spot's soft edge, said
    create_scene(c, "hand", kHandWritten);
    EXPECT_EQ(get_json(c, "/api/scenes/imported")["scene"], get_json(c, "/api/scenes/hand")["scene"]);
    const std::string imported = frame(c, "imported");
    EXPECT_FALSE(imported.empty());
    EXPECT_TRUE(imported == frame(c, "hand")) << "the frames differ";
}

TEST_F(DaemonGltf, AnExportedSceneImportsBackToTheSameDocumentAndFrame) {
    auto c = client();
    create_scene(c, "original", json::parse(R"({"image": {"width": 32, "height": 24}, "volume": {"resolution": 32},
        "photons": {"count": 256}, "objects": {"a": {"mesh": "torus", "rotation_deg": [20, 0, 10], "scale": 0.6, "abbe": 40},
        "b": {"mesh": "prism", "position": [0.5, 0.2, 0], "scale": 0.3, "abbe": 40, "film": {"top_nm": 200, "bottom_nm": 600}}},
        "lights": {"key": {"intensity": 12}, "sun": {"type": "directional", "direction": [1, -2, 0], "intensity": 0.5}}})"));
    auto glb = c.Get("/api/scenes/original/scene.glb");
    ASSERT_TRUE(glb);
    ASSERT_EQ(glb->status, 200) << glb->body;
    EXPECT_EQ(glb->get_header_value("Content-Type"), kGlb);
    auto res = c.Post("/api/scenes?id=copy", glb->body, kGlb);
    ASSERT_TRUE(res);
    ASSERT_EQ(res->status, 201) << res->body;
    EXPECT_EQ(json::parse(res->body)["warnings"], json::array());
    EXPECT_EQ(get_json(c, "/api/scenes/copy")["scene"], get_json(c, "/api/scenes/original")["scene"]);
    EXPECT_TRUE(frame(c, "copy") == frame(c, "original")) << "the frames differ";
}

TEST_F(DaemonGltf, HostileFilesAreRefusedWithTheirPathAndLeaveNothingStored) {
    auto c = client();
    const json scenes = get_json(c, "/api/scenes"), meshes = get_json(c, "/api/meshes");
    GltfBuilder external = two_glasses();
    json text = json::parse(external.gltf_text());
    text["buffers"][0]["uri"] = "../../etc/passwd";
    GltfBuilder crowded = two_glasses();
    for (int i = 0; i < 63; ++i) crowded.add_node({{"mesh", 1}});  // 65 primitives
    GltfBuilder past = two_glasses();
    past.gltf["accessors"][2]["count"] = 100000;
    const std::string glb = two_glasses().glb();
    const struct {
        std::string body, type, path;
    } cases[] = {{text.dump(), "model/gltf+json", "/buffers/0/uri"},
                 {crowded.glb(), kGlb, "/meshes/1/primitives/0"},
                 {past.glb(), kGlb, "/meshes/1/primitives/0/attributes/POSITION"},
                 {glb.substr(0, glb.size() - 100), kGlb, "(glb)"}};
    for (const auto& bad : cases) {
        auto res = c.Post("/api/scenes?id=hostile", bad.body, bad.type.c_str());
        ASSERT_TRUE(res);
        EXPECT_EQ(res->status, 422) << res->body;
        EXPECT_EQ(json::parse(res->body).value("gltf_path", ""), bad.path) << res->body;
    }
    // A scene naming an environment the daemon does not have: refused by the store, its meshes removed.
    GltfBuilder dark = two_glasses();
    dark.gltf["scenes"][0]["extras"]["refract"]["environment"] = {{"type", "image"}, {"image", "nowhere"}};
    dark.gltf["meshes"][1]["name"] = "dark-tetra";  // uploaded, then removed again
    auto unlit = c.Post("/api/scenes?id=hostile", dark.glb(), kGlb);
    ASSERT_TRUE(unlit);
    EXPECT_EQ(unlit->status, 422) << unlit->body;
    EXPECT_EQ(json::parse(unlit->body).value("pointer", ""), "/environment/image") << unlit->body;
    // A good file under a taken id: refused before its mesh is uploaded.
    create_scene(c, "taken");
    auto res = c.Post("/api/scenes?id=taken", glb, kGlb);
    ASSERT_TRUE(res);
    EXPECT_EQ(res->status, 409) << res->body;
    json after = get_json(c, "/api/scenes");
    after["scenes"].erase(std::remove_if(after["scenes"].begin(), after["scenes"].end(),
                                         [](const json& s) { return s["id"] == "taken"; }),
                          after["scenes"].end());
    EXPECT_EQ(after, scenes);
    EXPECT_EQ(get_json(c, "/api/meshes"), meshes);
}

TEST_F(DaemonGltf, AFrameAsOpenExrIsLinearHalfFloatWithItsMetadata) {
    auto c = client();
    json document = kHandWritten;
    document["objects"].erase("tetra");  // an upload only an import makes (each ctest case has a daemon of its own)
    create_scene(c, "exr", document);
    auto res = c.Get("/api/scenes/exr/frame.exr?width=24&height=16");
    ASSERT_TRUE(res);
    ASSERT_EQ(res->status, 200) << res->body;
    EXPECT_EQ(res->get_header_value("Content-Type"), "image/x-exr");
    Imf::StdISStream stream;
    stream.str(res->body);
    Imf::InputFile file(stream);
    const Imf::Header& header = file.header();
    EXPECT_EQ(header.dataWindow().max.x + 1, 24);
    EXPECT_EQ(header.dataWindow().max.y + 1, 16);
    EXPECT_EQ(header.channels().findChannel("G")->type, Imf::HALF);
    EXPECT_EQ(header.typedAttribute<Imf::StringAttribute>("refractRevision").value(), res->get_header_value("X-Refract-Revision"));
    EXPECT_EQ(header.typedAttribute<Imf::StringAttribute>("refractPhotons").value(), "256");
    EXPECT_EQ(header.typedAttribute<Imf::DoubleAttribute>("refractLevel").value(), 1.0);
    EXPECT_EQ(header.typedAttribute<Imf::V3dAttribute>("cameraPosition").value(), Imath::V3d(0, 0.5, 5));
    std::vector<float> green(24 * 16);
    Imf::FrameBuffer buffer;
    buffer.insert("G", Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(green.data()), sizeof(float), sizeof(float) * 24));
    file.setFrameBuffer(buffer);
    file.readPixels(0, 15);
    EXPECT_GT(*std::max_element(green.begin(), green.end()), 0.01f);  // radiance, not a black frame
    // The same revision again comes from the cache; a PNG is a frame of its own, not the EXR's.
    auto again = c.Get("/api/scenes/exr/frame.exr?width=24&height=16");
    ASSERT_TRUE(again);
    EXPECT_EQ(again->get_header_value("X-Refract-Cached"), "1");
    EXPECT_EQ(again->body, res->body);
    auto png = get_frame(c, "exr", "?width=24&height=16");
    ASSERT_TRUE(png);
    EXPECT_TRUE(is_png(png->body));
}

// A .gltf whose data: URI would pass the body limit never reaches the importer: the body is refused
// first (413), and nothing is stored.
TEST(DaemonGltfLimit, ADataUriOverTheBodyLimitIsRefusedWithTheBody) {
    TempDir dir;
    Daemon daemon(dir.path() / "data", {"--max-body", "4K"});
    auto c = daemon.client();
    GltfBuilder b;
    const std::vector<glm::vec3> many(400, glm::vec3(0.0f));  // 4.8 KB of positions, 6.4 KB as base64
    b.add_node({{"mesh", b.add_mesh("big", many, {{0, 1, 2}})}});
    auto res = c.Post("/api/scenes?id=big", b.gltf_text(), "model/gltf+json");
    ASSERT_TRUE(res);
    EXPECT_EQ(res->status, 413) << res->body;
    get_json(c, "/api/scenes/big", 404);
    EXPECT_EQ(get_json(c, "/api/meshes")["meshes"], json::array());
}

}  // namespace
}  // namespace refract::test
