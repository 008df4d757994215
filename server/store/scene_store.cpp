#include "store/scene_store.h"
#include "store/index_grid_file.h"
#include "volume/vdb_check.h"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <iostream>
#include <sstream>

namespace refract::scene {

namespace fs = std::filesystem;

namespace {

// Marks a write that has not reached its rename. '~' is in no valid scene id or mesh name, so the start-up
// sweep can never take a stored file for a temp file.
constexpr std::string_view kTempMarker = "~tmp.";

bool is_temp_file(const fs::path& path) {
    return path.filename().string().find(kTempMarker) != std::string::npos;
}

std::string errno_text() {
    return std::strerror(errno);
}

// Closes a POSIX file descriptor on every path out of a scope.
struct Fd {
    int fd = -1;
    ~Fd() {
        if (fd >= 0) ::close(fd);
    }
};

void fsync_directory(const fs::path& dir) {
    Fd d{::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC)};
    if (d.fd >= 0) ::fsync(d.fd);
}

std::string read_text_file(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw StoreError(StoreFailure::broken, "cannot read " + path.string());
    std::ostringstream text;
    text << in.rdbuf();
    return text.str();
}

}  // namespace

void write_file_atomically(const fs::path& path, const void* bytes, size_t size) {
    static std::atomic<uint64_t> counter{0};
    fs::path temp = path;
    temp += std::string(kTempMarker) + std::to_string(::getpid()) + "." + std::to_string(counter.fetch_add(1));
    {
        Fd f{::open(temp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644)};
        if (f.fd < 0)
            throw StoreError(StoreFailure::broken, "cannot create " + temp.string() + ": " + errno_text());
        const char* p = static_cast<const char*>(bytes);
        size_t left = size;
        while (left > 0) {
            ssize_t written = ::write(f.fd, p, left);
            if (written < 0 && errno == EINTR) continue;
            if (written <= 0) {
                std::string why = errno_text();
                ::unlink(temp.c_str());
                throw StoreError(StoreFailure::broken, "cannot write " + temp.string() + ": " + why);
            }
            p += written;
            left -= static_cast<size_t>(written);
        }
        if (::fsync(f.fd) != 0) {
            std::string why = errno_text();
            ::unlink(temp.c_str());
            throw StoreError(StoreFailure::broken, "cannot sync " + temp.string() + ": " + why);
        }
    }
    if (::rename(temp.c_str(), path.c_str()) != 0) {
        std::string why = errno_text();
        ::unlink(temp.c_str());
        throw StoreError(StoreFailure::broken, "cannot rename to " + path.string() + ": " + why);
    }
    fsync_directory(path.parent_path());
}

SceneStore::SceneStore(fs::path data_dir, protocol::Limits limits, mesh::MeshLimits mesh_limits,
                       uint64_t max_host_memory)
    : data_dir_(std::move(data_dir)), limits_(limits), mesh_limits_(mesh_limits), cache_(max_host_memory) {
    std::error_code ec;
    for (const char* sub : {"scenes", "meshes", "grids", "environments", "volumes"}) {
        fs::create_directories(data_dir_ / sub, ec);
        if (ec)
            throw StoreError(StoreFailure::broken,
                             "cannot create " + (data_dir_ / sub).string() + ": " + ec.message());
    }
    lock_data_dir();
    try {
        load_scenes();
    } catch (...) {
        ::close(lock_fd_);
        throw;
    }
}

SceneStore::~SceneStore() {
    ::close(lock_fd_);
}

void SceneStore::lock_data_dir() {
    // Two daemons on one directory would hand out the same revisions. flock, like PostgreSQL's
    // postmaster.pid, names the holder and is released by the kernel however the holder dies.
    fs::path path = data_dir_ / "refractd.pid";
    lock_fd_ = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (lock_fd_ < 0)
        throw StoreError(StoreFailure::broken, "cannot open " + path.string() + ": " + errno_text());
    if (::flock(lock_fd_, LOCK_EX | LOCK_NB) != 0) {
        std::string why = errno == EWOULDBLOCK ? "" : ": " + errno_text();
        char holder[32] = {};
        ssize_t got = ::pread(lock_fd_, holder, sizeof holder - 1, 0);
        std::string pid = got > 0 ? std::string(holder, static_cast<size_t>(got)) : "";
        while (!pid.empty() && (pid.back() == '\n' || pid.back() == ' ')) pid.pop_back();
        ::close(lock_fd_);
        throw StoreError(StoreFailure::in_use, "data directory " + data_dir_.string() +
                                                   " is in use by another refractd" +
                                                   (pid.empty() ? "" : " (pid " + pid + ")") + why);
    }
    std::string pid = std::to_string(::getpid()) + "\n";
    if (::ftruncate(lock_fd_, 0) != 0 || ::pwrite(lock_fd_, pid.data(), pid.size(), 0) < 0)
        std::cerr << "refractd: cannot write " << path << ": " << errno_text() << "\n";
}

fs::path SceneStore::scene_path(const std::string& id) const {
    return data_dir_ / "scenes" / (id + ".json");
}
fs::path SceneStore::mesh_path(const std::string& name) const {
    return data_dir_ / "meshes" / (name + ".obj");
}
fs::path SceneStore::grid_path(const std::string& name) const {
    return data_dir_ / "grids" / (name + ".grid");
}
fs::path SceneStore::environment_path(const std::string& name) const {
    return data_dir_ / "environments" / (name + ".env");
}
fs::path SceneStore::volume_path(const std::string& name) const {
    return data_dir_ / "volumes" / (name + ".vdb");
}

void SceneStore::load_scenes() {
    for (const char* sub : {"scenes", "meshes", "grids", "environments", "volumes"}) {
        for (const auto& item : fs::directory_iterator(data_dir_ / sub)) {
            // A temp file is a write that never reached its rename: the previous version stands.
            if (is_temp_file(item.path())) {
                std::error_code ec;
                fs::remove(item.path(), ec);
            }
        }
    }
    // Files quarantined by an earlier start stay reported, and their ids stay taken, until removed.
    std::error_code ec;
    for (const auto& item : fs::directory_iterator(data_dir_ / "quarantine", ec)) {
        std::string name = item.path().filename().string();
        quarantined_.push_back({name.substr(0, name.find(".json")), item.path().string(),
                                "found unreadable by an earlier start"});
    }
    for (const auto& item : fs::directory_iterator(data_dir_ / "scenes")) {
        const fs::path& path = item.path();
        if (path.extension() != ".json") continue;
        std::string id = path.stem().string();
        if (!valid_scene_id(id)) {
            std::cerr << "refractd: ignoring " << path << ": not a scene id\n";
            continue;
        }
        try {
            nlohmann::json stored = nlohmann::json::parse(read_text_file(path));
            const nlohmann::json& revision = stored.at("revision");
            if (!revision.is_number_unsigned() || revision.get<uint64_t>() < 1 ||
                revision.get<uint64_t>() > kMaxRevision)
                throw std::invalid_argument("revision must be an integer in [1, 2^53 - 1]");
            auto entry = std::make_shared<Entry>();
            entry->current.id = id;
            entry->current.revision = revision.get<uint64_t>();
            try {
                entry->current.document = protocol::parse_scene(stored.at("scene"), limits_);
            } catch (const protocol::ValidationError&) {
                // Stored under looser limits than this run's: keep it, it was valid when acknowledged.
                entry->current.document = protocol::parse_scene(stored.at("scene"));
            }
            scenes_[id] = std::move(entry);
        } catch (const std::exception& e) {
            quarantine(path, id, e.what());
        }
    }
}

void SceneStore::quarantine(const fs::path& path, const std::string& id, const std::string& error) {
    // Moved, not deleted: what the store cannot read may still be what a user needs. The id stays taken,
    // so nothing is ever written in its place.
    fs::path dir = data_dir_ / "quarantine";
    fs::path target = dir / path.filename();
    std::error_code ec;
    fs::create_directories(dir, ec);
    for (int n = 1; !ec && fs::exists(target); ++n) target = dir / (path.filename().string() + "." + std::to_string(n));
    if (!ec) fs::rename(path, target, ec);
    if (ec) target = path;  // could not move it: it stays where it is, still never overwritten
    else fsync_directory(data_dir_ / "scenes");
    std::cerr << "refractd: scene file " << path << " is unreadable (" << error << "); kept at " << target
              << ", scene '" << id << "' unavailable until it is repaired or removed\n";
    quarantined_.push_back({id, target.string(), error});
}

void SceneStore::persist_scene(const SceneSnapshot& snapshot) const {
    nlohmann::json stored = {{"revision", snapshot.revision},
                             {"scene", protocol::to_json(snapshot.document)}};
    std::string text = stored.dump(2);
    text += '\n';
    write_file_atomically(scene_path(snapshot.id), text.data(), text.size());
}

std::shared_ptr<SceneStore::Entry> SceneStore::find(const std::string& id) const {
    std::lock_guard lock(mutex_);
    auto it = scenes_.find(id);
    return it == scenes_.end() ? nullptr : it->second;
}

SceneSnapshot SceneStore::create(const std::string& id, const nlohmann::json& document) {
    if (!id.empty() && !valid_scene_id(id))
        throw StoreError(StoreFailure::invalid, "scene id must match [a-z0-9-]{1,32}");
    auto entry = std::make_shared<Entry>();
    entry->current.document = protocol::parse_scene(document, limits_);
    check_environment(entry->current.document, [this](const std::string& name) { return has_environment(name); });
    check_volumes(entry->current.document, [this](const std::string& name) { return volume_report(name); });
    entry->current.revision = 1;

    std::lock_guard lock(mutex_);
    if (id.empty()) {
        do {
            entry->current.id = random_hex_id();
        } while (scenes_.count(entry->current.id) != 0);
    } else {
        if (scenes_.count(id) != 0)
            throw StoreError(StoreFailure::taken, "scene '" + id + "' already exists");
        for (const auto& file : quarantined_)
            if (file.scene_id == id)
                throw StoreError(StoreFailure::taken,
                                 "scene '" + id + "' has a stored file that could not be read (kept at " +
                                     file.path + "); repair or remove it and restart");
        entry->current.id = id;
    }
    persist_scene(entry->current);
    scenes_[entry->current.id] = entry;
    publish({StoreEvent::Kind::revision, entry->current.id, entry->current.revision});
    return entry->current;
}

std::optional<SceneSnapshot> SceneStore::get(const std::string& id) const {
    std::lock_guard lock(mutex_);
    auto it = scenes_.find(id);
    if (it == scenes_.end()) return std::nullopt;
    return it->second->current;
}

std::vector<SceneSnapshot> SceneStore::list() const {
    std::lock_guard lock(mutex_);
    std::vector<SceneSnapshot> all;
    all.reserve(scenes_.size());
    for (const auto& [id, entry] : scenes_) all.push_back(entry->current);
    return all;
}

size_t SceneStore::size() const {
    std::lock_guard lock(mutex_);
    return scenes_.size();
}

bool SceneStore::remove(const std::string& id) {
    std::shared_ptr<Entry> entry = find(id);
    if (!entry) return false;
    std::lock_guard edit(entry->edit_mutex);
    if (entry->deleted) return false;
    std::error_code ec;
    fs::remove(scene_path(id), ec);
    if (ec) throw StoreError(StoreFailure::broken, "cannot delete scene file: " + ec.message());
    fsync_directory(data_dir_ / "scenes");
    entry->deleted = true;
    {
        std::lock_guard lock(mutex_);
        scenes_.erase(id);
    }
    {
        std::lock_guard assets(asset_mutex_);
        fs::remove(grid_path(id), ec);
        next_version(AssetKind::grid, id);
        cache_.forget(AssetKind::grid, id);
    }
    publish({StoreEvent::Kind::deleted, id});
    return true;
}

EditResult SceneStore::apply(const std::shared_ptr<Entry>& entry, const nlohmann::json& merge_patch,
                             std::optional<uint64_t> if_match) {
    // Caller holds entry->edit_mutex: nobody else writes `current` meanwhile, so reading it unlocked is safe.
    if (entry->deleted)
        throw StoreError(StoreFailure::not_found, "scene '" + entry->current.id + "' does not exist");
    const SceneSnapshot& current = entry->current;
    if (if_match && *if_match != current.revision)
        throw StoreError(StoreFailure::stale_revision, "scene is at revision " +
                                                           std::to_string(current.revision) + ", not " +
                                                           std::to_string(*if_match));
    EditResult result;
    result.before = current.document;
    result.after = current;
    result.after.document = protocol::apply_merge_patch(current.document, merge_patch, limits_);
    result.changed = !(result.after.document == current.document);
    if (!result.changed) return result;
    if (!(result.after.document.environment == current.document.environment))
        check_environment(result.after.document, [this](const std::string& name) { return has_environment(name); });
    if (!(result.after.document.volumes == current.document.volumes))
        check_volumes(result.after.document, [this](const std::string& name) { return volume_report(name); });
    result.after.revision = next_revision(current.revision);
    persist_scene(result.after);
    std::lock_guard lock(mutex_);
    entry->current = result.after;
    return result;
}

EditResult SceneStore::patch(const std::string& id, const nlohmann::json& merge_patch,
                             std::optional<uint64_t> if_match) {
    std::shared_ptr<Entry> entry = find(id);
    if (!entry) throw StoreError(StoreFailure::not_found, "scene '" + id + "' does not exist");
    EditResult result;
    {
        std::lock_guard edit(entry->edit_mutex);
        result = apply(entry, merge_patch, if_match);
    }
    if (result.changed) publish({StoreEvent::Kind::revision, id, result.after.revision});
    return result;
}

MeshEntry SceneStore::put_mesh(const std::string& name, const std::string& obj_text) {
    auto parsed = parse_mesh_upload(name, obj_text, mesh_limits_, cache_);
    MeshEntry entry{name, mesh::inspect(*parsed)};
    std::string report = to_json(entry.report).dump(2);
    {
        std::lock_guard lock(asset_mutex_);
        write_file_atomically(mesh_path(name), obj_text.data(), obj_text.size());
        fs::path report_path = data_dir_ / "meshes" / (name + ".json");
        write_file_atomically(report_path, report.data(), report.size());
        // A new pointer: the renderer sees the re-upload and re-voxelizes.
        const uint64_t size = host_bytes(*parsed);
        cache_.insert(AssetKind::mesh, name, next_version(AssetKind::mesh, name), std::move(parsed), size);
    }
    publish({StoreEvent::Kind::mesh, name});
    return entry;
}

uint64_t SceneStore::version_of(AssetKind kind, const std::string& name) const {
    auto it = versions_.find({kind, name});
    return it == versions_.end() ? 0 : it->second;
}

uint64_t SceneStore::next_version(AssetKind kind, const std::string& name) {
    return versions_[{kind, name}] = ++last_version_;
}

template <typename T, typename Decode>
std::shared_ptr<const T> SceneStore::load(AssetKind kind, const std::string& name, const fs::path& path,
                                          const std::string& what, Decode decode) const {
    uint64_t version = 0;
    std::string bytes;
    {
        std::lock_guard lock(asset_mutex_);
        version = version_of(kind, name);
        if (auto cached = cache_.find<T>(kind, name, version)) return cached;
        if (!fs::exists(path)) return nullptr;
        bytes = read_text_file(path);
    }
    // Decoded without the lock: a large map takes a while, and uploads and lookups of others go on.
    try {
        auto loaded = std::make_shared<const T>(decode(bytes));
        const uint64_t size = host_bytes(*loaded);
        return cache_.insert(kind, name, version, std::move(loaded), size);
    } catch (const std::exception& e) {
        std::cerr << "refractd: cannot load stored " << what << " " << path << ": " << e.what() << "\n";
        throw RenderError("stored " + what + " '" + name + "' cannot be read: " + e.what());
    }
}

bool SceneStore::remove_upload(AssetKind kind, const std::string& name, const fs::path& main_file,
                               const std::string& what, StoreEvent::Kind event) {
    {
        std::lock_guard lock(asset_mutex_);
        if (!fs::exists(main_file)) return false;
        check_unused(list(), kind, name, what);
        std::error_code ec;
        // The main file goes first: a report is listed only beside its file, so a crash between the two
        // leaves the asset deleted, with a report nothing reads until the next upload of the name replaces
        // it (a grid has none).
        if (!fs::remove(main_file, ec)) {
            if (ec)
                throw StoreError(StoreFailure::broken,
                                 "cannot delete " + main_file.string() + ": " + ec.message());
            return false;
        }
        fs::remove(fs::path(main_file).replace_extension(".json"), ec);
        fsync_directory(main_file.parent_path());
        next_version(kind, name);
        cache_.forget(kind, name);
    }
    publish({event, name});
    return true;
}

bool SceneStore::remove_mesh(const std::string& name_or_reference) {
    const std::string name = strip_upload_prefix(name_or_reference);
    return valid_mesh_name(name) &&
           remove_upload(AssetKind::mesh, name, mesh_path(name), "mesh '" + name + "'", StoreEvent::Kind::mesh);
}

std::vector<std::pair<std::string, nlohmann::json>> SceneStore::stored_reports(const char* kind,
                                                                                const fs::path& ending) const {
    std::vector<std::pair<std::string, nlohmann::json>> all;
    for (const auto& item : fs::directory_iterator(data_dir_ / kind)) {
        const fs::path& path = item.path();
        if (path.extension() != ".json" || is_temp_file(path)) continue;
        std::string name = path.stem().string();
        fs::path stored = path;
        if (!valid_mesh_name(name) || !fs::exists(stored.replace_extension(ending))) continue;
        try {
            all.emplace_back(name, nlohmann::json::parse(read_text_file(path)));
        } catch (const std::exception& e) {
            std::cerr << "refractd: skipping unreadable report " << path << ": " << e.what() << "\n";
        }
    }
    std::sort(all.begin(), all.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
    return all;
}

std::vector<MeshEntry> SceneStore::list_meshes() const {
    std::lock_guard lock(asset_mutex_);
    std::vector<MeshEntry> all;
    for (const auto& [name, report] : stored_reports("meshes", ".obj")) {
        try {
            all.push_back({name, report_from_json(report)});
        } catch (const std::exception& e) {
            std::cerr << "refractd: skipping unreadable mesh report of " << name << ": " << e.what() << "\n";
        }
    }
    return all;
}

std::shared_ptr<const mesh::Mesh> SceneStore::mesh(const std::string& name_or_reference) const {
    std::string name = strip_upload_prefix(name_or_reference);
    if (!valid_mesh_name(name)) return nullptr;
    return load<mesh::Mesh>(AssetKind::mesh, name, mesh_path(name), "mesh",
                            [this](const std::string& obj) { return mesh::parse_obj(obj, mesh_limits_); });
}

EnvironmentEntry SceneStore::put_environment(const std::string& name, const std::string& bytes) {
    auto decoded = decode_environment_upload(name, bytes, cache_);
    EnvironmentEntry entry{name, decoded->width, decoded->height, false};
    const std::string report = nlohmann::json{{"width", entry.width}, {"height", entry.height}}.dump();
    {
        std::lock_guard lock(asset_mutex_);
        write_file_atomically(environment_path(name), bytes.data(), bytes.size());
        fs::path report_path = data_dir_ / "environments" / (name + ".json");
        write_file_atomically(report_path, report.data(), report.size());
        // A new pointer: the renderer sees the re-upload.
        const uint64_t size = host_bytes(*decoded);
        cache_.insert(AssetKind::environment, name, next_version(AssetKind::environment, name), std::move(decoded),
                      size);
    }
    publish({StoreEvent::Kind::environment, name});
    return entry;
}

bool SceneStore::has_environment(const std::string& name) const {
    std::lock_guard lock(asset_mutex_);
    return fs::exists(environment_path(name));
}

bool SceneStore::remove_environment(const std::string& name) {
    return valid_mesh_name(name) && !image::built_in_environment(name) &&
           remove_upload(AssetKind::environment, name, environment_path(name), "environment '" + name + "'",
                         StoreEvent::Kind::environment);
}

std::vector<EnvironmentEntry> SceneStore::list_stored_environments() const {
    std::lock_guard lock(asset_mutex_);
    std::vector<EnvironmentEntry> all;
    for (const auto& [name, report] : stored_reports("environments", ".env")) {
        try {
            all.push_back({name, report.at("width").get<uint32_t>(), report.at("height").get<uint32_t>(), false});
        } catch (const std::exception& e) {
            std::cerr << "refractd: skipping unreadable environment report of " << name << ": " << e.what() << "\n";
        }
    }
    return all;
}

std::shared_ptr<const image::EnvironmentMap> SceneStore::stored_environment(const std::string& name) const {
    if (!valid_mesh_name(name)) return nullptr;
    return load<image::EnvironmentMap>(AssetKind::environment, name, environment_path(name), "environment",
                                       [](const std::string& bytes) { return image::decode_environment(bytes); });
}

VolumeEntry SceneStore::put_volume(const std::string& name, const std::string& bytes) {
    VolumeEntry entry{name, inspect_volume_upload(name, bytes, limits_)};
    const std::string report = volume::to_json(entry.report).dump();
    {
        // The file goes first: a report is listed only beside its file, so a crash between the two lists
        // the new file with the previous report until the next upload.
        std::lock_guard lock(asset_mutex_);
        write_file_atomically(volume_path(name), bytes.data(), bytes.size());
        fs::path report_path = data_dir_ / "volumes" / (name + ".json");
        write_file_atomically(report_path, report.data(), report.size());
        next_version(AssetKind::volume, name);
    }
    publish({StoreEvent::Kind::volume, name});
    return entry;
}

std::optional<volume::VolumeReport> SceneStore::volume_report(const std::string& name) const {
    if (!valid_mesh_name(name)) return std::nullopt;
    std::lock_guard lock(asset_mutex_);
    if (!fs::exists(volume_path(name))) return std::nullopt;
    try {
        return volume::volume_report_from_json(
            nlohmann::json::parse(read_text_file(data_dir_ / "volumes" / (name + ".json"))));
    } catch (const std::exception& e) {
        std::cerr << "refractd: unreadable volume report of " << name << ": " << e.what() << "\n";
        return std::nullopt;
    }
}

std::shared_ptr<const volume::DensityGrid> SceneStore::density(const std::string& name, const std::string& grid) const {
    if (!valid_mesh_name(name)) return nullptr;
    // One cache entry per grid, under the volume's version: a re-upload or deletion misses them all.
    const std::string key = name + "/" + grid;
    uint64_t version = 0;
    std::string bytes;
    {
        std::lock_guard lock(asset_mutex_);
        version = version_of(AssetKind::volume, name);
        if (auto cached = cache_.find<volume::DensityGrid>(AssetKind::volume, key, version)) return cached;
        if (!fs::exists(volume_path(name))) return nullptr;
        bytes = read_text_file(volume_path(name));
    }
    try {
        auto exported = std::make_shared<const volume::DensityGrid>(
            volume::export_density_apart(bytes, grid, volume::limits_for_resolution(limits_.max_resolution)));
        const uint64_t size = host_bytes(*exported);
        return cache_.insert(AssetKind::volume, key, version, std::move(exported), size);
    } catch (const std::exception& e) {
        throw RenderError("stored volume '" + name + "' grid '" + grid + "' cannot be read: " + e.what());
    }
}

std::vector<VolumeEntry> SceneStore::list_volumes() const {
    std::lock_guard lock(asset_mutex_);
    std::vector<VolumeEntry> all;
    for (const auto& [name, report] : stored_reports("volumes", ".vdb")) {
        try {
            all.push_back({name, volume::volume_report_from_json(report)});
        } catch (const std::exception& e) {
            std::cerr << "refractd: skipping unreadable volume report of " << name << ": " << e.what() << "\n";
        }
    }
    return all;
}

bool SceneStore::remove_volume(const std::string& name) {
    return valid_mesh_name(name) &&
           remove_upload(AssetKind::volume, name, volume_path(name), "volume '" + name + "'", StoreEvent::Kind::volume);
}

EditResult SceneStore::put_index_grid(const std::string& scene_id, IndexGrid grid) {
    validate_index_grid(grid);
    cache_.check_fits("the index grid", host_bytes(grid));
    std::shared_ptr<Entry> entry = find(scene_id);
    if (!entry) throw StoreError(StoreFailure::not_found, "scene '" + scene_id + "' does not exist");
    std::unique_lock edit(entry->edit_mutex);
    if (entry->deleted) throw StoreError(StoreFailure::not_found, "scene '" + scene_id + "' does not exist");
    {
        // The grid is written before the scene points at it: a crash in between leaves the old revision.
        std::lock_guard lock(asset_mutex_);
        std::vector<char> bytes = encode_grid(grid);
        write_file_atomically(grid_path(scene_id), bytes.data(), bytes.size());
        auto stored = std::make_shared<const IndexGrid>(std::move(grid));
        const uint64_t size = host_bytes(*stored);
        cache_.insert(AssetKind::grid, scene_id, next_version(AssetKind::grid, scene_id), std::move(stored), size);
    }
    nlohmann::json patch = {{"object", {{"index_field", "grid"}, {"grid", scene_id}}}};
    EditResult result = apply(entry, patch, std::nullopt);
    if (!result.changed) {
        // Same document, new grid contents: still a new revision, so clients see the change.
        result.after.revision = next_revision(entry->current.revision);
        persist_scene(result.after);
        std::lock_guard lock(mutex_);
        entry->current = result.after;
        result.changed = true;
    }
    edit.unlock();
    publish({StoreEvent::Kind::revision, scene_id, result.after.revision});
    return result;
}

std::shared_ptr<const IndexGrid> SceneStore::grid(const std::string& name) const {
    if (!valid_scene_id(name)) return nullptr;
    return load<IndexGrid>(AssetKind::grid, name, grid_path(name), "index grid",
                           [](const std::string& bytes) { return decode_grid(bytes); });
}

bool SceneStore::remove_index_grid(const std::string& scene_id) {
    return valid_scene_id(scene_id) && remove_upload(AssetKind::grid, scene_id, grid_path(scene_id),
                                                     "the index grid of scene '" + scene_id + "'", StoreEvent::Kind::grid);
}

}  // namespace refract::scene
