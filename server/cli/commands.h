// The refract CLI's commands, given checked arguments. Each returns a process exit code; errors are
// thrown as exceptions.
#pragma once

#include "cli/arguments.h"
#include "protocol/scene_document.h"
#include "render/medium_field.h"

namespace refract::cli {

// The grids volume `member` names of a built-in volume (volume/builtin_volumes.h): its density and, where
// it emits, its emission grid. Throws std::runtime_error when the volume has no such grid.
scene::VolumeGrids builtin_volume_grids(const protocol::DensityVolume& member);

int devices_command();
int voxelize_command(const Arguments& args);
int trace_command(const Arguments& args);
int render_command(const Arguments& args);
int animate_command(const Arguments& args);
int bench_command(const Arguments& args);

}  // namespace refract::cli
