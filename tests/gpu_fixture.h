// One Vulkan context and one set of compiled passes per test binary (creating them per test would
// dominate the suite's time on lavapipe), with the validation layer on and its errors failing tests.
#pragma once

#include <gtest/gtest.h>

#include <memory>
#include <stdexcept>
#include <vector>

#include "mesh/mesh.h"
#include "protocol/scene_document.h"
#include "render/object_mesh.h"
#include "render/scene_gpu.h"
#include "vk/context.h"

namespace refract::testing {

class GpuTest : public ::testing::Test {
protected:
    static void SetUpTestSuite() {
        if (!context_) {
            vk::ContextOptions options;
            options.compile_on_first_use = true;  // a binary's tests use few of the passes' variants
            context_ = std::make_unique<vk::Context>(vk::options_from_environment(options));
            kit_ = std::make_unique<scene::PassKit>(*context_);
        }
    }
    void TearDown() override {
        EXPECT_EQ(context_->validation_error_count(), errors_before_)
            << "Vulkan validation error: " << context_->last_validation_message();
    }
    void SetUp() override { errors_before_ = context_->validation_error_count(); }

    static vk::Context& context() { return *context_; }
    static scene::PassKit& kit() { return *kit_; }

    // The objects' world meshes as the renderer builds them (built-ins and procedural lenses only).
    static scene::WorldMeshes worlds(const protocol::SceneDocument& d) {
        return scene::world_meshes(d, [](const std::string& name) -> std::shared_ptr<const mesh::Mesh> {
            throw std::runtime_error("test scene names an upload: " + name);
        });
    }
    // The first object's.
    static mesh::Mesh world_mesh(const protocol::SceneDocument& d) { return worlds(d).begin()->second; }

private:
    friend class GpuTestEnvironment;
    static inline std::unique_ptr<vk::Context> context_;
    static inline std::unique_ptr<scene::PassKit> kit_;
    size_t errors_before_ = 0;
};

// Releases the shared context when the tests are done, inside main: left to the static destructors, it
// would outlive NVIDIA's driver, whose own exit handlers run first (every test binary then crashed on
// exit on an H200, after its tests had passed).
class GpuTestEnvironment : public ::testing::Environment {
public:
    void TearDown() override {
        GpuTest::kit_.reset();
        GpuTest::context_.reset();
    }
};
inline ::testing::Environment* const gpu_test_environment =
    ::testing::AddGlobalTestEnvironment(new GpuTestEnvironment);

// How far apart two frames' pixels are: the sum of their rgb differences' lengths. A change that must stay
// within the photon noise is held against what two photon seeds' frames differ by.
inline double frame_difference(const std::vector<glm::vec4>& a, const std::vector<glm::vec4>& b) {
    double sum = 0.0;
    for (size_t i = 0; i < a.size(); ++i) sum += glm::length(glm::dvec3(a[i]) - glm::dvec3(b[i]));
    return sum;
}

}  // namespace refract::testing
