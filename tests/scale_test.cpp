// Scale-out on existing engines, end to end: three refractd replicas sharing one PostgreSQL store behind
// HAProxy (deploy/haproxy/haproxy.cfg, the file as shipped). Run through tests/scale/with_postgres.sh,
// which provides a throwaway cluster and cleans everything up however this process ends.
#include <gtest/gtest.h>
#include <libpq-fe.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdlib>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "daemon/harness.h"
#include "volume/vdb_samples.h"
#include "daemon/ws_client.h"

extern char** environ;

namespace refract::test {
namespace {

using json = nlohmann::json;
using Clock = std::chrono::steady_clock;
namespace fs = std::filesystem;

const json kSmallScene = {{"image", {{"width", 64}, {"height", 64}}},
                          {"volume", {{"resolution", 32}}},
                          {"photons", {{"count", 256}}}};

std::string env(const char* name) {
    const char* value = std::getenv(name);
    if (!value || !*value)
        throw std::runtime_error(std::string(name) + " is not set: run this test through tests/scale/with_postgres.sh");
    return value;
}

// The test cluster's URL for another database of it.
std::string database_url(const std::string& database) {
    std::string url = env("REFRACT_TEST_PG_URL");
    size_t slash = url.find("@/") + 1;
    size_t query = url.find('?', slash);
    return url.substr(0, slash + 1) + database + url.substr(query);
}

// One SQL statement on the test cluster; the error text, empty when it succeeded.
std::string sql(const std::string& url, const std::string& statement) {
    std::unique_ptr<PGconn, void (*)(PGconn*)> conn(PQconnectdb(url.c_str()), PQfinish);
    if (PQstatus(conn.get()) != CONNECTION_OK) return PQerrorMessage(conn.get());
    std::unique_ptr<PGresult, void (*)(PGresult*)> result(PQexec(conn.get(), statement.c_str()), PQclear);
    ExecStatusType status = PQresultStatus(result.get());
    return status == PGRES_COMMAND_OK || status == PGRES_TUPLES_OK ? "" : PQresultErrorMessage(result.get());
}

void pg_ctl(const std::string& action) {
    std::string command = env("REFRACT_TEST_PG_CTL") + " " + action + " > /dev/null";
    ASSERT_EQ(std::system(command.c_str()), 0) << command;
}

httplib::Client client_for(uint16_t port) {
    httplib::Client client("127.0.0.1", port);
    client.set_connection_timeout(5, 0);
    client.set_read_timeout(60, 0);
    return client;
}

// HAProxy with the shipped configuration in front of `replicas`, stopped (SIGTERM, then SIGKILL) with
// its scope.
class Haproxy {
public:
    explicit Haproxy(const std::vector<uint16_t>& replicas) : port_(free_port()) {
        ::setenv("REFRACT_LISTEN", ("127.0.0.1:" + std::to_string(port_)).c_str(), 1);
        for (size_t i = 0; i < replicas.size(); ++i)
            ::setenv(("REFRACT_REPLICA_" + std::to_string(i + 1)).c_str(),
                     ("127.0.0.1:" + std::to_string(replicas[i])).c_str(), 1);
        std::string config = std::string(REFRACT_SOURCE_DIR) + "/deploy/haproxy/haproxy.cfg";
        std::vector<std::string> args = {"haproxy", "-db", "-f", config};
        std::vector<char*> argv;
        for (auto& arg : args) argv.push_back(arg.data());
        argv.push_back(nullptr);
        // Debian puts it in /usr/sbin, which a non-root PATH may lack.
        if (posix_spawnp(&pid_, "haproxy", nullptr, nullptr, argv.data(), environ) != 0 &&
            posix_spawn(&pid_, "/usr/sbin/haproxy", nullptr, nullptr, argv.data(), environ) != 0)
            throw std::runtime_error("cannot start haproxy (REFRACT_TEST_SERVICES=1 bash scripts/install-deps.sh)");
        auto client = client_for(port_);
        for (auto deadline = Clock::now() + std::chrono::seconds(20); Clock::now() < deadline;) {
            if (auto res = client.Get("/api/health"); res && res->status == 200) return;
            std::this_thread::sleep_for(std::chrono::milliseconds(100));
        }
        throw std::runtime_error("haproxy did not answer /api/health within 20 s");
    }
    ~Haproxy() {
        ::kill(pid_, SIGTERM);
        int status = 0;
        for (int i = 0; i < 50 && ::waitpid(pid_, &status, WNOHANG) == 0; ++i)
            std::this_thread::sleep_for(std::chrono::milliseconds(100));
        ::kill(pid_, SIGKILL);
        ::waitpid(pid_, &status, 0);
    }
    Haproxy(const Haproxy&) = delete;
    Haproxy& operator=(const Haproxy&) = delete;
    uint16_t port() const { return port_; }

private:
    uint16_t port_;
    pid_t pid_ = -1;
};

std::vector<std::string> replica_args(const std::string& url) {
    return {"--store", url, "--max-resolution", "32", "--max-queue", "256"};
}

int patch(httplib::Client& client, const std::string& id, const json& body, json* answer = nullptr,
          std::optional<uint64_t> if_match = std::nullopt) {
    httplib::Headers headers;
    // Appended: GCC 12 reports a false -Wrestrict for "\"" + std::string (its bug 105329).
    if (if_match) headers.emplace("If-Match", std::string("\"").append(std::to_string(*if_match)).append("\""));
    auto res = client.Patch("/api/scenes/" + id, headers, body.dump(), "application/merge-patch+json");
    if (!res) return 0;
    if (answer) *answer = json::parse(res->body, nullptr, false);
    return res->status;
}

std::string health_of(uint16_t port) {
    auto res = client_for(port).Get("/api/health");
    return res ? res->body : "{}";
}

// A frame of `id` that was rendered for this request, not answered from the replica's cached frame:
// another replica's change reaches this one by an announcement, a few milliseconds later.
httplib::Result fresh_frame(httplib::Client& client, const std::string& id) {
    for (auto deadline = Clock::now() + std::chrono::seconds(5);;) {
        auto frame = client.Get("/api/scenes/" + id + "/frame.png");
        if (!frame || frame->status != 200) return frame;
        if (frame->get_header_value("X-Refract-Cached") == "0" || Clock::now() > deadline) return frame;
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
}

json get_scene(httplib::Client& client, const std::string& id) {
    auto res = client.Get("/api/scenes/" + id);
    if (!res || res->status != 200) return nullptr;
    return json::parse(res->body, nullptr, false);
}

// Three replicas on one fresh database and HAProxy before them, shared by the tests below (in order:
// the last one kills a replica).
class ScaleOut : public ::testing::Test {
protected:
    static void SetUpTestSuite() {
        dir_ = std::make_unique<TempDir>();
        std::string url = database_url("scaleout");
        ASSERT_EQ(sql(env("REFRACT_TEST_PG_URL"), "CREATE DATABASE scaleout"), "");
        for (int i = 0; i < 3; ++i)
            replicas_.push_back(std::make_unique<Daemon>(dir_->path() / std::string("r").append(std::to_string(i)),
                                                         replica_args(url)));
        haproxy_ = std::make_unique<Haproxy>(
            std::vector<uint16_t>{replicas_[0]->port(), replicas_[1]->port(), replicas_[2]->port()});
    }
    static void TearDownTestSuite() {
        haproxy_.reset();
        replicas_.clear();
        dir_.reset();
    }
    void TearDown() override {
        if (HasFailure())
            for (auto& replica : replicas_) std::cerr << "--- replica log ---\n" << replica->log();
    }

    static httplib::Client proxy() { return client_for(haproxy_->port()); }

    static std::unique_ptr<TempDir> dir_;
    static std::vector<std::unique_ptr<Daemon>> replicas_;
    static std::unique_ptr<Haproxy> haproxy_;
};
std::unique_ptr<TempDir> ScaleOut::dir_;
std::vector<std::unique_ptr<Daemon>> ScaleOut::replicas_;
std::unique_ptr<Haproxy> ScaleOut::haproxy_;

TEST(ScaleOutStart, AnUnreachableDatabaseIsAClearErrorAndExitStatus1) {
    // Port 1 on loopback: nothing listens, the connection is refused at once.
    auto [status, output] = run_refractd({"--store", "postgresql://refract@127.0.0.1:1/refract", "--port",
                                          std::to_string(free_port())},
                                         std::chrono::seconds(30));
    EXPECT_EQ(status, 1) << output;
    EXPECT_NE(output.find("cannot connect to PostgreSQL (database refract on 127.0.0.1:1)"), std::string::npos)
        << output;
}

TEST(ScaleOutStart, ASchemaOfANewerVersionIsRefused) {
    ASSERT_EQ(sql(env("REFRACT_TEST_PG_URL"), "CREATE DATABASE newer"), "");
    std::string url = database_url("newer");
    {
        // A first start creates and versions the schema.
        TempDir dir;
        Daemon daemon(dir.path() / "data", {"--store", url});
        EXPECT_EQ(daemon.stop(), 0) << daemon.log();
    }
    ASSERT_EQ(sql(url, "UPDATE refract_schema SET version = 99"), "");
    auto [status, output] =
        run_refractd({"--store", url, "--port", std::to_string(free_port())}, std::chrono::seconds(30));
    EXPECT_EQ(status, 1) << output;
    EXPECT_NE(output.find("schema is version 99, newer than this refractd's 4; refusing to start"), std::string::npos)
        << output;
}

TEST_F(ScaleOut, SceneIdsDifferingOnlyInCaseAreRefusedByTheDaemonAndTheDatabase) {
    auto client = proxy();
    auto created = client.Post("/api/scenes?id=casey", kSmallScene.dump(), "application/json");
    ASSERT_TRUE(created);
    EXPECT_EQ(created->status, 201) << created->body;
    auto upper = client.Post("/api/scenes?id=Casey", kSmallScene.dump(), "application/json");
    ASSERT_TRUE(upper);
    EXPECT_EQ(upper->status, 400) << upper->body;
    auto get = client.Get("/api/scenes/CASEY");
    ASSERT_TRUE(get);
    EXPECT_EQ(get->status, 404);
    // Nor can anything writing to the database directly store one.
    std::string refused = sql(database_url("scaleout"),
                              "INSERT INTO scenes (id, revision, document) VALUES ('Casey', 1, '{}')");
    EXPECT_NE(refused.find("scene_id_format"), std::string::npos) << refused;
    // And a revision that does not follow the stored one is refused by the database too.
    refused = sql(database_url("scaleout"), "UPDATE scenes SET revision = revision + 2 WHERE id = 'casey'");
    EXPECT_NE(refused.find("cannot follow"), std::string::npos) << refused;
}

TEST_F(ScaleOut, TheSameIfMatchThroughTwoReplicasHasExactlyOneWinner) {
    auto client = proxy();
    ASSERT_EQ(client.Post("/api/scenes?id=race", kSmallScene.dump(), "application/json")->status, 201);
    auto a = client_for(replicas_[0]->port());
    auto b = client_for(replicas_[1]->port());
    for (uint64_t round = 1; round <= 10; ++round) {
        int status_a = 0, status_b = 0;
        std::thread ta([&] { status_a = patch(a, "race", {{"image", {{"exposure", 0.1 * double(round)}}}}, nullptr, round); });
        std::thread tb([&] { status_b = patch(b, "race", {{"image", {{"exposure", -0.1 * double(round)}}}}, nullptr, round); });
        ta.join();
        tb.join();
        EXPECT_EQ((status_a == 200) + (status_b == 200), 1) << "round " << round << ": " << status_a << ", " << status_b;
        EXPECT_EQ((status_a == 412) + (status_b == 412), 1) << "round " << round << ": " << status_a << ", " << status_b;
        EXPECT_EQ(get_scene(client, "race")["revision"], round + 1);
    }
}

TEST_F(ScaleOut, ViewersOnTwoReplicasGetAFrameOfAThirdClientsEdit) {
    auto client = proxy();
    ASSERT_EQ(client.Post("/api/scenes?id=shared", kSmallScene.dump(), "application/json")->status, 201);
    std::vector<std::unique_ptr<WsClient>> viewers;
    viewers.push_back(std::make_unique<WsClient>(replicas_[0]->port(), "/api/scenes/shared/ws"));
    viewers.push_back(std::make_unique<WsClient>(replicas_[1]->port(), "/api/scenes/shared/ws"));
    // Browsers are told to upgrade through the proxy's one port, not the replica's WebSocket port.
    EXPECT_EQ(json::parse(client.Get("/api/health")->body).value("ws_on_http_port", false), true);
    EXPECT_FALSE(json::parse(health_of(replicas_[0]->port())).contains("ws_on_http_port"));
    // And one through HAProxy, on its one port: the upgrade is routed by the same hash.
    viewers.push_back(std::make_unique<WsClient>(haproxy_->port(), "/api/scenes/shared/ws"));
    for (auto& viewer : viewers) {
        viewer->send({{"seq", "hello"}, {"refine", 0}});
        EXPECT_EQ(viewer->read_frame().first["revision"], 1);
    }
    auto third = client_for(replicas_[2]->port());
    json answer;
    ASSERT_EQ(patch(third, "shared", {{"light", {{"position", {-2, 3, 1}}, {"direction", {2, -3, -1}}}}}, &answer), 200);
    ASSERT_EQ(answer["revision"], 2);
    for (auto& viewer : viewers) {
        auto [header, png] = viewer->read_frame();
        EXPECT_EQ(header["revision"], 2) << header.dump();
        EXPECT_EQ(header["seq"], nullptr);  // nobody on this session asked: pushed
        EXPECT_GT(png.size(), 8u);
    }
}

TEST_F(ScaleOut, MeshesAndIndexGridsUploadedToOneReplicaRenderOnTheOthers) {
    auto r1 = client_for(replicas_[0]->port());
    auto r2 = client_for(replicas_[1]->port());
    auto r3 = client_for(replicas_[2]->port());
    const std::string tetrahedron = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";
    auto uploaded = r1.Put("/api/meshes/tet", tetrahedron, "text/plain");
    ASSERT_TRUE(uploaded);
    ASSERT_EQ(uploaded->status, 201) << uploaded->body;
    json document = kSmallScene;
    document["object"] = {{"mesh", "upload:tet"}};
    auto created = r2.Post("/api/scenes?id=assets", document.dump(), "application/json");
    ASSERT_TRUE(created);
    ASSERT_EQ(created->status, 201) << created->body;
    auto meshes = r3.Get("/api/meshes");
    ASSERT_TRUE(meshes);
    EXPECT_NE(meshes->body.find("\"tet\""), std::string::npos) << meshes->body;
    auto frame = r3.Get("/api/scenes/assets/frame.png");
    ASSERT_TRUE(frame);
    EXPECT_EQ(frame->status, 200) << frame->body;

    // A re-upload through another replica changes the frame without a new revision: the replica holding
    // the scene drops its cached frame when the announcement arrives and voxelizes again.
    const std::string bigger = "v 0 0 0\nv 2 0 0\nv 0 2 0\nv 0 0 2\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";
    ASSERT_EQ(r2.Put("/api/meshes/tet", bigger, "text/plain")->status, 201);
    frame = fresh_frame(r3, "assets");
    ASSERT_TRUE(frame);
    EXPECT_NE(frame->get_header_value("X-Refract-Passes").find("voxelize"), std::string::npos)
        << frame->get_header_value("X-Refract-Passes");

    // An index grid (a simulation's field) stored through one replica, rendered by another.
    constexpr uint32_t n = 8;
    std::vector<float> values(n * n * n);
    for (size_t i = 0; i < values.size(); ++i) values[i] = 1.0f + 0.05f * static_cast<float>(i % n);
    std::string body(reinterpret_cast<const char*>(values.data()), values.size() * sizeof(float));
    auto put = r1.Put("/api/scenes/assets/index-field?nx=8&ny=8&nz=8&min=-1,-1,-1&max=1,1,1", body,
                      "application/octet-stream");
    ASSERT_TRUE(put);
    ASSERT_EQ(put->status, 200) << put->body;
    EXPECT_EQ(json::parse(put->body)["revision"], 2);
    frame = r2.Get("/api/scenes/assets/frame.png");
    ASSERT_TRUE(frame);
    EXPECT_EQ(frame->status, 200) << frame->body;
    EXPECT_EQ(frame->get_header_value("X-Refract-Revision"), "2");
}

TEST_F(ScaleOut, EnvironmentsUploadedToOneReplicaLightScenesOnTheOthers) {
    auto r1 = client_for(replicas_[0]->port());
    auto r2 = client_for(replicas_[1]->port());
    auto r3 = client_for(replicas_[2]->port());
    // A flat 8 x 4 Radiance file: every pixel RGBE (128, 128, 128, 129), radiance 1.
    auto hdr = [](unsigned char exponent) {
        std::string bytes = "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 4 +X 8\n";
        for (int i = 0; i < 32; ++i) bytes += std::string{'\x80', '\x80', '\x80', static_cast<char>(exponent)};
        return bytes;
    };
    auto uploaded = r1.Put("/api/environments/studio", hdr(129), "image/vnd.radiance");
    ASSERT_TRUE(uploaded);
    ASSERT_EQ(uploaded->status, 201) << uploaded->body;
    json document = kSmallScene;
    document["environment"] = {{"type", "image"}, {"image", "studio"}};
    auto created = r2.Post("/api/scenes?id=lit", document.dump(), "application/json");
    ASSERT_TRUE(created);
    ASSERT_EQ(created->status, 201) << created->body;
    document["environment"]["image"] = "nowhere";
    auto refused = r2.Post("/api/scenes?id=unlit", document.dump(), "application/json");
    ASSERT_TRUE(refused);
    EXPECT_EQ(refused->status, 422) << refused->body;
    auto listed = r3.Get("/api/environments");
    ASSERT_TRUE(listed);
    EXPECT_NE(listed->body.find("\"studio\""), std::string::npos) << listed->body;
    auto frame = r3.Get("/api/scenes/lit/frame.png");
    ASSERT_TRUE(frame);
    EXPECT_EQ(frame->status, 200) << frame->body;
    // A re-upload through another replica relights the scene without a new revision.
    ASSERT_EQ(r2.Put("/api/environments/studio", hdr(130), "image/vnd.radiance")->status, 201);
    frame = fresh_frame(r3, "lit");
    ASSERT_TRUE(frame);
    EXPECT_NE(frame->get_header_value("X-Refract-Passes").find("photons"), std::string::npos)
        << frame->get_header_value("X-Refract-Passes");
}

// Deleting uploads in the shared store: refused through any replica while a scene uses them (409 naming
// it), then gone for every replica, and the scene's own grid deleted with its document unchanged.
TEST_F(ScaleOut, UploadsDeletedThroughOneReplicaAreGoneForAll) {
    auto r1 = client_for(replicas_[0]->port());
    auto r2 = client_for(replicas_[1]->port());
    auto r3 = client_for(replicas_[2]->port());
    const std::string tetrahedron = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";
    ASSERT_EQ(r1.Put("/api/meshes/doomed", tetrahedron, "text/plain")->status, 201);
    json document = kSmallScene;
    document["object"] = {{"mesh", "upload:doomed"}};
    ASSERT_EQ(r2.Post("/api/scenes?id=user", document.dump(), "application/json")->status, 201);
    ASSERT_EQ(r3.Get("/api/scenes/user/frame.png")->status, 200);  // held decoded by r3 now

    auto refused = r3.Delete("/api/meshes/doomed");
    ASSERT_TRUE(refused);
    EXPECT_EQ(refused->status, 409) << refused->body;
    EXPECT_EQ(json::parse(refused->body)["scenes"], json::array({"user"})) << refused->body;
    EXPECT_NE(r1.Get("/api/meshes")->body.find("\"doomed\""), std::string::npos);

    const json sphere = {{"object", {{"mesh", "sphere"}}}};
    ASSERT_EQ(r1.Patch("/api/scenes/user", sphere.dump(), "application/merge-patch+json")->status, 200);
    auto deleted = r2.Delete("/api/meshes/doomed");
    ASSERT_TRUE(deleted);
    EXPECT_EQ(deleted->status, 204) << deleted->body;
    for (auto* replica : {&r1, &r2, &r3}) {
        EXPECT_EQ(replica->Get("/api/meshes")->body.find("\"doomed\""), std::string::npos);
        EXPECT_EQ(replica->Delete("/api/meshes/doomed")->status, 404);
    }
    // Nothing of it is left: a scene that names it again cannot render, on any replica.
    auto renamed = r3.Patch("/api/scenes/user", json{{"object", {{"mesh", "upload:doomed"}}}}.dump(),
                            "application/merge-patch+json");
    ASSERT_TRUE(renamed);
    ASSERT_EQ(renamed->status, 200) << renamed->body;
    EXPECT_EQ(r1.Get("/api/scenes/user/frame.png")->status, 422);
}

TEST_F(ScaleOut, VolumesUploadedToOneReplicaAreListedAndDeletedOnAll) {
    auto r1 = client_for(replicas_[0]->port());
    auto r2 = client_for(replicas_[1]->port());
    auto r3 = client_for(replicas_[2]->port());
    auto uploaded = r1.Put("/api/volumes/smoke", density_sphere_vdb(4, true), "application/octet-stream");
    ASSERT_TRUE(uploaded);
    ASSERT_EQ(uploaded->status, 201) << uploaded->body;
    auto refused = r2.Put("/api/volumes/smoke", density_with_value_vdb(-1.0f), "application/octet-stream");
    ASSERT_TRUE(refused);
    EXPECT_EQ(refused->status, 400) << refused->body;
    EXPECT_NE(refused->body.find("grid 'density' holds a negative value"), std::string::npos) << refused->body;
    // The refused upload left the first one as it was, for every replica.
    const json listed = json::parse(r3.Get("/api/volumes")->body)["volumes"];
    ASSERT_EQ(listed.size(), 1u) << listed;
    EXPECT_EQ(listed[0], json::parse(uploaded->body));
    // A scene names it through another replica, renders it on a third, and keeps it from deletion; one that
    // names a volume none holds is refused at its pointer.
    json scene = {{"image", {{"width", 32}, {"height", 32}}}, {"volume", {{"resolution", 32}}},
                  {"photons", {{"count", 4096}}}, {"volumes", {{"puff", {{"asset", "smoke"}}}}}};
    ASSERT_EQ(r2.Post("/api/scenes?id=smoky", scene.dump(), "application/json")->status, 201);
    scene["volumes"]["puff"]["asset"] = "cloud";
    auto unknown = r3.Post("/api/scenes?id=cloudy", scene.dump(), "application/json");
    ASSERT_TRUE(unknown);
    EXPECT_EQ(unknown->status, 422) << unknown->body;
    EXPECT_EQ(json::parse(unknown->body)["pointer"], "/volumes/puff/asset");
    auto frame = r3.Get("/api/scenes/smoky/frame.png");
    ASSERT_TRUE(frame);
    EXPECT_EQ(frame->status, 200) << frame->body;
    // A re-upload through another replica changes the frame without a new revision: the replica holding
    // the scene drops its cached frame when the announcement arrives and renders the new volume.
    ASSERT_EQ(r1.Put("/api/volumes/smoke", density_sphere_vdb(6), "application/octet-stream")->status, 201);
    auto again = fresh_frame(r3, "smoky");
    ASSERT_TRUE(again);
    EXPECT_EQ(again->status, 200) << again->body;
    EXPECT_NE(again->body, frame->body) << "the replica kept the frame of the volume replaced";
    EXPECT_EQ(r1.Delete("/api/volumes/smoke")->status, 409);
    ASSERT_EQ(r1.Patch("/api/scenes/smoky", R"({"volumes": null})", "application/merge-patch+json")->status, 200);
    auto deleted = r2.Delete("/api/volumes/smoke");
    ASSERT_TRUE(deleted);
    EXPECT_EQ(deleted->status, 204) << deleted->body;
    for (auto* replica : {&r1, &r2, &r3}) {
        EXPECT_TRUE(json::parse(replica->Get("/api/volumes")->body)["volumes"].empty());
        EXPECT_EQ(replica->Delete("/api/volumes/smoke")->status, 404);
    }
}

TEST_F(ScaleOut, ConnectionsCutMidEditNeitherLoseNorInventAnEdit) {
    auto client = client_for(replicas_[0]->port());
    ASSERT_EQ(client.Post("/api/scenes?id=cut", kSmallScene.dump(), "application/json")->status, 201);
    // Every refractd connection to the database is cut, again and again, while one writer edits: some
    // edits lose their connection before, during or after the commit.
    std::atomic<bool> stop{false};
    std::thread cutter([&] {
        while (!stop) {
            sql(database_url("scaleout"),
                "SELECT pg_terminate_backend(pid) FROM pg_stat_activity WHERE application_name = 'refractd'");
            std::this_thread::sleep_for(std::chrono::milliseconds(5));
        }
    });
    uint64_t acknowledged = 0, last_revision = 1;
    double last_exposure = 0.5;
    std::vector<double> unknown_since_last;  // answered "unknown" after the last acknowledgement
    size_t unknown = 0, refused = 0;
    auto until = Clock::now() + std::chrono::seconds(3);
    for (int n = 1; Clock::now() < until; ++n) {
        const double exposure = 0.001 * n;
        json answer;
        int status = patch(client, "cut", {{"image", {{"exposure", exposure}}}}, &answer);
        if (status == 200) {
            ++acknowledged;
            EXPECT_GT(answer["revision"].get<uint64_t>(), last_revision);
            last_revision = answer["revision"];
            last_exposure = exposure;
            unknown_since_last.clear();
            continue;
        }
        ASSERT_EQ(status, 503) << answer.dump();
        if (answer.value("error", "").find("unknown") != std::string::npos) {
            ++unknown;
            unknown_since_last.push_back(exposure);
        } else {
            ++refused;  // not applied: failed before the update, or found not committed
        }
    }
    stop = true;
    cutter.join();
    // A server process told to end a moment ago may still be closing its connection.
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
    json scene;
    for (auto deadline = Clock::now() + std::chrono::seconds(10); Clock::now() < deadline && scene.is_null();)
        scene = get_scene(client, "cut");
    ASSERT_FALSE(scene.is_null());
    const uint64_t revision = scene["revision"];
    // Every acknowledged edit is there, and nothing answered "not applied" is: only the edits whose
    // outcome was answered as unknown may add revisions.
    EXPECT_GE(revision - 1, acknowledged);
    EXPECT_LE(revision - 1, acknowledged + unknown);
    const double exposure = scene["scene"]["image"]["exposure"];
    if (revision == last_revision) {
        EXPECT_DOUBLE_EQ(exposure, last_exposure);
    } else {
        EXPECT_NE(std::find(unknown_since_last.begin(), unknown_since_last.end(), exposure), unknown_since_last.end());
    }
    EXPECT_GT(acknowledged, 0u);
    EXPECT_GT(refused + unknown, 0u) << "no connection was cut mid-edit: the test proved nothing";
    std::cerr << "cut connections: " << acknowledged << " edits acknowledged, " << refused << " not applied, "
              << unknown << " unknown; revision " << revision << "\n";
}

TEST_F(ScaleOut, ASceneDeletedAndCreatedAgainThroughAnotherReplicaIsNotAnsweredFromTheOldOne) {
    auto r1 = client_for(replicas_[0]->port());
    auto r2 = client_for(replicas_[1]->port());
    ASSERT_EQ(r1.Post("/api/scenes?id=again", kSmallScene.dump(), "application/json")->status, 201);
    auto first = r1.Get("/api/scenes/again/frame.png");
    ASSERT_TRUE(first && first->status == 200);
    auto deleted = r2.Delete("/api/scenes/again");
    ASSERT_TRUE(deleted);
    ASSERT_EQ(deleted->status, 204);
    json other = kSmallScene;
    other["image"]["exposure"] = 3.0;  // the same id and revision 1, another document
    ASSERT_EQ(r2.Post("/api/scenes?id=again", other.dump(), "application/json")->status, 201);
    auto frame = fresh_frame(r1, "again");
    ASSERT_TRUE(frame);
    EXPECT_NE(frame->body, first->body);
}

TEST_F(ScaleOut, TheDatabaseGoingAwayAnswers503WithAReasonLosesNothingAndRecovers) {
    auto client = client_for(replicas_[0]->port());
    ASSERT_EQ(client.Post("/api/scenes?id=outage", kSmallScene.dump(), "application/json")->status, 201);
    json answer;
    ASSERT_EQ(patch(client, "outage", {{"image", {{"exposure", 1.0}}}}, &answer), 200);
    ASSERT_EQ(answer["revision"], 2);

    WsClient viewer(replicas_[0]->port(), "/api/scenes/outage/ws");
    viewer.send({{"seq", 1}, {"refine", 0}});
    EXPECT_EQ(viewer.read_frame().first["revision"], 2);

    pg_ctl("stop -m fast");
    // A WebSocket edit is refused with the reason and the session stays open; a new session is refused.
    viewer.send({{"seq", 2}, {"patch", {{"image", {{"exposure", 2.5}}}}}});
    json refusal = json::parse(viewer.read().second);
    EXPECT_EQ(refusal["type"], "error");
    EXPECT_NE(refusal.value("error", "").find("scene store unavailable"), std::string::npos) << refusal.dump();
    EXPECT_THROW(WsClient(replicas_[0]->port(), "/api/scenes/outage/ws"), boost::system::system_error);
    int status = patch(client, "outage", {{"image", {{"exposure", 2.0}}}}, &answer);
    EXPECT_EQ(status, 503);
    EXPECT_NE(answer.value("error", "").find("scene store unavailable"), std::string::npos) << answer.dump();
    auto get = client.Get("/api/scenes/outage");
    ASSERT_TRUE(get);
    EXPECT_EQ(get->status, 503) << get->body;
    json health = json::parse(client.Get("/api/health")->body);
    EXPECT_EQ(health["status"], "degraded");
    EXPECT_TRUE(health.contains("store_error")) << health.dump();

    pg_ctl("start");
    // Every edit answered 200 is applied, every other one is not: the revision counts the 200s.
    uint64_t acknowledged = 2;
    double last_exposure = 1.0;
    auto deadline = Clock::now() + std::chrono::seconds(20);
    while (Clock::now() < deadline && acknowledged < 4) {
        double exposure = 3.0 + double(acknowledged);
        status = patch(client, "outage", {{"image", {{"exposure", exposure}}}}, &answer);
        if (status == 200) {
            ++acknowledged;
            last_exposure = exposure;
            EXPECT_EQ(answer["revision"], acknowledged);
        } else {
            EXPECT_EQ(status, 503) << answer.dump();
            std::this_thread::sleep_for(std::chrono::milliseconds(200));
        }
    }
    ASSERT_EQ(acknowledged, 4u) << "no recovery within 20 s";
    json scene = get_scene(client, "outage");
    EXPECT_EQ(scene["revision"], 4);
    EXPECT_EQ(scene["scene"]["image"]["exposure"], last_exposure);
    EXPECT_EQ(json::parse(client.Get("/api/health")->body)["status"], "ok");
    EXPECT_TRUE(replicas_[0]->running());
}

TEST_F(ScaleOut, TwentyScenesSurviveAReplicaKilledDuringAPatchBurst) {
    auto client = proxy();
    constexpr size_t kScenes = 20;
    auto name = [](size_t i) { return "scene-" + std::to_string(i); };
    for (size_t i = 0; i < kScenes; ++i)
        ASSERT_EQ(client.Post("/api/scenes?id=" + name(i), kSmallScene.dump(), "application/json")->status, 201);
    for (size_t i = 0; i < kScenes; ++i) {
        auto frame = client.Get("/api/scenes/" + name(i) + "/frame.png");
        ASSERT_TRUE(frame);
        ASSERT_EQ(frame->status, 200) << frame->body;
    }

    // Each scene is edited by one writer at a time, each edit a new exposure: the revision an edit was
    // acknowledged with must hold that exposure afterwards.
    struct Edits {
        uint64_t acknowledged_revision = 1;
        double acknowledged_exposure = 0.5;
        std::vector<double> unanswered;  // sent after the last acknowledgement, answered otherwise
        int refused = 0;
    };
    std::vector<Edits> edits(kScenes);
    std::atomic<bool> stop{false};
    std::vector<std::thread> writers;
    for (size_t w = 0; w < 4; ++w) {
        writers.emplace_back([&, w] {
            auto writer = proxy();
            for (size_t n = 0; !stop; ++n) {
                size_t i = w + 4 * (n % (kScenes / 4));
                double exposure = 0.001 * double(n + 1) + 0.1 * double(w);
                json answer;
                int status = patch(writer, name(i), {{"image", {{"exposure", exposure}}}}, &answer);
                if (status == 200) {
                    EXPECT_GT(answer["revision"].get<uint64_t>(), edits[i].acknowledged_revision);
                    edits[i].acknowledged_revision = answer["revision"].get<uint64_t>();
                    edits[i].acknowledged_exposure = exposure;
                    edits[i].unanswered.clear();
                } else {
                    edits[i].unanswered.push_back(exposure);  // a 502 (replica died mid-request), a 503
                    ++edits[i].refused;
                }
            }
        });
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(1500));
    replicas_[1]->kill9();
    std::this_thread::sleep_for(std::chrono::milliseconds(1500));
    stop = true;
    for (auto& writer : writers) writer.join();

    auto killed_at = Clock::now();
    std::vector<bool> answered(kScenes, false);
    size_t remaining = kScenes;
    while (remaining > 0 && Clock::now() - killed_at < std::chrono::seconds(10)) {
        for (size_t i = 0; i < kScenes; ++i) {
            if (answered[i]) continue;
            json scene = get_scene(client, name(i));
            if (scene.is_null()) continue;
            auto frame = client.Get("/api/scenes/" + name(i) + "/frame.png");
            if (!frame || frame->status != 200) continue;
            EXPECT_EQ(frame->get_header_value("X-Refract-Revision"), std::to_string(scene["revision"].get<uint64_t>()));
            const Edits& e = edits[i];
            const uint64_t revision = scene["revision"];
            const double exposure = scene["scene"]["image"]["exposure"];
            if (revision == e.acknowledged_revision) {
                EXPECT_DOUBLE_EQ(exposure, e.acknowledged_exposure) << name(i);
            } else {
                // Only the one edit in flight when its replica died may have committed unanswered.
                EXPECT_EQ(revision, e.acknowledged_revision + 1) << name(i);
                EXPECT_NE(std::find(e.unanswered.begin(), e.unanswered.end(), exposure), e.unanswered.end())
                    << name(i) << " holds exposure " << exposure << ", never sent after its last acknowledgement";
            }
            answered[i] = true;
            --remaining;
        }
    }
    double seconds = std::chrono::duration<double>(Clock::now() - killed_at).count();
    EXPECT_EQ(remaining, 0u) << "scenes not answering through HAProxy 10 s after the burst";
    uint64_t acknowledged = 0;
    int refused = 0;
    for (const Edits& e : edits) {
        acknowledged += e.acknowledged_revision - 1;
        refused += e.refused;
    }
    std::cerr << "burst: " << acknowledged << " edits acknowledged, " << refused
              << " refused or lost with the replica; all " << kScenes << " scenes answered with their last revision "
              << seconds << " s after the burst\n";
}

}  // namespace
}  // namespace refract::test
