// refract: the command-line face of the renderer (devices, voxelize, trace, render, bench).
#include <exception>
#include <iostream>
#include <string>
#include <vector>

#include "cli/commands.h"
#include "protocol/scene_document.h"

namespace {

constexpr const char* kUsage = R"(usage: refract COMMAND [options]

Commands:
  devices                                 list Vulkan devices and whether each is usable
  voxelize SCENE.json --out DIR           voxelize + index field + octree; writes slice PNGs and summary.json
  trace SCENE.json --out DIR              ... + photons; writes radiance slices, floor caustic map, summary.json
  render SCENE.json -o FRAME.png          the whole pipeline once
         [--hdr FRAME.pfm] [--stats STATS.json]
         [--quality still|interactive]    interactive: the passes as refractd runs them during a
                                          drag, at the document's own image size and photon count
  bench [--scene FILE | --suite standard] [--case PREFIX] [--runs N] [--json]
                                          per-pass GPU milliseconds (timestamp queries) for fixed scenes
  bench --daemon HOST:PORT [--runs N]     a running refractd end to end: edit + frame round trips
                                          against the pass times it reports (service overhead)
  help                                    this text

Options for every command:
  --mesh NAME=FILE.obj                    make FILE.obj available to the scene as "upload:NAME"
  --device NAME                           use the device whose name contains NAME (also REFRACT_DEVICE)
SCENE.json may be - for the default scene {}.
)";

}  // namespace

int main(int argc, char** argv) {
    const std::vector<std::string> args(argv + 1, argv + argc);
    if (args.empty() || args[0] == "help" || args[0] == "--help" || args[0] == "-h") {
        std::cout << kUsage;
        return args.empty() ? 2 : 0;
    }
    try {
        const auto parsed = refract::cli::parse_arguments({args.begin() + 1, args.end()});
        if (args[0] == "devices") return refract::cli::devices_command();
        if (args[0] == "voxelize") return refract::cli::voxelize_command(parsed);
        if (args[0] == "trace") return refract::cli::trace_command(parsed);
        if (args[0] == "render") return refract::cli::render_command(parsed);
        if (args[0] == "bench") return refract::cli::bench_command(parsed);
        std::cerr << "refract: unknown command '" << args[0] << "'\n" << kUsage;
        return 2;
    } catch (const refract::protocol::ValidationError& e) {
        std::cerr << "refract: invalid scene: " << e.what() << "\n";
        return 1;
    } catch (const std::exception& e) {
        std::cerr << "refract: " << e.what() << "\n";
        return 1;
    }
}
