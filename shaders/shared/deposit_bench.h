// Layout of the deposit micro-benchmark (refract bench --deposits): the cost of adding a photon's
// six sums to a voxel as three packed 64-bit integer atomics (what photon_trace.comp does) against
// six float atomics (VK_EXT_shader_atomic_float), on the same scattered addresses.
#ifndef REFRACT_SHADERS_DEPOSIT_BENCH_H
#define REFRACT_SHADERS_DEPOSIT_BENCH_H

#include "shared_types.h"

REFRACT_SHADERS_BEGIN

#define DEPOSIT_BENCH_GROUP_SIZE 64
#define DEPOSIT_BENCH_BINDING_PACKED 0  // 3 x uint64 per voxel
#define DEPOSIT_BENCH_BINDING_FLOATS 1  // 6 x float per voxel
#define DEPOSIT_BENCH_PACKED 0u
#define DEPOSIT_BENCH_FLOAT 1u

struct DepositBenchPush {
    uint voxels;
    uint deposits_per_thread;
    uint threads;
    uint mode;
};

REFRACT_SHADERS_END

#ifdef __cplusplus
static_assert(sizeof(refract::shaders::DepositBenchPush) == 16);
#endif
#endif
