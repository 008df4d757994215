// refractd's parts, in this process: its configuration, HTTP helpers, static files, the scene store and the
// render queue (the daemon itself: daemon_test.cpp). Built with the sanitizers too (scripts/test.sh).
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <fstream>
#include <mutex>
#include <nlohmann/json.hpp>
#include <set>
#include <thread>

#include "daemon/api.h"
#include "daemon/harness.h"
#include "http/daemon_config.h"
#include "http/examples.h"
#include "http/metrics.h"
#include "http/service.h"
#include "http/static_files.h"
#include "http/stop_deadline.h"
#include "image/environment_map.h"
#include "render/invalidation.h"
#include "render/render_queue.h"
#include "store/scene_store.h"

namespace refract::test {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;


TEST(DaemonConfig, ParsesFlagsAndRejectsNonsense) {
    http::DaemonConfig defaults;
    auto parsed = http::parse_command_line(
        {"--port", "9000", "--max-body=1M", "--token", "t", "--max-queue", "3"}, defaults);
    EXPECT_EQ(parsed.config.port, 9000);
    EXPECT_EQ(parsed.config.effective_ws_port(), 9001);
    EXPECT_EQ(parsed.config.max_body, size_t{1} << 20);
    EXPECT_EQ(parsed.config.token, "t");
    EXPECT_EQ(parsed.config.max_queue, 3u);
    EXPECT_TRUE(http::parse_command_line({"--help"}, defaults).help);
    EXPECT_THROW(http::parse_command_line({"--port", "banana"}, defaults), http::ConfigError);
    EXPECT_THROW(http::parse_command_line({"--port", "70000"}, defaults), http::ConfigError);
    EXPECT_THROW(http::parse_command_line({"--frobnicate"}, defaults), http::ConfigError);
    EXPECT_THROW(http::parse_command_line({"--port"}, defaults), http::ConfigError);
    EXPECT_THROW(http::parse_command_line({"--port", "9000", "--ws-port", "9000"}, defaults),
                 http::ConfigError);
}

TEST(DaemonConfig, TheStopTimeoutIsWholeSecondsWithinAnHour) {
    http::DaemonConfig defaults;
    EXPECT_EQ(http::parse_command_line({}, defaults).config.stop_timeout_s, 10u);
    EXPECT_EQ(http::parse_command_line({"--stop-timeout", "3"}, defaults).config.stop_timeout_s, 3u);
    EXPECT_EQ(http::parse_command_line({"--stop-timeout=3600"}, defaults).config.stop_timeout_s, 3600u);
    for (const char* bad : {"0", "3601", "-1", "1.5", "", "ten", "99999999999999999999"})
        EXPECT_THROW(http::parse_command_line({"--stop-timeout", bad}, defaults), http::ConfigError) << bad;
    EXPECT_THROW(http::parse_command_line({"--stop-timeout"}, defaults), http::ConfigError);
}

// A stop stuck in a step is ended at the deadline, told which step; one that finishes is never ended.
TEST(DaemonStop, AStopPastItsDeadlineIsEndedInTheStepItWaitsFor) {
    std::mutex mutex;
    std::vector<std::string> ended;
    auto record = [&](const std::string& step) {
        std::lock_guard lock(mutex);
        ended.push_back(step);
    };
    {
        http::StopDeadline deadline(std::chrono::milliseconds(50), record);
        deadline.step("the render thread");
        deadline.step("the WebSocket sessions");
        std::this_thread::sleep_for(std::chrono::milliseconds(400));
    }
    EXPECT_EQ(ended, std::vector<std::string>{"the WebSocket sessions"});
    ended.clear();
    {
        http::StopDeadline deadline(std::chrono::seconds(3), record);
        deadline.step("the device");
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    EXPECT_TRUE(ended.empty());
}

TEST(DaemonConfig, ListensBeyondLoopbackOnlyWithATokenOrWhenToldToBeOpen) {
    http::DaemonConfig defaults;
    for (const char* loopback : {"127.0.0.1", "127.1.2.3", "::1", "localhost"})
        EXPECT_NO_THROW(http::parse_command_line({"--bind", loopback}, defaults)) << loopback;
    EXPECT_THROW(http::parse_command_line({"--bind", "0.0.0.0"}, defaults), http::ConfigError);
    EXPECT_THROW(http::parse_command_line({"--bind", "::"}, defaults), http::ConfigError);
    EXPECT_THROW(http::parse_command_line({"--bind", "10.0.0.7"}, defaults), http::ConfigError);
    EXPECT_NO_THROW(http::parse_command_line({"--bind", "0.0.0.0", "--token", "t"}, defaults));
    EXPECT_TRUE(http::parse_command_line({"--bind", "0.0.0.0", "--open"}, defaults).config.open);

    TempDir dir;
    const std::string token_file = (dir.path() / "token").string();
    std::ofstream(token_file) << "s3cret\n";
    EXPECT_EQ(http::parse_command_line({"--bind", "::", "--token-file", token_file}, defaults).config.token, "s3cret");
    std::ofstream(token_file, std::ios::trunc) << "\n";
    EXPECT_THROW(http::parse_command_line({"--token-file", token_file}, defaults), http::ConfigError);
    EXPECT_THROW(http::parse_command_line({"--token-file", (dir.path() / "none").string()}, defaults),
                 http::ConfigError);
}

TEST(DaemonConfig, TheSharedStoreTakesAPostgresqlUrl) {
    http::DaemonConfig defaults;
    EXPECT_EQ(http::parse_command_line({"--store", "postgresql://u@db:5432/refract"}, defaults).config.store,
              "postgresql://u@db:5432/refract");
    EXPECT_THROW(http::parse_command_line({"--store", "/var/lib/refract"}, defaults), http::ConfigError);
    EXPECT_THROW(http::parse_command_line({"--store", "mysql://db/refract"}, defaults), http::ConfigError);
}

TEST(DaemonHttp, IfMatchAcceptsQuotedAndBareRevisions) {
    EXPECT_EQ(http::parse_if_match("3"), 3u);
    EXPECT_EQ(http::parse_if_match("\"17\""), 17u);
    EXPECT_EQ(http::parse_if_match("W/\"5\""), 5u);
    EXPECT_EQ(http::parse_if_match(""), std::nullopt);
    EXPECT_EQ(http::parse_if_match("*"), std::nullopt);
    EXPECT_THROW(http::parse_if_match("\"abc\""), std::invalid_argument);
}

TEST(DaemonHttp, RoutesKeepMetricLabelsFew) {
    EXPECT_EQ(http::route_of("/api/scenes/abc/frame.png"), "/api/scenes/{id}/frame.png");
    EXPECT_EQ(http::route_of("/api/scenes/abc"), "/api/scenes/{id}");
    EXPECT_EQ(http::route_of("/api/meshes/bunny.obj"), "/api/meshes/{name}");
    EXPECT_EQ(http::route_of("/api/examples/prism"), "/api/examples/{name}");
    EXPECT_EQ(http::route_of("/index.html"), "static");
    EXPECT_EQ(http::route_of("/api/what/ever/x/y"), "other");
}

TEST(DaemonHttp, JsonDepthIsBounded) {
    EXPECT_NO_THROW(http::parse_json_document(R"({"volume":{"bounds":{"min":[0,0,0]}}})"));
    std::string deep = std::string(100000, '[') + std::string(100000, ']');
    EXPECT_THROW(http::parse_json_document(deep), std::invalid_argument);
    EXPECT_ANY_THROW(http::parse_json_document("{\"a\": NaN}"));
    // A repeated key would keep only its last value, silently: refused at any depth.
    EXPECT_THROW(http::parse_json_document(R"({"light":{"intensity":1,"intensity":2}})"), std::invalid_argument);
    EXPECT_THROW(http::parse_json_document(R"([{"a":1},{"b":1,"b":1}])"), std::invalid_argument);
    EXPECT_NO_THROW(http::parse_json_document(R"([{"a":1},{"a":1}])"));
}

TEST(DaemonStaticFiles, ServesInsideTheRootOnly) {
    TempDir dir;
    fs::create_directories(dir.path() / "root" / "js");
    std::ofstream(dir.path() / "root" / "index.html") << "<html></html>";
    std::ofstream(dir.path() / "root" / "js" / "app.js") << "1;";
    std::ofstream(dir.path() / "root" / "js" / "index.html") << "<html></html>";
    std::ofstream(dir.path() / "secret.txt") << "secret";
    fs::create_symlink(dir.path() / "secret.txt", dir.path() / "root" / "leak.txt");
    fs::path root = dir.path() / "root";

    auto index = http::resolve_static(root, "/");
    EXPECT_EQ(index.status, 200);
    EXPECT_EQ(index.content_type, "text/html; charset=utf-8");
    EXPECT_EQ(http::resolve_static(root, "/js/app.js").content_type, "text/javascript; charset=utf-8");
    EXPECT_EQ(http::resolve_static(root, "/js").path.filename(),
              "index.html");  // a directory means its index
    EXPECT_EQ(http::resolve_static(root, "/../secret.txt").status, 400);
    EXPECT_EQ(http::resolve_static(root, "/js/../../secret.txt").status, 400);
    EXPECT_EQ(http::resolve_static(root, "/leak.txt").status, 404);  // symlink out of the root
    EXPECT_EQ(http::resolve_static(root, "/missing.css").status, 404);
    EXPECT_EQ(http::content_type_for("a.svg"), "image/svg+xml");
    EXPECT_EQ(http::content_type_for("a.PNG"), "image/png");
    EXPECT_EQ(http::content_type_for("a.json"), "application/json");
    EXPECT_EQ(http::content_type_for("a.css"), "text/css; charset=utf-8");
}

TEST(DaemonStaticFiles, ExamplesAreReadByValidNamesFromTheirDirectoryOnly) {
    TempDir dir;
    fs::path examples = dir.path() / "examples";
    fs::create_directories(examples / "sub");
    std::ofstream(examples / "ball_lens.json") << R"({"object": {"ior": 1.6}})";
    std::ofstream(examples / "broken.json") << "{ not json";
    std::ofstream(examples / "Upper.json") << "{}";  // not a valid name: never listed
    std::ofstream(examples / "notes.txt") << "{}";
    std::ofstream(examples / "sub" / "inner.json") << "{}";
    std::ofstream(dir.path() / "secret.json") << R"({"secret": 1})";
    fs::create_symlink(dir.path() / "secret.json", examples / "leak.json");

    EXPECT_EQ(http::list_examples(examples), (std::vector<std::string>{"ball_lens", "broken"}));
    EXPECT_EQ(http::example_title("ball_lens"), "Ball lens");
    EXPECT_EQ(http::examples_index(examples)["examples"][0],
              (nlohmann::json{{"name", "ball_lens"}, {"title", "Ball lens"}}));
    auto good = http::read_example(examples, "ball_lens");
    EXPECT_EQ(good.status, 200);
    EXPECT_EQ(good.document["object"]["ior"], 1.6);
    EXPECT_EQ(http::read_example(examples, "broken").status, 500);
    EXPECT_EQ(http::read_example(examples, "missing").status, 404);
    EXPECT_EQ(http::read_example(examples, "leak").status, 404);  // symlink out of the directory
    for (const std::string& bad : std::vector<std::string>{"", "..", "../secret", "sub/inner", "Upper", "ball_lens.json", "a b", "x%2f..",
                            std::string(65, 'a'), std::string("a\0b", 3)}) {
        EXPECT_FALSE(http::valid_example_name(bad)) << bad;
        EXPECT_EQ(http::read_example(examples, bad).status, 400) << bad;
    }
    EXPECT_TRUE(http::valid_example_name(std::string(64, 'a')));
    EXPECT_EQ(http::read_example(examples, std::string(64, 'a')).status, 404);
    // A directory that does not exist lists nothing and finds nothing.
    EXPECT_TRUE(http::list_examples(dir.path() / "none").empty());
    EXPECT_EQ(http::examples_index(dir.path() / "none"), (nlohmann::json{{"examples", nlohmann::json::array()}}));
    EXPECT_EQ(http::read_example(dir.path() / "none", "ball_lens").status, 404);
}

TEST(DaemonSceneStore, EditsPersistAndRejectedEditsChangeNothing) {
    TempDir dir;
    protocol::Limits limits;
    {
        scene::SceneStore store(dir.path(), limits, {});
        auto created = store.create("one", kSmallScene);
        EXPECT_EQ(created.revision, 1u);
        auto edit = store.patch("one", {{"light", {{"intensity", 5.0}}}});
        EXPECT_TRUE(edit.changed);
        EXPECT_EQ(edit.after.revision, 2u);
        EXPECT_EQ(scene::passes_invalidated(edit.before, edit.after.document),
                  scene::kPhotons | scene::kView | scene::kToneMap);
        EXPECT_THROW(store.patch("one", {{"light", {{"intensity", -1.0}}}}), protocol::ValidationError);
        EXPECT_EQ(store.get("one")->revision, 2u);
        auto noop = store.patch("one", {{"light", {{"intensity", 5.0}}}});
        EXPECT_FALSE(noop.changed);
        EXPECT_EQ(noop.after.revision, 2u);
        try {
            store.patch("one", {{"camera", {{"fov_deg", 30.0}}}}, 1);
            FAIL() << "a stale If-Match must be refused";
        } catch (const scene::StoreError& e) {
            EXPECT_EQ(e.failure(), scene::StoreFailure::stale_revision);
            EXPECT_EQ(http::http_status(e.failure()), 412);
        }
        EXPECT_THROW(store.create("one", json::object()), scene::StoreError);
        EXPECT_THROW(store.create("Bad Id", json::object()), scene::StoreError);
        EXPECT_THROW(store.patch("nope", json::object()), scene::StoreError);
        auto random = store.create("", json::object());
        EXPECT_TRUE(scene::valid_scene_id(random.id));
        EXPECT_TRUE(store.remove(random.id));
        EXPECT_FALSE(store.remove(random.id));
    }
    // A write that never reached its rename leaves a temp file: ignored and cleaned on load.
    std::ofstream(dir.path() / "scenes" / "one.json~tmp.1.2") << "{garbage";
    scene::SceneStore reopened(dir.path(), limits, {});
    ASSERT_EQ(reopened.size(), 1u);
    auto one = reopened.get("one");
    ASSERT_TRUE(one);
    EXPECT_EQ(one->revision, 2u);
    EXPECT_EQ(one->document.lights.at("light").intensity, 5.0);
    EXPECT_FALSE(fs::exists(dir.path() / "scenes" / "one.json~tmp.1.2"));
}

TEST(DaemonSceneStore, MeshesAndGridsAreValidatedStoredAndReplaced) {
    TempDir dir;
    std::optional<scene::SceneStore> opened;
    opened.emplace(dir.path(), protocol::Limits{}, mesh::MeshLimits{});
    scene::SceneStore& store = *opened;
    auto entry = store.put_mesh("tet", kTetrahedronObj);
    EXPECT_EQ(entry.report.triangles, 4u);
    EXPECT_TRUE(entry.report.watertight());
    auto first = store.mesh("upload:tet");
    ASSERT_TRUE(first);
    store.put_mesh("tet", kTetrahedronObj);
    EXPECT_NE(store.mesh("tet"), first);  // a re-upload is a new pointer: the renderer re-voxelizes
    EXPECT_THROW(store.put_mesh("broken", "v 0 0 0\nf 1 2 3\n"), mesh::MeshError);
    EXPECT_THROW(store.put_mesh("../evil", kTetrahedronObj), scene::StoreError);
    EXPECT_EQ(store.list_meshes().size(), 1u);
    EXPECT_EQ(store.mesh("unknown"), nullptr);

    store.create("g", json::object());
    scene::IndexGrid grid;
    grid.nx = grid.ny = grid.nz = 4;
    grid.n.assign(64, 1.33f);
    auto edit = store.put_index_grid("g", grid);
    EXPECT_EQ(edit.after.document.object().index_field, protocol::IndexFieldKind::grid);
    EXPECT_EQ(edit.after.document.object().grid, "g");
    EXPECT_EQ(edit.after.revision, 2u);
    ASSERT_TRUE(store.grid("g"));
    EXPECT_EQ(store.grid("g")->n[5], 1.33f);
    grid.n[7] = 0.5f;
    EXPECT_THROW(store.put_index_grid("g", grid), scene::StoreError);
    grid.n[7] = std::numeric_limits<float>::quiet_NaN();
    EXPECT_THROW(store.put_index_grid("g", grid), scene::StoreError);
    grid.n[7] = 1.33f;
    // Refused at upload, not at the first frame: voxels that are not cubes, bounds floats cannot hold.
    for (auto [min, max] : {std::pair<protocol::Vec3, protocol::Vec3>{{-1, -1, -1}, {1, 1, 3}},
                            {{-1e300, -1e300, -1e300}, {1e300, 1e300, 1e300}},
                            {{0, 0, 0}, {1e-7, 1e-7, 1e-7}}}) {
        scene::IndexGrid odd = grid;
        odd.bounds.min = min;
        odd.bounds.max = max;
        try {
            store.put_index_grid("g", odd);
            ADD_FAILURE() << "grid bounds " << max[0] << " accepted";
        } catch (const scene::StoreError& e) {
            EXPECT_EQ(e.failure(), scene::StoreFailure::invalid) << e.what();
            EXPECT_EQ(http::http_status(e.failure()), 400);
        }
    }
    EXPECT_EQ(store.get("g")->revision, 2u);

    opened.reset();
    scene::SceneStore reopened(dir.path(), {}, {});
    ASSERT_TRUE(reopened.grid("g"));
    EXPECT_EQ(reopened.grid("g")->nx, 4u);
    ASSERT_TRUE(reopened.mesh("tet"));
    EXPECT_EQ(reopened.mesh("tet")->triangles.size(), 4u);
}

TEST(DaemonSceneStore, NamesThatLookLikeTempFilesSurviveARestart) {
    TempDir dir;
    {
        scene::SceneStore store(dir.path(), {}, {});
        store.put_mesh("a.tmp.b", kTetrahedronObj);
        store.create("tmp", json::object());
        EXPECT_THROW(store.put_mesh("a~tmp.b", kTetrahedronObj), scene::StoreError);
    }
    scene::SceneStore reopened(dir.path(), {}, {});
    ASSERT_TRUE(reopened.mesh("a.tmp.b"));
    EXPECT_EQ(reopened.list_meshes().size(), 1u);
    EXPECT_TRUE(reopened.get("tmp"));
}

TEST(DaemonSceneStore, ASecondStoreOnTheSameDirectoryIsRefused) {
    TempDir dir;
    std::optional<scene::SceneStore> first;
    first.emplace(dir.path(), protocol::Limits{}, mesh::MeshLimits{});
    try {
        scene::SceneStore second(dir.path(), {}, {});
        FAIL() << "two stores on one directory would hand out the same revisions";
    } catch (const scene::StoreError& e) {
        EXPECT_EQ(e.failure(), scene::StoreFailure::in_use);
        EXPECT_EQ(http::http_status(e.failure()), 409);
        EXPECT_NE(std::string(e.what()).find("pid " + std::to_string(::getpid())), std::string::npos) << e.what();
    }
    first.reset();  // the lock goes with its holder
    EXPECT_NO_THROW(scene::SceneStore(dir.path(), {}, {}));
}

TEST(DaemonSceneStore, UnreadableScenesAreQuarantinedReportedAndNeverOverwritten) {
    TempDir dir;
    {
        scene::SceneStore store(dir.path(), {}, {});
        for (const char* id : {"good", "cut", "negative", "huge", "last"}) store.create(id, kSmallScene);
        store.patch("good", {{"light", {{"intensity", 3.0}}}});
    }
    const fs::path scenes = dir.path() / "scenes";
    std::string cut = read_file(scenes / "cut.json");
    cut.resize(cut.size() / 2);
    std::ofstream(scenes / "cut.json", std::ios::trunc) << cut;
    auto set_revision = [&](const char* id, json revision) {
        json stored = json::parse(read_file(scenes / (std::string(id) + ".json")));
        stored["revision"] = revision;
        std::ofstream(scenes / (std::string(id) + ".json"), std::ios::trunc) << stored.dump();
    };
    set_revision("negative", -1);
    set_revision("huge", json(18446744073709551615ull));
    set_revision("last", json(scene::kMaxRevision));

    scene::SceneStore store(dir.path(), {}, {});
    EXPECT_EQ(store.get("good")->revision, 2u);
    std::set<std::string> quarantined;
    for (const auto& file : store.quarantined()) {
        quarantined.insert(file.scene_id);
        EXPECT_TRUE(fs::exists(file.path)) << file.path;
        EXPECT_FALSE(file.error.empty());
    }
    EXPECT_EQ(quarantined, (std::set<std::string>{"cut", "negative", "huge"}));
    EXPECT_EQ(read_file(dir.path() / "quarantine" / "cut.json"), cut);  // kept byte for byte
    for (const char* id : {"cut", "negative", "huge"}) {
        EXPECT_FALSE(store.get(id));
        try {
            store.create(id, json::object());
            FAIL() << id << ": a new scene must not take the place of an unreadable one";
        } catch (const scene::StoreError& e) {
            EXPECT_EQ(e.failure(), scene::StoreFailure::taken);
            EXPECT_EQ(http::http_status(e.failure()), 409);
            EXPECT_NE(std::string(e.what()).find("quarantine"), std::string::npos) << e.what();
        }
    }
    // The last revision JSON keeps exact is the last one handed out: no wrap to 0.
    EXPECT_EQ(store.get("last")->revision, scene::kMaxRevision);
    try {
        store.patch("last", {{"light", {{"intensity", 7.0}}}});
        FAIL() << "an edit past the highest revision must be refused";
    } catch (const scene::StoreError& e) {
        EXPECT_EQ(e.failure(), scene::StoreFailure::out_of_revisions);
        EXPECT_EQ(http::http_status(e.failure()), 409);
    }
    EXPECT_EQ(store.get("last")->revision, scene::kMaxRevision);
}

// The store names what went wrong; http/ alone chooses the status each is answered with.
TEST(DaemonSceneStore, EachStoreFailureIsAnsweredWithItsStatus) {
    using Failure = scene::StoreFailure;
    const std::pair<Failure, int> expected[] = {
        {Failure::invalid, 400},        {Failure::not_found, 404},      {Failure::taken, 409},
        {Failure::in_use, 409},         {Failure::out_of_revisions, 409}, {Failure::stale_revision, 412},
        {Failure::too_large, 413},      {Failure::broken, 500},         {Failure::unavailable, 503},
    };
    for (const auto& [failure, status] : expected)
        EXPECT_EQ(http::http_status(failure), status) << static_cast<int>(failure);
}

TEST(DaemonSceneStore, QuarantinedScenesStayReportedAcrossRestarts) {
    TempDir dir;
    { scene::SceneStore(dir.path(), {}, {}).create("cut", kSmallScene); }
    std::ofstream(dir.path() / "scenes" / "cut.json", std::ios::trunc) << "{";
    { EXPECT_EQ(scene::SceneStore(dir.path(), {}, {}).quarantined().size(), 1u); }
    scene::SceneStore store(dir.path(), {}, {});
    ASSERT_EQ(store.quarantined().size(), 1u);
    EXPECT_EQ(store.quarantined()[0].scene_id, "cut");
    EXPECT_THROW(store.create("cut", json::object()), scene::StoreError);
    EXPECT_EQ(read_file(dir.path() / "quarantine" / "cut.json"), "{");
}

TEST(DaemonSceneStore, UnreadableStoredAssetsSayWhy) {
    TempDir dir;
    {
        scene::SceneStore store(dir.path(), {}, {});
        store.put_mesh("tet", kTetrahedronObj);
        store.create("g", json::object());
        scene::IndexGrid grid;
        grid.nx = grid.ny = grid.nz = 4;
        grid.n.assign(64, 1.33f);
        store.put_index_grid("g", grid);
    }
    std::ofstream(dir.path() / "meshes" / "tet.obj", std::ios::trunc) << "v 0 0 0\nf 1 2 3\n";
    std::string grid = read_file(dir.path() / "grids" / "g.grid");
    std::ofstream(dir.path() / "grids" / "g.grid", std::ios::trunc) << grid.substr(0, grid.size() - 4);
    scene::SceneStore store(dir.path(), {}, {});
    try {
        store.mesh("upload:tet");
        FAIL() << "a corrupt stored mesh must say why";
    } catch (const scene::RenderError& e) {
        EXPECT_NE(std::string(e.what()).find("stored mesh 'tet' cannot be read"), std::string::npos) << e.what();
    }
    try {
        store.grid("g");
        FAIL() << "a corrupt stored grid must say why";
    } catch (const scene::RenderError& e) {
        EXPECT_NE(std::string(e.what()).find("truncated"), std::string::npos) << e.what();
    }
    EXPECT_EQ(store.mesh("unknown"), nullptr);
    EXPECT_TRUE(fs::exists(dir.path() / "meshes" / "tet.obj"));
}

// A render function the test drives: each call blocks until the test allows one more.
struct SteppedRenderer {
    std::mutex mutex;
    std::condition_variable changed;
    int allowed = 0;
    std::vector<std::pair<std::string, uint64_t>> calls;  // (scene, revision) in render order

    scene::FrameResult render(const scene::FrameRequest& request) {
        std::unique_lock lock(mutex);
        calls.emplace_back(request.scene_id, request.revision);
        changed.notify_all();
        changed.wait(lock, [&] { return allowed > 0; });
        --allowed;
        if (request.document.object().mesh == "upload:missing") throw scene::RenderError("unknown mesh");
        scene::FrameResult frame;
        frame.png = {1, 2, 3};
        frame.rerun = scene::kView;
        return frame;
    }
    void allow(int n) {
        std::lock_guard lock(mutex);
        allowed += n;
        changed.notify_all();
    }
    void wait_calls(size_t n) {
        std::unique_lock lock(mutex);
        ASSERT_TRUE(changed.wait_for(lock, std::chrono::seconds(10), [&] { return calls.size() >= n; }));
    }
};

scene::FrameRequest request_for(const std::string& id, uint64_t revision) {
    scene::FrameRequest request;
    request.scene_id = id;
    request.revision = revision;
    request.document.image.width = 8;
    request.document.image.height = 8;
    return request;
}

TEST(DaemonRenderQueue, LatestWinsAndEveryWaiterGetsTheNewestFrame) {
    SteppedRenderer renderer;
    scene::RenderQueue queue([&](const scene::FrameRequest& r) { return renderer.render(r); }, {});
    std::mutex mutex;
    std::vector<uint64_t> delivered;
    auto record = [&](const scene::FrameOutcome& outcome) {
        std::lock_guard lock(mutex);
        delivered.push_back(outcome.revision);
    };
    ASSERT_TRUE(queue.submit(request_for("a", 1), record));
    renderer.wait_calls(1);
    for (uint64_t revision = 2; revision <= 5; ++revision)
        ASSERT_TRUE(queue.submit(request_for("a", revision), record));
    EXPECT_EQ(queue.waiting(), 5u);
    renderer.allow(2);
    renderer.wait_calls(2);
    queue.stop();
    EXPECT_EQ(renderer.calls, (std::vector<std::pair<std::string, uint64_t>>{{"a", 1}, {"a", 5}}));
    EXPECT_EQ(delivered, (std::vector<uint64_t>{1, 5, 5, 5, 5}));
}

TEST(DaemonRenderQueue, RepeatsAreAnsweredFromTheLastFrame) {
    SteppedRenderer renderer;
    renderer.allow(10);
    scene::RenderQueue queue([&](const scene::FrameRequest& r) { return renderer.render(r); }, {});
    auto first = queue.render_and_wait(request_for("a", 3), std::chrono::seconds(10));
    ASSERT_TRUE(first);
    EXPECT_FALSE(first->cached);
    auto again = queue.render_and_wait(request_for("a", 3), std::chrono::seconds(10));
    ASSERT_TRUE(again);
    EXPECT_TRUE(again->cached);
    EXPECT_EQ(again->frame, first->frame);
    auto older = queue.render_and_wait(request_for("a", 2), std::chrono::seconds(10));
    EXPECT_TRUE(older->cached);
    auto other_size = request_for("a", 3);
    other_size.document.image.width = 16;
    EXPECT_FALSE(queue.render_and_wait(other_size, std::chrono::seconds(10))->cached);
    queue.forget_cached_frames();
    EXPECT_FALSE(queue.render_and_wait(other_size, std::chrono::seconds(10))->cached);
    EXPECT_EQ(renderer.calls.size(), 3u);
}

TEST(DaemonRenderQueue, BoundedFairAndForgetful) {
    SteppedRenderer renderer;
    std::vector<std::string> evicted;
    scene::RenderQueueOptions options;
    options.max_waiters = 3;
    options.evict = [&](const std::string& id) { evicted.push_back(id); };
    scene::RenderQueue queue([&](const scene::FrameRequest& r) { return renderer.render(r); }, options);
    std::mutex mutex;
    std::map<std::string, std::vector<scene::FrameOutcome::Status>> outcomes;
    auto record = [&](const std::string& id) {
        return [&, id](const scene::FrameOutcome& outcome) {
            std::lock_guard lock(mutex);
            outcomes[id].push_back(outcome.status);
        };
    };
    ASSERT_TRUE(queue.submit(request_for("a", 1), record("a")));
    renderer.wait_calls(1);
    ASSERT_TRUE(queue.submit(request_for("a", 2), record("a")));
    ASSERT_TRUE(queue.submit(request_for("b", 1), record("b")));
    EXPECT_FALSE(queue.submit(request_for("c", 1), record("c")));  // full: the caller answers 503

    renderer.allow(1);  // a1 done; a2 starts
    renderer.wait_calls(2);
    ASSERT_TRUE(queue.submit(request_for("a", 3), record("a")));  // queued behind b: round-robin
    queue.forget_scene("b");
    renderer.allow(2);
    renderer.wait_calls(3);
    queue.stop();
    EXPECT_EQ(renderer.calls, (std::vector<std::pair<std::string, uint64_t>>{{"a", 1}, {"a", 2}, {"a", 3}}));
    EXPECT_EQ(outcomes["b"], std::vector<scene::FrameOutcome::Status>{scene::FrameOutcome::Status::gone});
    EXPECT_EQ(outcomes["a"].size(), 3u);
    EXPECT_EQ(evicted, std::vector<std::string>{"b"});
    EXPECT_EQ(outcomes.count("c"), 0u);
}

TEST(DaemonRenderQueue, RoundRobinBetweenScenes) {
    SteppedRenderer renderer;
    scene::RenderQueue queue([&](const scene::FrameRequest& r) { return renderer.render(r); }, {});
    auto ignore = [](const scene::FrameOutcome&) {};
    queue.submit(request_for("a", 1), ignore);
    renderer.wait_calls(1);
    queue.submit(request_for("a", 2), ignore);
    queue.submit(request_for("b", 1), ignore);
    renderer.allow(1);
    renderer.wait_calls(2);                     // a2 renders
    queue.submit(request_for("a", 3), ignore);  // a busy scene must not starve b
    renderer.allow(3);
    renderer.wait_calls(4);
    queue.stop();
    EXPECT_EQ(renderer.calls,
              (std::vector<std::pair<std::string, uint64_t>>{{"a", 1}, {"a", 2}, {"b", 1}, {"a", 3}}));
}

// A render function whose frames run in parts, asking the queue between them (as SceneGpu::run does):
// scene "heavy" takes `parts` parts of `part` each, any other scene one part.
struct PartedRenderer {
    std::mutex mutex;
    std::vector<std::string> log;  // "heavy:0", "light", ... in the order the parts ran
    uint32_t parts = 50;
    std::chrono::milliseconds part{20};

    void note(const std::string& entry) {
        std::lock_guard lock(mutex);
        log.push_back(entry);
    }
    size_t count(const std::string& prefix) {
        std::lock_guard lock(mutex);
        return static_cast<size_t>(std::count_if(log.begin(), log.end(), [&](const std::string& e) {
            return e.compare(0, prefix.size(), prefix) == 0;
        }));
    }
    scene::FrameResult render(const scene::FrameRequest& request) {
        const bool heavy = request.scene_id == "heavy";
        for (uint32_t i = 0; i < (heavy ? parts : 1u); ++i) {
            if (i > 0 && request.options.give_way && request.options.give_way()) {
                scene::FrameResult stopped;
                stopped.outcome = scene::FrameResult::Outcome::superseded;
                return stopped;
            }
            std::string entry = request.scene_id;  // appended: GCC 12's false -Wrestrict (its bug 105329)
            entry += ':';
            entry += std::to_string(i);
            note(entry);
            std::this_thread::sleep_for(part);
        }
        scene::FrameResult frame;
        frame.png = {1};
        return frame;
    }
};

TEST(DaemonRenderQueue, OtherScenesRenderBetweenThePartsOfAHeavyFrame) {
    PartedRenderer renderer;
    scene::RenderQueue queue([&](const scene::FrameRequest& r) { return renderer.render(r); }, {});
    std::atomic<int> heavy_done{0};
    std::atomic<size_t> heavy_parts_when_light_done{0};
    ASSERT_TRUE(queue.submit(request_for("heavy", 1), [&](const scene::FrameOutcome& o) {
        EXPECT_EQ(o.status, scene::FrameOutcome::Status::ok);
        heavy_done = 1;
    }));
    ASSERT_TRUE(wait_until([&] { return renderer.count("heavy:") >= 2; }, std::chrono::seconds(10)));
    auto light = queue.render_and_wait(request_for("light", 1), std::chrono::seconds(10));
    heavy_parts_when_light_done = renderer.count("heavy:");
    ASSERT_TRUE(light);
    EXPECT_EQ(light->status, scene::FrameOutcome::Status::ok);
    // Answered within a part or two of the heavy frame, which then goes on to its end.
    EXPECT_EQ(heavy_done.load(), 0);
    EXPECT_LT(heavy_parts_when_light_done.load(), renderer.parts / 2);
    ASSERT_TRUE(wait_until([&] { return heavy_done.load() == 1; }, std::chrono::seconds(20)));
    EXPECT_EQ(renderer.count("heavy:"), renderer.parts);
    queue.stop();
}

TEST(DaemonRenderQueue, AFrameNobodyWaitsForIsDroppedOrAbandonedAtItsNextPart) {
    PartedRenderer renderer;
    scene::RenderQueue queue([&](const scene::FrameRequest& r) { return renderer.render(r); }, {});
    // The asker's timeout passes: the frame stops at its next part.
    auto outcome = queue.render_and_wait(request_for("heavy", 1), std::chrono::milliseconds(100));
    ASSERT_TRUE(outcome);
    EXPECT_EQ(outcome->status, scene::FrameOutcome::Status::timed_out);
    EXPECT_TRUE(wait_until([&] { return queue.waiting() == 0; }, std::chrono::seconds(10)));
    const size_t parts = renderer.count("heavy:");
    EXPECT_LT(parts, 10u) << "a frame whose asker left must stop, not render its " << renderer.parts << " parts";

    // The asker hangs up while the frame waits behind another: it is never rendered.
    scene::RenderQueueOptions one;
    one.max_waiters = 2;
    SteppedRenderer stepped;
    scene::RenderQueue small([&](const scene::FrameRequest& r) { return stepped.render(r); }, one);
    ASSERT_TRUE(small.submit(request_for("a", 1), [](const scene::FrameOutcome&) {}));
    stepped.wait_calls(1);
    auto gone = std::make_shared<std::atomic<bool>>(false);
    std::atomic<int> dropped{0};
    ASSERT_TRUE(small.submit(request_for("b", 1), [&](const scene::FrameOutcome& o) {
        EXPECT_EQ(o.status, scene::FrameOutcome::Status::abandoned);
        ++dropped;
    }, gone));
    gone->store(true);
    // Full but for the client that left: its place goes to the next.
    ASSERT_TRUE(small.submit(request_for("c", 1), [](const scene::FrameOutcome&) {}));
    EXPECT_EQ(dropped.load(), 1);
    stepped.allow(5);
    ASSERT_TRUE(wait_until([&] { return small.frames_rendered() == 2; }, std::chrono::seconds(10)));
    small.stop();
    EXPECT_EQ(stepped.calls, (std::vector<std::pair<std::string, uint64_t>>{{"a", 1}, {"c", 1}}));
}

TEST(DaemonRenderQueue, StopAbandonsTheFrameInProgressAtItsNextPart) {
    PartedRenderer renderer;
    renderer.parts = 1000;  // 20 s whole
    scene::RenderQueue queue([&](const scene::FrameRequest& r) { return renderer.render(r); }, {});
    std::atomic<int> status{-1};
    ASSERT_TRUE(queue.submit(request_for("heavy", 1),
                             [&](const scene::FrameOutcome& o) { status = static_cast<int>(o.status); }));
    ASSERT_TRUE(wait_until([&] { return renderer.count("heavy:") >= 1; }, std::chrono::seconds(10)));
    const auto start = std::chrono::steady_clock::now();
    queue.stop();
    EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(1));
    EXPECT_EQ(status.load(), static_cast<int>(scene::FrameOutcome::Status::shutting_down));
}

TEST(DaemonRenderQueue, PlayedFramesAndEditsTakeTurns) {
    SteppedRenderer renderer;
    scene::RenderQueue queue([&](const scene::FrameRequest& r) { return renderer.render(r); }, {});
    auto ignore = [](const scene::FrameOutcome&) {};
    queue.submit(request_for("busy", 1), ignore);
    renderer.wait_calls(1);
    for (uint64_t session = 1; session <= 3; ++session) {
        std::string id = "s";
        id += std::to_string(session);
        auto played = request_for(id, 100 + session);
        played.playback = std::to_string(session);
        queue.submit(played, ignore);
    }
    queue.submit(request_for("edited", 7), ignore);  // queued behind three played frames
    renderer.allow(6);
    renderer.wait_calls(5);
    queue.stop();
    // The edit waits for one played frame at most; the played ones keep their order.
    EXPECT_EQ(renderer.calls, (std::vector<std::pair<std::string, uint64_t>>{
                                  {"busy", 1}, {"s1", 101}, {"edited", 7}, {"s2", 102}, {"s3", 103}}));
}

TEST(DaemonRenderQueue, UnrenderableScenesAndMissingDevicesAreReported) {
    SteppedRenderer renderer;
    renderer.allow(1);
    scene::RenderQueue queue([&](const scene::FrameRequest& r) { return renderer.render(r); }, {});
    auto request = request_for("a", 1);
    request.document.object().mesh = "upload:missing";
    auto outcome = queue.render_and_wait(request, std::chrono::seconds(10));
    EXPECT_EQ(outcome->status, scene::FrameOutcome::Status::unrenderable);

    scene::RenderQueue no_device({}, {}, "no Vulkan here");
    auto none = no_device.render_and_wait(request_for("a", 1), std::chrono::seconds(1));
    EXPECT_EQ(none->status, scene::FrameOutcome::Status::no_device);
    EXPECT_EQ(none->error, "no Vulkan here");
}

}  // namespace
}  // namespace refract::test
