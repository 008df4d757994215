// One Vulkan context and one set of compiled passes per test binary (creating them per test would
// dominate the suite's time on lavapipe), with the validation layer on and its errors failing tests.
#pragma once

#include <gtest/gtest.h>

#include <memory>

#include "mesh/mesh.h"
#include "protocol/scene_document.h"
#include "scene/scene_gpu.h"
#include "vk/context.h"

namespace refract::testing {

class GpuTest : public ::testing::Test {
protected:
    static void SetUpTestSuite() {
        if (!context_) {
            context_ = std::make_unique<vk::Context>(vk::options_from_environment({}));
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

    // The object's world mesh as the renderer builds it (procedural lenses fill a sphere).
    static mesh::Mesh world_mesh(const protocol::SceneDocument& d) {
        mesh::Mesh base;
        const auto& o = d.object;
        if (o.mesh == "cube" && o.index_field == protocol::IndexFieldKind::uniform) base = mesh::make_cube();
        else if (o.mesh == "torus" && o.index_field == protocol::IndexFieldKind::uniform) base = mesh::make_torus();
        else base = mesh::make_sphere(5);
        auto f = [](const protocol::Vec3& v) {
            return glm::vec3(static_cast<float>(v[0]), static_cast<float>(v[1]), static_cast<float>(v[2]));
        };
        return mesh::transformed(base, static_cast<float>(o.scale), f(o.rotation_deg), f(o.position));
    }

private:
    static inline std::unique_ptr<vk::Context> context_;
    static inline std::unique_ptr<scene::PassKit> kit_;
    size_t errors_before_ = 0;
};

}  // namespace refract::testing
