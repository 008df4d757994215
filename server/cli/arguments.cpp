#include "cli/arguments.h"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>

#include "protocol/scene_document.h"

namespace refract::cli {
namespace {

namespace fs = std::filesystem;

constexpr const char* kOverview = R"(usage: refract COMMAND [options]
       refract help [COMMAND]    (or refract COMMAND --help)
       refract --version

Commands:
  devices                                 list Vulkan devices and whether each is usable
  voxelize SCENE.json --out DIR           voxelize + index field + octree; writes slice PNGs and summary.json
  trace SCENE.json --out DIR              ... + photons; writes radiance slices, floor caustic map, summary.json
  render SCENE.json -o FRAME.png          the whole pipeline once
         [--hdr FRAME.pfm] [--stats STATS.json]
         [--quality still|interactive]    interactive: the passes as refractd runs them during a
                                          drag, at the document's own image size and photon count
  animate SCENE.json KEYFRAMES.json -o DIR [--fps N]
                                          a frame sequence: keyframes are merge patches at times
  bench [--scene FILE | --suite standard] [--case PREFIX] [--runs N] [--json]
                                          per-pass GPU milliseconds (timestamp queries) for fixed scenes
  bench --daemon HOST:PORT [--runs N]     a running refractd end to end: edit + frame round trips
                                          against the pass times it reports (service overhead)
  help [COMMAND]                          this text, or COMMAND's usage and options

Options for every command:
  --mesh NAME=FILE.obj                    make FILE.obj available to the scene as "upload:NAME"
  --environment NAME=FILE                 make FILE (.hdr or .exr) available as environment image NAME
  --volume NAME=FILE                      make FILE (.vdb or .nvdb, checked as refractd checks an upload)
                                          available to the scene's volumes as asset NAME
  --device NAME                           use the device whose name contains NAME (also REFRACT_DEVICE)
SCENE.json may be - for the default scene {}.
)";

// One option of a command: its spellings, its value's name in the usage (empty: a switch), what it is
// for (further lines after '\n'), and how its value is checked and stored.
struct Option {
    std::string name, alias, value, help;
    std::function<void(Arguments&, const std::string& flag, const std::string& value)> store;
};

// One command: what follows "refract NAME" in its usage, what it does, whether it takes SCENE.json (and
// a second input file after it), its options and what they must say together.
struct Command {
    std::string name, synopsis, description;
    bool takes_scene = false;
    std::vector<Option> options;
    std::function<void(const Arguments&)> check = [](const Arguments&) {};
    std::string second_input;  // the label of a second input file after SCENE.json (empty: none)
};

bool ends_with_ignoring_case(const std::string& text, const std::string& suffix) {
    return text.size() >= suffix.size() &&
           std::equal(suffix.begin(), suffix.end(), text.end() - static_cast<std::ptrdiff_t>(suffix.size()),
                      [](char a, char b) {
                          return std::tolower(static_cast<unsigned char>(a)) ==
                                 std::tolower(static_cast<unsigned char>(b));
                      });
}

int parse_whole_number(const std::string& flag, const std::string& text, int min, int max) {
    long long value = 0;
    const char* end = text.data() + text.size();
    const auto [rest, error] = std::from_chars(text.data(), end, value);
    const bool number = (error == std::errc() || error == std::errc::result_out_of_range) && rest == end;
    if (!number) throw UsageError(flag + ": '" + text + "' is not a whole number");
    if (error != std::errc() || value < min || value > max)
        throw UsageError(flag + ": '" + text + "' must be between " + std::to_string(min) + " and " +
                         std::to_string(max));
    return static_cast<int>(value);
}

// A file the command reads: it must exist, be no directory and open.
void check_input_file(const std::string& label, const std::string& path) {
    std::error_code ignored;
    const fs::file_status status = fs::status(path, ignored);
    if (!fs::exists(status)) throw UsageError(label + " '" + path + "' does not exist");
    if (fs::is_directory(status)) throw UsageError(label + " '" + path + "' is a directory");
    if (!std::ifstream(path)) throw UsageError(label + " '" + path + "' cannot be read");
}

// A file the command writes: the format its extension names, in a directory that exists.
void check_output_file(const std::string& flag, const std::string& path, const std::string& extension) {
    if (!ends_with_ignoring_case(path, extension))
        throw UsageError(flag + ": '" + path + "' must end in " + extension);
    const fs::path file(path);
    const fs::path dir = file.has_parent_path() ? file.parent_path() : fs::path(".");
    std::error_code ignored;
    if (!fs::is_directory(dir, ignored))
        throw UsageError(flag + ": directory '" + dir.string() +
                         (fs::exists(dir, ignored) ? "' is not a directory" : "' does not exist"));
    if (fs::is_directory(file, ignored)) throw UsageError(flag + ": '" + path + "' is a directory");
}

// A directory the command creates if needed: nothing on its way may be a file.
void check_output_dir(const std::string& flag, const std::string& path) {
    std::error_code ignored;
    fs::path existing(path);
    while (!existing.empty() && !fs::exists(existing, ignored)) existing = existing.parent_path();
    if (!existing.empty() && !fs::is_directory(existing, ignored))
        throw UsageError(flag + ": '" + existing.string() + "' is not a directory");
}

// NAME=FILE of an asset flag, FILE readable.
std::pair<std::string, std::string> named_file(const std::string& flag, const std::string& spec, const char* form) {
    const auto eq = spec.find('=');
    if (eq == std::string::npos || eq == 0 || eq + 1 == spec.size())
        throw UsageError(flag + ": '" + spec + "' must be " + form);
    check_input_file(flag + ":", spec.substr(eq + 1));
    return {spec.substr(0, eq), spec.substr(eq + 1)};
}

std::vector<Option> with_common_options(std::vector<Option> options) {
    options.push_back({"--mesh", "", "NAME=FILE.obj",
                       "make FILE.obj available to the scene as \"upload:NAME\"",
                       [](Arguments& a, const std::string& flag, const std::string& spec) {
                           a.meshes.push_back(named_file(flag, spec, "NAME=FILE.obj"));
                       }});
    options.push_back({"--environment", "", "NAME=FILE",
                       "make FILE (.hdr or .exr) available to the scene as environment image NAME",
                       [](Arguments& a, const std::string& flag, const std::string& spec) {
                           a.environments.push_back(named_file(flag, spec, "NAME=FILE"));
                       }});
    options.push_back({"--volume", "", "NAME=FILE",
                       "an OpenVDB volume the scene's volumes name NAME, checked as refractd checks an upload",
                       [](Arguments& a, const std::string& flag, const std::string& spec) {
                           a.volumes.push_back(named_file(flag, spec, "NAME=FILE"));
                           if (!protocol::valid_name(a.volumes.back().first))
                               throw UsageError(flag + ": the name in '" + spec + "' must match [A-Za-z0-9_.-]{1,64}");
                       }});
    options.push_back({"--device", "", "NAME",
                       "use the device whose name contains NAME (also REFRACT_DEVICE)",
                       [](Arguments& a, const std::string&, const std::string& name) { a.device = name; }});
    return options;
}

void require_out(const Arguments& a, const std::string& command, const std::string& what) {
    if (a.out.empty()) throw UsageError(command + " needs " + what);
}

// voxelize and trace: SCENE.json in; slice PNGs and summary.json out, into a directory.
Command slices_command(const std::string& name, const std::string& description) {
    Option out = {"--out", "-o", "DIR",
                  "where the slice PNGs and summary.json go (created if missing); required",
                  [](Arguments& a, const std::string& flag, const std::string& dir) {
                      check_output_dir(flag, dir);
                      a.out = dir;
                  }};
    Command command{name, "SCENE.json --out DIR", description, true, with_common_options({out})};
    command.check = [name](const Arguments& a) { require_out(a, name, "--out DIR"); };
    return command;
}

// render's options besides the common ones.
std::vector<Option> render_options() {
    return {
        {"--out", "-o", "FRAME.png",
         "the frame, 8-bit sRGB; or FRAME.exr, linear half-float RGB with\n"
         "the frame's photons, level and camera in its header; required",
         [](Arguments& a, const std::string& flag, const std::string& file) {
             check_output_file(flag, file, ends_with_ignoring_case(file, ".exr") ? ".exr" : ".png");
             a.out = file;
         }},
        {"--hdr", "", "FRAME.pfm", "also the linear frame, 32-bit float RGB",
         [](Arguments& a, const std::string& flag, const std::string& file) {
             check_output_file(flag, file, ".pfm");
             a.hdr = file;
         }},
        {"--stats", "", "STATS.json", "also the printed summary, as a file",
         [](Arguments& a, const std::string& flag, const std::string& file) {
             check_output_file(flag, file, ".json");
             a.stats = file;
         }},
        {"--quality", "", "still|interactive",
         "interactive: the passes as refractd runs them during a drag, at the\n"
         "document's own image size and photon count (default still)",
         [](Arguments& a, const std::string& flag, const std::string& quality) {
             if (quality != "still" && quality != "interactive")
                 throw UsageError(flag + ": '" + quality + "' must be still or interactive");
             a.interactive = quality == "interactive";
         }},
    };
}

// animate's options besides the common ones.
std::vector<Option> animate_options() {
    return {
        {"--out", "-o", "DIR", "where the frames go (created if missing); required",
         [](Arguments& a, const std::string& flag, const std::string& dir) {
             check_output_dir(flag, dir);
             a.out = dir;
         }},
        {"--fps", "", "N", "frames per second of animation time, 1 to 240 (default 24)",
         [](Arguments& a, const std::string& flag, const std::string& n) {
             a.fps = parse_whole_number(flag, n, 1, 240);
         }},
    };
}

// bench's options besides the common ones.
std::vector<Option> bench_options() {
    return {
        {"--scene", "", "FILE",
         "one scene document instead of the suite: its full rebuild, light\n"
         "and camera edits",
         [](Arguments& a, const std::string& flag, const std::string& file) {
             check_input_file(flag + ":", file);
             a.scene_file = file;
         }},
        {"--suite", "", "standard", "the fixed suite of docs/benchmarks.md (the default)",
         [](Arguments& a, const std::string& flag, const std::string& suite) {
             if (suite != "standard") throw UsageError(flag + ": '" + suite + "' must be standard");
             a.suite = suite;
         }},
        {"--case", "", "PREFIX", "only the suite's cases whose names start with PREFIX",
         [](Arguments& a, const std::string&, const std::string& prefix) { a.only = prefix; }},
        {"--runs", "", "N",
         "timed runs per case, 1 to 1000 (default 10 on a GPU, 3 on a CPU;\n"
         "5 with --daemon)",
         [](Arguments& a, const std::string& flag, const std::string& n) {
             a.runs = parse_whole_number(flag, n, 1, 1000);
         }},
        {"--json", "", "", "the report as JSON instead of a table",
         [](Arguments& a, const std::string&, const std::string&) { a.json = true; }},
        {"--daemon", "", "HOST:PORT", "measure the refractd listening there",
         [](Arguments& a, const std::string& flag, const std::string& address) {
             const auto colon = address.rfind(':');
             if (colon == std::string::npos || colon == 0)
                 throw UsageError(flag + ": '" + address + "' must be HOST:PORT");
             parse_whole_number(flag + " port", address.substr(colon + 1), 1, 65535);
             a.daemon = address;
         }},
    };
}

// What bench's options must say together: one scene, the suite (and its cases) and a daemon exclude each
// other.
void check_bench_options(const Arguments& a) {
    const std::pair<bool, const char*> suite_only[] = {{!a.suite.empty(), "--suite"},
                                                       {!a.only.empty(), "--case"}};
    for (const auto& [given, flag] : suite_only) {
        if (given && !a.scene_file.empty())
            throw UsageError(std::string(flag) + ": not with --scene (one scene has no suite)");
        if (given && !a.daemon.empty()) throw UsageError(std::string(flag) + ": not with --daemon");
    }
    if (!a.scene_file.empty() && !a.daemon.empty()) throw UsageError("--scene: not with --daemon");
}

// Every command, in the order `refract help` lists them.
const std::vector<Command>& commands() {
    static const std::vector<Command> table = [] {
        std::vector<Command> t;
        t.push_back({"devices", "",
                     "Lists the Vulkan devices, each with its driver and memory, and whether it is usable\n"
                     "(if not, what it misses).",
                     false, with_common_options({})});
        t.push_back(slices_command(
            "voxelize",
            "Voxelizes the scene's object, then builds the index field and the octree; writes index-field\n"
            "and octree-level slices (PNG) and summary.json into DIR and prints the summary."));
        t.push_back(slices_command(
            "trace",
            "As voxelize, then traces the photons; also writes radiance slices and the floor's caustic map\n"
            "(PNG), and photon statistics in summary.json."));
        t.push_back(
            {"render",
             "SCENE.json -o FRAME.png|FRAME.exr [--hdr FRAME.pfm] [--stats STATS.json] [--quality still|interactive]",
             "Runs the whole pipeline once and writes the frame; prints a summary (device, size, photons,\n"
             "per-pass GPU milliseconds) as JSON.",
             true, with_common_options(render_options()),
             [](const Arguments& a) { require_out(a, "render", "-o FRAME.png"); }});
        t.push_back(
            {"animate", "SCENE.json KEYFRAMES.json -o DIR [--fps N]",
             "Renders SCENE.json animated by KEYFRAMES.json, a list of {\"time\": seconds, \"patch\": merge\n"
             "patch}, as DIR/frame_00000.png onwards: one frame every 1/N s from 0 to the last keyframe,\n"
             "numbers and vectors interpolated between keyframes. Each frame reruns only the passes its\n"
             "change makes stale; prints a summary (frames, passes rerun per frame) as JSON.",
             true, with_common_options(animate_options()),
             [](const Arguments& a) { require_out(a, "animate", "-o DIR"); }, "KEYFRAMES.json"});
        t.push_back(
            {"bench",
             "[--scene FILE | --suite standard] [--case PREFIX] [--runs N] [--json]\n"
             "       refract bench --daemon HOST:PORT [--runs N] [--json]",
             "Per-pass GPU milliseconds (timestamp queries) for fixed scenes and edits, median and spread\n"
             "of N runs after a warm-up; or, with --daemon, a running refractd end to end: edit + frame\n"
             "round trips against the pass times it reports (service overhead). See docs/benchmarks.md.",
             false, with_common_options(bench_options()), check_bench_options});
        return t;
    }();
    return table;
}

const Command& find_command(const std::string& name) {
    for (const Command& c : commands())
        if (c.name == name) return c;
    if (name.starts_with("-"))
        throw UsageError("unknown option '" + name + "' (options follow the command; see refract help)");
    throw UsageError("unknown command '" + name + "' (see refract help)");
}

void no_more_arguments(const std::vector<std::string>& args, size_t from, const std::string& after) {
    if (args.size() > from) throw UsageError("unexpected argument '" + args[from] + "' after " + after);
}

bool is_help(const std::string& arg) {
    return arg == "--help" || arg == "-h";
}

}  // namespace

Invocation parse_command_line(const std::vector<std::string>& args) {
    Invocation invocation;
    if (args.empty()) {
        invocation.action = Invocation::Action::help;
        return invocation;
    }
    if (args[0] == "--version") {
        no_more_arguments(args, 1, "--version");
        invocation.action = Invocation::Action::version;
        return invocation;
    }
    if (args[0] == "help" || is_help(args[0])) {
        invocation.action = Invocation::Action::help;
        if (args.size() > 1 && args[1] != "help") invocation.command = find_command(args[1]).name;
        no_more_arguments(args, 2, args[0] + (args.size() > 1 ? " " + args[1] : std::string()));
        return invocation;
    }
    const Command& command = find_command(args[0]);
    invocation.command = command.name;

    // First the shape of the line (known options, their values, the count of positionals), so that
    // --help anywhere answers; then each value in order; then what the command needs.
    struct Given {
        const Option* option;
        std::string flag, value;
    };
    std::vector<Given> given;
    Arguments& parsed = invocation.arguments;
    for (size_t i = 1; i < args.size(); ++i) {
        const std::string& arg = args[i];
        if (is_help(arg)) {
            invocation.action = Invocation::Action::help;
            return invocation;
        }
        if (arg.size() < 2 || arg[0] != '-') {
            parsed.positional.push_back(arg);
            continue;
        }
        std::string flag = arg;
        std::string value;
        const auto eq = arg.find('=');
        const bool inline_value = arg.starts_with("--") && eq != std::string::npos;
        if (inline_value) {
            flag = arg.substr(0, eq);
            value = arg.substr(eq + 1);
        }
        const auto option = std::find_if(
            command.options.begin(), command.options.end(),
            [&](const Option& o) { return o.name == flag || (!o.alias.empty() && o.alias == flag); });
        if (option == command.options.end())
            throw UsageError("unknown option '" + flag + "' for " + command.name + " (see refract help " +
                             command.name + ")");
        if (option->value.empty() && inline_value) throw UsageError(flag + " takes no value");
        if (!option->value.empty() && !inline_value) {
            if (i + 1 >= args.size() || args[i + 1].starts_with("--"))
                throw UsageError(flag + " needs a value (" + option->value + ")");
            value = args[++i];
        }
        given.push_back({&*option, flag, value});
    }
    const size_t inputs = (command.takes_scene ? 1u : 0u) + (command.second_input.empty() ? 0u : 1u);
    if (parsed.positional.size() > inputs)
        throw UsageError("unexpected argument '" + parsed.positional[inputs] + "' (" + command.name +
                         (!command.takes_scene            ? " takes only options)"
                          : command.second_input.empty() ? " takes one SCENE.json)"
                                                          : " takes SCENE.json and " + command.second_input + ")"));

    for (const Given& g : given) g.option->store(parsed, g.flag, g.value);
    if (command.takes_scene) {
        if (parsed.positional.empty())
            throw UsageError(command.name + " needs SCENE.json (- for the default scene)");
        if (parsed.positional[0] != "-") check_input_file("SCENE.json", parsed.positional[0]);
    }
    if (!command.second_input.empty()) {
        if (parsed.positional.size() < 2) throw UsageError(command.name + " needs " + command.second_input);
        check_input_file(command.second_input, parsed.positional[1]);
    }
    command.check(parsed);
    return invocation;
}

std::string usage_text(const std::string& name) {
    if (name.empty()) return kOverview;
    const Command& command = find_command(name);
    std::ostringstream out;
    out << "usage: refract " << command.name << (command.synopsis.empty() ? "" : " ") << command.synopsis
        << "\n\n"
        << command.description << "\n\nOptions:\n";
    constexpr size_t kColumn = 32;  // where the options' descriptions start
    auto line = [&](const std::string& left, const std::string& help) {
        out << "  " << left << std::string(kColumn - 2 - std::min(left.size(), kColumn - 3), ' ');
        for (const char c : help) {
            out << c;
            if (c == '\n') out << std::string(kColumn, ' ');
        }
        out << "\n";
    };
    for (const Option& o : command.options)
        line((o.alias.empty() ? "" : o.alias + ", ") + o.name + (o.value.empty() ? "" : " " + o.value),
             o.help);
    line("-h, --help", "this text");
    if (command.takes_scene)
        out << "\nSCENE.json may be - for the default scene {}, or a glTF 2.0 scene (.glb, or .gltf with\n"
               "data: buffers; docs/gltf.md).\n";
    return out.str();
}

}  // namespace refract::cli
