// Fuzzes the reader of a grid's export (volume::decode_density), the bytes refract-vdb-check sends the
// daemon, which a subverted checker could choose. Invariants: only VolumeError is thrown, and an export
// that is read encodes back to exactly the bytes it was read from.
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "fuzz_check.h"
#include "volume/density_export.h"
#include "volume/vdb_reader.h"

using namespace refract::volume;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    const std::string_view input(reinterpret_cast<const char*>(data), size);
    DensityGrid grid;
    try {
        // A small limit, so that the fuzzer's inputs reach it.
        grid = decode_density(input, 4);
    } catch (const VolumeError&) {
        return 0;
    }
    REFRACT_FUZZ_CHECK(grid.leaves.size() <= 4);
    REFRACT_FUZZ_CHECK(encode_density(grid) == input);
    return 0;
}
