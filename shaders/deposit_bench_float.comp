#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_shader_atomic_float : require
// Deposit micro-benchmark, float variant: six float atomics per deposit (needs VK_EXT_shader_atomic_float).
#include "deposit_bench.h"

layout(local_size_x = DEPOSIT_BENCH_GROUP_SIZE) in;
layout(std430, binding = DEPOSIT_BENCH_BINDING_FLOATS) buffer Floats { float floats[]; };
layout(push_constant) uniform Push { DepositBenchPush push; };

#include "deposit_bench_walk.glsl"

void deposit(uint voxel, vec3 w) {
    atomicAdd(floats[6u * voxel], w.r);
    atomicAdd(floats[6u * voxel + 1u], w.g);
    atomicAdd(floats[6u * voxel + 2u], w.b);
    atomicAdd(floats[6u * voxel + 3u], w.r);
    atomicAdd(floats[6u * voxel + 4u], w.g);
    atomicAdd(floats[6u * voxel + 5u], w.b);
}

void main() { walk(); }
