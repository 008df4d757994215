#include "cli/commands.h"

#include <algorithm>
#include <cctype>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <sstream>
#include <stdexcept>

#include <nlohmann/json.hpp>

#include "cli/slices.h"
#include "gltf/gltf_error.h"
#include "gltf/gltf_import.h"
#include "image/environment_map.h"
#include "image/exr.h"
#include "image/png.h"
#include "mesh/mesh.h"
#include "protocol/animation.h"
#include "protocol/scene_document.h"
#include "render/object_mesh.h"
#include "render/renderer.h"
#include "render/scene_gpu.h"
#include "vk/context.h"
#include "volume/builtin_volumes.h"
#include "volume/vdb_reader.h"

namespace refract::cli {
namespace {

using nlohmann::json;

struct Loaded {
    protocol::SceneDocument document;
    std::map<std::string, std::shared_ptr<const mesh::Mesh>> meshes;
    std::map<std::string, std::shared_ptr<const image::EnvironmentMap>> environments;
    std::map<std::string, std::pair<std::string, std::string>> volumes;  // --volume NAME: its file and bytes
};

json read_json_file(const std::string& path) {
    std::ifstream in(path);
    if (!in) throw std::runtime_error("cannot read " + path);
    try {
        return json::parse(in);
    } catch (const json::parse_error& e) {
        throw std::runtime_error(path + ": not valid JSON: " + e.what());
    }
}

// The path's extension in lower case (".glb", ".exr").
std::string extension_of(const std::string& path) {
    std::string extension = std::filesystem::path(path).extension().string();
    for (char& c : extension) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return extension;
}

bool is_gltf(const std::string& path) { return extension_of(path) == ".glb" || extension_of(path) == ".gltf"; }

// A glTF scene: its document, and its meshes beside those --mesh gave; what it says that has no meaning
// here goes to stderr.
void load_gltf(const std::string& path, Loaded& loaded) {
    std::ifstream in(path, std::ios::binary);
    std::ostringstream bytes;
    bytes << in.rdbuf();
    try {
        gltf::ImportedScene imported = gltf::import_gltf(bytes.str(), [&](const std::string& reference) {
            protocol::Object object;
            object.mesh = reference;
            return scene::base_mesh(object, [&](const std::string& name) -> std::shared_ptr<const mesh::Mesh> {
                const auto it = loaded.meshes.find(name);
                return it == loaded.meshes.end() ? nullptr : it->second;
            });
        });
        for (auto& m : imported.meshes) loaded.meshes[m.name] = std::make_shared<mesh::Mesh>(std::move(m.mesh));
        for (const auto& warning : imported.warnings) std::cerr << path << ": " << warning << "\n";
        loaded.document = std::move(imported.document);
    } catch (const gltf::GltfError& e) {
        throw std::runtime_error(path + ": " + e.what());
    }
}

Loaded load(const Arguments& args) {
    Loaded loaded;
    for (const auto& [name, file] : args.meshes)
        loaded.meshes[name] = std::make_shared<mesh::Mesh>(mesh::load_obj_file(file));
    const std::string& scene = args.positional[0];
    if (is_gltf(scene))
        load_gltf(scene, loaded);
    else
        loaded.document = protocol::parse_scene(scene == "-" ? json::object() : read_json_file(scene));
    // Checked whole, as refractd checks an upload; the scene's volumes name them.
    for (const auto& [name, file] : args.volumes) {
        std::ifstream in(file, std::ios::binary);
        std::ostringstream bytes;
        bytes << in.rdbuf();
        try {
            volume::inspect_vdb(bytes.str(), volume::limits_for_resolution(protocol::Limits{}.max_resolution));
        } catch (const volume::VolumeError& e) {
            throw std::runtime_error(file + ": " + e.what());
        }
        loaded.volumes[name] = {file, bytes.str()};
    }
    for (const auto& [name, file] : args.environments) {
        std::ifstream in(file, std::ios::binary);
        std::ostringstream bytes;
        bytes << in.rdbuf();
        try {
            loaded.environments[name] = std::make_shared<image::EnvironmentMap>(image::decode_environment(bytes.str()));
        } catch (const image::EnvironmentError& e) {
            throw std::runtime_error(file + ": " + e.what());
        }
    }
    return loaded;
}

// The environment image `name`, given by --environment or built in; nullptr when neither has it.
std::shared_ptr<const image::EnvironmentMap> find_environment(const Loaded& loaded, const std::string& name) {
    const auto it = loaded.environments.find(name);
    return it != loaded.environments.end() ? it->second : image::built_in_environment(name);
}

// The scene's environment image, resolved as the renderer resolves it; nullptr unless it has one.
std::shared_ptr<const image::EnvironmentMap> environment_of(const Loaded& loaded) {
    const auto& environment = loaded.document.environment;
    if (environment.type != protocol::EnvironmentKind::image) return nullptr;
    auto map = find_environment(loaded, environment.image);
    if (!map) throw std::runtime_error("the scene names environment " + environment.image + ": pass --environment " +
                                       environment.image + "=FILE");
    return map;
}

// The grid of each of the scene's volumes, from the files --volume gave (exported in this process: the
// CLI reads the user's own files, as it checks them) or the built-in ones.
scene::Densities densities_of(const Loaded& loaded) {
    scene::Densities densities;
    for (const auto& [key, member] : loaded.document.volumes) {
        if (volume::is_builtin_volume(member.asset) && !loaded.volumes.contains(member.asset)) {
            densities[key] = builtin_volume_grids(member);
            continue;
        }
        const auto it = loaded.volumes.find(member.asset);
        if (it == loaded.volumes.end())
            throw std::runtime_error("the scene names volume " + member.asset + ": pass --volume " + member.asset + "=FILE (.vdb or .nvdb)");
        auto grid = [&](const std::string& name) {
            return std::make_shared<const volume::DensityGrid>(volume::export_density(
                it->second.second, name, volume::limits_for_resolution(protocol::Limits{}.max_resolution)));
        };
        try {
            densities[key].density = grid(member.grid);
            if (member.emission.emits()) densities[key].emission = grid(member.emission_grid());
        } catch (const volume::VolumeError& e) {
            throw std::runtime_error(it->second.first + ": " + e.what());
        }
    }
    return densities;
}

// The objects' meshes in world space, resolved as the renderer resolves them.
scene::WorldMeshes world_meshes(const Loaded& loaded) {
    return scene::world_meshes(loaded.document, [&](const std::string& name) -> std::shared_ptr<const mesh::Mesh> {
        const auto it = loaded.meshes.find(name);
        if (it == loaded.meshes.end()) throw std::runtime_error("the scene names upload:" + name + ": pass --mesh " + name + "=FILE.obj");
        return it->second;
    });
}

std::filesystem::path output_dir(const Arguments& args) {
    std::filesystem::create_directories(args.out);
    return args.out;
}

json timings_json(const std::vector<std::pair<std::string, double>>& gpu_ms) {
    json t = json::object();
    for (const auto& [name, ms] : gpu_ms) t[name] = ms;
    return t;
}

json grid_json(const passes::GridGeometry& g) {
    const glm::vec3 hi = g.max_corner();
    return {{"dims", {g.dims.x, g.dims.y, g.dims.z}},
            {"voxel_size", g.voxel_size},
            {"light_factor", g.light_factor},
            {"bounds", {{"min", {g.origin.x, g.origin.y, g.origin.z}}, {"max", {hi.x, hi.y, hi.z}}}}};
}

void write_json(const std::filesystem::path& path, const json& j) {
    std::ofstream out(path);
    out << j.dump(2) << "\n";
    if (!out) throw std::runtime_error("cannot write " + path.string());
}

// A one-shot command compiles only the pipelines its frames dispatch: with every pass's set compiled up
// front a 32^2 render took 0.74-0.84 s on lavapipe against 0.40 s (the 512^2 one against POV-Ray: 1.87-1.96
// against 1.58-1.59 s).
vk::Context make_context_for(const Arguments& args) {
    vk::ContextOptions options;
    options.device_name = args.device;
    options.compile_on_first_use = true;
    return vk::Context(vk::options_from_environment(options));
}

void write_index_slices(const std::filesystem::path& dir, const scene::SceneGpu& gpu) {
    const auto field = gpu.read_index_field();
    std::vector<float> n(field.size());
    for (size_t i = 0; i < n.size(); ++i) n[i] = field[i].x;
    const auto [lo, hi] = std::minmax_element(n.begin(), n.end());
    write_slice_png((dir / "index_xy.png").string(), n, gpu.grid().dims, SliceAxis::xy, *lo, *hi);
    write_slice_png((dir / "index_xz.png").string(), n, gpu.grid().dims, SliceAxis::xz, *lo, *hi);
    const auto levels = gpu.read_levels();
    std::vector<float> l(levels.begin(), levels.end());
    write_slice_png((dir / "octree_levels_xy.png").string(), l, gpu.grid().dims, SliceAxis::xy, 0.0f, 5.0f);
}

// The frame as PNG, or for a .exr path as linear half-float RGB with the frame's metadata.
void write_frame(const std::string& path, const scene::SceneGpu& gpu, const protocol::SceneDocument& document) {
    if (extension_of(path) != ".exr") {
        image::write_file(path, image::encode_png(gpu.read_ldr(), gpu.width(), gpu.height()));
        return;
    }
    const auto hdr = gpu.read_hdr();
    const std::string exr = image::encode_exr(std::span<const float>(&hdr[0].x, hdr.size() * 4), gpu.width(),
                                              gpu.height(), image::frame_attributes(document, 1, document.photons.count));
    image::write_file(path, std::span(reinterpret_cast<const uint8_t*>(exr.data()), exr.size()));
}

}  // namespace

scene::VolumeGrids builtin_volume_grids(const protocol::DensityVolume& member) {
    scene::VolumeGrids grids{volume::builtin_density(member.asset, member.grid),
                             member.emission.emits() ? volume::builtin_density(member.asset, member.emission_grid()) : nullptr};
    if (!grids.density || (member.emission.emits() && !grids.emission))
        throw std::runtime_error("built-in volume " + member.asset + " has no grid '" +
                                 (grids.density ? member.emission_grid() : member.grid) + "'");
    return grids;
}

int devices_command() {
    const auto devices = vk::list_devices();
    if (devices.empty()) {
        std::cout << "no Vulkan devices found (install mesa-vulkan-drivers for lavapipe)\n";
        return 1;
    }
    for (const auto& d : devices) {
        std::cout << d.index << ": " << d.name << " [" << d.type << "] driver " << d.driver_name << " ("
                  << d.driver_info << "), Vulkan " << d.api_version << ", " << d.device_local_bytes / (1024 * 1024)
                  << " MiB device-local: " << (d.suitable ? "usable" : "NOT usable");
        for (const auto& m : d.missing) std::cout << "\n     missing: " << m;
        std::cout << "\n";
    }
    return 0;
}

int voxelize_command(const Arguments& args) {
    const Loaded loaded = load(args);
    const auto dir = output_dir(args);
    vk::Context context = make_context_for(args);
    scene::PassKit kit(context);
    scene::SceneGpu gpu(kit);
    const scene::WorldMeshes worlds = world_meshes(loaded);
    scene::RunOptions options;
    options.limit = scene::kVoxelize | scene::kIndexField | scene::kOctree;
    const auto stats = gpu.run(scene::kAllPasses, loaded.document, worlds, nullptr, options);
    write_index_slices(dir, gpu);
    const auto coverage = gpu.read_coverage();
    double filled = 0.0;
    for (float c : coverage) filled += static_cast<double>(c);
    const double h = gpu.grid().voxel_size;
    json meshes = json::object();
    for (const auto& [name, world] : worlds) {
        const auto report = mesh::inspect(world);
        meshes[name] = {{"triangles", report.triangles}, {"boundary_edges", report.boundary_edges},
                        {"non_manifold_edges", report.non_manifold_edges}, {"watertight", report.watertight()}};
    }
    json summary = {{"device", context.info().name},
                    {"resolution", loaded.document.volume.resolution},
                    {"grid", grid_json(gpu.grid())},
                    {"filled_volume_m3", filled * h * h * h},
                    {"meshes", meshes},
                    {"gpu_ms", timings_json(stats.gpu_ms)}};
    write_json(dir / "summary.json", summary);
    std::cout << summary.dump(2) << "\n";
    return 0;
}

int trace_command(const Arguments& args) {
    const Loaded loaded = load(args);
    const scene::Densities densities = densities_of(loaded);  // a grid not there is refused before the device
    const auto dir = output_dir(args);
    vk::Context context = make_context_for(args);
    scene::PassKit kit(context);
    scene::SceneGpu gpu(kit);
    scene::RunOptions options;
    options.limit = scene::kAllPasses & ~scene::kView;
    const auto stats = gpu.run(scene::kAllPasses, loaded.document, world_meshes(loaded), nullptr, options,
                               environment_of(loaded).get(), densities);
    write_index_slices(dir, gpu);
    const auto radiance = gpu.read_radiance();
    std::vector<float> fluence(radiance.size());
    for (size_t i = 0; i < fluence.size(); ++i) fluence[i] = (radiance[i].r + radiance[i].g + radiance[i].b) / 3.0f;
    std::vector<float> sorted = fluence;
    std::sort(sorted.begin(), sorted.end());
    const float p999 = sorted[static_cast<size_t>(0.999 * static_cast<double>(sorted.size() - 1))];
    // Log scale: three decades below the 99.9th percentile.
    std::vector<float> log_fluence(fluence.size());
    for (size_t i = 0; i < fluence.size(); ++i)
        log_fluence[i] = std::log10(std::max(fluence[i], p999 * 1e-3f) / std::max(p999, 1e-30f));
    write_slice_png((dir / "radiance_xy.png").string(), log_fluence, gpu.grid().coarsened(gpu.grid().light_factor), SliceAxis::xy, -3.0f, 0.0f);
    write_slice_png((dir / "radiance_xz.png").string(), log_fluence, gpu.grid().coarsened(gpu.grid().light_factor), SliceAxis::xz, -3.0f, 0.0f);
    const auto floor = gpu.read_floor_map();
    float floor_peak = 0.0f;
    for (const auto& v : floor) floor_peak = std::max(floor_peak, (v.r + v.g + v.b) / 3.0f);
    write_map_png((dir / "floor_caustics.png").string(), floor, gpu.floor_map_side(), gpu.floor_map_side(), floor_peak);
    json summary = {{"device", context.info().name},
                    {"grid", grid_json(gpu.grid())},
                    {"photons_emitted", loaded.document.photons.count},
                    {"photons_traced", stats.photons_entered},
                    {"mean_steps_per_photon", stats.mean_steps_per_photon()},
                    {"mean_bounces_per_photon", stats.mean_bounces_per_photon()},
                    {"floor_hits", stats.floor_hits},
                    {"direct_overlaps", stats.direct_overlaps},
                    {"peak_fluence_w_m2", sorted.back()},
                    {"gpu_ms", timings_json(stats.gpu_ms)}};
    write_json(dir / "summary.json", summary);
    std::cout << summary.dump(2) << "\n";
    return 0;
}

int render_command(const Arguments& args) {
    const Loaded loaded = load(args);
    const scene::Densities densities = densities_of(loaded);  // a grid not there is refused before the device
    vk::Context context = make_context_for(args);
    scene::PassKit kit(context);
    scene::SceneGpu gpu(kit);
    const auto host_start = std::chrono::steady_clock::now();
    const auto stats = gpu.run(scene::kAllPasses, loaded.document, world_meshes(loaded), nullptr,
                               scene::run_options_for(args.interactive ? scene::Quality::interactive : scene::Quality::still),
                               environment_of(loaded).get(), densities);
    const auto encode_start = std::chrono::steady_clock::now();
    write_frame(args.out, gpu, loaded.document);
    const auto end = std::chrono::steady_clock::now();
    if (!args.hdr.empty()) {
        const auto hdr = gpu.read_hdr();
        image::write_pfm(args.hdr, std::span<const float>(&hdr[0].x, hdr.size() * 4), gpu.width(), gpu.height());
    }
    json summary = {{"device", context.info().name},
                    {"width", gpu.width()},
                    {"height", gpu.height()},
                    {"photons_traced", stats.photons_entered},
                    {"mean_steps_per_photon", stats.mean_steps_per_photon()},
                    {"mean_bounces_per_photon", stats.mean_bounces_per_photon()},
                    {"view_steps", stats.view_steps},
                    {"gpu_ms", timings_json(stats.gpu_ms)},
                    {"encode_ms", std::chrono::duration<double, std::milli>(end - encode_start).count()},
                    {"host_ms", std::chrono::duration<double, std::milli>(end - host_start).count()}};
    if (!args.stats.empty()) write_json(args.stats, summary);
    std::cout << summary.dump(2) << "\n";
    return 0;
}

int animate_command(const Arguments& args) {
    const Loaded loaded = load(args);
    const std::string& keyframes_file = args.positional[1];
    protocol::Animation animation = [&] {
        try {
            return protocol::Animation(loaded.document, read_json_file(keyframes_file));
        } catch (const protocol::ValidationError& e) {
            throw std::runtime_error(keyframes_file + ": " + e.what());
        }
    }();
    const auto frames = static_cast<uint64_t>(std::floor(animation.duration() * args.fps)) + 1;
    if (frames > 100000) throw std::runtime_error(keyframes_file + ": " + std::to_string(frames) + " frames at --fps " +
                                                  std::to_string(args.fps) + " (at most 100000)");
    const auto dir = output_dir(args);
    vk::Context context = make_context_for(args);
    // One renderer for the whole sequence: each frame reruns only the passes its change made stale.
    scene::Renderer renderer(context);
    scene::Assets assets;
    assets.mesh = [&](const std::string& name) -> std::shared_ptr<const mesh::Mesh> {
        const auto it = loaded.meshes.find(name);
        return it == loaded.meshes.end() ? nullptr : it->second;
    };
    assets.grid = [](const std::string&) -> std::shared_ptr<const scene::IndexGrid> { return nullptr; };
    assets.environment = [&](const std::string& name) { return find_environment(loaded, name); };
    std::map<std::string, uint64_t> reruns;      // pass name -> frames that ran it
    std::map<std::string, uint64_t> voxelized;  // object name -> frames that voxelized it
    const auto start = std::chrono::steady_clock::now();
    for (uint64_t f = 0; f < frames; ++f) {
        const double t = static_cast<double>(f) / args.fps;
        protocol::SceneDocument document;
        try {
            document = animation.at(t);
        } catch (const protocol::ValidationError& e) {
            throw std::runtime_error(keyframes_file + ": the document at " + std::to_string(t) + " s: " + e.what());
        }
        const auto frame = renderer.render("animation", document, assets);
        char name[32];
        std::snprintf(name, sizeof name, "frame_%05llu.png", static_cast<unsigned long long>(f));
        image::write_file(dir / name, frame.png);
        std::stringstream passes(scene::pass_names(frame.rerun));
        for (std::string pass; std::getline(passes, pass, ',');) ++reruns[pass];
        for (const auto& object : frame.voxelized) ++voxelized[object];
    }
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    json summary = {{"device", context.info().name},
                    {"frames", frames},
                    {"fps", args.fps},
                    {"duration_s", animation.duration()},
                    {"frames_rerunning", reruns},
                    {"frames_voxelizing", voxelized},
                    {"render_s", seconds}};
    std::cout << summary.dump(2) << "\n";
    return 0;
}

}  // namespace refract::cli
