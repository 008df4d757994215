// A volume file checked in a process of its own, for a long-lived one (the daemon): OpenVDB was never
// meant for hostile bytes, keeps memory of files it refuses and reads a whole tree before its box can be
// checked; the child's memory, its time and any crash end with it. The child is a program started
// afresh (refract-vdb-check), not a fork: a fork of a threaded process copies whatever lock another
// thread held at that moment (an allocator's, TBB's), and the child would wait on it forever.
#pragma once

#include <chrono>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <string_view>

#include "volume/vdb_reader.h"

namespace refract::volume {

// The check could not be run (its program is missing or would not start): a fault of the installation,
// not of the file.
class CheckUnavailable : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

// The checker: $REFRACT_VDB_CHECK when set, else refract-vdb-check beside the running executable (as
// the build and the container image place it).
std::filesystem::path check_program();

// inspect_vdb(bytes, limits) run by `program` within `time_limit`: the same report, or VolumeError with
// the same reason; VolumeError too when the check crashed or ran out of time, CheckUnavailable when it
// could not start.
VolumeReport inspect_vdb_apart(std::string_view bytes, const VolumeLimits& limits,
                               const std::filesystem::path& program = check_program(),
                               std::chrono::seconds time_limit = std::chrono::seconds(30));

// The float grid `grid` of the file in `bytes` (export_density) exported by `program` within
// `time_limit` and read back with decode_density, every length checked: the answer of a child whose
// OpenVDB a hostile file may have subverted is trusted no more than the file. Throws as
// inspect_vdb_apart does.
DensityGrid export_density_apart(std::string_view bytes, const std::string& grid, const VolumeLimits& limits,
                                 uint64_t max_leaves = kMaxDensityLeaves,
                                 const std::filesystem::path& program = check_program(),
                                 std::chrono::seconds time_limit = std::chrono::seconds(30));

// The checker's side: its answer for `bytes`, a report or the reason it was refused, in the form
// inspect_vdb_apart reads.
std::string check_answer(std::string_view bytes, const VolumeLimits& limits);
// The exporter's side: the grid's export or the reason it was refused, in the form export_density_apart reads.
std::string export_answer(std::string_view bytes, const std::string& grid, const VolumeLimits& limits,
                          uint64_t max_leaves);

}  // namespace refract::volume
