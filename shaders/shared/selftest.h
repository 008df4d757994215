// Layout shared by the Vulkan self-test shader and its host test (tests/vk_context_test.cpp).
#ifndef REFRACT_SHADERS_SELFTEST_H
#define REFRACT_SHADERS_SELFTEST_H

#ifdef __cplusplus
#include <cstdint>
namespace refract::shaders {
using uint = uint32_t;
#endif

#define SELFTEST_GROUP_SIZE 64
#define SELFTEST_BINDING_INPUT 0
#define SELFTEST_BINDING_OUTPUT 1
#define SELFTEST_BINDING_IMAGE 2
#define SELFTEST_BINDING_SAMPLES 3

struct SelftestPush {
    uint count;
    uint multiplier;
    uint mode;  // 0: out = in * multiplier + index; 1: interpolate the 3D image at the samples' points
    uint pad;
};

#ifdef __cplusplus
static_assert(sizeof(SelftestPush) == 16);
}  // namespace refract::shaders
#endif
#endif
