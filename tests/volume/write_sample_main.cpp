// Writes a density sphere written by OpenVDB (vdb_samples.h) to the file named by its argument: the browser
// test uploads it as a user would a .vdb from Houdini or Blender.
#include <cstdio>
#include <fstream>
#include <string>

#include "volume/vdb_samples.h"

int main(int argc, char** argv) {
    if (argc != 2) {
        std::fprintf(stderr, "usage: vdb_sample_writer OUT.vdb\n");
        return 2;
    }
    const std::string bytes = refract::test::density_sphere_vdb(8);
    std::ofstream out(argv[1], std::ios::binary);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    return out ? 0 : 1;
}
