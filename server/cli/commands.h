// The refract CLI's commands, given checked arguments. Each returns a process exit code; errors are
// thrown as exceptions.
#pragma once

#include "cli/arguments.h"

namespace refract::cli {

int devices_command();
int voxelize_command(const Arguments& args);
int trace_command(const Arguments& args);
int render_command(const Arguments& args);
int animate_command(const Arguments& args);
int bench_command(const Arguments& args);

}  // namespace refract::cli
