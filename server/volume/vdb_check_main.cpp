// refract-vdb-check MAX_BOX_VOXELS MAX_GRIDS [GRID MAX_LEAVES]: checks the OpenVDB file on its standard
// input and writes its answer to its standard output (vdb_check.h), for a daemon that keeps OpenVDB out
// of its own memory; with GRID, exports that float grid's active voxels instead (density_export.h).
#include <unistd.h>

#include <cerrno>
#include <charconv>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <string_view>

#include "volume/vdb_check.h"

namespace {

bool parse(std::string_view text, uint64_t& value) {
    const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
    return error == std::errc{} && end == text.data() + text.size();
}

}  // namespace

int main(int argc, char** argv) {
    uint64_t box = 0, grids = 0, leaves = 0;
    const bool exports = argc == 5;
    if ((argc != 3 && !exports) || !parse(argv[1], box) || !parse(argv[2], grids) || grids > UINT32_MAX ||
        (exports && !parse(argv[4], leaves))) {
        std::fputs("usage: refract-vdb-check MAX_BOX_VOXELS MAX_GRIDS [GRID MAX_LEAVES] < FILE.vdb\n", stderr);
        return 2;
    }
    std::string bytes;
    char buffer[1 << 16];
    for (ssize_t n; (n = ::read(STDIN_FILENO, buffer, sizeof buffer)) != 0;) {
        if (n < 0 && errno == EINTR) continue;
        if (n < 0) {
            std::perror("refract-vdb-check: reading the file");
            return 1;
        }
        bytes.append(buffer, static_cast<size_t>(n));
    }
    const refract::volume::VolumeLimits limits{.max_box_voxels = box, .max_grids = static_cast<uint32_t>(grids)};
    const std::string answer = exports ? refract::volume::export_answer(bytes, argv[3], limits, leaves)
                                       : refract::volume::check_answer(bytes, limits);
    std::fwrite(answer.data(), 1, answer.size(), stdout);
    std::fflush(stdout);
    // What OpenVDB kept of a refused file goes with the process: no destructors, no leak report.
    std::_Exit(0);
}
