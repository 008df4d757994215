// Volumes every daemon and the CLI hold without an upload, made from closed forms (no OpenVDB): what the
// examples name, and what a new user's first volume can be before they have a .vdb of their own. Their
// names start with kBuiltinVolumePrefix, which no upload's may (so none shadows an upload).
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "volume/density_export.h"
#include "volume/vdb_reader.h"

namespace refract::volume {

inline constexpr std::string_view kBuiltinVolumePrefix = "builtin.";

// "builtin.cloud": a cumulus of about 2.4 x 1.1 x 1.5 m, density up to 1 with billowed edges ("density").
// "builtin.flame": a flame 0.5 m tall, "temperature" up to 1900 K in its core, and thin "density" (its soot).
// "builtin.smoke": a plume rising 1.2 m from a point, widening and thinning as it goes ("density").
// Each stands on its grid's origin (y up), its world box in its report.
const std::vector<std::string>& builtin_volume_names();
// Whether `name` is in the built-ins' namespace (kBuiltinVolumePrefix), one of them or not.
bool is_builtin_volume(std::string_view name);

// The report of a built-in volume, as GET /api/volumes lists an upload's; nullopt for any other name.
std::optional<VolumeReport> builtin_volume_report(std::string_view name);
// Grid `grid` of built-in volume `name`, made once per process; nullptr where it has no such grid.
std::shared_ptr<const DensityGrid> builtin_density(std::string_view name, std::string_view grid);

}  // namespace refract::volume
