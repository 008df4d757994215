// The refract CLI's commands. Each returns a process exit code; errors are thrown as exceptions.
#pragma once

#include <string>
#include <vector>

namespace refract::cli {

struct Arguments {
    std::vector<std::string> positional;
    std::vector<std::pair<std::string, std::string>> meshes;  // --mesh NAME=FILE.obj
    std::string out, hdr, stats, device, scene_file, suite, daemon, only;  // only: --case prefix
    bool json = false;
    bool interactive = false;  // --quality interactive
    int runs = 0;
};

Arguments parse_arguments(const std::vector<std::string>& args);

int devices_command();
int voxelize_command(const Arguments& args);
int trace_command(const Arguments& args);
int render_command(const Arguments& args);
int bench_command(const Arguments& args);

}  // namespace refract::cli
