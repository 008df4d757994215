// glTF in and out without a device: the mapping of a glTF written in the test to the exact document it
// means, export -> import giving the same document, the exported file through the Khronos validator,
// and hostile files refused with the glTF path named.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <numbers>

#include <unistd.h>

#include "gltf/gltf_builder.h"
#include "gltf/gltf_error.h"
#include "gltf/gltf_export.h"
#include "gltf/gltf_import.h"
#include "mesh/mesh.h"

namespace refract {
namespace {

using nlohmann::json;
using test::GltfBuilder;

// The built-in meshes and, by name, uploads that "exist" for an import.
struct Meshes {
    std::map<std::string, std::shared_ptr<const mesh::Mesh>> uploads;

    std::shared_ptr<const mesh::Mesh> operator()(const std::string& reference) const {
        static const auto cube = std::make_shared<const mesh::Mesh>(mesh::make_cube());
        static const auto sphere = std::make_shared<const mesh::Mesh>(mesh::make_sphere(5));
        if (reference == "cube") return cube;
        if (reference == "sphere") return sphere;
        const auto it = uploads.find(reference);
        return it == uploads.end() ? nullptr : it->second;
    }
};

mesh::Mesh tetrahedron() {
    return {{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}}, {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}}};
}

// Numbers equal to the 12 significant digits an import keeps of a converted value (1e-11 of their size),
// everything else exactly; the first difference as a message.
std::string difference(const json& got, const json& want, const std::string& at = "") {
    if (got.is_number() && want.is_number()) {
        const double a = got.get<double>(), b = want.get<double>();
        return std::fabs(a - b) <= 1e-11 * std::max(1.0, std::fabs(b)) ? "" : at + ": " + got.dump() + " != " + want.dump();
    }
    // An object compares the members `want` names (the rest are the document's defaults, checked apart).
    if (got.type() != want.type() || (got.is_array() && got.size() != want.size()))
        return at + ": " + got.dump() + " != " + want.dump();
    if (got.is_object()) {
        for (auto it = want.begin(); it != want.end(); ++it) {
            if (!got.contains(it.key())) return at + "/" + it.key() + ": missing";
            if (auto d = difference(got[it.key()], it.value(), at + "/" + it.key()); !d.empty()) return d;
        }
        return "";
    }
    if (got.is_array()) {
        for (size_t i = 0; i < want.size(); ++i)
            if (auto d = difference(got[i], want[i], at + "/" + std::to_string(i)); !d.empty()) return d;
        return "";
    }
    return got == want ? "" : at + ": " + got.dump() + " != " + want.dump();
}

json glass(double ior, json volume, json more = json::object()) {
    json extensions = {{"KHR_materials_transmission", {{"transmissionFactor", 1.0}}},
                       {"KHR_materials_ior", {{"ior", ior}}},
                       {"KHR_materials_volume", volume}};
    extensions.update(more);
    return {{"extensions", extensions}};
}

// A glTF with every mapped feature at known values: two objects (a built-in cube, turned, scaled and
// placed; a tetrahedron under a moved parent), each light type, a camera.
GltfBuilder known_gltf() {
    GltfBuilder b;
    const double h = std::sqrt(0.5);
    b.gltf["materials"] = {
        glass(1.7, {{"thicknessFactor", 2.0}, {"attenuationDistance", 2.0}, {"attenuationColor", {0.5, 0.25, 1.0}}},
              {{"KHR_materials_dispersion", {{"dispersion", 0.5}}},
               {"KHR_materials_iridescence",
                {{"iridescenceFactor", 1.0}, {"iridescenceIor", 1.4}, {"iridescenceThicknessMaximum", 300.0}}}}),
        glass(1.33, {{"thicknessFactor", 1.0}})};
    const mesh::Mesh cube = mesh::make_cube(), tetra = tetrahedron();
    b.add_node({{"name", "glass"}, {"mesh", b.add_mesh("cube", cube.positions, cube.triangles, 0)},
                {"translation", {1.0, 2.0, 3.0}}, {"rotation", {0.0, h, 0.0, h}}, {"scale", {0.5, 0.5, 0.5}}});
    const int child = b.add_node({{"name", "tetra"}, {"mesh", b.add_mesh("tetra", tetra.positions, tetra.triangles, 1)},
                                  {"translation", {0.0, 0.0, -1.0}}},
                                 false);
    b.add_node({{"name", "group"}, {"translation", {0.0, 1.0, 0.0}}, {"children", {child}}});
    b.gltf["extensionsUsed"] = {"KHR_lights_punctual", "KHR_materials_transmission", "KHR_materials_ior",
                                "KHR_materials_volume", "KHR_materials_dispersion", "KHR_materials_iridescence"};
    b.gltf["extensions"]["KHR_lights_punctual"]["lights"] = {
        {{"type", "point"}, {"color", {1.0, 0.5, 0.25}}, {"intensity", 683.0}},
        {{"type", "spot"}, {"intensity", 1366.0}, {"spot", {{"innerConeAngle", 0.4}, {"outerConeAngle", 0.5}}}},
        {{"type", "directional"}, {"intensity", 6830.0}}};
    b.add_node({{"name", "bulb"}, {"translation", {0.0, 3.0, 0.0}}, {"extensions", {{"KHR_lights_punctual", {{"light", 0}}}}}});
    b.add_node({{"name", "lamp"}, {"translation", {2.0, 3.0, 1.0}}, {"rotation", {-h, 0.0, 0.0, h}},
                {"extensions", {{"KHR_lights_punctual", {{"light", 1}}}}}});
    b.add_node({{"name", "sun"}, {"extensions", {{"KHR_lights_punctual", {{"light", 2}}}}}});
    b.gltf["cameras"] = {{{"type", "perspective"}, {"perspective", {{"yfov", 0.6}, {"aspectRatio", 2.0}, {"znear", 0.1}}}}};
    b.add_node({{"name", "eye"}, {"camera", 0}, {"translation", {0.0, 1.0, 5.0}}});
    return b;
}

TEST(Gltf, KnownValuesMapToTheExpectedDocument) {
    const gltf::ImportedScene scene = gltf::import_gltf(known_gltf().glb(), Meshes{});
    const double degrees = 180.0 / std::numbers::pi;
    const json want = {
        {"camera", {{"position", {0, 1, 5}}, {"target", {0, 1, 4}}, {"up", {0, 1, 0}}, {"fov_deg", 0.6 * degrees}}},
        {"image", {{"width", 1024}, {"height", 512}}},
        {"lights",
         {{"bulb", {{"type", "point"}, {"position", {0, 3, 0}}, {"color", {1, 0.5, 0.25}}, {"intensity", 1.0}}},
          {"lamp", {{"type", "spot"}, {"position", {2, 3, 1}}, {"direction", {0, -1, 0}}, {"intensity", 2.0},
                    {"cone_deg", 0.5 * degrees}}},
          {"sun", {{"type", "directional"}, {"direction", {0, 0, -1}}, {"intensity", 10.0}}}}},
        {"objects",
         {{"glass", {{"mesh", "cube"}, {"position", {1, 2, 3}}, {"rotation_deg", {0, 90, 0}}, {"scale", 0.5},
                     {"ior", 1.7}, {"abbe", 40.0}, {"extinction", {std::log(2.0) / 2.0, std::log(4.0) / 2.0, 0.0}},
                     {"scattering", {0, 0, 0}}, {"film", {{"ior", 1.4}, {"top_nm", 300.0}, {"bottom_nm", 300.0}}}}},
          {"tetra", {{"mesh", "upload:tetra"}, {"position", {0, 1, -1}}, {"rotation_deg", {0, 0, 0}}, {"scale", 1.0},
                     {"ior", 1.33}, {"abbe", 40.0}, {"extinction", {0, 0, 0}}, {"film", {{"top_nm", 0.0}}}}}}}};
    EXPECT_EQ(difference(protocol::to_json(scene.document), want), "");
    EXPECT_FALSE(std::signbit(scene.document.objects.at("glass").extinction[2]));  // 0, not -0: printed "0.0"
    // What glTF cannot say is the default document's.
    const protocol::SceneDocument defaults;
    EXPECT_EQ(scene.document.medium, defaults.medium);
    EXPECT_EQ(scene.document.floor, defaults.floor);
    EXPECT_EQ(scene.document.objects.at("glass").phase, defaults.object().phase);
    ASSERT_EQ(scene.meshes.size(), 1u);  // the cube is the built-in; the tetrahedron a new upload
    EXPECT_EQ(scene.meshes[0].name, "tetra");
    EXPECT_EQ(scene.meshes[0].mesh.positions, tetrahedron().positions);
    // Said, not dropped: the spot's soft edge, the second object's dispersion.
    const auto said = [&](const std::string& part) {
        return std::any_of(scene.warnings.begin(), scene.warnings.end(),
                           [&](const std::string& w) { return w.find(part) != std::string::npos; });
    };
    EXPECT_TRUE(said("innerConeAngle")) << json(scene.warnings).dump(1);
    EXPECT_TRUE(said("dispersion is one per scene")) << json(scene.warnings).dump(1);
}

TEST(Gltf, TheSameFileAsGltfWithADataUriMapsTheSame) {
    const GltfBuilder b = known_gltf();
    EXPECT_EQ(gltf::import_gltf(b.gltf_text(), Meshes{}).document, gltf::import_gltf(b.glb(), Meshes{}).document);
}

// A document using what glTF carries and what only extras.refract does.
protocol::SceneDocument rich_document() {
    return protocol::parse_scene(json::parse(R"({
      "camera": {"position": [0.3, 1.2, 4.5], "target": [0, -0.2, 0.1], "up": [0.1, 2, 0], "fov_deg": 38.5},
      "image": {"width": 96, "height": 64, "exposure": 1.25},
      "lights": {
        "key": {"type": "spot", "position": [2, 3, 1], "direction": [-2, -3, -1], "color": [2, 1.5, 1], "intensity": 17.5, "cone_deg": 22},
        "fill": {"type": "point", "position": [-1, 2, 2], "intensity": 3.3},
        "sun": {"type": "directional", "direction": [0.2, -1, 0.1], "color": [1, 0.9, 0.8], "intensity": 0.7}},
      "objects": {
        "lens": {"mesh": "sphere", "position": [-0.6, 0, 0], "rotation_deg": [10, 200, -30], "scale": 0.45, "ior": 1.62,
                 "abbe": 30, "extinction": [0.3, 0.05, 0.01], "scattering": [0.01, 0.01, 0.005],
                 "phase": {"model": "henyey-greenstein", "g": 0.4}, "film": {"ior": 1.38, "top_nm": 120, "bottom_nm": 480}},
        "block": {"mesh": "cube", "position": [0.7, -0.4, 0.2], "rotation_deg": [0, 45, 0], "scale": 0.3, "ior": 1.33,
                  "abbe": 30, "fresnel": false, "resolution": 32, "extinction": [0, 0, 0], "scattering": [0, 0, 0]},
        "luneburg": {"mesh": "cube", "index_field": "luneburg", "position": [0, 0.6, -0.5], "scale": 0.3, "abbe": 30},
        "tetra": {"mesh": "upload:tetra", "position": [0, -0.8, 0.6], "rotation_deg": [0, 0, 90], "scale": 0.5, "abbe": 30}},
      "medium": {"ior": 1.0, "extinction": [0.1, 0.1, 0.12], "scattering": [0.08, 0.08, 0.1]},
      "volume": {"resolution": 48, "margin": 0.3},
      "photons": {"count": 4096, "seed": 7},
      "floor": {"height": -1.1, "checker_size": 0.3},
      "environment": {"type": "uniform", "color": [0.1, 0.12, 0.2], "lights": false}
    })"));
}

Meshes with_tetra() {
    Meshes meshes;
    meshes.uploads["upload:tetra"] = std::make_shared<const mesh::Mesh>(tetrahedron());
    return meshes;
}

std::string export_rich() {
    const Meshes meshes = with_tetra();
    return gltf::export_glb(rich_document(), [&](const protocol::Object& o) { return meshes(gltf::rendered_mesh(o)); });
}

TEST(Gltf, ExportThenImportGivesTheSameDocument) {
    const std::string glb = export_rich();
    const gltf::ImportedScene back = gltf::import_gltf(glb, with_tetra());
    EXPECT_EQ(back.document, rich_document()) << protocol::to_json(back.document).dump(1);
    EXPECT_TRUE(back.meshes.empty());  // the tetrahedron is the upload of its name already
    EXPECT_TRUE(back.warnings.empty()) << json(back.warnings).dump(1);
    // In a daemon without the upload it comes back as one, byte for byte; under a name taken by other
    // geometry, as a new upload with the geometry's hash appended.
    const gltf::ImportedScene fresh = gltf::import_gltf(glb, Meshes{});
    ASSERT_EQ(fresh.meshes.size(), 1u);
    EXPECT_EQ(fresh.meshes[0].mesh.positions, tetrahedron().positions);
    EXPECT_EQ(fresh.meshes[0].mesh.triangles, tetrahedron().triangles);
    Meshes taken;
    taken.uploads["upload:tetra"] = std::make_shared<const mesh::Mesh>(mesh::make_cube());
    const gltf::ImportedScene renamed = gltf::import_gltf(glb, taken);
    ASSERT_EQ(renamed.meshes.size(), 1u);
    EXPECT_EQ(renamed.document.objects.at("tetra").mesh, "upload:" + renamed.meshes[0].name);
    EXPECT_NE(renamed.meshes[0].name, "tetra");
}

TEST(Gltf, WithoutRefractsExtrasTheGltfAloneGivesTheSamePlacesAndGlass) {
    // What another tool keeps of an exported file: no extras. Everything glTF says comes back.
    const std::string glb = export_rich();
    uint32_t json_length = 0;
    std::memcpy(&json_length, glb.data() + 12, 4);
    json gltf_json = json::parse(glb.substr(20, json_length));
    for (auto& node : gltf_json["nodes"]) node.erase("extras");
    GltfBuilder b;
    b.gltf = gltf_json;
    uint32_t bin_length = 0;
    std::memcpy(&bin_length, glb.data() + 20 + json_length, 4);
    b.bin = glb.substr(28 + json_length, bin_length);
    b.gltf.erase("buffers");
    const protocol::SceneDocument got = gltf::import_gltf(b.glb(), with_tetra()).document;
    const protocol::SceneDocument want = rich_document();
    const auto& lens = got.objects.at("lens");
    EXPECT_NEAR(lens.ior, 1.62, 1e-12);
    EXPECT_NEAR(lens.abbe, 30.0, 1e-9);
    for (size_t c = 0; c < 3; ++c) EXPECT_NEAR(lens.extinction[c], want.objects.at("lens").extinction[c], 1e-12);
    EXPECT_NEAR(lens.scale, 0.45, 1e-12);
    EXPECT_NEAR(got.lights.at("key").intensity * got.lights.at("key").color[0], 17.5 * 2, 1e-9);
    EXPECT_NEAR(got.camera.fov_deg, 38.5, 1e-9);
    EXPECT_EQ(got.image, want.image);  // the scene's extras still say it
}

// ------------------------------------------------------------------------------------------------------
// Hostile files: each refused with the glTF path named

std::string refusal(const std::string& bytes, const gltf::ImportLimits& limits = {}) {
    try {
        gltf::import_gltf(bytes, Meshes{}, {}, limits);
    } catch (const gltf::GltfError& e) {
        return e.what();
    }
    return "(imported)";
}

GltfBuilder one_tetra() {
    GltfBuilder b;
    const mesh::Mesh t = tetrahedron();
    b.add_node({{"mesh", b.add_mesh("tetra", t.positions, t.triangles)}});
    return b;
}

TEST(GltfHostile, TruncatedGlbChunks) {
    const std::string glb = one_tetra().glb();
    EXPECT_NE(refusal(glb.substr(0, glb.size() - 8)).find("(glb): the header says"), std::string::npos);
    std::string cut = glb.substr(0, glb.size() - 8);
    const uint32_t length = static_cast<uint32_t>(cut.size());
    std::memcpy(cut.data() + 8, &length, 4);  // the header agrees; the BIN chunk does not fit
    EXPECT_NE(refusal(cut).find("(glb): chunk 1 claims"), std::string::npos) << refusal(cut);
}

TEST(GltfHostile, AccessorPastItsBuffer) {
    GltfBuilder b = one_tetra();
    b.gltf["accessors"][0]["count"] = 1000;
    EXPECT_NE(refusal(b.glb()).find("/meshes/0/primitives/0/attributes/POSITION: accessor 0 reaches past"),
              std::string::npos) << refusal(b.glb());
    GltfBuilder view = one_tetra();
    view.gltf["bufferViews"][1]["byteLength"] = 1 << 20;
    EXPECT_NE(refusal(view.glb()).find("/meshes/0/primitives/0/indices: accessor 1 reads buffer view 1, which reaches past"),
              std::string::npos) << refusal(view.glb());
}

TEST(GltfHostile, ExternalUris) {
    GltfBuilder b = one_tetra();
    json j = json::parse(b.gltf_text());
    j["buffers"][0]["uri"] = "/etc/passwd";
    EXPECT_NE(refusal(j.dump()).find("/buffers/0/uri: external URI '/etc/passwd' refused"), std::string::npos);
    j["buffers"][0]["uri"] = "https://example.com/mesh.bin";
    EXPECT_NE(refusal(j.dump()).find("/buffers/0/uri: external URI"), std::string::npos);
}

TEST(GltfHostile, DataUriOverTheLimit) {
    const std::string text = one_tetra().gltf_text();
    EXPECT_EQ(refusal(text, {.max_bytes = 1000}), "(imported)");
    EXPECT_NE(refusal(text, {.max_bytes = 40}).find("/buffers/0/uri: data: URI of about"), std::string::npos)
        << refusal(text, {.max_bytes = 40});
}

TEST(GltfHostile, NonFiniteTransforms) {
    GltfBuilder inf = one_tetra();
    inf.gltf["nodes"][0]["translation"] = {0.0, 1e300, 0.0};
    inf.gltf["nodes"][0]["scale"] = {1.0, 1e300, 1.0};
    const int parent = inf.add_node({{"scale", {1e300, 1e300, 1e300}}, {"children", {0}}});
    inf.gltf["scenes"][0]["nodes"] = {parent};
    EXPECT_NE(refusal(inf.glb()).find("/nodes/0: its world transform is not finite"), std::string::npos)
        << refusal(inf.glb());
    // JSON has no NaN, and a number beyond a double's range does not parse.
    std::string text = one_tetra().gltf_text();
    text.replace(text.find("\"mesh\":0"), 8, "\"mesh\":0,\"translation\":[1e999,0,0]");
    EXPECT_NE(refusal(text).find("does not parse"), std::string::npos) << refusal(text);
}

TEST(GltfHostile, DeeplyNestedJson) {
    // tinygltf copies extras recursively: 200,000 levels would exhaust its stack. Refused before it reads.
    const std::string deep = std::string(200000, '[') + std::string(200000, ']');
    GltfBuilder b = one_tetra();
    std::string text = b.gltf_text();
    text.insert(text.size() - 1, ",\"extras\":" + deep);
    EXPECT_NE(refusal(text).find("(root): the JSON nests 200001 levels deep (at most 64)"), std::string::npos) << refusal(text);
    // Brackets inside strings are text, not nesting.
    text = b.gltf_text();
    text.insert(text.size() - 1, ",\"extras\":\"" + std::string(1000, '[') + "\"");
    EXPECT_EQ(refusal(text), "(imported)");
}

TEST(GltfHostile, MorePrimitivesThanTheObjectLimit) {
    GltfBuilder b = one_tetra();
    for (size_t i = 1; i < protocol::kMaxObjects; ++i) b.add_node({{"mesh", 0}});
    EXPECT_EQ(refusal(b.glb()), "(imported)");
    b.add_node({{"mesh", 0}});
    EXPECT_NE(refusal(b.glb()).find("/meshes/0/primitives/0: a primitive past the 64 objects"), std::string::npos)
        << refusal(b.glb());
}

TEST(GltfHostile, ValuesOutOfRangeNameTheirGltfPath) {
    GltfBuilder b = one_tetra();
    b.gltf["materials"] = {glass(9.0, {{"thicknessFactor", 1.0}})};
    b.gltf["meshes"][0]["primitives"][0]["material"] = 0;
    EXPECT_NE(refusal(b.glb()).find("/meshes/0/primitives/0: /objects/tetra/ior: must be"), std::string::npos)
        << refusal(b.glb());
}

// ------------------------------------------------------------------------------------------------------
// The Khronos validator (npm gltf-validator, installed with the e2e test's packages)

TEST(Gltf, TheExportedFilePassesTheKhronosValidator) {
    const auto path = std::filesystem::temp_directory_path() / ("refract-gltf-" + std::to_string(::getpid()) + ".glb");
    {
        std::ofstream out(path, std::ios::binary);
        out << export_rich();
    }
    const std::string command = std::string("node ") + REFRACT_SOURCE_DIR + "/tests/e2e/validate_gltf.mjs " + path.string();
    const int status = std::system(command.c_str());
    std::filesystem::remove(path);
    EXPECT_EQ(status, 0) << command;
}

}  // namespace
}  // namespace refract
