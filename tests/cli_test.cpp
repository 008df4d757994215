// The refract binary's command line: each bad argument is refused in one line that names it (exit 2)
// before a scene is rendered or a device started; help and --version answer without a device.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <ostream>
#include <string>
#include <vector>

extern char** environ;

namespace {

namespace fs = std::filesystem;

// What a run of refract printed and how it ended.
struct Outcome {
    int status = -1;  // exit status; -1: killed by a signal
    std::string out, err;
};

std::string read_file(const fs::path& path) {
    std::ifstream in(path);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// Runs refract with `args` where the Vulkan loader finds no driver: a command line that got as far as
// a device fails with a device error (exit 1), never with the usage errors these tests expect.
Outcome run_refract(const std::vector<std::string>& args) {
    const fs::path dir = fs::temp_directory_path() / ("refract_cli_test_" + std::to_string(::getpid()));
    fs::create_directories(dir);
    const std::string out_path = (dir / "stdout").string(), err_path = (dir / "stderr").string();

    std::vector<std::string> env_strings = {"VK_ICD_FILENAMES=/nonexistent/refract_no_icd.json",
                                            "VK_DRIVER_FILES=/nonexistent/refract_no_icd.json"};
    for (char** e = environ; *e != nullptr; ++e) {
        const std::string entry = *e;
        if (!entry.starts_with("VK_ICD_FILENAMES=") && !entry.starts_with("VK_DRIVER_FILES=") &&
            !entry.starts_with("VK_ADD_DRIVER_FILES="))
            env_strings.push_back(entry);
    }
    std::vector<std::string> argv_strings = {REFRACT_PATH};
    argv_strings.insert(argv_strings.end(), args.begin(), args.end());
    auto pointers = [](std::vector<std::string>& strings) {
        std::vector<char*> p;
        for (auto& s : strings) p.push_back(s.data());
        p.push_back(nullptr);
        return p;
    };
    std::vector<char*> argv = pointers(argv_strings), envp = pointers(env_strings);

    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, out_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC,
                                     0644);
    posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, err_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC,
                                     0644);
    pid_t pid = 0;
    const int error = posix_spawn(&pid, REFRACT_PATH, &actions, nullptr, argv.data(), envp.data());
    posix_spawn_file_actions_destroy(&actions);
    Outcome run;
    if (error != 0) {
        ADD_FAILURE() << "cannot spawn " << REFRACT_PATH;
        return run;
    }
    int wait_status = 0;
    ::waitpid(pid, &wait_status, 0);
    if (WIFEXITED(wait_status)) run.status = WEXITSTATUS(wait_status);
    run.out = read_file(out_path);
    run.err = read_file(err_path);
    fs::remove_all(dir);
    return run;
}

const std::string kScene = REFRACT_SOURCE_DIR "/examples/luneburg.json";
const std::string kExamples = REFRACT_SOURCE_DIR "/examples";

// A command line refract must refuse, and the line it must print.
struct BadLine {
    std::string name;
    std::vector<std::string> args;
    std::string message;
};

// How ctest and failures show a case: its command line.
void PrintTo(const BadLine& line, std::ostream* out) {
    *out << "refract";
    for (const auto& arg : line.args) *out << " " << arg;
}

class BadArguments : public testing::TestWithParam<BadLine> {};

TEST_P(BadArguments, RefusedInOneLineNamingTheArgumentWithStatus2) {
    const BadLine& line = GetParam();
    const Outcome run = run_refract(line.args);
    EXPECT_EQ(run.status, 2);
    EXPECT_EQ(run.err, line.message + "\n");
    EXPECT_EQ(run.out, "");
}

const BadLine kBadLines[] = {
    // Numbers
    {"RunsNotANumber", {"bench", "--runs", "abc"}, "refract: --runs: 'abc' is not a whole number"},
    {"RunsFraction", {"bench", "--runs", "2.5"}, "refract: --runs: '2.5' is not a whole number"},
    {"RunsNegative", {"bench", "--runs", "-3"}, "refract: --runs: '-3' must be between 1 and 1000"},
    {"RunsZero", {"bench", "--runs=0"}, "refract: --runs: '0' must be between 1 and 1000"},
    {"RunsHuge",
     {"bench", "--runs", "99999999999999999999"},
     "refract: --runs: '99999999999999999999' must be between 1 and 1000"},
    {"DaemonPortNotANumber",
     {"bench", "--daemon", "localhost:http"},
     "refract: --daemon port: 'http' is not a whole number"},
    {"DaemonPortOutOfRange",
     {"bench", "--daemon", "localhost:70000"},
     "refract: --daemon port: '70000' must be between 1 and 65535"},
    {"DaemonWithoutPort",
     {"bench", "--daemon", "localhost"},
     "refract: --daemon: 'localhost' must be HOST:PORT"},
    // Files read
    {"SceneIsADirectory",
     {"render", kExamples, "-o", "x.png"},
     "refract: SCENE.json '" + kExamples + "' is a directory"},
    {"SceneMissing",
     {"voxelize", "no-such-scene.json", "--out", "slices"},
     "refract: SCENE.json 'no-such-scene.json' does not exist"},
    {"SceneNotGiven",
     {"render", "-o", "x.png"},
     "refract: render needs SCENE.json (- for the default scene)"},
    {"BenchSceneIsADirectory",
     {"bench", "--scene", kExamples},
     "refract: --scene: '" + kExamples + "' is a directory"},
    {"MeshMissing",
     {"render", "-", "-o", "x.png", "--mesh", "bunny=no-such.obj"},
     "refract: --mesh: 'no-such.obj' does not exist"},
    {"MeshWithoutName",
     {"render", "-", "-o", "x.png", "--mesh", "bunny.obj"},
     "refract: --mesh: 'bunny.obj' must be NAME=FILE.obj"},
    {"MeshWithoutFile", {"bench", "--mesh", "bunny="}, "refract: --mesh: 'bunny=' must be NAME=FILE.obj"},
    // Files written
    {"FrameNotPng", {"render", kScene, "-o", "x.jpg"}, "refract: -o: 'x.jpg' must end in .png"},
    {"FrameNotPngLong", {"render", kScene, "--out=x.jpg"}, "refract: --out: 'x.jpg' must end in .png"},
    {"HdrNotPfm",
     {"render", kScene, "-o", "x.png", "--hdr", "x.exr"},
     "refract: --hdr: 'x.exr' must end in .pfm"},
    {"StatsNotJson",
     {"render", kScene, "-o", "x.png", "--stats", "stats.txt"},
     "refract: --stats: 'stats.txt' must end in .json"},
    {"FrameDirectoryMissing",
     {"render", kScene, "-o", "/nonexistent-refract-dir/x.png"},
     "refract: -o: directory '/nonexistent-refract-dir' does not exist"},
    {"StatsDirectoryMissing",
     {"render", kScene, "-o", "x.png", "--stats", "/nonexistent-refract-dir/s.json"},
     "refract: --stats: directory '/nonexistent-refract-dir' does not exist"},
    {"OutDirThroughAFile",
     {"trace", kScene, "--out", kScene + "/slices"},
     "refract: --out: '" + kScene + "' is not a directory"},
    {"FrameNotGiven", {"render", kScene}, "refract: render needs -o FRAME.png"},
    {"OutDirNotGiven", {"voxelize", kScene}, "refract: voxelize needs --out DIR"},
    // Positionals and options
    {"StrayPositional",
     {"render", kScene, "other.json", "-o", "x.png"},
     "refract: unexpected argument 'other.json' (render takes one SCENE.json)"},
    {"StrayPositionalBench",
     {"bench", "standard"},
     "refract: unexpected argument 'standard' (bench takes only options)"},
    {"StrayPositionalDevices",
     {"devices", "all"},
     "refract: unexpected argument 'all' (devices takes only options)"},
    {"UnknownOption",
     {"render", kScene, "-o", "x.png", "--fast"},
     "refract: unknown option '--fast' for render (see refract help render)"},
    {"OptionOfAnotherCommand",
     {"render", kScene, "-o", "x.png", "--runs", "3"},
     "refract: unknown option '--runs' for render (see refract help render)"},
    {"OptionBeforeCommand",
     {"--runs", "3", "bench"},
     "refract: unknown option '--runs' (options follow the command; see refract help)"},
    {"ValueMissingAtEnd", {"render", kScene, "-o"}, "refract: -o needs a value (FRAME.png)"},
    {"ValueMissingBeforeOption", {"bench", "--runs", "--json"}, "refract: --runs needs a value (N)"},
    {"SwitchWithValue", {"bench", "--json=yes"}, "refract: --json takes no value"},
    {"QualityUnknown",
     {"render", "-", "-o", "x.png", "--quality", "fast"},
     "refract: --quality: 'fast' must be still or interactive"},
    {"SuiteUnknown", {"bench", "--suite", "big"}, "refract: --suite: 'big' must be standard"},
    {"CaseWithScene",
     {"bench", "--scene", kScene, "--case", "target"},
     "refract: --case: not with --scene (one scene has no suite)"},
    {"SceneWithDaemon",
     {"bench", "--scene", kScene, "--daemon", "localhost:8080"},
     "refract: --scene: not with --daemon"},
    // animate
    {"KeyframesNotGiven", {"animate", kScene, "-o", "frames"}, "refract: animate needs KEYFRAMES.json"},
    {"VolumeNameInvalid",
     {"render", kScene, "-o", "x.png", "--volume", "a b=" + kScene},
     "refract: --volume: the name in 'a b=" + kScene + "' must match [A-Za-z0-9_.-]{1,64}"},
    {"KeyframesIsADirectory",
     {"animate", kScene, kExamples, "-o", "frames"},
     "refract: KEYFRAMES.json '" + kExamples + "' is a directory"},
    {"AnimateOutNotGiven", {"animate", kScene, kScene}, "refract: animate needs -o DIR"},
    {"FpsZero", {"animate", kScene, kScene, "-o", "frames", "--fps", "0"}, "refract: --fps: '0' must be between 1 and 240"},
    {"FpsNotANumber",
     {"animate", kScene, kScene, "-o", "frames", "--fps", "fast"},
     "refract: --fps: 'fast' is not a whole number"},
    {"StrayPositionalAnimate",
     {"animate", kScene, kScene, kScene, "-o", "frames"},
     "refract: unexpected argument '" + kScene + "' (animate takes SCENE.json and KEYFRAMES.json)"},
    {"UnknownCommand", {"draw"}, "refract: unknown command 'draw' (see refract help)"},
    {"HelpForUnknownCommand", {"help", "draw"}, "refract: unknown command 'draw' (see refract help)"},
    {"HelpWithTwoCommands",
     {"help", "render", "bench"},
     "refract: unexpected argument 'bench' after help render"},
    {"VersionWithMore", {"--version", "render"}, "refract: unexpected argument 'render' after --version"},
};

INSTANTIATE_TEST_SUITE_P(Cli, BadArguments, testing::ValuesIn(kBadLines),
                         [](const testing::TestParamInfo<BadLine>& param) { return param.param.name; });

TEST(Cli, VersionIsTheProjectVersion) {
    const Outcome run = run_refract({"--version"});
    EXPECT_EQ(run.status, 0);
    EXPECT_EQ(run.out, "refract " REFRACT_VERSION "\n");
    EXPECT_EQ(run.err, "");
}

TEST(Cli, HelpCommandAndCommandHelpPrintTheSameUsage) {
    for (const std::string command : {"devices", "voxelize", "trace", "render", "bench"}) {
        SCOPED_TRACE(command);
        const Outcome help = run_refract({"help", command});
        EXPECT_EQ(help.status, 0);
        EXPECT_EQ(help.err, "");
        EXPECT_TRUE(help.out.starts_with("usage: refract " + command)) << help.out;
        EXPECT_NE(help.out.find("-h, --help"), std::string::npos) << help.out;
        for (const std::string flag : {"--help", "-h"}) {
            const Outcome run = run_refract({command, flag});
            EXPECT_EQ(run.status, 0);
            EXPECT_EQ(run.out, help.out);
            EXPECT_EQ(run.err, "");
        }
    }
}

TEST(Cli, RenderHelpListsItsOptions) {
    const Outcome run = run_refract({"help", "render"});
    EXPECT_EQ(run.status, 0);
    EXPECT_TRUE(run.out.starts_with("usage: refract render SCENE.json -o FRAME.png")) << run.out;
    for (const std::string option : {"-o, --out FRAME.png", "--hdr FRAME.pfm", "--stats STATS.json",
                                     "--quality still|interactive", "--mesh NAME=FILE.obj", "--device NAME"})
        EXPECT_NE(run.out.find("\n  " + option + " "), std::string::npos) << option << " in\n" << run.out;
    EXPECT_EQ(run.out.find("--runs"), std::string::npos) << run.out;
}

TEST(Cli, HelpAnswersBeforeTheOtherArgumentsAreChecked) {
    const Outcome help = run_refract({"help", "render"});
    const Outcome run = run_refract({"render", "no-such-scene.json", "-o", "x.jpg", "--help"});
    EXPECT_EQ(run.status, 0);
    EXPECT_EQ(run.out, help.out);
}

TEST(Cli, OverviewListsEveryCommand) {
    const Outcome help = run_refract({"help"});
    EXPECT_EQ(help.status, 0);
    EXPECT_TRUE(help.out.starts_with("usage: refract COMMAND")) << help.out;
    for (const std::string command : {"devices", "voxelize", "trace", "render", "animate", "bench", "help"})
        EXPECT_NE(help.out.find("\n  " + command + " "), std::string::npos) << command;
    EXPECT_EQ(run_refract({"--help"}).out, help.out);
    EXPECT_EQ(run_refract({"help", "help"}).out, help.out);
    const Outcome bare = run_refract({});
    EXPECT_EQ(bare.status, 2);  // a command is missing
    EXPECT_EQ(bare.out, help.out);
}

// Good command lines get past the checks to the device, which these runs do not have (exit 1): the
// checks refuse nothing that was good before them.
TEST(Cli, GoodArgumentsReachTheDevice) {
    const fs::path dir = fs::temp_directory_path() / ("refract_cli_good_" + std::to_string(::getpid()));
    fs::create_directories(dir);
    const std::string frame = (dir / "frame.PNG").string(), slices = (dir / "new" / "slices").string();
    const std::string keyframes = (dir / "keyframes.json").string();
    std::ofstream(keyframes) << R"([{"time": 0, "patch": {}}, {"time": 1, "patch": {"light": {"intensity": 5}}}])";
    const std::vector<std::vector<std::string>> lines = {
        {"render", kScene, "-o", frame, "--hdr", (dir / "frame.pfm").string(), "--stats",
         (dir / "s.json").string(), "--quality", "interactive", "--device", "none"},
        {"render", "-", "--out=" + frame, "--mesh", "bunny=" REFRACT_SOURCE_DIR "/examples/meshes/bunny.obj"},
        {"render", REFRACT_SOURCE_DIR "/examples/gltf/glass_shelf.glb", "-o", (dir / "frame.exr").string()},
        {"voxelize", kScene, "--out", slices},
        {"trace", "-", "-o", slices},
        {"animate", kScene, keyframes, "-o", slices, "--fps", "2"},
        {"bench", "--case", "target", "--runs", "1000", "--json"},
        {"bench", "--scene", kScene, "--runs=1", "--json"},
        {"devices"},
    };
    for (const auto& line : lines) {
        SCOPED_TRACE(line[0] + " " + line[1 % line.size()]);
        const Outcome run = run_refract(line);
        EXPECT_EQ(run.status, 1) << run.err;
        EXPECT_NE(run.err.find("VK_ERROR_"), std::string::npos) << run.err;  // from Vulkan, not the checks
    }
    EXPECT_FALSE(fs::exists(frame));
    fs::remove_all(dir);
}

// A keyframe file that is not a valid animation is refused with the pointer of the bad keyframe (exit 1),
// before a device starts or a frame is written.
TEST(Cli, AnimateRefusesBadKeyframesBeforeTheDevice) {
    const fs::path dir = fs::temp_directory_path() / ("refract_cli_keys_" + std::to_string(::getpid()));
    fs::create_directories(dir);
    const std::pair<std::string, std::string> cases[] = {
        {R"([{"time": 2, "patch": {}}, {"time": 1, "patch": {}}])", "/1/time: must be later than the keyframe before it"},
        {R"([{"time": 0, "patch": {"object": {"ior": 0}}}])", "/0/patch/object/ior"},
        {R"({"time": 0})", "keyframes must be a list"},
        {R"([{"time": 0, "patch": {}})", "not valid JSON"},
    };
    for (const auto& [text, expected] : cases) {
        const std::string keys = (dir / "keys.json").string(), out = (dir / "frames").string();
        std::ofstream(keys) << text;
        const Outcome run = run_refract({"animate", "-", keys, "-o", out});
        EXPECT_EQ(run.status, 1) << text;
        EXPECT_TRUE(run.err.starts_with("refract: " + keys + ": ")) << run.err;
        EXPECT_NE(run.err.find(expected), std::string::npos) << run.err;
        EXPECT_EQ(run.err.find("VK_ERROR_"), std::string::npos) << run.err;
        EXPECT_FALSE(fs::exists(out));
    }
    fs::remove_all(dir);
}

// A glTF scene is read before a device starts: one it cannot import is refused with its glTF path (exit 1).
TEST(Cli, RenderRefusesAnUnusableGltfBeforeTheDevice) {
    const fs::path file = fs::temp_directory_path() / ("refract_cli_" + std::to_string(::getpid()) + ".gltf");
    std::ofstream(file) << R"({"asset": {"version": "2.0"}, "buffers": [{"uri": "mesh.bin", "byteLength": 4}]})";
    const Outcome run = run_refract({"render", file.string(), "-o", (fs::temp_directory_path() / "x.exr").string()});
    EXPECT_EQ(run.status, 1);
    EXPECT_NE(run.err.find(file.string() + ": /buffers/0/uri: external URI 'mesh.bin' refused"), std::string::npos) << run.err;
    EXPECT_EQ(run.err.find("VK_ERROR_"), std::string::npos) << run.err;
    fs::remove(file);
}

// A --volume file is checked as refractd checks an upload, before a device starts (exit 1, naming the file).
TEST(Cli, RenderRefusesAnUnusableVolumeBeforeTheDevice) {
    const fs::path file = fs::temp_directory_path() / ("refract_cli_" + std::to_string(::getpid()) + ".vdb");
    std::ofstream(file) << "not a volume at all";
    const Outcome run = run_refract(
        {"render", "-", "-o", (fs::temp_directory_path() / "x.exr").string(), "--volume", "smoke=" + file.string()});
    EXPECT_EQ(run.status, 1);
    EXPECT_NE(run.err.find(file.string() + ": not an OpenVDB file"), std::string::npos) << run.err;
    EXPECT_EQ(run.err.find("VK_ERROR_"), std::string::npos) << run.err;
    fs::remove(file);
}

// A built-in volume needs no --volume; a grid it lacks is refused by name (exit 1), before a device starts.
TEST(Cli, RenderRefusesAGridTheBuiltInVolumeLacks) {
    const fs::path scene = fs::temp_directory_path() / ("refract_cli_builtin_" + std::to_string(::getpid()) + ".json");
    std::ofstream(scene) << R"({"volumes": {"fire": {"asset": "builtin.flame", "grid": "soot"}}})";
    const Outcome run = run_refract({"render", scene.string(), "-o", (fs::temp_directory_path() / "x.exr").string()});
    EXPECT_EQ(run.status, 1);
    EXPECT_NE(run.err.find("built-in volume builtin.flame has no grid 'soot'"), std::string::npos) << run.err;
    EXPECT_EQ(run.err.find("VK_ERROR_"), std::string::npos) << run.err;
    fs::remove(scene);
}

}  // namespace
