#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#extension GL_EXT_shader_atomic_int64 : require
// Deposit micro-benchmark, integer variant: three 64-bit atomics per deposit, as photon_trace.comp.
#include "deposit_bench.h"

layout(local_size_x = DEPOSIT_BENCH_GROUP_SIZE) in;
layout(std430, binding = DEPOSIT_BENCH_BINDING_PACKED) buffer Packed { uint64_t packed[]; };
layout(push_constant) uniform Push { DepositBenchPush push; };

#include "deposit_bench_walk.glsl"

void deposit(uint voxel, vec3 w) {
    ivec3 q = ivec3(w * 4096.0);
    atomicAdd(packed[3u * voxel], uint64_t(q.r) + (uint64_t(q.g) << 32));
    atomicAdd(packed[3u * voxel + 1u], uint64_t(q.b) + (uint64_t(q.r) << 32));
    atomicAdd(packed[3u * voxel + 2u], uint64_t(q.g) + (uint64_t(q.b) << 32));
}

void main() { walk(); }
