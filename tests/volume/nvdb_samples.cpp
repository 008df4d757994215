#include "volume/nvdb_samples.h"

#include <nanovdb/util/IO.h>
#include <nanovdb/util/OpenToNanoVDB.h>
#include <openvdb/io/Stream.h>
#include <openvdb/openvdb.h>
#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <vector>

#include "volume/vdb_layout.h"

namespace refract::test {

std::string nvdb_from_vdb(const std::string& vdb) {
    openvdb::initialize();
    // In file order: split as the reader splits a file (io::File::getGrids orders the grids by name).
    std::vector<nanovdb::GridHandle<nanovdb::HostBuffer>> handles;
    for (const std::string& one_grid : volume::split_grids(vdb, 64)) {
        std::istringstream in(one_grid, std::ios::binary);
        const openvdb::GridPtrVecPtr grids = openvdb::io::Stream(in, /*delayLoad=*/false).getGrids();
        for (const openvdb::GridBase::Ptr& grid : *grids) handles.push_back(nanovdb::openToNanoVDB(grid));
    }
    // Through a file: writeGrids seeks past what it has written, which a string stream cannot.
    const std::filesystem::path path =
        std::filesystem::temp_directory_path() / ("refract_nvdb_" + std::to_string(::getpid()) + ".nvdb");
    nanovdb::io::writeGrids(path.string(), handles);
    std::ifstream in(path, std::ios::binary);
    std::ostringstream bytes;
    bytes << in.rdbuf();
    std::filesystem::remove(path);
    return bytes.str();
}

uint64_t nvdb_grid_offset(const std::string& nvdb, uint32_t index) {
    constexpr uint64_t kHeader = 16, kMeta = 176, kNameSize = 136;
    uint16_t count = 0;
    std::memcpy(&count, nvdb.data() + 12, sizeof count);
    if (index >= count) throw std::out_of_range("nvdb_grid_offset: no such grid");
    uint64_t at = kHeader, buffers = 0;
    std::vector<uint64_t> sizes;
    for (uint16_t i = 0; i < count; ++i) {
        uint32_t name_size = 0;
        uint64_t size = 0;
        std::memcpy(&name_size, nvdb.data() + at + kNameSize, sizeof name_size);
        std::memcpy(&size, nvdb.data() + at, sizeof size);
        sizes.push_back(size);
        at += kMeta + name_size;
    }
    for (uint32_t i = 0; i < index; ++i) buffers += sizes[i];
    return at + buffers;
}

std::string volume_refusal(const std::string& bytes, const volume::VolumeLimits& limits) {
    try {
        volume::inspect_vdb(bytes, limits);
    } catch (const volume::VolumeError& e) {
        return e.what();
    }
    return "(accepted)";
}

}  // namespace refract::test
