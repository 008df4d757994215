#include "store/store.h"

#include <algorithm>
#include <cmath>
#include <iostream>
#include <random>
#include <sstream>

#include "volume/builtin_volumes.h"
#include "volume/vdb_check.h"

namespace refract::scene {

namespace {

constexpr uint32_t kMinGridSide = 2;
constexpr uint32_t kMaxGridSide = 512;

}  // namespace

std::string random_hex_id() {
    static std::mutex mutex;
    static std::mt19937_64 engine{std::random_device{}()};
    std::lock_guard lock(mutex);
    std::ostringstream out;
    out << std::hex << (engine() & 0xffffffffull);
    std::string id = out.str();
    return std::string(8 - id.size(), '0') + id;
}

std::string strip_upload_prefix(const std::string& name) {
    constexpr std::string_view prefix = "upload:";
    if (name.compare(0, prefix.size(), prefix) == 0) return name.substr(prefix.size());
    return name;
}

uint64_t next_revision(uint64_t revision) {
    if (revision >= kMaxRevision)
        throw StoreError(StoreFailure::out_of_revisions, "the scene is at the highest revision, 2^53 - 1");
    return revision + 1;
}

void validate_index_grid(const IndexGrid& grid) {
    for (uint32_t side : {grid.nx, grid.ny, grid.nz}) {
        if (side < kMinGridSide || side > kMaxGridSide)
            throw StoreError(StoreFailure::invalid, "index grid sides must be between " +
                                                        std::to_string(kMinGridSide) + " and " +
                                                        std::to_string(kMaxGridSide));
    }
    // Bounds the renderer's float coordinates hold: within a kilometre of the origin (a scene's box is
    // metres across), voxels at least a micrometre.
    constexpr double kMaxCoordinate = 1e3, kMinVoxel = 1e-6;
    const uint32_t sides[3] = {grid.nx, grid.ny, grid.nz};
    for (size_t axis = 0; axis < 3; ++axis) {
        const double lo = grid.bounds.min[axis], hi = grid.bounds.max[axis];
        if (!std::isfinite(lo) || !std::isfinite(hi) || !(lo < hi))
            throw StoreError(StoreFailure::invalid, "index grid bounds need finite min < max on every axis");
        if (std::abs(lo) > kMaxCoordinate || std::abs(hi) > kMaxCoordinate || (hi - lo) / sides[axis] < kMinVoxel)
            throw StoreError(
                StoreFailure::invalid,
                "index grid bounds must lie within 1000 m of the origin, with voxels of at least 1 um");
    }
    if (!has_cubic_voxels(grid))
        throw StoreError(
            StoreFailure::invalid,
            "index grid voxels must be cubic (within 1%): (max - min) / side the same on every axis");
    if (grid.n.size() != size_t{grid.nx} * grid.ny * grid.nz)
        throw StoreError(StoreFailure::invalid,
                         "index grid holds " + std::to_string(grid.n.size()) + " values, expected nx*ny*nz");
    for (size_t i = 0; i < grid.n.size(); ++i) {
        float n = grid.n[i];
        if (!std::isfinite(n) || n < 1.0f || n > 4.0f) {
            std::ostringstream message;
            message << "index grid value " << i << " is " << n
                    << "; every value must be finite and in [1, 4]";
            throw StoreError(StoreFailure::invalid, message.str());
        }
    }
}

void check_unused(const std::vector<SceneSnapshot>& scenes, AssetKind kind, const std::string& name,
                  const std::string& what) {
    std::vector<std::string> users;
    for (const auto& scene : scenes) {
        const protocol::SceneDocument& document = scene.document;
        bool uses = kind == AssetKind::environment && document.environment.type == protocol::EnvironmentKind::image &&
                    document.environment.image == name;
        for (const auto& [volume_name, density] : document.volumes)
            uses = uses || (kind == AssetKind::volume && density.asset == name);
        for (const auto& [object_name, object] : document.objects) {
            uses = uses || (kind == AssetKind::mesh && object.mesh == "upload:" + name) ||
                   (kind == AssetKind::grid && object.index_field == protocol::IndexFieldKind::grid && object.grid == name);
        }
        if (uses) users.push_back(scene.id);
    }
    if (users.empty()) return;
    std::sort(users.begin(), users.end());
    std::string list;
    for (const auto& id : users) list += (list.empty() ? "'" : ", '") + id + "'";
    throw AssetInUse(what + " is used by scene" + (users.size() == 1 ? " " : "s ") + list +
                         "; edit them to use another before deleting it",
                     std::move(users));
}

volume::VolumeReport inspect_volume_upload(const std::string& name, const std::string& bytes,
                                           const protocol::Limits& limits) {
    if (!valid_mesh_name(name))
        throw StoreError(StoreFailure::invalid, "volume name must match [A-Za-z0-9_.-]{1,64}");
    return volume::inspect_vdb_apart(bytes, volume::limits_for_resolution(limits.max_resolution));
}

uint64_t host_bytes(const mesh::Mesh& mesh) {
    return sizeof mesh + mesh.positions.capacity() * sizeof(glm::vec3) + mesh.triangles.capacity() * sizeof(glm::uvec3);
}

uint64_t host_bytes(const IndexGrid& grid) {
    return sizeof grid + grid.n.capacity() * sizeof(float);
}

uint64_t host_bytes(const image::EnvironmentMap& map) {
    return sizeof map + map.rgb.capacity() * sizeof(float);
}

uint64_t host_bytes(const volume::DensityGrid& grid) {
    return sizeof grid + grid.leaves.capacity() * sizeof(volume::DensityLeaf);
}

bool valid_scene_id(const std::string& id) {
    if (id.empty() || id.size() > 32) return false;
    for (char c : id) {
        bool ok = (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '-';
        if (!ok) return false;
    }
    return true;
}

std::shared_ptr<const mesh::Mesh> parse_mesh_upload(const std::string& name, const std::string& obj_text,
                                                    const mesh::MeshLimits& limits, const AssetCache& cache) {
    if (!valid_mesh_name(name))
        throw StoreError(StoreFailure::invalid, "mesh name must match [A-Za-z0-9_.-]{1,64}");
    auto parsed = std::make_shared<const mesh::Mesh>(mesh::parse_obj(obj_text, limits));
    cache.check_fits("mesh '" + name + "'", host_bytes(*parsed));
    return parsed;
}

std::shared_ptr<const image::EnvironmentMap> decode_environment_upload(const std::string& name, const std::string& bytes,
                                                                       const AssetCache& cache) {
    if (!valid_mesh_name(name))
        throw StoreError(StoreFailure::invalid, "environment name must match [A-Za-z0-9_.-]{1,64}");
    if (image::built_in_environment(name))
        throw StoreError(StoreFailure::invalid, "\"" + name + "\" is a built-in environment");
    cache.check_fits("environment '" + name + "'", image::environment_size(bytes).decoded_bytes());
    return std::make_shared<const image::EnvironmentMap>(image::decode_environment(bytes));
}

bool valid_mesh_name(const std::string& name) {
    if (name.empty() || name.size() > 64 || name == "." || name == "..") return false;
    for (char c : name) {
        bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' ||
                  c == '.' || c == '-';
        if (!ok) return false;
    }
    return true;
}

nlohmann::json to_json(const mesh::MeshReport& report) {
    return {
        {"vertices", report.vertices},
        {"triangles", report.triangles},
        {"boundary_edges", report.boundary_edges},
        {"non_manifold_edges", report.non_manifold_edges},
        {"degenerate_triangles", report.degenerate_triangles},
        {"watertight", report.watertight()},
        {"bounds",
         {{"min", {report.min.x, report.min.y, report.min.z}},
          {"max", {report.max.x, report.max.y, report.max.z}}}},
    };
}

mesh::MeshReport report_from_json(const nlohmann::json& j) {
    mesh::MeshReport report;
    report.vertices = j.at("vertices").get<size_t>();
    report.triangles = j.at("triangles").get<size_t>();
    report.boundary_edges = j.at("boundary_edges").get<size_t>();
    report.non_manifold_edges = j.value("non_manifold_edges", size_t{0});
    report.degenerate_triangles = j.value("degenerate_triangles", size_t{0});
    const auto& bounds = j.at("bounds");
    for (int axis = 0; axis < 3; ++axis) {
        report.min[axis] = bounds.at("min").at(static_cast<size_t>(axis)).get<float>();
        report.max[axis] = bounds.at("max").at(static_cast<size_t>(axis)).get<float>();
    }
    return report;
}

std::vector<EnvironmentEntry> Store::list_environments() const {
    std::vector<EnvironmentEntry> all;
    for (const auto& name : image::built_in_environment_names()) {
        const auto map = image::built_in_environment(name);
        all.push_back({name, map->width, map->height, true});
    }
    for (auto& entry : list_stored_environments()) all.push_back(std::move(entry));
    return all;
}

std::shared_ptr<const image::EnvironmentMap> Store::environment(const std::string& name) const {
    if (auto built_in = image::built_in_environment(name)) return built_in;
    return valid_mesh_name(name) ? stored_environment(name) : nullptr;
}

void check_environment(const protocol::SceneDocument& document,
                       const std::function<bool(const std::string& name)>& stored) {
    const auto& environment = document.environment;
    if (environment.type != protocol::EnvironmentKind::image || image::built_in_environment(environment.image) ||
        (valid_mesh_name(environment.image) && stored(environment.image)))
        return;
    throw protocol::ValidationError("/environment/image", "no environment named \"" + environment.image +
                                                              "\" (GET /api/environments lists them)");
}

void check_volumes(const protocol::SceneDocument& document,
                   const std::function<std::optional<volume::VolumeReport>(const std::string& name)>& stored) {
    for (const auto& member : document.volumes) {
        const std::string& key = member.first;
        const protocol::DensityVolume& density = member.second;  // named, not bound: the lambda below takes it
        const std::string base = "/volumes/" + key;  // keys are valid names: nothing to escape
        const std::optional<volume::VolumeReport> report =
            volume::is_builtin_volume(density.asset) ? volume::builtin_volume_report(density.asset) : stored(density.asset);
        if (!report)
            throw protocol::ValidationError(base + "/asset", "no volume named \"" + density.asset +
                                                                 "\" (GET /api/volumes lists them)");
        auto check_grid = [&](const std::string& name, const std::string& pointer) {
            std::string usable;
            bool found = false;
            for (const volume::GridSummary& grid : report->grids) {
                found = found || (grid.usable && grid.name == name);
                if (grid.usable) usable += (usable.empty() ? "\"" : ", \"") + grid.name + "\"";
            }
            if (!found)
                throw protocol::ValidationError(pointer, "volume \"" + density.asset + "\" has no usable float grid \"" +
                                                             name + "\" (its usable grids: " + usable + ")");
        };
        check_grid(density.grid, base + "/grid");
        if (density.emission.emits())
            check_grid(density.emission_grid(),
                       base + (density.emission.grid.empty() ? "/emission/temperature_grid" : "/emission/grid"));
    }
}

Assets Store::assets() const {
    Assets assets;
    assets.mesh = [this](const std::string& name) { return mesh(name); };
    assets.grid = [this](const std::string& name) { return grid(name); };
    assets.environment = [this](const std::string& name) { return environment(name); };
    assets.density = [this](const std::string& name, const std::string& grid) {
        return volume::is_builtin_volume(name) ? volume::builtin_density(name, grid) : density(name, grid);
    };
    return assets;
}

Subscription Store::on_change(StoreListener listener) const {
    std::lock_guard lock(listeners_mutex_);
    listeners_.emplace(next_listener_, std::move(listener));
    return Subscription(this, next_listener_++);
}

Subscription::~Subscription() {
    if (!store_) return;
    std::lock_guard lock(store_->listeners_mutex_);
    store_->listeners_.erase(id_);
}

void Store::publish(const StoreEvent& event) const {
    std::lock_guard lock(listeners_mutex_);
    for (const auto& [id, listener] : listeners_) {
        try {
            listener(event);
        } catch (const std::exception& e) {
            // A viewer that cannot be told must not turn a committed edit into a failed request.
            std::cerr << "refractd: change listener for '" << event.name << "' failed: " << e.what() << "\n";
        }
    }
}

}  // namespace refract::scene
