// The address pattern both deposit variants share: each thread walks a run of consecutive voxels
// (like a photon crossing the grid along x) from a hashed start, so neighbouring threads collide
// about as often as neighbouring photons do. The variant defines deposit(voxel, weight).
void deposit(uint voxel, vec3 w);

#include "hash.glsl"

void walk() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= push.threads) return;
    // Neighbouring threads start near each other, as stratified photons do.
    uint start = (hash(i / 16u) + (i % 16u) * 128u) % push.voxels;
    for (uint k = 0u; k < push.deposits_per_thread; ++k) {
        uint voxel = (start + k) % push.voxels;
        deposit(voxel, vec3(0.5, 0.25, 0.125));
    }
}
