// The refract command line: which command, its checked arguments, and each command's usage text.
#pragma once

#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace refract::cli {

// A command's arguments, each already checked: input files exist, numbers are in range, outputs have
// their format's extension and lie in directories that exist.
struct Arguments {
    std::vector<std::string> positional;
    std::vector<std::pair<std::string, std::string>> meshes;               // --mesh NAME=FILE.obj
    std::vector<std::pair<std::string, std::string>> environments;         // --environment NAME=FILE
    std::vector<std::pair<std::string, std::string>> volumes;              // --volume NAME=FILE.vdb
    std::string out, hdr, stats, device, scene_file, suite, daemon, only;  // only: --case prefix
    bool json = false;
    bool interactive = false;  // --quality interactive
    int runs = 0;              // 0: the command's default
    int fps = 24;              // animate: frames per second of animation time
};

// A command line that cannot be used; the one-line message names the argument. Exit status 2.
class UsageError : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

// What the command line asks for: run a command, print a usage text, or print the version.
struct Invocation {
    enum class Action { run, help, version };
    Action action = Action::run;
    std::string command;  // the command to run or whose usage to print; empty: the overview
    Arguments arguments;
};

// Parses argv (without argv[0]) and checks every argument before anything runs. Throws UsageError.
Invocation parse_command_line(const std::vector<std::string>& args);

// The overview of all commands (`refract help`), or one command's usage (`refract help COMMAND`).
std::string usage_text(const std::string& command = {});

}  // namespace refract::cli
