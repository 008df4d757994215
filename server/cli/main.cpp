// refract: the command-line face of the renderer (devices, voxelize, trace, render, animate, bench).
#include <exception>
#include <iostream>
#include <string>
#include <vector>

#include "cli/commands.h"
#include "protocol/scene_document.h"

int main(int argc, char** argv) {
    using refract::cli::Invocation;
    const std::vector<std::string> args(argv + 1, argv + argc);
    try {
        // Every argument is checked here, before a command reads a scene or starts a device.
        const Invocation invocation = refract::cli::parse_command_line(args);
        switch (invocation.action) {
            case Invocation::Action::help:
                std::cout << refract::cli::usage_text(invocation.command);
                return args.empty() ? 2 : 0;
            case Invocation::Action::version:
                std::cout << "refract " << REFRACT_VERSION << "\n";
                return 0;
            case Invocation::Action::run:
                break;
        }
        const auto& command = invocation.command;
        const auto& parsed = invocation.arguments;
        if (command == "devices") return refract::cli::devices_command();
        if (command == "voxelize") return refract::cli::voxelize_command(parsed);
        if (command == "trace") return refract::cli::trace_command(parsed);
        if (command == "render") return refract::cli::render_command(parsed);
        if (command == "animate") return refract::cli::animate_command(parsed);
        return refract::cli::bench_command(parsed);
    } catch (const refract::cli::UsageError& e) {
        std::cerr << "refract: " << e.what() << "\n";
        return 2;
    } catch (const refract::protocol::ValidationError& e) {
        std::cerr << "refract: invalid scene: " << e.what() << "\n";
        return 1;
    } catch (const std::exception& e) {
        std::cerr << "refract: " << e.what() << "\n";
        return 1;
    }
}
