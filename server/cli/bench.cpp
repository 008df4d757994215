// refract bench: per-pass GPU milliseconds (timestamp queries) for fixed scenes and edit kinds.
#include <httplib.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <thread>

#include "cli/commands.h"
#include "deposit_bench.h"
#include "deposit_bench_float_spv.h"
#include "deposit_bench_packed_spv.h"
#include "image/png.h"
#include "mesh/mesh.h"
#include "protocol/scene_document.h"
#include "render/medium_field.h"
#include "render/object_mesh.h"
#include "render/renderer.h"
#include "render/scene_gpu.h"
#include "render/scene_lattice.h"
#include "vk/commands.h"
#include "vk/context.h"
#include "vk/gpu_timer.h"
#include "vk/pipeline.h"

namespace refract::cli {
namespace {

using nlohmann::json;
using Clock = std::chrono::steady_clock;

// One measured configuration: a scene and the edit whose passes it reruns.
struct BenchCase {
    std::string name;
    json scene;                      // patch over the default document
    scene::PassSet edit = scene::kAllPasses;
    std::string edit_name = "full";  // "full" | "light" | "camera"
    scene::Quality quality = scene::Quality::still;  // how the passes run (as refractd runs them)
    // A merge patch each run applies and the next takes back (moving an object there and back), the
    // passes it invalidates rerun; null: each run reruns `edit` on the same document.
    json move = nullptr;
};

// Median and spread of a series of samples.
struct Summary {
    double median = 0.0, min = 0.0, max = 0.0;
};

Summary summarize(std::vector<double> v) {
    if (v.empty()) return {};
    std::sort(v.begin(), v.end());
    return {v[v.size() / 2], v.front(), v.back()};
}

json scene_patch(const std::string& base) {
    // The example scenes of the standard suite, small enough to be fixed here.
    if (base == "ball_lens_fog") return json::object();  // the default document
    if (base == "luneburg")
        return {{"object", {{"index_field", "luneburg"}, {"scale", 1.0}}},
                {"light", {{"type", "directional"}, {"direction", {0.3, -0.5, -1.0}}, {"intensity", 3.0}}}};
    if (base == "torus_floor")
        return {{"object", {{"mesh", "torus"}, {"rotation_deg", {60, 0, 0}}, {"ior", 1.5}}},
                {"medium", {{"extinction", {0.02, 0.02, 0.02}}, {"scattering", {0.02, 0.02, 0.02}}}}};
    if (base == "bunny") return {{"object", {{"mesh", "upload:bunny"}}}};
    // The ball lens in fog dispersing (flint glass): against "volume 128", what dispersion costs.
    if (base == "dispersion") return {{"object", {{"abbe", 30}}}};
    // The ball lens in fog dense enough (optical depth 2 across the beam's path to the lens, albedo 0.975)
    // that light scatters many times: what each bounce of the photons' random walks costs.
    if (base == "dense_fog")
        return {{"medium", {{"extinction", {0.8, 0.8, 0.8}}, {"scattering", {0.78, 0.78, 0.78}},
                            {"phase", {{"model", "henyey-greenstein"}, {"g", 0.3}}}}}};
    throw std::runtime_error("unknown bench scene " + base);
}

std::vector<BenchCase> standard_suite(bool gpu) {
    std::vector<BenchCase> cases;
    auto add = [&](const std::string& name, const std::string& base, json extra, scene::PassSet edit,
                   const std::string& edit_name, scene::Quality quality = scene::Quality::still) {
        json patch = scene_patch(base);
        patch.merge_patch(extra);
        cases.push_back({name, patch, edit, edit_name, quality});
    };
    // The targets of docs/benchmarks.md: camera edit, light edit, full rebuild of the ball lens in fog.
    const int image = gpu ? 1024 : 256;
    add("target camera", "ball_lens_fog", {{"volume", {{"resolution", 128}}}, {"photons", {{"count", gpu ? 1 << 20 : 1 << 16}}},
                                          {"image", {{"width", image}, {"height", image}}}}, scene::kView, "camera");
    add("target light", "ball_lens_fog", {{"volume", {{"resolution", 128}}}, {"photons", {{"count", gpu ? 1 << 20 : 1 << 16}}},
                                         {"image", {{"width", image}, {"height", image}}}}, scene::kPhotons | scene::kView, "light");
    // The same edits with the passes refractd runs while a client drags (quality=interactive), at fixed
    // sizes: those the frame budget starts from (half the document's image side, a quarter of its
    // photons) for a 2048^2 / 2^22 document (GPU) or a 512^2 / 2^18 one (lavapipe); two-voxel view
    // steps in fog, a radiance grid of a third of the resolution per axis, sampled photon deposits and
    // adaptive pixels. (refractd then sizes each frame to its budget: frame_budget.h.)
    add("target camera interactive", "ball_lens_fog", {{"volume", {{"resolution", 128}}}, {"photons", {{"count", gpu ? 1 << 20 : 1 << 16}}},
                                                       {"image", {{"width", image}, {"height", image}}}}, scene::kView, "camera", scene::Quality::interactive);
    add("target light interactive", "ball_lens_fog", {{"volume", {{"resolution", 128}}}, {"photons", {{"count", gpu ? 1 << 20 : 1 << 16}}},
                                                      {"image", {{"width", image}, {"height", image}}}}, scene::kPhotons | scene::kView, "light", scene::Quality::interactive);
    add("target light drag", "ball_lens_fog", {{"volume", {{"resolution", 128}}}, {"photons", {{"count", 1 << 12}}},
                                                      {"image", {{"width", 192}, {"height", 120}}}}, scene::kPhotons | scene::kView, "light", scene::Quality::interactive);
    add("target rebuild", "ball_lens_fog", {{"volume", {{"resolution", gpu ? 256 : 128}}}, {"photons", {{"count", gpu ? 1 << 22 : 1 << 18}}},
                                           {"image", {{"width", gpu ? 256 : 512}, {"height", gpu ? 256 : 512}}}},
        scene::kAllPasses, "full");
    // Scaling: one parameter at a time around a base case.
    const std::vector<int> resolutions = gpu ? std::vector<int>{64, 128, 256} : std::vector<int>{64, 128};
    const std::vector<int> photon_counts = gpu ? std::vector<int>{1 << 18, 1 << 20, 1 << 22}
                                               : std::vector<int>{1 << 14, 1 << 16, 1 << 18};
    const std::vector<int> images = gpu ? std::vector<int>{256, 512, 1024} : std::vector<int>{128, 256, 512};
    const int base_photons = gpu ? 1 << 20 : 1 << 16, base_image = gpu ? 512 : 256;
    for (int r : resolutions)
        add("volume " + std::to_string(r), "ball_lens_fog",
            {{"volume", {{"resolution", r}}}, {"photons", {{"count", base_photons}}}, {"image", {{"width", base_image}, {"height", base_image}}}},
            scene::kAllPasses, "full");
    for (int p : photon_counts)
        add("photons 2^" + std::to_string(std::countr_zero(static_cast<unsigned>(p))), "ball_lens_fog",
            {{"photons", {{"count", p}}}, {"image", {{"width", base_image}, {"height", base_image}}}},
            scene::kPhotons | scene::kView, "light");
    for (int i : images)
        add("image " + std::to_string(i), "ball_lens_fog",
            {{"photons", {{"count", base_photons}}}, {"image", {{"width", i}, {"height", i}}}}, scene::kView, "camera");
    for (const int b : {0, 1, 4, 16, 64})
        add("bounces " + std::to_string(b), "dense_fog",
            {{"photons", {{"count", base_photons}, {"max_bounces", b}}}, {"image", {{"width", base_image}, {"height", base_image}}}},
            scene::kPhotons | scene::kView, "light");
    // While dragging: the frame budget's starting sizes, and at most scene::kInteractiveBounces.
    for (const int b : {0, 64})
        add("bounces " + std::to_string(b) + " interactive", "dense_fog",
            {{"photons", {{"count", base_photons}, {"max_bounces", b}}}, {"image", {{"width", base_image}, {"height", base_image}}}},
            scene::kPhotons | scene::kView, "light", scene::Quality::interactive);
    // Several objects: examples/gallery.json (eight objects, three lights), its full build and a move of
    // its bunny by 5 cm, against the move of the bunny alone on a lattice of the same voxel size (its
    // own box: docs/objects-and-lights.md, "Several objects").
    std::ifstream gallery_file(std::string(REFRACT_SOURCE_DIR) + "/examples/gallery.json");
    if (gallery_file) {
        json gallery = json::parse(gallery_file);
        gallery["image"] = {{"width", base_image}, {"height", base_image * 9 / 16}};
        gallery["photons"] = {{"count", base_photons}};
        const json bunny = gallery["objects"]["bunny"];
        const json move = {{"objects", {{"bunny", {{"position", {bunny["position"][0].get<double>() + 0.05,
                                                                  bunny["position"][1], bunny["position"][2]}}}}}}};
        cases.push_back({"gallery", gallery, scene::kAllPasses, "full"});
        cases.push_back({"gallery move one", gallery, scene::kAllPasses, "move", scene::Quality::still, move});
        json alone = gallery;
        alone["objects"] = {{"bunny", bunny}};
        // The gallery's lattice voxel, which its objects' resolutions set.
        const protocol::SceneDocument parsed = protocol::parse_scene(gallery);
        const double voxel = scene::grid_for(parsed, scene::world_meshes(parsed, nullptr)).voxel_size;
        const double half = 0.65;  // around the bunny (scale 0.5) and its move
        json lo = json::array(), hi = json::array();
        for (size_t a = 0; a < 3; ++a) {
            lo.push_back(bunny["position"][a].get<double>() - half);
            hi.push_back(bunny["position"][a].get<double>() + half);
        }
        alone["volume"] = {{"resolution", static_cast<int>(std::lround(2.0 * half / voxel))}, {"bounds", {{"min", lo}, {"max", hi}}}};
        cases.push_back({"gallery bunny alone move", alone, scene::kAllPasses, "move", scene::Quality::still, move});
    }
    // Smoke: examples/smoke_past_glass.json (the built-in smoke lit through a glass ball) on a lattice of
    // 256 voxels, its still build and its light edit while dragging: what a sparse volume costs.
    std::ifstream smoke_file(std::string(REFRACT_SOURCE_DIR) + "/examples/smoke_past_glass.json");
    if (smoke_file) {
        json smoke = json::parse(smoke_file);
        smoke["volume"]["resolution"] = 256;
        smoke["image"] = {{"width", base_image}, {"height", base_image}};
        smoke["photons"] = {{"count", base_photons}};
        cases.push_back({"smoke 256", smoke, scene::kAllPasses, "full"});
        cases.push_back({"smoke 256 interactive", smoke, scene::kPhotons | scene::kView, "light", scene::Quality::interactive});
    }
    for (const std::string base : {"luneburg", "torus_floor", "bunny", "dispersion"})
        add(base, base, {{"photons", {{"count", base_photons}}}, {"image", {{"width", base_image}, {"height", base_image}}}},
            scene::kAllPasses, "full");
    return cases;
}

scene::WorldMeshes worlds_of(const protocol::SceneDocument& d, const std::map<std::string, std::shared_ptr<const mesh::Mesh>>& uploads) {
    return scene::world_meshes(d, [&](const std::string& name) -> std::shared_ptr<const mesh::Mesh> {
        const auto it = uploads.find(name);
        if (it == uploads.end()) throw std::runtime_error("bench: scene needs --mesh " + name + "=FILE.obj");
        return it->second;
    });
}

// The grids of the scene's volumes: the built-in ones (the bench reads no uploads).
scene::Densities bench_densities(const protocol::SceneDocument& d) {
    scene::Densities densities;
    for (const auto& [key, member] : d.volumes) densities[key] = builtin_volume_grids(member);
    return densities;
}

// Radiance-grid deposits per second as three packed 64-bit integer atomics (the photon pass's way)
// and as six float atomics, on the same addresses: the measurement behind the choice of integers.
json deposit_benchmark(vk::Context& context, int runs) {
    using shaders::DepositBenchPush;
    const uint32_t voxels = 128 * 128 * 128, threads = 1u << 16, per_thread = 128;
    const auto usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT;
    vk::Buffer packed(context, uint64_t{voxels} * 3 * sizeof(uint64_t), usage, vk::MemoryUse::device, "bench packed");
    vk::Buffer floats(context, uint64_t{voxels} * 6 * sizeof(float), usage, vk::MemoryUse::device, "bench floats");
    json result = {{"deposits", uint64_t{threads} * per_thread}};
    auto measure = [&](std::span<const uint32_t> spirv, uint32_t binding, const vk::Buffer& buffer, const char* name) {
        vk::ComputePipeline pipeline(context, spirv, {{binding, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER}},
                                     sizeof(DepositBenchPush), name);
        vk::GpuTimer timer(context, 2);
        std::vector<double> ms;
        for (int r = 0; r < runs + 1; ++r) {
            vk::run_once(context, [&](vk::CommandRecorder& rec) {
                timer.reset(rec.get());
                rec.fill(buffer, 0);
                rec.transfer_to_compute_barrier();
                timer.begin(rec.get(), name);
                pipeline.dispatch(rec.get(), {vk::Binding::storage_buffer(binding, buffer)},
                                  DepositBenchPush{voxels, per_thread, threads, 0},
                                  vk::group_count(threads, DEPOSIT_BENCH_GROUP_SIZE));
                timer.end(rec.get());
            });
            if (r > 0) ms.push_back(timer.read()[0].second);  // the first run warms up
        }
        const double median = summarize(ms).median;
        result[name] = {{"median_ms", median}, {"deposits_per_s", static_cast<double>(threads) * per_thread / (median * 1e-3)}};
    };
    measure(deposit_bench_packed_spv, DEPOSIT_BENCH_BINDING_PACKED, packed, "packed_int64");
    if (context.float_atomics())
        measure(deposit_bench_float_spv, DEPOSIT_BENCH_BINDING_FLOATS, floats, "float32");
    else
        result["float32"] = "VK_EXT_shader_atomic_float buffer add not supported";
    return result;
}

// Sum of the durations in a Server-Timing header ("voxelize;dur=1.2, view;dur=3.4").
double server_timing_ms(const std::string& header) {
    double sum = 0.0;
    for (size_t at = header.find("dur="); at != std::string::npos; at = header.find("dur=", at + 4))
        sum += std::strtod(header.c_str() + at + 4, nullptr);
    return sum;
}

// The daemon end to end: HTTP round trips of an edit + frame (POST frame.png) against the pass times
// the daemon reports for the same frames. The difference is the service's overhead.
int bench_daemon(const std::string& address, int runs, bool as_json) {
    const auto colon = address.rfind(':');
    if (colon == std::string::npos) throw std::runtime_error("--daemon takes HOST:PORT");
    httplib::Client client(address.substr(0, colon), std::stoi(address.substr(colon + 1)));
    client.set_read_timeout(600, 0);
    json report = {{"daemon", address}, {"runs", runs}, {"edits", json::object()}};
    // Still frames of the targets' sizes, and interactive ones of a document twice the side with four
    // times the photons, which refractd renders at the same sizes while a client drags.
    for (const bool interactive : {false, true}) {
        const std::string id = "bench-" + std::to_string(::getpid()) + (interactive ? "-interactive" : "");
        const int side = interactive ? 512 : 256;
        const json scene = {{"image", {{"width", side}, {"height", side}}},
                            {"photons", {{"count", interactive ? 1 << 18 : 1 << 16}}},
                            {"volume", {{"resolution", 128}}}};
        auto created = client.Post(("/api/scenes?id=" + id).c_str(), scene.dump(), "application/json");
        if (!created || created->status != 201)
            throw std::runtime_error("bench: cannot create a scene on " + address +
                                     (created ? ": " + created->body : ": no answer (is refractd running?)"));
        const std::string target = "/api/scenes/" + id + "/frame.png" + (interactive ? "?quality=interactive" : "");
        auto frame = [&](const json& patch, double& round_trip, double& passes) {
            const auto start = Clock::now();
            auto res = client.Post(target.c_str(), patch.dump(), "application/merge-patch+json");
            round_trip = std::chrono::duration<double, std::milli>(Clock::now() - start).count();
            if (!res || res->status != 200)
                throw std::runtime_error("bench: frame failed" + (res ? ": " + res->body : std::string()));
            passes = server_timing_ms(res->get_header_value("Server-Timing"));
        };
        double warm_trip = 0.0, warm_passes = 0.0;
        frame(json::object(), warm_trip, warm_passes);  // builds everything once
        // A move drags the object (Alt+drag in the client): its volume rebuilds with every frame.
        for (const std::string edit : {"camera", "light", "move"}) {
            std::vector<double> trips, passes, overheads;
            for (int r = 0; r < runs; ++r) {
                const double x = 0.3 * ((r % 2) ? 1.0 : -1.0);
                const json patch = edit == "camera" ? json{{"camera", {{"position", {x, 0.5, 5.0}}}}}
                                   : edit == "light" ? json{{"light", {{"position", {2.0 + x, 3.0, 1.0}}}}}
                                                     : json{{"objects", {{"object", {{"position", {0.1 * x, 0.0, 0.0}}}}}}};
                double trip = 0.0, pass = 0.0;
                frame(patch, trip, pass);
                trips.push_back(trip);
                passes.push_back(pass);
                overheads.push_back(trip - pass);
            }
            const Summary t = summarize(trips), p = summarize(passes), o = summarize(overheads);
            const std::string name = edit + (interactive ? " interactive" : "");
            report["edits"][name] = {{"round_trip_ms", t.median}, {"passes_ms", p.median}, {"overhead_ms", o.median},
                                     {"overhead_percent", 100.0 * o.median / t.median}};
            if (!as_json)
                std::printf("daemon %-18s edit + frame: round trip %.1f ms (%.1f-%.1f), passes + encode %.1f ms, "
                            "service overhead %.1f ms (%.1f%%)\n",
                            name.c_str(), t.median, t.min, t.max, p.median, o.median, 100.0 * o.median / t.median);
        }
        client.Delete(("/api/scenes/" + id).c_str());
    }
    if (as_json) std::cout << report.dump(2) << "\n";
    return 0;
}

// How each pass's time grows with its work, from the first to the last case of each one-parameter family
// of the suite (volume: voxels, photons: photons, image: pixels).
json scaling(const json& cases, bool quiet) {
    struct Family {
        const char* prefix;  // case names of the family start so
        const char* pass;
        const char* work;    // the entry's measure of the pass's work
    };
    json out = json::array();
    for (const Family f : {Family{"volume ", "voxelize", "voxels"}, Family{"volume ", "octree", "voxels"},
                           Family{"photons ", "photons", "photons"}, Family{"image ", "view", "pixels"}}) {
        std::vector<const json*> family;
        for (const auto& c : cases)
            if (c["case"].get<std::string>().starts_with(f.prefix) && c["passes"].contains(f.pass)) family.push_back(&c);
        if (family.size() < 2) continue;
        const json& first = *family.front();
        const json& last = *family.back();
        const double work = last[f.work].get<double>() / first[f.work].get<double>();
        const double from = first["passes"][f.pass]["median_ms"].get<double>();
        const double to = last["passes"][f.pass]["median_ms"].get<double>();
        out.push_back({{"pass", f.pass}, {"work", f.work}, {"from_case", first["case"]}, {"to_case", last["case"]},
                       {"work_ratio", work}, {"time_ratio", to / from}});
        if (!quiet)
            std::printf("scaling: %-9s %.0f -> %.0f ms (x%.1f) for x%.0f the %s (%s -> %s)\n", f.pass, from, to, to / from,
                        work, f.work, first["case"].get<std::string>().c_str(), last["case"].get<std::string>().c_str());
    }
    return out;
}

using Uploads = std::map<std::string, std::shared_ptr<const mesh::Mesh>>;

// The meshes the cases may name as "upload:NAME": those given with --mesh, and examples/meshes/bunny.obj
// as "bunny" (the suite's bunny case) unless --mesh gave one.
Uploads bench_uploads(const Arguments& args) {
    Uploads uploads;
    for (const auto& [name, file] : args.meshes) uploads[name] = std::make_shared<mesh::Mesh>(mesh::load_obj_file(file));
    const std::string bunny = std::string(REFRACT_SOURCE_DIR) + "/examples/meshes/bunny.obj";
    if (!uploads.count("bunny") && std::filesystem::exists(bunny))
        uploads["bunny"] = std::make_shared<mesh::Mesh>(mesh::load_obj_file(bunny));
    return uploads;
}

// The cases to measure: the --scene document's full rebuild, light and camera edits, or the standard
// suite's cases (those starting with --case).
std::vector<BenchCase> bench_cases(const Arguments& args, bool gpu) {
    std::vector<BenchCase> cases;
    if (!args.scene_file.empty()) {
        std::ifstream in(args.scene_file);
        if (!in) throw std::runtime_error("cannot read " + args.scene_file);
        const json scene = json::parse(in);
        for (const auto& [edit, name] : {std::pair{scene::kAllPasses, "full"}, {scene::kPhotons | scene::kView, "light"},
                                         {scene::kView, "camera"}})
            cases.push_back({args.scene_file, scene, edit, name});
    } else if (args.suite.empty() || args.suite == "standard") {
        cases = standard_suite(gpu);
        std::erase_if(cases, [&](const BenchCase& c) { return !c.name.starts_with(args.only); });
        if (cases.empty()) throw std::runtime_error("bench: no case of the suite starts with '" + args.only + "'");
    } else {
        throw std::runtime_error("unknown suite '" + args.suite + "' (standard)");
    }
    return cases;
}

// Runs the deposit microbenchmark, prints its line (unless `quiet`) and returns its report.
json report_deposits(vk::Context& context, int runs, bool quiet) {
    const json deposits = deposit_benchmark(context, runs);
    if (!quiet) {
        std::printf(
            "deposits (2^23 scattered voxel deposits of six sums): packed int64 atomics %.1f ms (%.1f M/s)",
            deposits["packed_int64"]["median_ms"].get<double>(),
            deposits["packed_int64"]["deposits_per_s"].get<double>() * 1e-6);
        if (deposits["float32"].is_object())
            std::printf(", float atomics %.1f ms (%.1f M/s)\n",
                        deposits["float32"]["median_ms"].get<double>(),
                        deposits["float32"]["deposits_per_s"].get<double>() * 1e-6);
        else
            std::printf(", float atomics: %s\n", deposits["float32"].get<std::string>().c_str());
    }
    return deposits;
}

// What the timed runs of one case measured, after a warm-up run that built everything once.
struct CaseRuns {
    std::map<std::string, std::vector<double>> pass_ms;  // GPU milliseconds of each pass, a sample a run
    std::vector<double> host_ms, encode_ms;              // each run's wall time, and its PNG encode's
    scene::RunStats last;                                // the last run's statistics
    int64_t memory = 0;                                  // device memory the scene holds
};

// Runs case `c` on `scene_gpu` (new, holding nothing) once to warm up, then `runs` times timed.
// `memory_before`: the device memory allocated before `scene_gpu` was made (what it adds is the case's).
CaseRuns run_case(vk::Context& context, int64_t memory_before, scene::SceneGpu& scene_gpu, const BenchCase& c,
                  const protocol::SceneDocument& document, const scene::WorldMeshes& worlds,
                  const scene::Densities& densities, const Uploads& uploads, int runs) {
    CaseRuns measured;
    scene::RunOptions run_options = scene::run_options_for(c.quality);
    // A rebuild voxelizes every object again, though their coverage is resident.
    run_options.voxelize.again = c.move.is_null() && (c.edit & scene::kVoxelize);
    scene_gpu.run(scene::kAllPasses, document, worlds, nullptr, run_options, nullptr,
                  densities);  // warm-up: builds everything once
    measured.memory = context.allocated_bytes() - memory_before;
    // A moving case alternates between the document and the moved one.
    const protocol::SceneDocument moved =
        c.move.is_null() ? document : protocol::apply_merge_patch(document, c.move);
    const scene::WorldMeshes moved_worlds = worlds_of(moved, uploads);
    for (int r = 0; r < runs; ++r) {
        const bool there = !c.move.is_null() && r % 2 == 0;
        const protocol::SceneDocument& from = there ? document : moved;
        const protocol::SceneDocument& to = there ? moved : document;
        const scene::PassSet passes = c.move.is_null() ? c.edit : scene::passes_invalidated(from, to);
        const auto start = Clock::now();
        measured.last = scene_gpu.run(passes, to, there ? moved_worlds : worlds, nullptr, run_options, nullptr, densities);
        const auto encode_start = Clock::now();
        const auto png = image::encode_png(scene_gpu.read_ldr(), scene_gpu.width(), scene_gpu.height());
        const auto end = Clock::now();
        for (const auto& [name, ms] : measured.last.gpu_ms) measured.pass_ms[name].push_back(ms);
        measured.encode_ms.push_back(std::chrono::duration<double, std::milli>(end - encode_start).count());
        measured.host_ms.push_back(std::chrono::duration<double, std::milli>(end - start).count());
    }
    return measured;
}

// What a dense lattice of the scene's voxel over the same box would hold, field and light alike (the
// budget's estimate; the measured memory's counterpart for a scene of one object).
int64_t dense_lattice_bytes(const scene::SceneGpu& scene_gpu, const protocol::SceneDocument& document) {
    const passes::GridGeometry& lattice = scene_gpu.grid();
    return scene::estimate_scene_bytes(lattice, lattice.dims.count(), 0, lattice.dims.count(),
                                       document.image.width, document.image.height);
}

// The report's entry for one case: its size, each pass's median and spread, and the throughputs.
json case_entry(const BenchCase& c, const protocol::SceneDocument& document, const scene::Densities& densities,
                const scene::SceneGpu& scene_gpu, const CaseRuns& measured) {
    json entry = {{"case", c.name},
                  {"edit", c.edit_name},
                  {"quality", c.quality == scene::Quality::interactive ? "interactive" : "still"},
                  {"device_memory_mib", static_cast<double>(measured.memory) / (1 << 20)},
                  {"voxels", scene_gpu.grid().dims.count()},
                  {"photons", document.photons.count},
                  {"pixels", uint64_t{document.image.width} * document.image.height},
                  {"passes", json::object()}};
    entry["field_atlas"] = {
        {"clusters", scene_gpu.field_atlas().dense ? 0 : scene_gpu.field_atlas().clusters.size()},
        {"voxels", scene_gpu.field_atlas().dims.count()}};
    entry["dense_lattice_mib"] = static_cast<double>(dense_lattice_bytes(scene_gpu, document)) / (1 << 20);
    if (!document.volumes.empty()) {
        // The sparse medium field against a dense one of the lattice's voxel (its two or three atlases).
        const scene::MediumFieldLayout field = scene::plan_medium_field(scene_gpu.grid(), document.volumes, densities);
        entry["medium_field"] = {
            {"step", field.step}, {"bricks", field.brick_count},
            {"mib", static_cast<double>(scene::medium_field_bytes(field)) / (1 << 20)},
            {"dense_mib", static_cast<double>(scene_gpu.grid().dims.count() * sizeof(glm::vec4) * (field.emits ? 3 : 2)) / (1 << 20)}};
    }
    double gpu_total = 0.0;
    for (const auto& [name, samples] : measured.pass_ms) {
        const Summary s = summarize(samples);
        entry["passes"][name] = {{"median_ms", s.median}, {"min_ms", s.min}, {"max_ms", s.max}};
        gpu_total += s.median;
    }
    const Summary host = summarize(measured.host_ms), encode = summarize(measured.encode_ms);
    entry["host_ms"] = {{"median_ms", host.median}, {"min_ms", host.min}, {"max_ms", host.max}};
    entry["encode_ms"] = encode.median;
    entry["gpu_total_ms"] = gpu_total;
    const scene::RunStats& last = measured.last;
    if (measured.pass_ms.count("photons")) {
        const double ms = summarize(measured.pass_ms.at("photons")).median;
        entry["photons_per_s"] = static_cast<double>(last.photons_entered) / (ms * 1e-3);
        entry["photon_steps_per_s"] = static_cast<double>(last.photon_steps) / (ms * 1e-3);
        entry["mean_steps_per_photon"] = last.mean_steps_per_photon();
        entry["mean_bounces_per_photon"] = last.mean_bounces_per_photon();
    }
    if (measured.pass_ms.count("view")) {
        const double ms = summarize(measured.pass_ms.at("view")).median;
        entry["view_steps_per_s"] = static_cast<double>(last.view_steps) / (ms * 1e-3);
        entry["ns_per_pixel"] = ms * 1e6 / static_cast<double>(entry["pixels"].get<uint64_t>());
    }
    if (measured.pass_ms.count("voxelize"))
        entry["ns_per_voxel_voxelize"] = summarize(measured.pass_ms.at("voxelize")).median * 1e6 /
                                         static_cast<double>(scene_gpu.grid().dims.count());
    return entry;
}

// The case's line of the table.
void print_case(const BenchCase& c, const json& entry, const scene::SceneGpu& scene_gpu,
                const CaseRuns& measured) {
    std::printf("%-25s %-6s", c.name.c_str(), c.edit_name.c_str());
    for (const char* pass : {"voxelize", "index_field", "octree", "photons", "view"}) {
        if (!measured.pass_ms.count(pass)) continue;
        const Summary s = summarize(measured.pass_ms.at(pass));
        std::printf(" %s %.1f (%.1f-%.1f)", pass, s.median, s.min, s.max);
    }
    std::printf(" | encode %.1f host %.1f ms | %.0f MiB", summarize(measured.encode_ms).median,
                summarize(measured.host_ms).median, static_cast<double>(measured.memory) / (1 << 20));
    if (!scene_gpu.field_atlas().dense)
        std::printf(" (a dense lattice: %.0f MiB; field atlas of %zu clusters, %.2f Mvoxels)",
                    entry["dense_lattice_mib"].get<double>(), scene_gpu.field_atlas().clusters.size(),
                    static_cast<double>(scene_gpu.field_atlas().dims.count()) * 1e-6);
    if (entry.contains("medium_field"))
        std::printf(" (medium field: %u bricks, %.1f MiB; dense %.0f MiB)", entry["medium_field"]["bricks"].get<uint32_t>(),
                    entry["medium_field"]["mib"].get<double>(), entry["medium_field"]["dense_mib"].get<double>());
    if (entry.contains("photons_per_s"))
        std::printf(" | %.2f Mphotons/s %.1f steps/photon %.2f bounces/photon %.1f Msteps/s",
                    entry["photons_per_s"].get<double>() * 1e-6, entry["mean_steps_per_photon"].get<double>(),
                    entry["mean_bounces_per_photon"].get<double>(),
                    entry["photon_steps_per_s"].get<double>() * 1e-6);
    if (entry.contains("view_steps_per_s"))
        std::printf(" | view %.1f Msteps/s %.0f ns/pixel", entry["view_steps_per_s"].get<double>() * 1e-6,
                    entry["ns_per_pixel"].get<double>());
    std::printf("\n");
    std::fflush(stdout);
}

}  // namespace

int bench_command(const Arguments& args) {
    if (!args.daemon.empty()) return bench_daemon(args.daemon, args.runs > 0 ? args.runs : 5, args.json);
    vk::ContextOptions options;
    options.device_name = args.device;
    vk::Context context(vk::options_from_environment(options));
    scene::PassKit kit(context);
    const bool gpu = !context.is_cpu_device();
    const int runs = args.runs > 0 ? args.runs : (gpu ? 10 : 3);
    const Uploads uploads = bench_uploads(args);
    const std::vector<BenchCase> cases = bench_cases(args, gpu);

    json report = {{"device", context.info().name}, {"driver", context.info().driver_name + " " + context.info().driver_info},
                   {"cpu_cores", std::thread::hardware_concurrency()}, {"runs", runs}, {"cases", json::array()}};
    if (!args.json)
        std::printf("device: %s (%s %s), %u CPU cores, median of %d runs (min-max)\n", context.info().name.c_str(),
                    context.info().driver_name.c_str(), context.info().driver_info.c_str(),
                    std::thread::hardware_concurrency(), runs);
    // The whole suite measures the deposits too; one scene or a few cases of it do not.
    if (args.scene_file.empty() && args.only.empty())
        report["deposit_microbenchmark"] = report_deposits(context, runs, args.json);
    for (const auto& c : cases) {
        const auto document = protocol::parse_scene(c.scene);
        const scene::WorldMeshes worlds = worlds_of(document, uploads);
        const int64_t memory_before = context.allocated_bytes();
        scene::SceneGpu scene_gpu(kit);
        const scene::Densities densities = bench_densities(document);
        const CaseRuns measured = run_case(context, memory_before, scene_gpu, c, document, worlds, densities, uploads, runs);
        const json entry = case_entry(c, document, densities, scene_gpu, measured);
        report["cases"].push_back(entry);
        if (!args.json) print_case(c, entry, scene_gpu, measured);
    }
    report["scaling"] = scaling(report["cases"], args.json);
    if (args.json) std::cout << report.dump(2) << "\n";
    return 0;
}

}  // namespace refract::cli
