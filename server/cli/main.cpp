// refract: the command-line face of the renderer (devices, voxelize, trace, render, bench).
#include <cstdio>
#include <cstring>
#include <exception>
#include <iostream>
#include <string>
#include <vector>

#include "vk/context.h"

namespace {

constexpr const char* kUsage = R"(usage: refract COMMAND [options]

Commands:
  devices                       list Vulkan devices and whether each is usable
  help                          this text

Common options:
  --device NAME                 use the device whose name contains NAME (also REFRACT_DEVICE)
)";

int devices_command() {
    const auto devices = refract::vk::list_devices();
    if (devices.empty()) {
        std::cout << "no Vulkan devices found (install mesa-vulkan-drivers for lavapipe)\n";
        return 1;
    }
    for (const auto& d : devices) {
        std::cout << d.index << ": " << d.name << " [" << d.type << "] driver " << d.driver_name << " ("
                  << d.driver_info << "), Vulkan " << d.api_version << ", "
                  << d.device_local_bytes / (1024 * 1024) << " MiB device-local: "
                  << (d.suitable ? "usable" : "NOT usable");
        for (const auto& m : d.missing) std::cout << "\n     missing: " << m;
        std::cout << "\n";
    }
    return 0;
}

}  // namespace

int main(int argc, char** argv) {
    const std::vector<std::string> args(argv + 1, argv + argc);
    if (args.empty() || args[0] == "help" || args[0] == "--help" || args[0] == "-h") {
        std::cout << kUsage;
        return args.empty() ? 2 : 0;
    }
    try {
        if (args[0] == "devices") return devices_command();
        std::cerr << "refract: unknown command '" << args[0] << "'\n" << kUsage;
        return 2;
    } catch (const std::exception& e) {
        std::cerr << "refract: " << e.what() << "\n";
        return 1;
    }
}
