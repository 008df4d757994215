// The scene document: defaults, round trip, merge-patch editing and validation (protocol/scene_document.h).
#include <gtest/gtest.h>

#include <limits>
#include <random>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "protocol/animation.h"
#include "protocol/scene_document.h"

namespace refract::protocol {
namespace {

using nlohmann::json;

// The pointer of the ValidationError `f` throws; fails the test if it throws nothing or something else.
template <class F>
std::string rejected_pointer(F&& f) {
    try {
        f();
    } catch (const ValidationError& e) {
        EXPECT_FALSE(e.rule().empty());
        const std::string shown = e.pointer().empty() ? "(root)" : e.pointer();
        EXPECT_EQ(std::string(e.what()), shown + ": " + e.rule());
        return e.pointer();
    } catch (const std::exception& e) {
        ADD_FAILURE() << "threw something other than ValidationError: " << e.what();
        return "<other exception>";
    }
    ADD_FAILURE() << "was accepted";
    return "<accepted>";
}

SceneDocument customised() {
    SceneDocument d;
    d.camera.position = {1.25, -0.5, 3.0};
    d.camera.target = {0.1, 0.2, 0.3};
    d.camera.up = {0.0, 0.0, 1.0};
    d.camera.fov_deg = 55.5;
    d.image = {800, 600, -1.5};
    d.lights.at("light").type = LightType::directional;
    d.lights.at("light").position = {-3.0, 4.0, 5.0};
    d.lights.at("light").direction = {0.0, -1.0, 0.1};
    d.lights.at("light").color = {1.0, 0.9, 0.8};
    d.lights.at("light").intensity = 3.3;
    d.lights.at("light").cone_deg = 90.0;
    d.object().mesh = "upload:bunny_v2.obj";
    d.object().position = {0.5, 0.25, -0.125};
    d.object().rotation_deg = {10.0, 20.0, 30.0};
    d.object().scale = 0.7;
    d.object().resolution = 96;
    d.object().index_field = IndexFieldKind::grid;
    d.object().ior = 1.0 / 3.0 + 1.0;
    d.object().maxwell_n0 = 2.5;
    d.object().abbe = 36.4;
    d.object().extinction = {0.1, 0.2, 0.3};
    d.object().scattering = {0.1, 0.1, 0.1};
    d.object().phase = {PhaseModel::schlick, -0.4};
    d.object().grid = "lens-01";
    d.medium.ior = 1.33;
    d.medium.extinction = {0.0, 0.0, 0.0};
    d.medium.scattering = {0.0, 0.0, 0.0};
    d.medium.phase = {PhaseModel::isotropic, 0.0};
    d.volume.resolution = 200;
    d.volume.smoothing = 0.0;
    d.volume.octree_epsilon = 1.0;
    d.volume.bounds = Bounds{{-2.0, -1.5, -1.0}, {2.0, 1.5, 1.0}};
    d.volume.margin = 0.0;
    d.photons = {12345, 4294967295u, 17};
    d.floor = {false, -2.5, {0.1, 0.5, 1.0}, false, 1.0};
    d.object().fresnel = false;
    d.object().film = {1.38, 99.6, 5000.0};
    d.environment = {EnvironmentKind::image, {0.5, 0.25, 1000.0}, 1e6, "sky-sun", -360.0, false};
    return d;
}

// ---- defaults -------------------------------------------------------------------------------------------

TEST(SceneDocument, EmptyObjectGivesDefaults) {
    const SceneDocument d = parse_scene(json::object());
    EXPECT_EQ(d, SceneDocument{});
    // A glass sphere in light fog under a spot light, seen from the front.
    EXPECT_EQ(d.object().mesh, "sphere");
    EXPECT_EQ(d.object().index_field, IndexFieldKind::uniform);
    EXPECT_DOUBLE_EQ(d.object().ior, 1.5);
    EXPECT_EQ(d.lights.at("light").type, LightType::spot);
    EXPECT_GT(d.medium.extinction[0], 0.0);
    EXPECT_EQ(d.medium.phase.model, PhaseModel::henyey_greenstein);
    EXPECT_GT(d.camera.position[2], 0.0);
    EXPECT_FALSE(d.volume.bounds.has_value());
    EXPECT_EQ(d.volume.resolution, 128u);
    EXPECT_EQ(d.photons.count, 1u << 18);
}

TEST(SceneDocument, EmptySectionsGiveDefaults) {
    const json j = {{"camera", json::object()},  {"image", json::object()},  {"light", json::object()},
                    {"object", json::object()},  {"medium", json::object()}, {"volume", json::object()},
                    {"photons", json::object()}, {"floor", json::object()}};
    EXPECT_EQ(parse_scene(j), SceneDocument{});
}

TEST(SceneDocument, MissingFieldsKeepDefaultsBesideGivenOnes) {
    const SceneDocument d =
        parse_scene(json::parse(R"({"light": {"intensity": 7}, "object": {"phase": {"g": 0.5}}})"));
    SceneDocument expected;
    expected.lights.at("light").intensity = 7.0;
    expected.object().phase.g = 0.5;
    EXPECT_EQ(d, expected);
}

// ---- round trip -----------------------------------------------------------------------------------------

TEST(SceneDocument, RoundTripDefaults) {
    const SceneDocument d;
    EXPECT_EQ(parse_scene(to_json(d)), d);
    EXPECT_EQ(parse_scene(json::parse(to_json(d).dump())), d);
}

TEST(SceneDocument, RoundTripCustomisedThroughText) {
    const SceneDocument d = customised();
    EXPECT_EQ(parse_scene(to_json(d)), d);
    EXPECT_EQ(parse_scene(json::parse(to_json(d).dump())), d);
    EXPECT_EQ(parse_scene(json::parse(to_json(d).dump(2))), d);
}

TEST(SceneDocument, RoundTripEveryEnumValue) {
    for (LightType t : {LightType::point, LightType::spot, LightType::directional}) {
        SceneDocument d;
        d.lights.at("light").type = t;
        EXPECT_EQ(parse_scene(to_json(d)), d);
    }
    for (PhaseModel m : {PhaseModel::isotropic, PhaseModel::schlick, PhaseModel::henyey_greenstein}) {
        SceneDocument d;
        d.object().phase.model = m;
        d.medium.phase.model = m;
        EXPECT_EQ(parse_scene(to_json(d)), d);
    }
    for (IndexFieldKind k :
         {IndexFieldKind::uniform, IndexFieldKind::luneburg, IndexFieldKind::maxwell, IndexFieldKind::grid}) {
        SceneDocument d;
        d.object().index_field = k;
        d.object().grid = "g";
        EXPECT_EQ(parse_scene(to_json(d)), d);
    }
    for (const char* mesh : {"sphere", "cube", "torus", "prism", "bunny", "upload:A-z_0.9"}) {
        SceneDocument d;
        d.object().mesh = mesh;
        EXPECT_EQ(parse_scene(to_json(d)), d);
    }
}

TEST(SceneDocument, ToJsonEmitsEveryField) {
    const json j = to_json(SceneDocument{});
    // Lights and objects in the collection form, the default scene's one of each named as the older form's.
    const std::vector<std::pair<std::string, std::vector<std::string>>> expected = {
        {"/camera", {"position", "target", "up", "fov_deg"}},
        {"/image", {"width", "height", "exposure"}},
        {"/lights/light", {"type", "position", "direction", "color", "intensity", "cone_deg"}},
        {"/objects/object",
         {"mesh", "position", "rotation_deg", "scale", "resolution", "index_field", "ior", "maxwell_n0", "abbe",
          "fresnel", "film", "extinction", "scattering", "phase", "grid"}},
        {"/medium", {"ior", "extinction", "scattering", "phase", "fade"}},
        {"/volumes", {}},  // none by default
        {"/volume", {"resolution", "smoothing", "octree_epsilon", "margin"}},
        {"/photons", {"count", "seed", "max_bounces"}},
        {"/floor", {"enabled", "height", "albedo", "checker", "checker_size"}},
        {"/environment", {"type", "color", "intensity", "image", "rotation_deg", "lights"}},
    };
    ASSERT_EQ(j.size(), expected.size());
    EXPECT_EQ(j["lights"].size(), 1u);
    EXPECT_EQ(j["objects"].size(), 1u);
    for (const auto& [section, fields] : expected) {
        const json::json_pointer at(section);
        ASSERT_TRUE(j.contains(at)) << section;
        EXPECT_EQ(j[at].size(), fields.size()) << section;
        for (const auto& f : fields) EXPECT_TRUE(j[at].contains(f)) << section << "." << f;
    }
    EXPECT_FALSE(j["volume"].contains("bounds"));
    EXPECT_EQ(j["medium"]["phase"]["model"], "henyey-greenstein");
    EXPECT_EQ(j["lights"]["light"]["type"], "spot");
    EXPECT_EQ(j["image"]["width"], 512);

    const json c = to_json(customised());
    ASSERT_TRUE(c["volume"].contains("bounds"));
    EXPECT_EQ(c["volume"]["bounds"]["min"], json::array({-2.0, -1.5, -1.0}));
    EXPECT_EQ(c["volume"]["bounds"]["max"], json::array({2.0, 1.5, 1.0}));
}

// ---- parse_scene specifics ------------------------------------------------------------------------------

TEST(SceneDocument, RootMustBeObject) {
    for (const json& j : {json::array(), json("scene"), json(nullptr), json(3), json(true)}) {
        EXPECT_EQ(rejected_pointer([&] { parse_scene(j); }), "") << j.dump();
    }
}

TEST(SceneDocument, RuleWording) {
    try {
        parse_scene(json::parse(R"({"light": {"intensity": -1}})"));
        FAIL() << "accepted";
    } catch (const ValidationError& e) {
        EXPECT_EQ(e.pointer(), "/light/intensity");
        EXPECT_EQ(e.rule(), "must be a number in [0, 1e6]");
        EXPECT_STREQ(e.what(), "/light/intensity: must be a number in [0, 1e6]");
    }
    try {
        parse_scene(json::array());
        FAIL() << "accepted";
    } catch (const ValidationError& e) {
        EXPECT_EQ(e.pointer(), "");
        EXPECT_EQ(e.rule(), "must be a JSON object");
    }
}

TEST(SceneDocument, NullBoundsMeansNoBounds) {
    const SceneDocument d = parse_scene(json::parse(R"({"volume": {"bounds": null}})"));
    EXPECT_FALSE(d.volume.bounds.has_value());
}

TEST(SceneDocument, IntegersMayBeWrittenAsWholeFloats) {
    const SceneDocument d =
        parse_scene(json::parse(R"({"volume": {"resolution": 64.0}, "image": {"width": 100}})"));
    EXPECT_EQ(d.volume.resolution, 64u);
    EXPECT_EQ(d.image.width, 100u);
    // Signed-integer JSON values built in code are accepted when non-negative.
    EXPECT_EQ(parse_scene(json{{"photons", {{"seed", static_cast<int64_t>(7)}}}}).photons.seed, 7u);
}

TEST(SceneDocument, PartialBoundsTakeDefaultsForTheRest) {
    const SceneDocument d = parse_scene(json::parse(R"({"volume": {"bounds": {"min": [-3, -3, -3]}}})"));
    ASSERT_TRUE(d.volume.bounds.has_value());
    EXPECT_EQ(d.volume.bounds->min, (Vec3{-3.0, -3.0, -3.0}));
    EXPECT_EQ(d.volume.bounds->max, Bounds{}.max);
}

TEST(SceneDocument, BoundaryValuesAccepted) {
    const json j = json::parse(R"({
        "camera": {"fov_deg": 169.9, "position": [10000, -10000, 10000]},
        "image": {"width": 1, "height": 4096, "exposure": -20},
        "light": {"type": "point", "direction": [0, 0, 0], "intensity": 1e6, "color": [0, 1000, 0], "cone_deg": 90},
        "object": {"scale": 1000, "ior": 4, "maxwell_n0": 1, "abbe": 5, "extinction": [1000, 0, 0], "scattering": [1000, 0, 0],
                   "phase": {"model": "henyey-greenstein", "g": -0.99}},
        "medium": {"ior": 1, "phase": {"g": 0.99}, "fade": 10000},
        "volume": {"resolution": 32, "smoothing": 4, "octree_epsilon": 1, "margin": 0},
        "photons": {"count": 1, "seed": 4294967295},
        "floor": {"albedo": [0, 1, 0.5], "checker_size": 0.001}
    })");
    const SceneDocument d = parse_scene(j);
    EXPECT_EQ(d.photons.seed, 4294967295u);
    EXPECT_EQ(parse_scene(to_json(d)), d);
}

// ---- an object's own resolution -------------------------------------------------------------------------

TEST(ObjectResolution, RoundTripsAndDefaultsToTheScenesVoxel) {
    const SceneDocument d = parse_scene(json::parse(R"({"objects": {"a": {"resolution": 200}, "b": {}}})"));
    EXPECT_EQ(d.objects.at("a").resolution, 200u);
    EXPECT_EQ(d.objects.at("b").resolution, 0u);  // absent: the scene's voxel
    EXPECT_EQ(Object{}.resolution, 0u);
    const json j = to_json(d);
    EXPECT_EQ(j["objects"]["a"]["resolution"], 200);
    EXPECT_EQ(j["objects"]["b"]["resolution"], 0);  // the stored form always has it
    EXPECT_EQ(parse_scene(j), d);
    EXPECT_EQ(parse_scene(json::parse(j.dump())), d);
    // A document from before the field loads as it did: every object at the scene's voxel.
    json old = to_json(SceneDocument{});
    old["objects"]["object"].erase("resolution");
    EXPECT_EQ(parse_scene(old), SceneDocument{});
    // The older one-object form takes it too; 0, the bounds and a whole float are accepted.
    EXPECT_EQ(parse_scene(json::parse(R"({"object": {"resolution": 64}})")).object().resolution, 64u);
    for (const uint32_t r : {0u, 16u, 512u}) {
        EXPECT_EQ(parse_scene(json{{"objects", {{"a", {{"resolution", r}}}}}}).objects.at("a").resolution, r);
    }
    EXPECT_EQ(parse_scene(json::parse(R"({"objects": {"a": {"resolution": 48.0}}})")).objects.at("a").resolution,
              48u);
}

TEST(ObjectResolution, HostileValuesAreRejectedAtItsPointer) {
    const Limits limits;
    const std::vector<json> values = {8, 1, 15, limits.max_resolution + 1, -5, 2.5, "fine", nullptr, true,
                                      json::array({64}), json::object(), std::numeric_limits<double>::quiet_NaN(),
                                      1e300, 4294967296.0};
    for (const json& v : values) {
        SCOPED_TRACE(v.dump());
        // As a whole document (null included: only a merge patch removes a field with it)...
        EXPECT_EQ(rejected_pointer([&] { (void)parse_scene(json{{"objects", {{"a", {{"resolution", v}}}}}}); }),
                  "/objects/a/resolution");
        // ...and as an edit, which changes nothing.
        if (v.is_null()) continue;
        const SceneDocument current = parse_scene(json::parse(R"({"objects": {"a": {}}})"));
        const SceneDocument before = current;
        EXPECT_EQ(rejected_pointer([&] {
                      (void)apply_merge_patch(current, json{{"objects", {{"a", {{"resolution", v}}}}}});
                  }),
                  "/objects/a/resolution");
        EXPECT_EQ(current, before);
    }
    // The rule says what is allowed.
    try {
        (void)parse_scene(json::parse(R"({"objects": {"a": {"resolution": 8}}})"));
        ADD_FAILURE() << "accepted";
    } catch (const ValidationError& e) {
        EXPECT_EQ(e.rule(), "must be 0 (the scene's voxel) or an integer in [16, 512]");
    }
}

TEST(Volumes, NoneByDefaultAndEveryFieldRoundTrips) {
    EXPECT_TRUE(parse_scene(json::object()).volumes.empty());
    EXPECT_TRUE(parse_scene(json{{"volumes", nullptr}}).volumes.empty());
    const SceneDocument d = parse_scene(json::parse(R"({"volumes": {"smoke": {"asset": "plume"},
        "cloud": {"asset": "cumulus", "grid": "density fine", "position": [1, 2, 3], "rotation_deg": [0, 90, 0],
                  "scale": 0.5, "density_scale": 3, "extinction": [1, 2, 3], "scattering": [0.5, 1, 1.5],
                  "phase": {"model": "isotropic"}}}})"));
    ASSERT_EQ(d.volumes.size(), 2u);
    const DensityVolume& smoke = d.volumes.at("smoke");
    EXPECT_EQ(smoke.asset, "plume");
    EXPECT_EQ(smoke.grid, "density");
    EXPECT_EQ(smoke.scale, 1.0);
    EXPECT_EQ(smoke.density_scale, 1.0);
    EXPECT_EQ(smoke.extinction, (Vec3{1, 1, 1}));
    EXPECT_EQ(smoke.phase, (Phase{PhaseModel::henyey_greenstein, 0.0}));
    EXPECT_EQ(d.volumes.at("cloud").grid, "density fine");  // grid names are OpenVDB's: any characters
    EXPECT_EQ(parse_scene(to_json(d)), d);
    EXPECT_EQ(parse_scene(json::parse(to_json(d).dump())), d);
    // A merge patch edits one member by its key, adds one, and removes one with null.
    const SceneDocument edited = apply_merge_patch(
        d, json::parse(R"({"volumes": {"smoke": {"density_scale": 2}, "cloud": null, "puff": {"asset": "plume"}}})"));
    ASSERT_EQ(edited.volumes.size(), 2u);
    EXPECT_EQ(edited.volumes.at("smoke").density_scale, 2.0);
    EXPECT_EQ(edited.volumes.at("smoke").asset, "plume");
    EXPECT_TRUE(edited.volumes.contains("puff"));
    EXPECT_TRUE(apply_merge_patch(d, json{{"volumes", nullptr}}).volumes.empty());
}

TEST(Volumes, EmissionIsOffByDefaultAndNamesOneGridWhenOn) {
    const SceneDocument d = parse_scene(json::parse(R"({"volumes": {"smoke": {"asset": "plume"},
        "fire": {"asset": "flame", "emission": {"temperature_grid": "temperature", "intensity": 3}},
        "glow": {"asset": "flame", "emission": {"grid": "heat", "color": [1, 0.5, 0.1], "intensity": 0.5}}}})"));
    const DensityVolume& smoke = d.volumes.at("smoke");
    EXPECT_FALSE(smoke.emission.emits());
    EXPECT_EQ(smoke.emission_grid(), "");
    EXPECT_EQ(smoke.emission.color, (Vec3{1, 1, 1}));
    EXPECT_EQ(d.volumes.at("fire").emission_grid(), "temperature");
    EXPECT_EQ(d.volumes.at("glow").emission_grid(), "heat");
    EXPECT_EQ(d.volumes.at("glow").emission.color, (Vec3{1, 0.5, 0.1}));
    EXPECT_EQ(parse_scene(json::parse(to_json(d).dump())), d);
    // A grid may be named while the volume does not emit (intensity 0): it is kept, and read by nothing.
    const SceneDocument dark = apply_merge_patch(d, json::parse(R"({"volumes": {"glow": {"emission": {"intensity": 0}}}})"));
    EXPECT_EQ(dark.volumes.at("glow").emission.grid, "heat");
    EXPECT_EQ(dark.volumes.at("glow").emission_grid(), "");
    // Switching from one kind to the other in one edit.
    const SceneDocument switched = apply_merge_patch(
        d, json::parse(R"({"volumes": {"fire": {"emission": {"temperature_grid": "", "grid": "heat"}}}})"));
    EXPECT_EQ(switched.volumes.at("fire").emission_grid(), "heat");
    // The edit that names both is blamed at what it touched.
    EXPECT_EQ(rejected_pointer([&] {
                  (void)apply_merge_patch(d, json::parse(R"({"volumes": {"fire": {"emission": {"grid": "heat"}}}})"));
              }),
              "/volumes/fire/emission/grid");
}

TEST(Volumes, HostileMembersAreRejectedAtTheirPointer) {
    json nine = json::object();
    for (int i = 0; i < 9; ++i) nine["v" + std::to_string(i)] = {{"asset", "a"}};
    const std::vector<std::pair<json, std::string>> cases = {
        {json::array(), "/volumes"},
        {"smoke", "/volumes"},
        {nine, "/volumes"},
        {{{"bad/name", {{"asset", "a"}}}}, "/volumes/bad~1name"},
        {{{"v", json::array()}}, "/volumes/v"},
        {{{"v", json::object()}}, "/volumes/v/asset"},
        {{{"v", {{"asset", ""}}}}, "/volumes/v/asset"},
        {{{"v", {{"asset", "../etc"}}}}, "/volumes/v/asset"},
        {{{"v", {{"asset", 7}}}}, "/volumes/v/asset"},
        {{{"v", {{"asset", "a"}, {"grid", ""}}}}, "/volumes/v/grid"},
        {{{"v", {{"asset", "a"}, {"grid", std::string(65, 'g')}}}}, "/volumes/v/grid"},
        {{{"v", {{"asset", "a"}, {"emission", 1}}}}, "/volumes/v/emission"},
        {{{"v", {{"asset", "a"}, {"scale", 0}}}}, "/volumes/v/scale"},
        {{{"v", {{"asset", "a"}, {"density_scale", -1}}}}, "/volumes/v/density_scale"},
        {{{"v", {{"asset", "a"}, {"density_scale", 1e9}}}}, "/volumes/v/density_scale"},
        {{{"v", {{"asset", "a"}, {"position", {0, 1e5, 0}}}}}, "/volumes/v/position/1"},
        {{{"v", {{"asset", "a"}, {"extinction", {1, -1, 1}}}}}, "/volumes/v/extinction/1"},
        {{{"v", {{"asset", "a"}, {"scattering", {2, 1, 1}}}}}, "/volumes/v/scattering/0"},
        {{{"v", {{"asset", "a"}, {"phase", {{"g", 1}}}}}}, "/volumes/v/phase/g"},
        {{{"v", {{"asset", "a"}, {"phase", {{"model", "schlick"}}}}}}, "/volumes/v/phase/model"},
        {{{"v", {{"asset", "a"}, {"emission", {{"intensity", -1}}}}}}, "/volumes/v/emission/intensity"},
        {{{"v", {{"asset", "a"}, {"emission", {{"intensity", 1e7}, {"grid", "flame"}}}}}}, "/volumes/v/emission/intensity"},
        {{{"v", {{"asset", "a"}, {"emission", {{"color", {1, -1, 1}}}}}}}, "/volumes/v/emission/color/1"},
        {{{"v", {{"asset", "a"}, {"emission", {{"grid", 3}}}}}}, "/volumes/v/emission/grid"},
        {{{"v", {{"asset", "a"}, {"emission", {{"grid", std::string(65, 'g')}}}}}}, "/volumes/v/emission/grid"},
        {{{"v", {{"asset", "a"}, {"emission", {{"temperature_grid", std::string(65, 't')}}}}}},
         "/volumes/v/emission/temperature_grid"},
        {{{"v", {{"asset", "a"}, {"emission", {{"flame", "x"}}}}}}, "/volumes/v/emission/flame"},
        {{{"v", {{"asset", "a"}, {"emission", {{"intensity", 2}}}}}}, "/volumes/v/emission/intensity"},
        {{{"v", {{"asset", "a"}, {"emission", {{"intensity", 2}, {"grid", "f"}, {"temperature_grid", "t"}}}}}},
         "/volumes/v/emission/grid"},
    };
    const SceneDocument current = parse_scene(json::parse(R"({"volumes": {"v": {"asset": "a"}}})"));
    for (const auto& [volumes, pointer] : cases) {
        SCOPED_TRACE(volumes.dump());
        EXPECT_EQ(rejected_pointer([&] { (void)parse_scene(json{{"volumes", volumes}}); }), pointer);
    }
    // As edits, which change nothing.
    EXPECT_EQ(rejected_pointer([&] {
                  (void)apply_merge_patch(current, json::parse(R"({"volumes": {"v": {"asset": null}}})"));
              }),
              "/volumes/v/asset");
    EXPECT_EQ(rejected_pointer([&] {
                  (void)apply_merge_patch(current, json::parse(R"({"volumes": {"v": {"scattering": [5, 5, 5]}}})"));
              }),
              "/volumes/v/scattering/0");
    EXPECT_EQ(current.volumes.at("v").asset, "a");
}

TEST(ObjectResolution, FollowsTheResolutionLimit) {
    Limits limits;
    limits.max_resolution = 128;
    EXPECT_EQ(parse_scene(json::parse(R"({"objects": {"a": {"resolution": 128}}})"), limits).objects.at("a").resolution,
              128u);
    try {
        (void)apply_merge_patch(SceneDocument{}, json::parse(R"({"objects": {"object": {"resolution": 129}}})"),
                                limits);
        ADD_FAILURE() << "accepted";
    } catch (const ValidationError& e) {
        EXPECT_EQ(e.pointer(), "/objects/object/resolution");
        EXPECT_EQ(e.rule(), "must be 0 (the scene's voxel) or an integer in [16, 128]");
    }
}

TEST(ObjectResolution, MergePatchEditsOnlyThatObjectsFieldAndNullRestoresTheDefault) {
    const SceneDocument two = parse_scene(json::parse(
        R"({"objects": {"a": {"scale": 0.5, "resolution": 200}, "b": {"position": [2, 0, 0], "resolution": 32}}})"));
    const SceneDocument edited = apply_merge_patch(two, json::parse(R"({"objects": {"a": {"resolution": 64}}})"));
    SceneDocument expected = two;
    expected.objects.at("a").resolution = 64;
    EXPECT_EQ(edited, expected);
    EXPECT_EQ(edited.objects.at("b"), two.objects.at("b"));
    EXPECT_DOUBLE_EQ(edited.objects.at("a").scale, 0.5);
    // null removes the field, and an absent field is the scene's voxel.
    const SceneDocument reset = apply_merge_patch(edited, json::parse(R"({"objects": {"a": {"resolution": null}}})"));
    EXPECT_EQ(reset.objects.at("a").resolution, 0u);
    EXPECT_EQ(reset.objects.at("b").resolution, 32u);
    // The older form edits the one object's.
    EXPECT_EQ(apply_merge_patch(SceneDocument{}, json::parse(R"({"object": {"resolution": 256}})")).object().resolution,
              256u);
    EXPECT_EQ(rejected_pointer([] {
                  (void)apply_merge_patch(SceneDocument{}, json::parse(R"({"object": {"resolution": 8}})"));
              }),
              "/object/resolution");
}

TEST(ObjectResolution, AnimationHoldsItUntilTheNextKeyframe) {
    Animation a(SceneDocument{}, json::parse(R"([
        {"time": 0, "patch": {"object": {"resolution": 64}}},
        {"time": 1, "patch": {"object": {"resolution": 128}}}])"));
    EXPECT_EQ(a.at(0.5).object().resolution, 64u);
    EXPECT_EQ(a.at(0.99).object().resolution, 64u);
    EXPECT_EQ(a.at(1.0).object().resolution, 128u);
    Animation from_zero(SceneDocument{}, json::parse(R"([
        {"time": 0, "patch": {}}, {"time": 1, "patch": {"object": {"resolution": 256}}}])"));
    EXPECT_EQ(from_zero.at(0.5).object().resolution, 0u);
    EXPECT_EQ(from_zero.at(1.0).object().resolution, 256u);
}

// ---- merge patch ----------------------------------------------------------------------------------------

TEST(MergePatch, EmptyPatchChangesNothing) {
    const SceneDocument d = customised();
    EXPECT_EQ(apply_merge_patch(d, json::object()), d);
}

TEST(MergePatch, NestedMergeKeepsSiblings) {
    const SceneDocument current = customised();
    const SceneDocument before = current;
    const SceneDocument d = apply_merge_patch(
        current, json::parse(R"({"light": {"intensity": 5}, "object": {"phase": {"g": 0.25}}})"));
    SceneDocument expected = customised();
    expected.lights.at("light").intensity = 5.0;
    expected.object().phase.g = 0.25;
    EXPECT_EQ(d, expected);
    EXPECT_EQ(d.object().phase.model, PhaseModel::schlick);  // sibling inside the nested object kept
    EXPECT_EQ(current, before);
}

TEST(MergePatch, NullDeletesAndFieldReturnsToDefault) {
    const SceneDocument current = customised();
    SceneDocument d = apply_merge_patch(current, json::parse(R"({"light": {"intensity": null}})"));
    EXPECT_DOUBLE_EQ(d.lights.at("light").intensity, Light{}.intensity);
    EXPECT_EQ(d.lights.at("light").type, LightType::directional);  // the rest of the section kept

    d = apply_merge_patch(current, json::parse(R"({"camera": null})"));
    EXPECT_EQ(d.camera, Camera{});
    EXPECT_EQ(d.lights.at("light"), current.lights.at("light"));

    d = apply_merge_patch(current, json::parse(R"({"object": {"phase": {"model": null}}})"));
    EXPECT_EQ(d.object().phase.model, Phase{}.model);
    EXPECT_DOUBLE_EQ(d.object().phase.g, -0.4);

    // Deleting a member that is not there is a no-op, even under a name the document does not know.
    EXPECT_EQ(apply_merge_patch(current, json::parse(R"({"camera": {"no_such_field": null}})")), current);
}

TEST(MergePatch, BoundsAddMergeRemove) {
    const SceneDocument start;
    ASSERT_FALSE(start.volume.bounds.has_value());
    SceneDocument d = apply_merge_patch(
        start, json::parse(R"({"volume": {"bounds": {"min": [-2, -2, -2], "max": [2, 2, 2]}}})"));
    ASSERT_TRUE(d.volume.bounds.has_value());
    EXPECT_EQ(d.volume.bounds->min, (Vec3{-2.0, -2.0, -2.0}));
    EXPECT_EQ(d.volume.bounds->max, (Vec3{2.0, 2.0, 2.0}));
    EXPECT_DOUBLE_EQ(d.volume.margin, Volume{}.margin);

    d = apply_merge_patch(d, json::parse(R"({"volume": {"bounds": {"max": [3, 3, 3]}}})"));
    ASSERT_TRUE(d.volume.bounds.has_value());
    EXPECT_EQ(d.volume.bounds->min, (Vec3{-2.0, -2.0, -2.0}));
    EXPECT_EQ(d.volume.bounds->max, (Vec3{3.0, 3.0, 3.0}));

    const SceneDocument with_bounds = d;
    d = apply_merge_patch(with_bounds, json::parse(R"({"volume": {"bounds": null}})"));
    EXPECT_FALSE(d.volume.bounds.has_value());
    EXPECT_EQ(d.volume.resolution, with_bounds.volume.resolution);
    EXPECT_TRUE(with_bounds.volume.bounds.has_value());
}

TEST(MergePatch, ArraysAreReplacedWhole) {
    const SceneDocument current = customised();
    const SceneDocument d = apply_merge_patch(current, json::parse(R"({"camera": {"position": [1, 2, 3]}})"));
    EXPECT_EQ(d.camera.position, (Vec3{1.0, 2.0, 3.0}));
    EXPECT_EQ(d.camera.target, current.camera.target);
    // An array cannot be patched element by element: an object patch turns it into an object.
    EXPECT_EQ(rejected_pointer(
                  [&] { apply_merge_patch(current, json::parse(R"({"camera": {"position": {"0": 5}}})")); }),
              "/camera/position");
    // A shorter array replaces the whole value too and is then the wrong length.
    EXPECT_EQ(rejected_pointer(
                  [&] { apply_merge_patch(current, json::parse(R"({"camera": {"position": [1]}})")); }),
              "/camera/position");
}

TEST(MergePatch, NonObjectPatchReplacesTheDocument) {
    const SceneDocument current = customised();
    for (const json& patch : {json::array({1, 2}), json("scene"), json(42), json(nullptr)}) {
        EXPECT_EQ(rejected_pointer([&] { apply_merge_patch(current, patch); }), "") << patch.dump();
        EXPECT_EQ(current, customised());
    }
}

TEST(MergePatch, SectionReplacedByScalarIsRejected) {
    EXPECT_EQ(
        rejected_pointer([] { apply_merge_patch(SceneDocument{}, json::parse(R"({"floor": false})")); }),
        "/floor");
}

TEST(MergePatch, CrossFieldErrorsBlameTheEditedValue) {
    // Lowering extinction below the (untouched) scattering blames extinction...
    EXPECT_EQ(rejected_pointer([] {
                  apply_merge_patch(SceneDocument{},
                                    json::parse(R"({"medium": {"extinction": [0.2, 0.01, 0.2]}})"));
              }),
              "/medium/extinction/1");
    // ...raising scattering above extinction blames scattering, and so does a document written whole.
    EXPECT_EQ(rejected_pointer([] {
                  apply_merge_patch(SceneDocument{},
                                    json::parse(R"({"medium": {"scattering": [0.2, 0.21, 0.2]}})"));
              }),
              "/medium/scattering/1");
    EXPECT_EQ(
        rejected_pointer([] {
            parse_scene(json::parse(R"({"medium": {"extinction": [1, 1, 1], "scattering": [1, 1, 2]}})"));
        }),
        "/medium/scattering/2");
}

// ---- collections of lights and objects ----------------------------------------------------------------

TEST(Collections, OlderFormLoadsAsACollectionOfOneAndIsStoredInTheNewForm) {
    const SceneDocument d = parse_scene(json::parse(R"({"light": {"intensity": 7}, "object": {"ior": 1.7}})"));
    ASSERT_EQ(d.lights.size(), 1u);
    ASSERT_EQ(d.objects.size(), 1u);
    EXPECT_DOUBLE_EQ(d.lights.at("light").intensity, 7.0);
    EXPECT_DOUBLE_EQ(d.objects.at("object").ior, 1.7);
    const json stored = to_json(d);
    EXPECT_FALSE(stored.contains("light"));
    EXPECT_FALSE(stored.contains("object"));
    EXPECT_DOUBLE_EQ(stored["lights"]["light"]["intensity"].get<double>(), 7.0);
    EXPECT_EQ(parse_scene(stored), d);
    // The same scene written in the new form is the same document.
    EXPECT_EQ(parse_scene(json::parse(R"({"lights": {"light": {"intensity": 7}}, "objects": {"object": {"ior": 1.7}}})")), d);
}

TEST(Collections, MergePatchesAddEditRenameAndRemoveOneLightByItsKey) {
    const SceneDocument one;
    SceneDocument two = apply_merge_patch(one, json::parse(R"({"lights": {"fill": {"type": "point", "intensity": 3}}})"));
    ASSERT_EQ(two.lights.size(), 2u);
    EXPECT_EQ(two.lights.at("light"), one.lights.at("light"));  // the other light is untouched
    EXPECT_EQ(two.lights.at("fill").type, LightType::point);
    EXPECT_DOUBLE_EQ(two.lights.at("fill").intensity, 3.0);
    EXPECT_EQ(two.lights.at("fill").color, Light{}.color);  // fields not given take defaults

    const SceneDocument edited = apply_merge_patch(two, json::parse(R"({"lights": {"fill": {"intensity": 4}}})"));
    EXPECT_DOUBLE_EQ(edited.lights.at("fill").intensity, 4.0);
    EXPECT_EQ(edited.lights.at("fill").type, LightType::point);
    EXPECT_EQ(edited.lights.at("light"), one.lights.at("light"));

    // A rename is an add and a remove in one patch.
    const SceneDocument renamed = apply_merge_patch(
        edited, json{{"lights", {{"fill", nullptr}, {"rim", to_json(edited)["lights"]["fill"]}}}});
    EXPECT_FALSE(renamed.lights.contains("fill"));
    EXPECT_EQ(renamed.lights.at("rim"), edited.lights.at("fill"));

    const SceneDocument removed = apply_merge_patch(renamed, json::parse(R"({"lights": {"rim": null}})"));
    EXPECT_EQ(removed, one);
}

// "o0", "o1", ... (built by append: GCC 12 warns falsely on a literal + std::string).
std::string object_name(size_t i) {
    std::string name = "o";
    name.append(std::to_string(i));
    return name;
}

TEST(Collections, MergePatchesAddEditAndRemoveOneObjectByItsKey) {
    const SceneDocument one;
    const SceneDocument two = apply_merge_patch(
        one, json::parse(R"({"objects": {"lens": {"index_field": "luneburg", "position": [2, 0, 0], "scale": 0.5}}})"));
    ASSERT_EQ(two.objects.size(), 2u);
    EXPECT_EQ(two.objects.at("object"), one.objects.at("object"));  // the other object is untouched
    EXPECT_EQ(two.objects.at("lens").index_field, IndexFieldKind::luneburg);
    EXPECT_EQ(two.objects.at("lens").extinction, Object{}.extinction);  // fields not given take defaults
    const SceneDocument moved = apply_merge_patch(two, json::parse(R"({"objects": {"lens": {"position": [3, 0, 0]}}})"));
    EXPECT_DOUBLE_EQ(moved.objects.at("lens").position[0], 3.0);
    EXPECT_EQ(moved.objects.at("lens").index_field, IndexFieldKind::luneburg);
    EXPECT_EQ(moved.objects.at("object"), one.objects.at("object"));
    EXPECT_EQ(apply_merge_patch(moved, json::parse(R"({"objects": {"lens": null}})")), one);
    // Up to kMaxObjects, in the stored form and back.
    json many = json::object();
    for (size_t i = 0; i < kMaxObjects; ++i) many[object_name(i)] = {{"position", {double(i), 0, 0}}};
    const SceneDocument full = parse_scene(json{{"objects", many}});
    EXPECT_EQ(full.objects.size(), kMaxObjects);
    EXPECT_EQ(parse_scene(to_json(full)), full);
}

TEST(Collections, OlderFormPatchesEditTheOneMemberWhateverItsName) {
    SceneDocument d = apply_merge_patch(SceneDocument{}, json::parse(R"({"lights": {"light": null, "key": {"intensity": 9}}})"));
    ASSERT_EQ(d.lights.size(), 1u);
    d = apply_merge_patch(d, json::parse(R"({"light": {"intensity": 2}})"));
    EXPECT_DOUBLE_EQ(d.lights.at("key").intensity, 2.0);
    // null reset the section in the older form, and still does.
    d = apply_merge_patch(d, json::parse(R"({"light": {"type": "point"}})"));
    d = apply_merge_patch(d, json::parse(R"({"light": null})"));
    EXPECT_EQ(d.lights.at("key"), Light{});
    // Errors name the field as the patch wrote it.
    try {
        (void)apply_merge_patch(d, json::parse(R"({"light": {"type": "spot", "direction": [0, 0, 0]}})"));
        ADD_FAILURE() << "accepted a spot light without a direction";
    } catch (const ValidationError& e) {
        EXPECT_EQ(e.pointer(), "/light/direction");
        EXPECT_EQ(e.rule().find("/lights/"), std::string::npos) << e.rule();
    }
}

TEST(Collections, AWholeDocumentInTheOlderFormReplacesTheCollections) {
    // What a client sends to turn a scene into one loaded from an older file: remove what the file
    // lacks (the collections), give what it has (one light, one object).
    const SceneDocument two = apply_merge_patch(SceneDocument{}, json::parse(R"({"lights": {"fill": {"type": "point"}}})"));
    const SceneDocument d = apply_merge_patch(
        two, json::parse(R"({"lights": null, "objects": null, "light": {"intensity": 3}, "object": {"ior": 1.2}})"));
    ASSERT_EQ(d.lights.size(), 1u);
    EXPECT_DOUBLE_EQ(d.lights.at("light").intensity, 3.0);
    EXPECT_DOUBLE_EQ(d.objects.at("object").ior, 1.2);
    EXPECT_EQ(rejected_pointer([&] {
                  (void)apply_merge_patch(two, json::parse(R"({"lights": null, "light": {"intensity": -3}})"));
              }),
              "/light/intensity");
}

TEST(Collections, BadCollectionsAreRejectedWithTheirPointerAndChangeNothing) {
    SceneDocument two = apply_merge_patch(SceneDocument{}, json::parse(R"({"lights": {"fill": {"type": "point"}}})"));
    const SceneDocument before = two;
    json nine = json::object();
    for (int i = 0; i < 9; ++i) nine["l" + std::to_string(i)] = json::object();
    json eight = nine;
    eight.erase("l8");
    json sixty_five = json::object();
    for (size_t i = 0; i <= kMaxObjects; ++i) sixty_five[object_name(i)] = json::object();
    EXPECT_EQ(parse_scene(json{{"lights", eight}}).lights.size(), kMaxLights);
    const std::vector<std::pair<json, std::string>> documents = {
        {json{{"lights", nine}}, "/lights"},
        {json::parse(R"({"lights": {}})"), "/lights"},
        {json::parse(R"({"lights": []})"), "/lights"},
        {json::parse(R"({"lights": {"a b": {}}})"), "/lights/a b"},
        {json::parse(R"({"lights": {"": {}}})"), "/lights/"},
        {json::parse(R"({"lights": {"..": {}}})"), "/lights/.."},
        {json{{"lights", {{std::string(65, 'x'), json::object()}}}}, "/lights/" + std::string(65, 'x')},
        {json::parse(R"({"lights": {"key": 5}})"), "/lights/key"},
        {json::parse(R"({"lights": {"key": {"intensity": -1}}})"), "/lights/key/intensity"},
        {json::parse(R"({"lights": {"key": {"wattage": 1}}})"), "/lights/key/wattage"},
        {json::parse(R"({"light": {}, "lights": {"key": {}}})"), "/light"},
        {json::parse(R"({"object": {}, "objects": {"glass": {}}})"), "/object"},
        {json{{"objects", sixty_five}}, "/objects"},
        {json::parse(R"({"objects": {}})"), "/objects"},
        {json::parse(R"({"objects": {"a": {"mesh": "teapot"}}})"), "/objects/a/mesh"},
        // An imported grid is the whole field; dispersion is one per scene.
        {json::parse(R"({"objects": {"a": {}, "b": {"index_field": "grid", "grid": "g"}}})"), "/objects/b/index_field"},
        {json::parse(R"({"objects": {"a": {"abbe": 40}, "b": {"abbe": 30}}})"), "/objects/b/abbe"},
        {json::parse(R"({"objects": {"a/b": {}}})"), "/objects/a~1b"},
    };
    for (const auto& [document, pointer] : documents) {
        SCOPED_TRACE(document.dump());
        EXPECT_EQ(rejected_pointer([&] { (void)parse_scene(document); }), pointer);
    }
    const std::vector<std::pair<json, std::string>> patches = {
        {json{{"lights", nine}}, "/lights"},
        {json::parse(R"({"lights": {"light": null, "fill": null}})"), "/lights"},
        {json::parse(R"({"light": {"intensity": 1}})"), "/light"},  // which of the two?
        {json::parse(R"({"lights": {"fill": {"cone_deg": 0}}})"), "/lights/fill/cone_deg"},
        {json::parse(R"({"lights": {"new one": {}}})"), "/lights/new one"},
        {json{{"objects", sixty_five}}, "/objects"},
        {json::parse(R"({"objects": {"object": null}})"), "/objects"},
        {json::parse(R"({"objects": {"second": {"abbe": 30}}})"), "/objects/second/abbe"},
        {json::parse(R"({"objects": {"second": {"index_field": "grid", "grid": "g"}}})"), "/objects/second/index_field"},
    };
    for (const auto& [patch, pointer] : patches) {
        SCOPED_TRACE(patch.dump());
        EXPECT_EQ(rejected_pointer([&] { (void)apply_merge_patch(two, patch); }), pointer);
        EXPECT_EQ(two, before);
    }
}

// ---- limits ---------------------------------------------------------------------------------------------

// A viewer's own view (a WebSocket session setting): its size and camera, checked by the document's rules.
TEST(View, ReadsASizeAndAnOptionalCameraAndSeesTheDocumentThroughThem) {
    const View follows = parse_view(json{{"width", 640}, {"height", 360}}, Limits{});
    EXPECT_EQ(follows.width, 640u);
    EXPECT_EQ(follows.height, 360u);
    EXPECT_FALSE(follows.camera);
    EXPECT_FALSE(parse_view(json{{"width", 640}, {"height", 360}, {"camera", nullptr}}, Limits{}).camera);
    const View own = parse_view(
        json{{"width", 64.0}, {"height", 48}, {"camera", {{"position", {3, 1, 2}}, {"target", {0, 0, 0}}, {"fov_deg", 50}}}},
        Limits{});
    ASSERT_TRUE(own.camera);
    EXPECT_EQ(own.camera->position, (Vec3{3, 1, 2}));
    EXPECT_EQ(own.camera->up, Camera{}.up);  // left out: the default, as in a document
    EXPECT_EQ(own.camera->fov_deg, 50.0);

    const SceneDocument document = customised();
    const SceneDocument seen = seen_through(document, own);
    EXPECT_EQ(seen.camera, *own.camera);
    EXPECT_EQ(seen.image.width, 64u);
    EXPECT_EQ(seen.image.height, 48u);
    EXPECT_EQ(seen.image.exposure, document.image.exposure);
    EXPECT_EQ(seen.lights, document.lights);
    EXPECT_EQ(seen_through(document, follows).camera, document.camera);
    EXPECT_EQ(seen_through(document, View{}), document);  // no view: the document's own
}

TEST(View, HostileViewsAreRefusedWithAPointerUnderTheirPlace) {
    const std::vector<std::pair<json, std::string>> cases = {
        {json(nullptr), "/view"},
        {json("640x360"), "/view"},
        {json{{"width", 640}}, "/view/height"},
        {json{{"height", 360}}, "/view/width"},
        {json{{"width", 0}, {"height", 360}}, "/view/width"},
        {json{{"width", 640}, {"height", -1}}, "/view/height"},
        {json{{"width", 4097}, {"height", 360}}, "/view/width"},
        {json{{"width", 640.5}, {"height", 360}}, "/view/width"},
        {json{{"width", 1e19}, {"height", 360}}, "/view/width"},
        {json{{"width", true}, {"height", 360}}, "/view/width"},
        {json{{"width", 640}, {"height", 360}, {"exposure", 1}}, "/view/exposure"},
        {json{{"width", 640}, {"height", 360}, {"camera", json::array()}}, "/view/camera"},
        {json{{"width", 640}, {"height", 360}, {"camera", {{"position", {0, 0, 0}}, {"target", {0, 0, 0}}}}},
         "/view/camera/target"},
        // Looking straight down the default up: the value the view wrote is blamed.
        {json{{"width", 640}, {"height", 360}, {"camera", {{"position", {0, 5, 0}}, {"target", {0, 0, 0}}}}},
         "/view/camera/target"},
        {json{{"width", 640}, {"height", 360}, {"camera", {{"up", {0, 0, 0}}}}}, "/view/camera/up"},
        {json{{"width", 640}, {"height", 360}, {"camera", {{"fov_deg", 170}}}}, "/view/camera/fov_deg"},
        {json{{"width", 640}, {"height", 360}, {"camera", {{"position", {0, 0, 1e5}}}}}, "/view/camera/position/2"},
        {json{{"width", 640}, {"height", 360}, {"camera", {{"roll", 3}}}}, "/view/camera/roll"},
    };
    for (const auto& [view, pointer] : cases)
        EXPECT_EQ(rejected_pointer([&] { parse_view(view, Limits{}); }), pointer) << view;
    // The daemon's image limit, and the rule's words naming the view's own members.
    Limits small;
    small.max_image_side = 256;
    EXPECT_EQ(rejected_pointer([&] { parse_view(json{{"width", 257}, {"height", 8}}, small); }), "/view/width");
    try {
        parse_view(json{{"width", 8}, {"height", 8}, {"camera", {{"position", {1, 1, 1}}, {"target", {1, 1, 1}}}}}, Limits{});
    } catch (const ValidationError& e) {
        EXPECT_NE(e.rule().find("/view/camera/position"), std::string::npos) << e.rule();
    }
}

TEST(Limits, AreHonoured) {
    Limits limits;
    limits.max_resolution = 128;
    limits.max_photons = 1u << 20;
    limits.max_image_side = 1024;
    const SceneDocument current;
    EXPECT_EQ(rejected_pointer([&] {
                  apply_merge_patch(current, json::parse(R"({"volume": {"resolution": 256}})"), limits);
              }),
              "/volume/resolution");
    EXPECT_EQ(apply_merge_patch(current, json::parse(R"({"volume": {"resolution": 128}})"), limits)
                  .volume.resolution,
              128u);
    // With the default limits 256 is fine.
    EXPECT_EQ(apply_merge_patch(current, json::parse(R"({"volume": {"resolution": 256}})")).volume.resolution,
              256u);

    EXPECT_EQ(
        rejected_pointer([&] { parse_scene(json::parse(R"({"photons": {"count": 1048577}})"), limits); }),
        "/photons/count");
    EXPECT_EQ(parse_scene(json::parse(R"({"photons": {"count": 1048576}})"), limits).photons.count, 1u << 20);
    EXPECT_EQ(rejected_pointer([&] { parse_scene(json::parse(R"({"image": {"height": 1025}})"), limits); }),
              "/image/height");
    EXPECT_EQ(parse_scene(json::parse(R"({"image": {"width": 1024}})"), limits).image.width, 1024u);

    try {
        parse_scene(json::parse(R"({"volume": {"resolution": 256}})"), limits);
        FAIL() << "accepted";
    } catch (const ValidationError& e) {
        EXPECT_EQ(e.rule(), "must be an integer in [32, 128]");
    }
}

// ---- rejected patches -----------------------------------------------------------------------------------

struct BadPatch {
    const char* what;
    json patch;
    const char* pointer;
};

std::vector<BadPatch> bad_patches() {
    const double nan = std::numeric_limits<double>::quiet_NaN();
    const double inf = std::numeric_limits<double>::infinity();
    const std::string long_name(65, 'a');
    return {
        // root and unknown keys
        {"unknown section", json::parse(R"({"cameras": {}})"), "/cameras"},
        {"unknown camera field", json::parse(R"({"camera": {"zoom": 2}})"), "/camera/zoom"},
        {"unknown key is pointer-escaped", json::parse(R"({"camera": {"a/b~c": 1}})"), "/camera/a~1b~0c"},
        {"unknown medium field", json::parse(R"({"medium": {"density": 1}})"), "/medium/density"},
        {"unknown phase field", json::parse(R"({"object": {"phase": {"k": 0.1}}})"), "/object/phase/k"},
        {"unknown bounds field", json::parse(R"({"volume": {"bounds": {"centre": [0, 0, 0]}}})"),
         "/volume/bounds/centre"},
        {"section not an object", json::parse(R"({"camera": 5})"), "/camera"},
        {"phase not an object", json::parse(R"({"object": {"phase": "isotropic"}})"), "/object/phase"},
        {"bounds not an object", json::parse(R"({"volume": {"bounds": [0, 0, 0]}})"), "/volume/bounds"},
        // camera
        {"fov as string", json::parse(R"({"camera": {"fov_deg": "40"}})"), "/camera/fov_deg"},
        {"fov at upper bound", json::parse(R"({"camera": {"fov_deg": 170}})"), "/camera/fov_deg"},
        {"fov at lower bound", json::parse(R"({"camera": {"fov_deg": 1}})"), "/camera/fov_deg"},
        {"up of two numbers", json::parse(R"({"camera": {"up": [0, 1]}})"), "/camera/up"},
        {"up not an array", json::parse(R"({"camera": {"up": "y"}})"), "/camera/up"},
        {"zero up", json::parse(R"({"camera": {"up": [0, 0, 0]}})"), "/camera/up"},
        {"up parallel to view", json::parse(R"({"camera": {"up": [0, -0.85, -5]}})"), "/camera/up"},
        {"view moved parallel to up", json::parse(R"({"camera": {"position": [0, 5, 0]}})"),
         "/camera/position"},
        {"target onto position", json::parse(R"({"camera": {"target": [0, 0.5, 5]}})"), "/camera/target"},
        {"position onto target", json::parse(R"({"camera": {"position": [0, -0.35, 0]}})"), "/camera/position"},
        {"position too far", json::parse(R"({"camera": {"position": [1e5, 0, 4]}})"), "/camera/position/0"},
        {"position element bool", json::parse(R"({"camera": {"target": [0, true, 0]}})"), "/camera/target/1"},
        // image
        {"zero width", json::parse(R"({"image": {"width": 0}})"), "/image/width"},
        {"width over limit", json::parse(R"({"image": {"width": 4097}})"), "/image/width"},
        {"negative height", json::parse(R"({"image": {"height": -5}})"), "/image/height"},
        {"fractional height", json::parse(R"({"image": {"height": 512.5}})"), "/image/height"},
        {"height as string", json::parse(R"({"image": {"height": "512"}})"), "/image/height"},
        {"exposure too high", json::parse(R"({"image": {"exposure": 21}})"), "/image/exposure"},
        // light
        {"negative intensity", json::parse(R"({"light": {"intensity": -1}})"), "/light/intensity"},
        {"intensity too high", json::parse(R"({"light": {"intensity": 2e6}})"), "/light/intensity"},
        {"intensity NaN", json{{"light", {{"intensity", nan}}}}, "/light/intensity"},
        {"intensity infinite", json{{"light", {{"intensity", inf}}}}, "/light/intensity"},
        {"unknown light type", json::parse(R"({"light": {"type": "area"}})"), "/light/type"},
        {"light type wrong case", json::parse(R"({"light": {"type": "Spot"}})"), "/light/type"},
        {"zero spot direction", json::parse(R"({"light": {"direction": [0, 0, 0]}})"), "/light/direction"},
        {"zero directional direction",
         json::parse(R"({"light": {"type": "directional", "direction": [0, 0, 0]}})"), "/light/direction"},
        {"zero cone", json::parse(R"({"light": {"cone_deg": 0}})"), "/light/cone_deg"},
        {"cone over 90", json::parse(R"({"light": {"cone_deg": 90.5}})"), "/light/cone_deg"},
        {"colour channel too bright", json::parse(R"({"light": {"color": [1, 1, 1001]}})"), "/light/color/2"},
        {"colour channel negative", json::parse(R"({"light": {"color": [1, -0.1, 1]}})"), "/light/color/1"},
        {"colour of four", json::parse(R"({"light": {"color": [1, 1, 1, 1]}})"), "/light/color"},
        // object
        {"unknown mesh", json::parse(R"({"object": {"mesh": "teapot"}})"), "/object/mesh"},
        {"empty upload name", json::parse(R"({"object": {"mesh": "upload:"}})"), "/object/mesh"},
        {"upload name with slash", json::parse(R"({"object": {"mesh": "upload:a/b"}})"), "/object/mesh"},
        {"upload name dot-dot", json::parse(R"({"object": {"mesh": "upload:.."}})"), "/object/mesh"},
        {"upload name too long", json{{"object", {{"mesh", "upload:" + long_name}}}}, "/object/mesh"},
        {"mesh not a string", json::parse(R"({"object": {"mesh": 3}})"), "/object/mesh"},
        {"zero scale", json::parse(R"({"object": {"scale": 0}})"), "/object/scale"},
        {"scale too big", json::parse(R"({"object": {"scale": 1001}})"), "/object/scale"},
        {"non-uniform scale", json::parse(R"({"object": {"scale": [1, 1, 1]}})"), "/object/scale"},
        {"object resolution below 16", json::parse(R"({"object": {"resolution": 15}})"), "/object/resolution"},
        {"object resolution above 512", json::parse(R"({"object": {"resolution": 513}})"), "/object/resolution"},
        {"object resolution as string", json::parse(R"({"object": {"resolution": "64"}})"), "/object/resolution"},
        {"rotation of four", json::parse(R"({"object": {"rotation_deg": [0, 0, 0, 0]}})"),
         "/object/rotation_deg"},
        {"position infinite", json{{"object", {{"position", {0.0, inf, 0.0}}}}}, "/object/position/1"},
        {"ior below 1", json::parse(R"({"object": {"ior": 0.9}})"), "/object/ior"},
        {"ior above 4", json::parse(R"({"object": {"ior": 4.5}})"), "/object/ior"},
        {"maxwell n0 above 4", json::parse(R"({"object": {"maxwell_n0": 5}})"), "/object/maxwell_n0"},
        {"abbe between 0 and 5", json::parse(R"({"object": {"abbe": 4.9}})"), "/object/abbe"},
        {"abbe negative", json::parse(R"({"object": {"abbe": -20}})"), "/object/abbe"},
        {"abbe above 1000", json::parse(R"({"object": {"abbe": 1001}})"), "/object/abbe"},
        {"abbe not a number", json::parse(R"({"object": {"abbe": "flint"}})"), "/object/abbe"},
        {"abbe NaN", json{{"object", {{"abbe", std::nan("")}}}}, "/object/abbe"},
        {"fresnel not a boolean", json::parse(R"({"object": {"fresnel": 1}})"), "/object/fresnel"},
        {"film thickness negative", json::parse(R"({"object": {"film": {"top_nm": -1}}})"), "/object/film/top_nm"},
        {"film thickness above 5000 nm", json::parse(R"({"object": {"film": {"bottom_nm": 5001}}})"),
         "/object/film/bottom_nm"},
        {"film thickness NaN", json{{"object", {{"film", {{"top_nm", nan}}}}}}, "/object/film/top_nm"},
        {"film index below 1", json::parse(R"({"object": {"film": {"ior": 0.5}}})"), "/object/film/ior"},
        {"film not an object", json::parse(R"({"object": {"film": 300}})"), "/object/film"},
        {"unknown film field", json::parse(R"({"object": {"film": {"thickness": 300}}})"), "/object/film/thickness"},
        {"unknown environment", json::parse(R"({"environment": {"type": "studio"}})"), "/environment/type"},
        {"environment colour negative", json::parse(R"({"environment": {"color": [1, -0.1, 1]}})"),
         "/environment/color/1"},
        {"environment colour NaN", json{{"environment", {{"color", {1.0, 1.0, std::nan("")}}}}}, "/environment/color/2"},
        {"environment intensity infinite", json{{"environment", {{"intensity", inf}}}},
         "/environment/intensity"},
        {"environment intensity above 1e6", json::parse(R"({"environment": {"intensity": 2e6}})"),
         "/environment/intensity"},
        {"unknown environment field", json::parse(R"({"environment": {"map": "sky.hdr"}})"), "/environment/map"},
        {"environment image without a name", json::parse(R"({"environment": {"type": "image", "image": ""}})"),
         "/environment/image"},
        {"environment image name with a slash", json::parse(R"({"environment": {"image": "../sky"}})"),
         "/environment/image"},
        {"environment rotation above 360", json::parse(R"({"environment": {"rotation_deg": 361}})"),
         "/environment/rotation_deg"},
        {"environment lights not a boolean", json::parse(R"({"environment": {"lights": "yes"}})"),
         "/environment/lights"},
        {"unknown index field", json::parse(R"({"object": {"index_field": "Uniform"}})"),
         "/object/index_field"},
        {"negative extinction", json::parse(R"({"object": {"extinction": [0.05, -1, 0.05]}})"),
         "/object/extinction/1"},
        {"extinction too high", json::parse(R"({"object": {"extinction": [1001, 1001, 1001]}})"),
         "/object/extinction/0"},
        {"scattering above extinction", json::parse(R"({"object": {"scattering": [0.02, 0.1, 0.02]}})"),
         "/object/scattering/1"},
        {"extinction below scattering", json::parse(R"({"object": {"extinction": [0.05, 0.05, 0.01]}})"),
         "/object/extinction/2"},
        {"scattering NaN", json{{"object", {{"scattering", {0.0, nan, 0.0}}}}}, "/object/scattering/1"},
        {"grid field without a grid", json::parse(R"({"object": {"index_field": "grid"}})"),
         "/object/index_field"},
        {"grid field with empty grid", json::parse(R"({"object": {"index_field": "grid", "grid": ""}})"),
         "/object/grid"},
        {"grid name with space", json::parse(R"({"object": {"grid": "my grid"}})"), "/object/grid"},
        {"grid not a string", json::parse(R"({"object": {"grid": 5}})"), "/object/grid"},
        {"grid deleted for a grid field", json::parse(R"({"object": {"grid": null, "index_field": "grid"}})"),
         "/object/grid"},
        {"phase model underscore", json::parse(R"({"object": {"phase": {"model": "henyey_greenstein"}}})"),
         "/object/phase/model"},
        {"phase g of 1", json::parse(R"({"object": {"phase": {"g": 1}}})"), "/object/phase/g"},
        {"phase g of -1", json::parse(R"({"object": {"phase": {"g": -1}}})"), "/object/phase/g"},
        // medium
        {"medium ior below 1", json::parse(R"({"medium": {"ior": 0.5}})"), "/medium/ior"},
        {"medium scattering above extinction", json::parse(R"({"medium": {"scattering": [0.3, 0.3, 0.3]}})"),
         "/medium/scattering/0"},
        {"medium phase g too close to 1", json::parse(R"({"medium": {"phase": {"g": 0.995}}})"),
         "/medium/phase/g"},
        {"medium fade negative", json::parse(R"({"medium": {"fade": -0.1}})"), "/medium/fade"},
        {"medium fade NaN", json{{"medium", {{"fade", nan}}}}, "/medium/fade"},
        {"medium fade infinite", json{{"medium", {{"fade", inf}}}}, "/medium/fade"},
        {"medium fade huge", json::parse(R"({"medium": {"fade": 1e300}})"), "/medium/fade"},
        {"medium fade as string", json::parse(R"({"medium": {"fade": "wide"}})"), "/medium/fade"},
        // volume
        {"resolution too low", json::parse(R"({"volume": {"resolution": 16}})"), "/volume/resolution"},
        {"resolution too high", json::parse(R"({"volume": {"resolution": 1024}})"), "/volume/resolution"},
        {"negative resolution", json::parse(R"({"volume": {"resolution": -128}})"), "/volume/resolution"},
        {"smoothing too high", json::parse(R"({"volume": {"smoothing": 4.5}})"), "/volume/smoothing"},
        {"zero octree epsilon", json::parse(R"({"volume": {"octree_epsilon": 0}})"),
         "/volume/octree_epsilon"},
        {"octree epsilon above 1", json::parse(R"({"volume": {"octree_epsilon": 1.5}})"),
         "/volume/octree_epsilon"},
        {"negative margin", json::parse(R"({"volume": {"margin": -0.1}})"), "/volume/margin"},
        {"empty bounds axis", json::parse(R"({"volume": {"bounds": {"min": [0, 0, 0], "max": [1, 0, 1]}}})"),
         "/volume/bounds/max/1"},
        {"bounds min above default max", json::parse(R"({"volume": {"bounds": {"min": [-1, 2, -1]}}})"),
         "/volume/bounds/min/1"},
        {"bounds max of two", json::parse(R"({"volume": {"bounds": {"max": [1, 1]}}})"),
         "/volume/bounds/max"},
        // photons
        {"zero photons", json::parse(R"({"photons": {"count": 0}})"), "/photons/count"},
        {"photons over limit", json::parse(R"({"photons": {"count": 16777217}})"), "/photons/count"},
        {"seed over 32 bits", json::parse(R"({"photons": {"seed": 4294967296}})"), "/photons/seed"},
        {"seed as bool", json::parse(R"({"photons": {"seed": true}})"), "/photons/seed"},
        {"negative bounces", json::parse(R"({"photons": {"max_bounces": -1}})"), "/photons/max_bounces"},
        {"bounces over the limit", json::parse(R"({"photons": {"max_bounces": 1025}})"), "/photons/max_bounces"},
        {"fractional bounces", json::parse(R"({"photons": {"max_bounces": 2.5}})"), "/photons/max_bounces"},
        {"bounces as string", json::parse(R"({"photons": {"max_bounces": "8"}})"), "/photons/max_bounces"},
        {"bounces as bool", json::parse(R"({"photons": {"max_bounces": true}})"), "/photons/max_bounces"},
        {"bounces as array", json::parse(R"({"photons": {"max_bounces": [8]}})"), "/photons/max_bounces"},
        {"bounces huge", json::parse(R"({"photons": {"max_bounces": 1e300}})"), "/photons/max_bounces"},
        {"bounces NaN", json{{"photons", {{"max_bounces", nan}}}}, "/photons/max_bounces"},
        {"bounces infinite", json{{"photons", {{"max_bounces", inf}}}}, "/photons/max_bounces"},
        {"bounces with a degenerate phase", json::parse(R"({"photons": {"max_bounces": 8}, "medium": {"phase": {"g": 1}}})"),
         "/medium/phase/g"},
        // floor
        {"enabled as number", json::parse(R"({"floor": {"enabled": 1}})"), "/floor/enabled"},
        {"checker as string", json::parse(R"({"floor": {"checker": "yes"}})"), "/floor/checker"},
        {"albedo above 1", json::parse(R"({"floor": {"albedo": [0.5, 1.5, 0.5]}})"), "/floor/albedo/1"},
        {"zero checker size", json::parse(R"({"floor": {"checker_size": 0}})"), "/floor/checker_size"},
        {"height as string", json::parse(R"({"floor": {"height": "low"}})"), "/floor/height"},
    };
}

TEST(MergePatch, BadPatchesAreRejectedWithTheirPointer) {
    const std::vector<BadPatch> cases = bad_patches();
    ASSERT_GE(cases.size(), 25u);
    for (const BadPatch& c : cases) {
        SCOPED_TRACE(std::string(c.what) + ": " + c.patch.dump());
        const SceneDocument current;
        EXPECT_EQ(rejected_pointer([&] { apply_merge_patch(current, c.patch); }), c.pointer);
        EXPECT_EQ(current, SceneDocument{});  // the document passed in is unchanged
    }
}

TEST(MergePatch, BadPatchesLeaveACustomisedDocumentUnchanged) {
    // Some rules tie values together (camera, scattering <= extinction, grid), so against this document a
    // few of the patches are valid; whatever the outcome, the document passed in must not change.
    const SceneDocument current = customised();
    std::size_t rejected = 0;
    for (const BadPatch& c : bad_patches()) {
        SCOPED_TRACE(std::string(c.what) + ": " + c.patch.dump());
        try {
            (void)apply_merge_patch(current, c.patch);
        } catch (const ValidationError&) {
            ++rejected;
        }
        EXPECT_EQ(current, customised());
    }
    EXPECT_GE(rejected, bad_patches().size() - 6);
}

TEST(MergePatch, BadPatchesAreAlsoRejectedAsWholeDocuments) {
    // The same values written into a fresh document (not as an edit) are rejected as well.
    for (const BadPatch& c : bad_patches()) {
        SCOPED_TRACE(std::string(c.what) + ": " + c.patch.dump());
        json doc = to_json(SceneDocument{});
        doc.merge_patch(c.patch);
        EXPECT_THROW(parse_scene(doc), ValidationError);
    }
}

}  // namespace
}  // namespace refract::protocol

namespace refract::protocol {
namespace {

// Every leaf of the full default document, as JSON pointers.
void leaf_pointers(const json& j, const std::string& at, std::vector<std::string>& out) {
    if (j.is_object()) {
        for (auto it = j.begin(); it != j.end(); ++it) leaf_pointers(it.value(), at + "/" + it.key(), out);
    } else {
        out.push_back(at);
    }
}

// Random merge patches over the whole document: each sets one to four leaves (or their parents, or an
// unknown key beside them) to a value of a random kind (in range, out of range, NaN, infinite, huge, of
// the wrong type or shape, a real enum value or garbage, null) or nudges the value already there. Every
// patch must either give a document that round-trips through to_json, or be refused with a
// ValidationError naming a pointer within what the patch touched. A fixed seed keeps it repeatable.
TEST(SceneDocument, RandomPatchesAreAppliedWholeOrRefusedWithAPointer) {
    const SceneDocument base = parse_scene(json::object());
    const json base_json = to_json(base);
    std::vector<std::string> leaves;
    leaf_pointers(base_json, "", leaves);
    std::mt19937 rng(20261125);
    auto pick = [&](size_t n) { return static_cast<size_t>(std::uniform_int_distribution<size_t>(0, n - 1)(rng)); };
    const double nan = std::numeric_limits<double>::quiet_NaN(), inf = std::numeric_limits<double>::infinity();
    const std::vector<json> values = {
        0, 1, -1, 0.5, 2.5, 5, 30, 1000, 1001, 1e9, -1e9, 4294967296.0, nan, inf, -inf, 1e-320,
        true, false, nullptr, "", "sphere", "prism", "upload:x", "luneburg", "spot", "henyey-greenstein",
        "../etc", json::array(), json::array({1, 2}), json::array({0.1, 0.2, 0.3}), json::array({1, nan, 1}),
        json::array({1, 2, 3, 4}), json::object(), json{{"model", "isotropic"}}, json{{"unknown", 1}}};
    size_t accepted = 0, refused = 0;
    for (int trial = 0; trial < 20000; ++trial) {
        json patch = json::object();
        const size_t edits = 1 + pick(4);
        for (size_t e = 0; e < edits; ++e) {
            std::string at = leaves[pick(leaves.size())];
            if (pick(8) == 0) at = at.substr(0, at.rfind('/'));   // the leaf's parent
            if (pick(12) == 0) at = at.substr(0, at.rfind('/')) + "/not_a_field";
            if (at.empty()) continue;
            json value = values[pick(values.size())];
            // Half the edits nudge the value already there, so that many patches are valid.
            if (pick(2) == 0 && base_json.contains(json::json_pointer(at))) {
                value = base_json[json::json_pointer(at)];
                if (value.is_number_float())
                    value = value.get<double>() == 0.0 ? static_cast<double>(pick(40))
                                                        : value.get<double>() * (0.9 + 0.2 * static_cast<double>(pick(1000)) / 1000.0);
                if (value.is_number_unsigned()) value = value.get<uint64_t>() + pick(3);
            }
            try {
                patch[json::json_pointer(at)] = value;
            } catch (const json::exception&) {
                continue;  // a path through a value set earlier in this patch
            }
        }
        try {
            const SceneDocument edited = apply_merge_patch(base, patch);
            EXPECT_EQ(parse_scene(to_json(edited)), edited) << patch.dump();
            ++accepted;
        } catch (const ValidationError& e) {
            EXPECT_FALSE(e.rule().empty()) << patch.dump();
            // The pointer names a value the patch touched, or a document-wide rule's field under it.
            const std::string top = e.pointer().substr(0, e.pointer().find('/', 1));
            EXPECT_TRUE(top.empty() || patch.contains(top.substr(1))) << e.what() << " for " << patch.dump();
            ++refused;
        } catch (const std::exception& e) {
            ADD_FAILURE() << "threw something other than ValidationError: " << e.what() << " for " << patch.dump();
        }
    }
    std::printf("random patches: %zu applied, %zu refused\n", accepted, refused);
    EXPECT_GT(accepted, 200u);
    EXPECT_GT(refused, 200u);
}

}  // namespace
}  // namespace refract::protocol
