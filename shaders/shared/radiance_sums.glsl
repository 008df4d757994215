// The radiance grid's fixed-point sums (transport.h: red | green, and RADIANCE_FLUX_WORDS flux words per
// voxel), reached by device address (TransportParams::radiance_sums) rather than bound as storage
// buffers: at 256^3 the flux words take 512 MiB, more than one storage-buffer binding may span on
// lavapipe (maxStorageBufferRange, 128 MiB: 161^3 voxels). A pass sets both in main.
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_buffer_reference_uvec2 : require
layout(buffer_reference, std430, buffer_reference_align = 8) buffer RadianceSums { uint64_t words[]; };
RadianceSums accum_rg;    // red | green << 32 per voxel; coloured transport only
RadianceSums accum_flux;  // RADIANCE_FLUX_WORDS words per voxel

// Two fixed-point values as one 64-bit addend: `low` sign-extended plus `high` << 32 (transport.h).
uint64_t pack(int low, int high) { return uint64_t(int64_t(low)) + (uint64_t(int64_t(high)) << 32); }

void reach_radiance_sums(uvec4 addresses) {
    accum_rg = RadianceSums(addresses.xy);
    accum_flux = RadianceSums(addresses.zw);
}
