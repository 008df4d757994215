// What a scene document names besides itself (meshes, index grids, environment maps), and how the
// renderer finds them: the store answers these lookups, the renderer never sees the store.
#pragma once

#include <functional>
#include <memory>
#include <string>

#include "assets/index_grid.h"
#include "volume/density_export.h"

namespace refract::mesh {
struct Mesh;
}
namespace refract::image {
struct EnvironmentMap;
}

namespace refract::scene {

// Where the renderer finds uploaded assets named by a scene document. A lookup returns nullptr when the
// name is unknown. A re-upload under the same name must return a different pointer (that invalidates).
struct Assets {
    std::function<std::shared_ptr<const mesh::Mesh>(const std::string& name)> mesh;
    std::function<std::shared_ptr<const IndexGrid>(const std::string& name)> grid;
    std::function<std::shared_ptr<const image::EnvironmentMap>(const std::string& name)> environment;
    // The float grid `grid` of the uploaded volume `name`, exported apart (volume/vdb_check.h).
    std::function<std::shared_ptr<const volume::DensityGrid>(const std::string& name, const std::string& grid)> density;
};

}  // namespace refract::scene
