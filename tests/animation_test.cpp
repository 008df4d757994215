// Keyframed animation (protocol/animation.h): keyframes validated with pointers into the list, and the
// document between keyframes interpolated as documented, checked against values worked out by hand.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include <nlohmann/json.hpp>

#include "protocol/animation.h"

namespace refract::protocol {
namespace {

using nlohmann::json;

SceneDocument base() { return parse_scene(json::object()); }

TEST(Animation, NumbersMoveLinearlyBetweenKeyframesAndHoldOutsideThem) {
    Animation a(base(), json::parse(R"([
        {"time": 1, "patch": {"light": {"intensity": 10, "position": [0, 2, 0]}, "image": {"exposure": 0}}},
        {"time": 3, "patch": {"light": {"intensity": 30, "position": [4, 2, -2]}, "image": {"exposure": 2}}}])"));
    EXPECT_EQ(a.keyframes(), 2u);
    EXPECT_DOUBLE_EQ(a.duration(), 3.0);
    EXPECT_DOUBLE_EQ(a.at(0.0).lights.at("light").intensity, 10.0);  // before the first keyframe: the first
    EXPECT_DOUBLE_EQ(a.at(1.5).lights.at("light").intensity, 15.0);
    EXPECT_DOUBLE_EQ(a.at(2.0).image.exposure, 1.0);
    EXPECT_EQ(a.at(2.5).lights.at("light").position, (Vec3{3.0, 2.0, -1.5}));
    EXPECT_DOUBLE_EQ(a.at(9.0).lights.at("light").intensity, 30.0);  // after the last: the last
}

TEST(Animation, PatchesAccumulateFromKeyframeToKeyframe) {
    Animation a(base(), json::parse(R"([
        {"time": 0, "patch": {"object": {"ior": 1.3}}},
        {"time": 1, "patch": {"light": {"intensity": 5}}}])"));
    EXPECT_DOUBLE_EQ(a.at(1.0).object().ior, 1.3);  // the second keyframe keeps the first one's patch
    EXPECT_DOUBLE_EQ(a.at(1.0).lights.at("light").intensity, 5.0);
}

TEST(Animation, WholeNumbersNamesAndSwitchesHoldUntilTheNextKeyframe) {
    Animation a(base(), json::parse(R"([
        {"time": 0, "patch": {"image": {"width": 100}, "object": {"mesh": "sphere"}, "floor": {"enabled": true}}},
        {"time": 1, "patch": {"image": {"width": 300}, "object": {"mesh": "cube"}, "floor": {"enabled": false}}}])"));
    const SceneDocument mid = a.at(0.9);
    EXPECT_EQ(mid.image.width, 100u);
    EXPECT_EQ(mid.object().mesh, "sphere");
    EXPECT_TRUE(mid.floor.enabled);
    const SceneDocument end = a.at(1.0);
    EXPECT_EQ(end.image.width, 300u);
    EXPECT_EQ(end.object().mesh, "cube");
    EXPECT_FALSE(end.floor.enabled);
}

TEST(Animation, ATurnAboutOneAxisKeepsEveryDegree) {
    Animation a(base(), json::parse(R"([
        {"time": 0, "patch": {"object": {"rotation_deg": [10, 0, 0]}}},
        {"time": 2, "patch": {"object": {"rotation_deg": [10, 720, 0]}}}])"));
    EXPECT_EQ(a.at(0.5).object().rotation_deg, (Vec3{10.0, 180.0, 0.0}));
    EXPECT_EQ(a.at(1.5).object().rotation_deg, (Vec3{10.0, 540.0, 0.0}));
}

// Rotation matrix R = Rz(c) Ry(b) Rx(a) (mesh::transformed), written out independently of the code.
std::array<std::array<double, 3>, 3> rotation(const Vec3& deg) {
    const double k = std::acos(-1.0) / 180.0;
    const double ca = std::cos(deg[0] * k), sa = std::sin(deg[0] * k), cb = std::cos(deg[1] * k),
                 sb = std::sin(deg[1] * k), cc = std::cos(deg[2] * k), sc = std::sin(deg[2] * k);
    return {{{cc * cb, cc * sb * sa - sc * ca, cc * sb * ca + sc * sa},
             {sc * cb, sc * sb * sa + cc * ca, sc * sb * ca - cc * sa},
             {-sb, cb * sa, cb * ca}}};
}

// The angle (degrees) of the rotation taking orientation p to orientation q: acos((trace(P^T Q) - 1) / 2).
double angle_between(const Vec3& p, const Vec3& q) {
    const auto P = rotation(p), Q = rotation(q);
    double trace = 0.0;
    for (size_t i = 0; i < 3; ++i)
        for (size_t k = 0; k < 3; ++k) trace += P[k][i] * Q[k][i];
    return std::acos(std::clamp((trace - 1.0) / 2.0, -1.0, 1.0)) * 180.0 / std::acos(-1.0);
}

TEST(Animation, ATurnAboutSeveralAxesFollowsTheShortestArcAtAConstantRate) {
    const Vec3 from{0.0, 0.0, 0.0}, to{90.0, 90.0, 0.0};
    Animation a(base(), json::parse(R"([
        {"time": 0, "patch": {"object": {"rotation_deg": [0, 0, 0]}}},
        {"time": 1, "patch": {"object": {"rotation_deg": [90, 90, 0]}}}])"));
    // Ry(90) Rx(90) is one turn of 120 degrees (about (1, 1, 1) / sqrt 3 up to sign): trace 0.
    const double total = angle_between(from, to);
    ASSERT_NEAR(total, 120.0, 1e-9);
    for (const double u : {0.25, 0.5, 0.75}) {
        const Vec3 r = a.at(u).object().rotation_deg;
        EXPECT_NEAR(angle_between(from, r), u * total, 1e-6) << u;
        EXPECT_NEAR(angle_between(r, to), (1.0 - u) * total, 1e-6) << u;
    }
}

TEST(Animation, ALightTurnsAtAConstantRate) {
    Animation a(base(), json::parse(R"([
        {"time": 0, "patch": {"light": {"direction": [1, 0, 0]}}},
        {"time": 1, "patch": {"light": {"direction": [0, 0, 3]}}}])"));
    const Vec3 d = a.at(1.0 / 3.0).lights.at("light").direction;  // a third of 90 degrees
    EXPECT_NEAR(d[0], std::cos(std::acos(-1.0) / 6.0), 1e-12);
    EXPECT_NEAR(d[1], 0.0, 1e-12);
    EXPECT_NEAR(d[2], std::sin(std::acos(-1.0) / 6.0), 1e-12);
}

// Keyframes address lights by name: each named light moves on its own, a light a keyframe adds appears
// from that keyframe on, and one it removes stays until then.
TEST(Animation, NamedLightsMoveOnTheirOwnAndAppearOrLeaveAtTheirKeyframe) {
    Animation a(base(), json::parse(R"([
        {"time": 0, "patch": {"lights": {"fill": {"type": "point", "position": [0, 2, 0], "intensity": 4}}}},
        {"time": 2, "patch": {"lights": {"fill": {"position": [2, 2, 0]}, "rim": {"type": "point", "intensity": 1}}}},
        {"time": 4, "patch": {"lights": {"fill": null}}}])"));
    const SceneDocument mid = a.at(1.0);
    EXPECT_EQ(mid.lights.at("fill").position, (Vec3{1.0, 2.0, 0.0}));
    EXPECT_EQ(mid.lights.at("light"), base().lights.at("light"));  // untouched by the keyframes
    EXPECT_FALSE(mid.lights.contains("rim"));
    const SceneDocument later = a.at(3.0);
    EXPECT_TRUE(later.lights.contains("rim"));
    EXPECT_TRUE(later.lights.contains("fill"));
    EXPECT_EQ(later.lights.at("fill").position, (Vec3{2.0, 2.0, 0.0}));
    EXPECT_FALSE(a.at(4.0).lights.contains("fill"));
}

struct BadKeyframes {
    const char* name;
    json keyframes;
    std::string pointer;
};

TEST(Animation, BadKeyframesAreRefusedWithTheirPointer) {
    const BadKeyframes cases[] = {
        {"not a list", json::parse(R"({"time": 0, "patch": {}})"), ""},
        {"empty", json::array(), ""},
        {"keyframe not an object", json::parse(R"([{"time": 0, "patch": {}}, 3])"), "/1"},
        {"time missing", json::parse(R"([{"patch": {}}])"), "/0/time"},
        {"time a string", json::parse(R"([{"time": "NaN", "patch": {}}])"), "/0/time"},
        {"time NaN", json::array({{{"time", std::numeric_limits<double>::quiet_NaN()}, {"patch", json::object()}}}),
         "/0/time"},
        {"time infinite", json::array({{{"time", std::numeric_limits<double>::infinity()}, {"patch", json::object()}}}),
         "/0/time"},
        {"time negative", json::parse(R"([{"time": -1, "patch": {}}])"), "/0/time"},
        {"time too late", json::parse(R"([{"time": 1e9, "patch": {}}])"), "/0/time"},
        {"out of order", json::parse(R"([{"time": 2, "patch": {}}, {"time": 1, "patch": {}}])"), "/1/time"},
        {"same time twice", json::parse(R"([{"time": 1, "patch": {}}, {"time": 1, "patch": {}}])"), "/1/time"},
        {"patch missing", json::parse(R"([{"time": 0}])"), "/0/patch"},
        {"patch not an object", json::parse(R"([{"time": 0, "patch": [1]}])"), "/0/patch"},
        {"unknown field", json::parse(R"([{"time": 0, "patch": {}, "ease": "in"}])"), "/0/ease"},
        {"invalid patch", json::parse(R"([{"time": 0, "patch": {}}, {"time": 1, "patch": {"object": {"ior": -2}}}])"),
         "/1/patch/object/ior"},
        {"light with a bad name",
         json::parse(R"([{"time": 0, "patch": {"lights": {"no spaces": {}}}}])"), "/0/patch/lights/no spaces"},
        {"older-form light of several",
         json::parse(R"([{"time": 0, "patch": {"lights": {"fill": {}}}}, {"time": 1, "patch": {"light": {"intensity": 2}}}])"),
         "/1/patch/light"},
    };
    for (const auto& c : cases) {
        try {
            Animation(base(), c.keyframes);
            ADD_FAILURE() << c.name << ": accepted";
        } catch (const ValidationError& e) {
            EXPECT_EQ(e.pointer(), c.pointer) << c.name << ": " << e.what();
        }
    }
    json many = json::array();
    for (size_t i = 0; i <= kMaxKeyframes; ++i) many.push_back({{"time", i}, {"patch", json::object()}});
    EXPECT_THROW(Animation(base(), many), ValidationError);
}

}  // namespace
}  // namespace refract::protocol
