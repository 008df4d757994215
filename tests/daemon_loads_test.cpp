// Every load starts with a preview (issue 37): a scene replaced over HTTP (an example loaded, a document
// imported, as the client does both) or a mesh it uses uploaded again reaches a viewer first as an
// interactive frame that builds the new volume, then as the still frame and its refinement. Against a
// real refractd; the frames' order and kind are asserted, never their times.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <chrono>
#include <string>
#include <thread>

#include "daemon/api.h"
#include "daemon/harness.h"
#include "daemon/ws_client.h"

namespace refract::test {
namespace {

using json = nlohmann::json;

// A closed octahedron of radius `r` as an OBJ file.
std::string octahedron(const std::string& r) {
    return "v " + r + " 0 0\nv -" + r + " 0 0\nv 0 " + r + " 0\nv 0 -" + r + " 0\nv 0 0 " + r + "\nv 0 0 -" + r +
           "\nf 1 3 5\nf 3 2 5\nf 2 4 5\nf 4 1 5\nf 3 1 6\nf 2 3 6\nf 4 2 6\nf 1 4 6\n";
}

// A scene at a lattice the load's preview coarsens (the small scene's 32 voxels are the least).
json scene_of(const json& objects) {
    json document = kSmallScene;
    document["volume"] = {{"resolution", 64}};
    document["objects"] = objects;
    return document;
}

// The frames of `ws` up to and including the first of `revision`, whose header it returns; frames of
// older revisions (the refinement level in flight when the scene changed) are passed over.
json first_frame_of(WsClient& ws, int revision) {
    for (int frames = 0; frames < 8; ++frames) {
        json header = ws.read_frame().first;
        if (header["revision"] == revision) return header;
        EXPECT_LT(header["revision"].get<int>(), revision) << header;
    }
    ADD_FAILURE() << "no frame of revision " << revision;
    return {};
}

// A viewer refining a scene sees it replaced by a document of other objects (the client's Load and
// Import): the first frame of the new revision is an interactive preview that built the new volume,
// then comes the still frame, then its refinement, all without asking.
TEST(DaemonLoads, AReplacedSceneComesAsAPreviewThenAsTheRefinedStill) {
    TempDir dir;
    Daemon daemon(dir.path() / "data");
    auto client = daemon.client();
    const std::string id = create_scene(client, "loads", scene_of({{"object", {{"mesh", "sphere"}}}}));
    WsClient ws(daemon.ws_port(), "/api/scenes/" + id + "/ws");
    ws.send({{"seq", 1}, {"quality", "still"}, {"refine", 3}});
    EXPECT_EQ(ws.read_frame().first["level"], 1);
    EXPECT_EQ(ws.read_frame().first["level"], 2);  // refining: level 3 is on its way

    const json loaded = {{"object", nullptr},
                         {"left", {{"mesh", "sphere"}, {"scale", 0.4}, {"position", {-0.5, 0.0, 0.0}}}},
                         {"right", {{"mesh", "cube"}, {"scale", 0.4}, {"position", {0.5, 0.0, 0.0}}}}};
    auto replaced = patch(client, id, {{"objects", loaded}});
    ASSERT_TRUE(replaced && replaced->status == 200);
    const json preview = first_frame_of(ws, 2);
    EXPECT_EQ(preview["quality"], "interactive") << preview;
    EXPECT_EQ(preview["voxelized"], json({"left", "right"})) << preview;
    for (int level = 1; level <= 3; ++level) {
        auto [still, png] = ws.read_frame();
        EXPECT_EQ(still["revision"], 2);
        EXPECT_EQ(still["quality"], "still");
        EXPECT_EQ(still["level"], level);
        EXPECT_EQ(png_size(png), (std::pair{64u, 64u}));
    }
    expect_no_validation_errors(daemon);
}

// A mesh the scene uses uploaded again (another shape, the same name) makes no revision: the client asks
// for a preview of it, which builds the volume anew, and the still frame follows unasked.
TEST(DaemonLoads, AMeshUploadedAgainComesAsAPreviewThenAsTheStill) {
    TempDir dir;
    Daemon daemon(dir.path() / "data");
    auto client = daemon.client();
    ASSERT_EQ(client.Put("/api/meshes/gem", octahedron("1"), "text/plain")->status, 201);
    const std::string id = create_scene(client, "uploads", scene_of({{"gem", {{"mesh", "upload:gem"}, {"scale", 0.6}}}}));
    WsClient ws(daemon.ws_port(), "/api/scenes/" + id + "/ws");
    ws.send({{"seq", 1}, {"quality", "still"}, {"refine", 1}});
    EXPECT_EQ(ws.read_frame().first["level"], 1);

    ASSERT_EQ(client.Put("/api/meshes/gem", octahedron("0.8"), "text/plain")->status, 201);
    ws.send({{"seq", 2}, {"quality", "interactive"}});
    auto [preview, preview_png] = ws.read_frame();
    EXPECT_EQ(preview["seq"], 2);
    EXPECT_EQ(preview["quality"], "interactive");
    EXPECT_EQ(preview["voxelized"], json({"gem"})) << preview;
    auto [still, still_png] = ws.read_frame();
    EXPECT_EQ(still["seq"], 2);
    EXPECT_EQ(still["quality"], "still");
    EXPECT_EQ(still["level"], 1);
    EXPECT_EQ(png_size(still_png), (std::pair{64u, 64u}));
    expect_no_validation_errors(daemon);
}

// A still frame asked for gives way to the viewer's next message, whose frame answers both (latest wins),
// and to a load over HTTP, whose preview answers it: neither waits for a still that takes minutes
// (kHeavyScene; the next frame's wait would otherwise end the read in 60 s).
TEST(DaemonLoads, AStillAskedForGivesWayToTheNextMessageAndToALoad) {
    TempDir dir;
    Daemon daemon(dir.path() / "data", {"--max-photons", kHeavyPhotons});
    auto client = daemon.client();
    const std::string id = create_scene(client, "heavy", kHeavyScene);
    WsClient ws(daemon.ws_port(), "/api/scenes/" + id + "/ws");
    ws.send({{"seq", 1}, {"quality", "interactive"}, {"refine", 0}});
    EXPECT_EQ(ws.read_frame().first["seq"], 1);  // the volume built: what follows is the still's photons

    ws.send({{"seq", 2}, {"quality", "still"}, {"refine", 0}});
    std::this_thread::sleep_for(std::chrono::seconds(1));
    ws.send({{"seq", 3}, {"quality", "interactive"}, {"refine", 0}});
    auto [next, next_png] = ws.read_frame();
    EXPECT_EQ(next["seq"], 3) << next;
    EXPECT_EQ(next["quality"], "interactive");

    ws.send({{"seq", 4}, {"quality", "still"}, {"refine", 0}});
    std::this_thread::sleep_for(std::chrono::seconds(1));
    auto loaded = patch(client, id, {{"objects", {{"object", {{"mesh", "cube"}}}}}});
    ASSERT_TRUE(loaded && loaded->status == 200);
    auto [preview, preview_png] = ws.read_frame();
    EXPECT_EQ(preview["seq"], 4) << preview;
    EXPECT_EQ(preview["revision"], 2);
    EXPECT_EQ(preview["quality"], "interactive");
    expect_no_validation_errors(daemon);
}

}  // namespace
}  // namespace refract::test
