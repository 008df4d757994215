#include "cli/commands.h"

#include <stdexcept>

namespace refract::cli {

int bench_command(const Arguments&) { throw std::runtime_error("bench: not built yet"); }

}  // namespace refract::cli
