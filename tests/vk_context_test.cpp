// The Vulkan foundation on whatever device the loader finds (lavapipe in CI), validation layer on.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <numeric>
#include <string>
#include <vector>

#include "selftest.h"
#include "selftest_spv.h"
#include "vk/commands.h"
#include "vk/context.h"
#include "vk/gpu_timer.h"
#include "vk/pipeline.h"
#include "vk/resources.h"

namespace refract {
namespace {

using shaders::SelftestPush;

class VkContextTest : public ::testing::Test {
protected:
    void SetUp() override { context = std::make_unique<vk::Context>(vk::options_from_environment({})); }
    void TearDown() override {
        ASSERT_EQ(context->validation_error_count(), 0u) << context->last_validation_message();
    }
    std::unique_ptr<vk::Context> context;
};

vk::ComputePipeline make_selftest(vk::Context& context) {
    return vk::ComputePipeline(context, selftest_spv,
                               {{SELFTEST_BINDING_INPUT, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
                                {SELFTEST_BINDING_OUTPUT, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
                                {SELFTEST_BINDING_IMAGE, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE},
                                {SELFTEST_BINDING_SAMPLES, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER}},
                               sizeof(SelftestPush), "selftest");
}

// The selftest pipeline's bindings, in its layout's order.
std::array<vk::Binding, 4> selftest_bindings(const vk::Buffer& in, const vk::Buffer& out,
                                             const vk::Image3D& image, const vk::Buffer& samples) {
    return {vk::Binding::storage_buffer(SELFTEST_BINDING_INPUT, in),
            vk::Binding::storage_buffer(SELFTEST_BINDING_OUTPUT, out),
            vk::Binding::storage_image(SELFTEST_BINDING_IMAGE, image),
            vk::Binding::storage_buffer(SELFTEST_BINDING_SAMPLES, samples)};
}

TEST_F(VkContextTest, ListsDevicesAndChoosesASuitableOne) {
    const auto devices = vk::list_devices();
    ASSERT_FALSE(devices.empty());
    EXPECT_TRUE(context->info().suitable);
    EXPECT_FALSE(context->info().name.empty());
    EXPECT_FALSE(context->info().driver_name.empty());
}

TEST_F(VkContextTest, ValidationIsOnInTests) { EXPECT_TRUE(context->validation_enabled()); }

// The same dispatch with the pipeline compiled when it is made (the daemon's and the CLI's contexts)
// and at its first dispatch (ContextOptions::compile_on_first_use, the tests').
TEST_F(VkContextTest, ComputeRoundTripIsExactCompiledUpFrontOrOnFirstUse) {
    vk::ContextOptions on_first_use;
    on_first_use.compile_on_first_use = true;
    const auto lazy = std::make_unique<vk::Context>(vk::options_from_environment(on_first_use));
    ASSERT_TRUE(lazy->compiles_on_first_use());
    ASSERT_FALSE(context->compiles_on_first_use());
    for (vk::Context* ctx : {context.get(), lazy.get()}) {
        SCOPED_TRACE(ctx->compiles_on_first_use() ? "compiled at its first dispatch" : "compiled up front");
        constexpr uint32_t n = 10007;  // not a multiple of the workgroup size: the bounds check matters
        std::vector<uint32_t> input(n);
        std::iota(input.begin(), input.end(), 3u);
        const auto usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT;
        vk::Buffer in(*ctx, n * 4, usage, vk::MemoryUse::upload, "in");
        vk::Buffer out(*ctx, n * 4, usage | VK_BUFFER_USAGE_TRANSFER_DST_BIT, vk::MemoryUse::readback, "out");
        vk::Buffer samples(*ctx, 16, usage, vk::MemoryUse::upload, "samples");
        vk::Image3D image(*ctx, {2, 2, 2}, VK_FORMAT_R32_SFLOAT, "volume");
        in.write(input.data(), n * 4);
        auto pipeline = make_selftest(*ctx);
        vk::run_once(*ctx, [&](vk::CommandRecorder& r) {
            r.init_image(image);
            r.fill(out, 0xffffffffu);
            r.transfer_to_compute_barrier();
            pipeline.dispatch(r.get(), selftest_bindings(in, out, image, samples),
                              SelftestPush{n, 7u, 0u, 0u}, vk::group_count(n, SELFTEST_GROUP_SIZE));
            r.to_host_barrier();
        });
        const auto result = out.mapped_span<uint32_t>();
        for (uint32_t i = 0; i < n; ++i) ASSERT_EQ(result[i], input[i] * 7u + i) << "at " << i;
        EXPECT_EQ(ctx->validation_error_count(), 0u) << ctx->last_validation_message();
    }
}

TEST_F(VkContextTest, ThreeDImageIsWrittenAndInterpolatedTrilinearly) {
    // A 4x4x4 image holding f(x,y,z) = x + 10y + 100z at texel centres, read texel by texel and
    // interpolated (trilinear.glsl): between texel centres a linear function comes back exactly (up to
    // float rounding), and outside them the nearest centre's value along each axis (clamp to edge).
    constexpr uint32_t side = 4;
    std::vector<float> texels(side * side * side);
    for (uint32_t z = 0; z < side; ++z)
        for (uint32_t y = 0; y < side; ++y)
            for (uint32_t x = 0; x < side; ++x)
                texels[(z * side + y) * side + x] = static_cast<float>(x + 10 * y + 100 * z);
    vk::Image3D image(*context, {side, side, side}, VK_FORMAT_R32_SFLOAT, "linear volume");
    vk::Buffer staging(*context, texels.size() * 4, VK_BUFFER_USAGE_TRANSFER_SRC_BIT, vk::MemoryUse::upload,
                       "staging");
    staging.write(texels.data(), texels.size() * 4);
    const std::vector<std::array<float, 3>> points = {
        {1.5f, 1.5f, 1.5f}, {0.5f, 2.25f, 3.0f}, {2.75f, 0.5f, 1.0f}, {0.2f, 3.9f, 1.3f}, {4.0f, 0.0f, 2.6f}};
    std::vector<float> sample_data;
    for (const auto& p : points)
        for (float c : {p[0] / side, p[1] / side, p[2] / side, -1.0f}) sample_data.push_back(c);
    const auto usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT;
    vk::Buffer samples(*context, sample_data.size() * 4, usage, vk::MemoryUse::readback, "samples");
    samples.write(sample_data.data(), sample_data.size() * 4);
    vk::Buffer dummy(*context, 4, usage, vk::MemoryUse::upload, "unused");
    auto pipeline = make_selftest(*context);
    vk::run_once(*context, [&](vk::CommandRecorder& r) {
        r.init_image(image);
        r.copy(staging, image);
        r.transfer_to_compute_barrier();
        pipeline.dispatch(r.get(), selftest_bindings(dummy, dummy, image, samples),
                          SelftestPush{static_cast<uint32_t>(points.size()), 0u, 1u, 0u}, 1);
        r.to_host_barrier();
    });
    const auto result = samples.mapped_span<float>();
    for (size_t i = 0; i < points.size(); ++i) {
        // Texel centres sit at integer + 0.5 in texel coordinates.
        const auto centred = [&](float c) { return std::clamp(c, 0.5f, side - 0.5f) - 0.5f; };
        const auto& p = points[i];
        const float expected = centred(p[0]) + 10.0f * centred(p[1]) + 100.0f * centred(p[2]);
        // Float weights: a sampler's 8-bit ones would miss by up to 100 / 256.
        EXPECT_NEAR(result[i * 4 + 3], expected, 1e-3f) << "sample " << i;
    }
}

TEST_F(VkContextTest, TimestampQueriesMeasureNonZeroDurations) {
    constexpr uint32_t n = 1u << 20;
    const auto usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT;
    vk::Buffer in(*context, n * 4, usage, vk::MemoryUse::device, "in");
    vk::Buffer out(*context, n * 4, usage, vk::MemoryUse::device, "out");
    vk::Buffer samples(*context, 16, usage, vk::MemoryUse::device, "samples");
    vk::Image3D image(*context, {1, 1, 1}, VK_FORMAT_R32_SFLOAT, "unused");
    auto pipeline = make_selftest(*context);
    vk::GpuTimer timer(*context);
    vk::run_once(*context, [&](vk::CommandRecorder& r) {
        timer.reset(r.get());
        r.init_image(image);
        timer.begin(r.get(), "multiply");
        pipeline.dispatch(r.get(), selftest_bindings(in, out, image, samples), SelftestPush{n, 3u, 0u, 0u},
                          vk::group_count(n, SELFTEST_GROUP_SIZE));
        timer.end(r.get());
    });
    const auto scopes = timer.read();
    ASSERT_EQ(scopes.size(), 1u);
    EXPECT_EQ(scopes[0].first, "multiply");
    EXPECT_GT(scopes[0].second, 0.0);
    EXPECT_LT(scopes[0].second, 60'000.0);
}

TEST_F(VkContextTest, EveryResourceReturnsItsMemory) {
    const int64_t before = context->allocated_bytes();
    {
        vk::Buffer buffer(*context, 1 << 20, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, vk::MemoryUse::device, "counted");
        vk::Image3D image(*context, {16, 16, 16}, VK_FORMAT_R32G32B32A32_SFLOAT, "counted");
        EXPECT_GE(context->allocated_bytes(), before + (1 << 20) + 16 * 16 * 16 * 16);
        vk::Buffer moved = std::move(buffer);  // a move transfers ownership, it does not double-count
        vk::Image3D moved_image = std::move(image);
        EXPECT_GE(context->allocated_bytes(), before + (1 << 20) + 16 * 16 * 16 * 16);
    }
    EXPECT_EQ(context->allocated_bytes(), before);
}

TEST_F(VkContextTest, AbsurdRequestsAreErrorsNotCrashes) {
    const uint32_t too_big = context->limits().maxImageDimension3D + 1;
    EXPECT_THROW(vk::Image3D(*context, {too_big, 1, 1}, VK_FORMAT_R32_SFLOAT, "too big"), vk::Error);
    EXPECT_THROW(vk::Buffer(*context, 0, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, vk::MemoryUse::device, "empty"),
                 vk::Error);
    const VkDeviceSize over = VkDeviceSize{context->limits().maxStorageBufferRange} + 1;
    EXPECT_THROW(vk::Buffer(*context, over, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, vk::MemoryUse::device, "huge"),
                 vk::Error);
    // A pipeline used with the wrong push-constant size is refused before it reaches the driver.
    auto pipeline = make_selftest(*context);
    vk::CommandRecorder recorder(*context, "misuse");
    recorder.begin();
    const uint32_t wrong = 0;
    EXPECT_THROW(pipeline.dispatch(recorder.get(), {}, &wrong, sizeof(wrong), 1), vk::Error);
    EXPECT_THROW(vk::check(VK_ERROR_DEVICE_LOST, "vkFake()", "here.cpp", 1), vk::Error);
    try {
        REFRACT_VK_CHECK(VK_ERROR_OUT_OF_DEVICE_MEMORY);
    } catch (const vk::Error& e) {
        EXPECT_NE(std::string(e.what()).find("VK_ERROR_OUT_OF_DEVICE_MEMORY"), std::string::npos);
        EXPECT_EQ(e.result(), VK_ERROR_OUT_OF_DEVICE_MEMORY);
    }
    recorder.submit_and_wait();
}

TEST(LinearGroups, FoldPastTheDispatchLimitIntoBalancedRows) {
    // Within the limit: one row, exactly enough groups.
    EXPECT_EQ(vk::linear_groups(1000, 64).x, 16u);
    EXPECT_EQ(vk::linear_groups(1000, 64).y, 1u);
    EXPECT_EQ(vk::linear_groups(0, 64).x, 1u);
    // Past it: rows of equal length covering every group, none longer than 65535.
    for (uint64_t groups : {65536ull, 131071ull, 262144ull, 2097152ull}) {
        const auto g = vk::linear_groups(groups * 64, 64);
        EXPECT_LE(g.x, 65535u);
        EXPECT_GE(uint64_t{g.x} * g.y, groups);
        EXPECT_LT(uint64_t{g.x} * (g.y - 1), groups) << "a whole row would be idle";
    }
    EXPECT_EQ(vk::linear_groups(65536ull * 64, 64).x, 32768u);
}

TEST(CpuDispatches, FourThreadsACoreUnlessTheUserChose) {
    // This process's own setting (ctest pins it) is put back whatever the checks find.
    const char* pinned = std::getenv("LP_NUM_THREADS");
    const std::string kept = pinned ? pinned : "";
    unsetenv("LP_NUM_THREADS");
    EXPECT_EQ(vk::split_cpu_dispatches_finely(2), "8");
    EXPECT_STREQ(std::getenv("LP_NUM_THREADS"), "8");
    EXPECT_EQ(vk::split_cpu_dispatches_finely(16), "8") << "a value in effect is never replaced";
    unsetenv("LP_NUM_THREADS");
    EXPECT_EQ(vk::split_cpu_dispatches_finely(0), "4") << "an unknown core count counts as one";
    setenv("LP_NUM_THREADS", "", 1);
    EXPECT_EQ(vk::split_cpu_dispatches_finely(2), "8") << "lavapipe reads an empty value as unset";
    setenv("LP_NUM_THREADS", "3", 1);
    EXPECT_EQ(vk::split_cpu_dispatches_finely(2), "3");
    EXPECT_STREQ(std::getenv("LP_NUM_THREADS"), "3");
    // A value lavapipe cannot read is the user's too: left as it is, lavapipe takes its own default
    // (the daemon still renders: checked by hand with abc, 0, -3 and 100000).
    setenv("LP_NUM_THREADS", "abc", 1);
    EXPECT_EQ(vk::split_cpu_dispatches_finely(2), "abc");
    EXPECT_STREQ(std::getenv("LP_NUM_THREADS"), "abc");
    if (pinned)
        setenv("LP_NUM_THREADS", kept.c_str(), 1);
    else
        unsetenv("LP_NUM_THREADS");
}

TEST(VkValidation, ValidationLayerReportsMisuseAsCountedError) {
    // Misuse the API directly (a buffer with no usage flags): the validation layer must report it
    // through our messenger, which counts it instead of crashing.
    vk::ContextOptions options = vk::options_from_environment({});
    options.validation = true;
    vk::Context context(options);
    VkBufferCreateInfo info{VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO};
    info.size = 64;
    info.usage = 0;
    VkBuffer buffer = VK_NULL_HANDLE;
    const VkResult result = vkCreateBuffer(context.device(), &info, nullptr, &buffer);
    if (result == VK_SUCCESS) vkDestroyBuffer(context.device(), buffer, nullptr);
    EXPECT_GT(context.validation_error_count(), 0u);
    EXPECT_NE(context.last_validation_message().find("usage"), std::string::npos)
        << context.last_validation_message();
}

}  // namespace
}  // namespace refract
