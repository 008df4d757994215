// Many viewers of one scene, each with its own view (issue 38): a WebSocket session's `view` setting (its
// image size and camera) shapes its frames and nothing else; views share the scene's photons; hostile
// views are refused whole; a scene's viewers hear of each other. Against a real refractd.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <chrono>
#include <cstdlib>
#include <string>
#include <thread>
#include <vector>

#include "daemon/api.h"
#include "daemon/harness.h"
#include "daemon/ws_client.h"

namespace refract::test {
namespace {

using json = nlohmann::json;

const json kCameraLeft = {{"position", {-2.5, 1.0, 3.0}}, {"target", {0.0, -0.2, 0.0}}, {"fov_deg", 40}};
const json kCameraRight = {{"position", {2.5, 1.5, 2.5}}, {"target", {0.0, -0.2, 0.0}}, {"fov_deg", 30}};

std::string ws_path(const std::string& id) { return "/api/scenes/" + id + "/ws"; }

double photon_runs(httplib::Client& client) { return metric(client, "refract_pass_runs_total{pass=\"photons\"}"); }

// The scene's revision as the store has it.
int revision_of(httplib::Client& client, const std::string& id) {
    return get_json(client, "/api/scenes/" + id)["revision"].get<int>();
}

// Waits for a notice of `type` ("viewers", "edited") that `accept` takes, passing over frames and
// other notices; returns it.
template <typename Accept>
json wait_notice(WsClient& ws, const std::string& type, Accept accept) {
    for (;;) {
        auto [text, payload] = ws.read_any();
        if (!text) continue;
        json message = json::parse(payload, nullptr, false);
        if (message.is_object() && message["type"] == type && accept(message)) return message;
    }
}

// A daemon on a temporary data directory, and an HTTP client of it.
class DaemonViews : public ::testing::Test {
protected:
    TempDir dir;
    Daemon daemon{dir.path() / "data"};
    httplib::Client client = daemon.client();
};

// Two viewers with views of their own get frames of their own sizes and cameras, and neither makes a
// revision; a third, following the document's camera, sees the document's camera edits, which move
// nobody else's view; frames are keyed by view (the same view at the same revision is the same frame).
TEST_F(DaemonViews, EachViewerSeesItsOwnViewAndNoneMakesARevision) {
    const std::string id = create_scene(client, "views");
    const json saved = get_json(client, "/api/scenes/" + id)["scene"];

    WsClient left(daemon.ws_port(), ws_path(id));
    WsClient right(daemon.ws_port(), ws_path(id));
    WsClient follower(daemon.ws_port(), ws_path(id));
    left.send({{"seq", 1}, {"refine", 0}, {"quality", "still"}, {"view", {{"width", 80}, {"height", 48}, {"camera", kCameraLeft}}}});
    right.send({{"seq", 1}, {"refine", 0}, {"quality", "still"}, {"view", {{"width", 80}, {"height", 48}, {"camera", kCameraRight}}}});
    follower.send({{"seq", 1}, {"refine", 0}, {"quality", "still"}});
    auto [left_header, left_png] = left.read_frame();
    auto [right_header, right_png] = right.read_frame();
    auto [follower_header, follower_png] = follower.read_frame();
    EXPECT_EQ(left_header["width"], 80);
    EXPECT_EQ(left_header["height"], 48);
    EXPECT_EQ(png_size(left_png), (std::pair{80u, 48u}));
    EXPECT_EQ(png_size(right_png), (std::pair{80u, 48u}));
    EXPECT_EQ(png_size(follower_png), (std::pair{64u, 64u}));  // the document's image size
    EXPECT_NE(left_png, right_png) << "two cameras, one frame";
    for (const json* header : {&left_header, &right_header, &follower_header}) EXPECT_EQ((*header)["revision"], 1);

    // Another size and camera for the same session: a frame of that view, still no revision.
    left.send({{"seq", 2}, {"quality", "still"}, {"view", {{"width", 40}, {"height", 72}, {"camera", kCameraLeft}}}});
    auto [tall, tall_png] = left.read_frame();
    EXPECT_EQ(png_size(tall_png), (std::pair{40u, 72u}));
    // The right viewer's view, asked for by the left one: the frame already rendered for it.
    left.send({{"seq", 3}, {"quality", "still"}, {"view", {{"width", 80}, {"height", 48}, {"camera", kCameraRight}}}});
    auto [same, same_png] = left.read_frame();
    EXPECT_TRUE(same["cached"].get<bool>());
    EXPECT_EQ(same_png, right_png);
    EXPECT_EQ(revision_of(client, id), 1);
    EXPECT_EQ(get_json(client, "/api/scenes/" + id)["scene"], saved) << "a view reached the stored document";

    // The document's camera moves (a presenter): the follower sees it, the others keep their own views.
    WsClient presenter(daemon.ws_port(), ws_path(id));
    presenter.send({{"seq", 1}, {"refine", 0}, {"patch", {{"camera", {{"position", {0.0, 2.5, 4.0}}}}}}});
    EXPECT_EQ(presenter.read_frame().first["revision"], 2);
    auto [pushed, pushed_png] = follower.read_frame();
    EXPECT_EQ(pushed["revision"], 2);
    EXPECT_EQ(pushed["seq"], nullptr);
    follower.send({{"seq", 2}, {"quality", "still"}});
    auto [moved, moved_png] = follower.read_frame();
    EXPECT_EQ(moved["revision"], 2);
    EXPECT_NE(moved_png, follower_png) << "the follower did not see the document's camera edit";
    // The right viewer is told of the edit, and rendered nothing for it: its own camera replaces the one edited.
    wait_notice(right, "edited", [](const json& m) { return m["revision"] == 2; });
    right.send({{"seq", 2}, {"quality", "still"}});
    auto [kept, kept_png] = right.read_frame();
    EXPECT_EQ(kept["revision"], 2);
    EXPECT_EQ(kept_png, right_png) << "the document's camera edit moved a viewer's own camera";

    // `"view": null` goes back to the document's view: its size and its (new) camera.
    right.send({{"seq", 3}, {"quality", "still"}, {"view", nullptr}});
    auto [back, back_png] = right.read_frame();
    EXPECT_EQ(png_size(back_png), (std::pair{64u, 64u}));
    EXPECT_EQ(back_png, moved_png);
    EXPECT_EQ(revision_of(client, id), 2);
    expect_no_validation_errors(daemon);
}

// A session's interactive frames come at its view's full size however small a frame the budget traces:
// upscaled, or with temporal reuse (`"temporal": true`) taken into its history. The header says how
// large a frame was traced.
TEST_F(DaemonViews, TemporalReuseSendsPreviewsAtTheViewersSize) {
    const std::string id = create_scene(client, "temporal");
    WsClient ws(daemon.ws_port(), ws_path(id));
    ws.send({{"seq", 1}, {"refine", 0}, {"quality", "still"}, {"view", {{"width", 160}, {"height", 96}, {"camera", kCameraLeft}}}});
    EXPECT_EQ(png_size(ws.read_frame().second), (std::pair{160u, 96u}));
    json camera = kCameraLeft;
    camera["position"][0] = -2.4;
    // A budget no frame of this size meets: the budget's size is smaller than the view.
    ws.send({{"seq", 2}, {"quality", "interactive"}, {"budget_ms", 10}, {"view", {{"width", 160}, {"height", 96}, {"camera", camera}}}});
    auto [budgeted, budgeted_png] = ws.read_frame();
    EXPECT_EQ(png_size(budgeted_png), (std::pair{160u, 96u}));
    EXPECT_LT(budgeted["traced_width"].get<int>(), 160);
    EXPECT_LT(budgeted["traced_height"].get<int>(), 96);
    camera["position"][0] = -2.3;
    ws.send({{"seq", 3}, {"quality", "interactive"}, {"temporal", true}, {"view", {{"width", 160}, {"height", 96}, {"camera", camera}}}});
    auto [header, png] = ws.read_frame();
    EXPECT_EQ(header["seq"], 3);
    EXPECT_EQ(png_size(png), (std::pair{160u, 96u}));
    EXPECT_LT(header["traced_width"].get<int>(), 160);
    // The setting holds for the session: the next preview too.
    camera["position"][0] = -2.2;
    ws.send({{"seq", 4}, {"quality", "interactive"}, {"view", {{"width", 160}, {"height", 96}, {"camera", camera}}}});
    EXPECT_EQ(png_size(ws.read_frame().second), (std::pair{160u, 96u}));
    expect_no_validation_errors(daemon);
}

// Views of one scene share its photons and radiance grid: a light edit seen by three viewers with
// three views traces photons once (asserted by the photon pass's runs in /metrics), and so do their
// three still frames after it.
TEST_F(DaemonViews, ALightEditTracesPhotonsOnceForAllViews) {
    const std::string id = create_scene(client, "shared");
    const std::vector<json> views = {
        {{"width", 72}, {"height", 40}, {"camera", kCameraLeft}},
        {{"width", 48}, {"height", 64}, {"camera", kCameraRight}},
        {{"width", 56}, {"height", 56}},  // the document's camera at a size of its own
    };
    std::vector<std::unique_ptr<WsClient>> viewers;
    for (const json& view : views) {
        viewers.push_back(std::make_unique<WsClient>(daemon.ws_port(), ws_path(id)));
        viewers.back()->send({{"seq", 1}, {"refine", 0}, {"view", view}});
        EXPECT_EQ(viewers.back()->read_frame().first["revision"], 1);
    }
    const double before = photon_runs(client);
    ASSERT_GE(before, 1);

    auto edit = patch(client, id, {{"light", {{"intensity", 35.0}}}});
    ASSERT_TRUE(edit && edit->status == 200);
    int traced = 0;
    for (size_t i = 0; i < viewers.size(); ++i) {
        auto [header, png] = viewers[i]->read_frame();
        EXPECT_EQ(header["revision"], 2);
        EXPECT_EQ(header["quality"], "interactive");
        // An interactive frame keeps its view's aspect (the budget may shrink it, never reshape it).
        const double aspect = views[i]["width"].get<double>() / views[i]["height"].get<double>();
        EXPECT_NEAR(header["width"].get<double>() / header["height"].get<double>(), aspect, 0.1) << header;
        for (const json& pass : header["passes"]) traced += pass == "photons";
    }
    EXPECT_EQ(traced, 1) << "each view traced the edit's photons";
    EXPECT_EQ(photon_runs(client), before + 1);

    // Their still frames: the first traces the document's photon count, the others shade from that grid.
    for (size_t i = 0; i < viewers.size(); ++i) {
        viewers[i]->send({{"seq", 2}, {"quality", "still"}});
        auto [header, png] = viewers[i]->read_frame();
        EXPECT_EQ(png_size(png), (std::pair{views[i]["width"].get<uint32_t>(), views[i]["height"].get<uint32_t>()}));
        EXPECT_EQ(header["revision"], 2);
    }
    EXPECT_EQ(photon_runs(client), before + 2);
    EXPECT_EQ(revision_of(client, id), 2);
    expect_no_validation_errors(daemon);
}

// Views share the scene's radiance grid across refinement too: the still of a second view starts from the
// photon batches the first view's refinement put there (its view alone runs), and its own refinement
// adds to that grid instead of starting it anew.
TEST_F(DaemonViews, ASecondViewsStillTakesTheBatchesAnotherViewRefined) {
    const std::string id = create_scene(client, "refined");
    WsClient first(daemon.ws_port(), ws_path(id));
    first.send({{"seq", 1}, {"refine", 4}, {"quality", "still"}, {"view", {{"width", 48}, {"height", 40}, {"camera", kCameraLeft}}}});
    for (int level = 0; level != 4;) level = first.read_frame().first["level"].get<int>();
    const double before = photon_runs(client);

    WsClient second(daemon.ws_port(), ws_path(id));
    second.send({{"seq", 1}, {"refine", 6}, {"quality", "still"}, {"view", {{"width", 40}, {"height", 48}, {"camera", kCameraRight}}}});
    auto [still, png] = second.read_frame();
    EXPECT_EQ(still["level"], 4) << still;
    EXPECT_EQ(still["passes"], json({"view", "tone_map"})) << still;
    EXPECT_EQ(photon_runs(client), before);
    // Levels 5 and 6 add one batch each to the same grid.
    for (int level : {5, 6}) {
        auto [header, refined] = second.read_frame();
        EXPECT_EQ(header["level"], level);
        EXPECT_EQ(png_size(refined), (std::pair{40u, 48u}));
    }
    EXPECT_EQ(photon_runs(client), before + 2);
    EXPECT_EQ(revision_of(client, id), 1);
}

// An edit of what a viewer's own view replaces (the scene's camera, a presenter's orbit) renders nothing
// for that viewer, only a notice; an edit it can see does.
TEST_F(DaemonViews, AnEditOfTheScenesCameraRendersNothingForAViewerWithItsOwn) {
    const std::string id = create_scene(client, "presented");
    WsClient own(daemon.ws_port(), ws_path(id));
    WsClient presenter(daemon.ws_port(), ws_path(id));
    own.send({{"seq", 1}, {"refine", 0}, {"view", {{"width", 48}, {"height", 40}, {"camera", kCameraLeft}}}});
    EXPECT_EQ(own.read_frame().first["revision"], 1);
    presenter.send({{"seq", 1}, {"refine", 0}});
    presenter.read_frame();
    const double frames_before = metric(client, "refract_frames_total");

    presenter.send({{"seq", 2}, {"patch", {{"camera", {{"position", {0.0, 2.0, 4.5}}}}}}});
    EXPECT_EQ(presenter.read_frame().first["revision"], 2);
    EXPECT_EQ(wait_notice(own, "edited", [](const json& m) { return m["revision"] == 2; })["by"], "viewer");
    std::this_thread::sleep_for(std::chrono::milliseconds(400));  // a frame for it would be on its way by now
    EXPECT_EQ(metric(client, "refract_frames_total"), frames_before + 1) << "the own view rendered the camera edit";

    presenter.send({{"seq", 3}, {"patch", {{"light", {{"intensity", 9.0}}}}}});
    presenter.read_frame();
    auto [pushed, png] = own.read_frame();
    EXPECT_EQ(pushed["revision"], 3) << "a frame of the camera edit came first";
    // An interactive frame is sized to the budget, each side rounded on its own: the own view's 48 x 40
    // within half a pixel a side, not the scene's square image.
    const auto [width, height] = png_size(png);
    EXPECT_GT(width, height) << "not the own view's aspect";
    EXPECT_LE(std::abs(static_cast<long>(width) * 40 - static_cast<long>(height) * 48), (40 + 48) / 2)
        << width << " x " << height << " is not the own view's aspect";
}

// A viewer with a camera of its own still gets its still frame after a preview whose revision a
// presenter's orbit has already passed: the orbit changes nothing it sees, so its preview stands for it.
TEST_F(DaemonViews, AnOrbitElsewhereDoesNotStopAViewersStillFrame) {
    const std::string id = create_scene(client, "stills");
    WsClient own(daemon.ws_port(), ws_path(id), 20);
    WsClient presenter(daemon.ws_port(), ws_path(id));
    own.send({{"seq", 1}, {"refine", 1}, {"view", {{"width", 48}, {"height", 40}, {"camera", kCameraLeft}}}});
    while (own.read_frame().first["quality"] != "still") {
    }
    // A light edit (which the viewer sees) and at once an orbit (which it does not).
    presenter.send({{"seq", 1}, {"refine", 0}, {"patch", {{"light", {{"intensity", 14.0}}}}}});
    presenter.send({{"seq", 2}, {"refine", 0}, {"patch", {{"camera", {{"position", {0.4, 2.0, 4.5}}}}}}});
    auto [preview, preview_png] = own.read_frame();
    EXPECT_EQ(preview["quality"], "interactive");
    EXPECT_GE(preview["revision"], 2);
    auto [still, still_png] = own.read_frame();
    EXPECT_EQ(still["quality"], "still");
    EXPECT_EQ(still["revision"], 3);
    EXPECT_EQ(png_size(still_png), (std::pair{48u, 40u}));
}

// A view out of range is refused whole, with a pointer into the message: the message's patch is not
// applied, the session keeps its view and the scene its revision.
TEST_F(DaemonViews, HostileViewsAreRefusedWholeAndChangeNothing) {
    const std::string id = create_scene(client, "hostile");
    WsClient ws(daemon.ws_port(), ws_path(id));
    ws.send({{"seq", 0}, {"refine", 0}, {"quality", "still"}, {"view", {{"width", 48}, {"height", 40}, {"camera", kCameraLeft}}}});
    auto [first, first_png] = ws.read_frame();
    ASSERT_EQ(png_size(first_png), (std::pair{48u, 40u}));

    const json same_point = {{"position", {1, 1, 1}}, {"target", {1, 1, 1}}};
    const json up_along_view = {{"position", {0, 3, 0}}, {"target", {0, 0, 0}}, {"up", {0, 1, 0}}};
    const std::vector<std::pair<json, std::string>> hostile = {
        {{{"width", 0}, {"height", 40}}, "/view/width"},
        {{{"width", 48}, {"height", 0}}, "/view/height"},
        {{{"width", 100000}, {"height", 40}}, "/view/width"},
        {{{"width", 48}, {"height", 4097}}, "/view/height"},
        {{{"width", 1e300}, {"height", 40}}, "/view/width"},
        {{{"width", -48}, {"height", 40}}, "/view/width"},
        {{{"width", 48.5}, {"height", 40}}, "/view/width"},
        {{{"width", "48"}, {"height", 40}}, "/view/width"},
        {{{"height", 40}}, "/view/width"},
        {{{"width", 48}}, "/view/height"},
        {{{"width", 48}, {"height", 40}, {"zoom", 2}}, "/view/zoom"},
        {{{"width", 48}, {"height", 40}, {"camera", same_point}}, "/view/camera/target"},
        {{{"width", 48}, {"height", 40}, {"camera", up_along_view}}, "/view/camera/up"},
        {{{"width", 48}, {"height", 40}, {"camera", {{"fov_deg", 0}}}}, "/view/camera/fov_deg"},
        {{{"width", 48}, {"height", 40}, {"camera", {{"position", {0, "x", 1}}}}}, "/view/camera/position/1"},
        {{{"width", 48}, {"height", 40}, {"camera", 3}}, "/view/camera"},
        {json(5), "/view"},
        {json::array({48, 40}), "/view"},
    };
    int seq = 1;
    for (const auto& [view, pointer] : hostile) {
        ws.send({{"seq", seq}, {"quality", "still"}, {"view", view}, {"patch", {{"light", {{"intensity", 7.0}}}}}});
        auto [text, payload] = ws.read();
        ASSERT_TRUE(text) << view;
        const json error = json::parse(payload);
        EXPECT_EQ(error["type"], "error") << view;
        EXPECT_EQ(error["seq"], seq) << view;
        EXPECT_EQ(error["pointer"], pointer) << view << ": " << error;
        EXPECT_TRUE(error["rule"].is_string() && !error["rule"].get<std::string>().empty()) << error;
        EXPECT_NE(error["error"].get<std::string>().find(pointer), std::string::npos) << error;
        ++seq;
    }
    EXPECT_EQ(revision_of(client, id), 1) << "a refused message's patch was applied";
    // The session's view is the one it had.
    ws.send({{"seq", seq}, {"quality", "still"}});
    auto [after, after_png] = ws.read_frame();
    EXPECT_EQ(after["revision"], 1);
    EXPECT_EQ(after_png, first_png);
    expect_alive(daemon);
}

// The last frame of a play of `keyframes` (still frames, 10 a second) into `ws`; every frame of it is
// checked to come at `width` x `height`.
std::string played(WsClient& ws, const json& keyframes, uint32_t width, uint32_t height) {
    ws.send({{"seq", 50}, {"type", "play"}, {"fps", 10}, {"quality", "still"}, {"keyframes", keyframes}});
    for (;;) {
        auto [header, png] = ws.read_frame();
        EXPECT_EQ(png_size(png), (std::pair{width, height})) << header;
        if (header.contains("play") && header["play"]["last"] == true) return png;
    }
}

// Animations played into a viewer come at its size and from its camera, unless they move the camera
// themselves (a fly-through), whose frames take the animation's camera at the viewer's size.
TEST_F(DaemonViews, PlaysComeAtTheViewersSizeAndFlyThroughsKeepTheirCamera) {
    const std::string id = create_scene(client, "played");
    WsClient own(daemon.ws_port(), ws_path(id));
    WsClient follower(daemon.ws_port(), ws_path(id));
    own.send({{"seq", 1}, {"refine", 0}, {"view", {{"width", 56}, {"height", 40}, {"camera", kCameraLeft}}}});
    follower.send({{"seq", 1}, {"refine", 0}, {"view", {{"width", 56}, {"height", 40}}}});
    own.read_frame();
    follower.read_frame();

    const json lights = {{{"time", 0}, {"patch", {{"light", {{"intensity", 10.0}}}}}},
                         {{"time", 0.1}, {"patch", {{"light", {{"intensity", 30.0}}}}}}};
    EXPECT_NE(played(own, lights, 56, 40), played(follower, lights, 56, 40)) << "the play ignored the viewer's camera";
    const json fly = {{{"time", 0}, {"patch", {{"camera", {{"position", {0.0, 1.0, 4.0}}}}}}},
                      {{"time", 0.1}, {"patch", {{"camera", {{"position", {0.5, 1.2, 4.0}}}}}}}};
    EXPECT_EQ(played(own, fly, 56, 40), played(follower, fly, 56, 40)) << "a fly-through took the viewer's own camera";
    EXPECT_EQ(revision_of(client, id), 1);
}

// A scene's viewers are told how many they are (on this daemon), and of the edits the others make.
TEST_F(DaemonViews, ViewersAreCountedAndToldOfEachOthersEdits) {
    const std::string id = create_scene(client, "together");
    const std::string other = create_scene(client, "elsewhere");
    auto count_is = [](size_t n) { return [n](const json& m) { return m["count"] == n; }; };

    WsClient first(daemon.ws_port(), ws_path(id));
    wait_notice(first, "viewers", count_is(1));
    WsClient stranger(daemon.ws_port(), ws_path(other));  // another scene's viewer counts for that one only
    wait_notice(stranger, "viewers", count_is(1));
    {
        WsClient second(daemon.ws_port(), ws_path(id));
        wait_notice(second, "viewers", count_is(2));
        wait_notice(first, "viewers", count_is(2));

        second.send({{"seq", 1}, {"refine", 0}, {"patch", {{"light", {{"intensity", 12.0}}}}}});
        auto [own, png] = second.read_frame();
        EXPECT_EQ(own["revision"], 2);
        const json edited = wait_notice(first, "edited", [](const json&) { return true; });
        EXPECT_EQ(edited["revision"], 2);
        EXPECT_EQ(edited["by"], "viewer");
        // An edit that changes nothing makes no revision and no notice; the editor is never told of its own.
        second.send({{"seq", 2}, {"refine", 0}, {"patch", {{"light", {{"intensity", 12.0}}}}}});
        second.read_frame();
        for (const json& notice : second.notices()) EXPECT_NE(notice["type"], "edited") << notice;
    }
    wait_notice(first, "viewers", count_is(1));  // the second left
    for (const json& notice : stranger.notices()) EXPECT_EQ(notice["count"], 1) << notice;
    expect_alive(daemon);
}

}  // namespace
}  // namespace refract::test
