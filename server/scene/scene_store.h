// The daemon's scene store: every scene document with its revision, the uploaded meshes and the imported
// index grids, each persisted under the data directory before an edit is acknowledged.
// Thread-safe: any HTTP or WebSocket thread may call it. It never renders and never touches Vulkan.
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "mesh/mesh.h"
#include "protocol/scene_document.h"
#include "scene/renderer.h"

namespace refract::scene {

// A scene as one revision: what the render queue renders and what GET answers.
struct SceneSnapshot {
    std::string id;
    uint64_t revision = 0;
    protocol::SceneDocument document;
};

// The outcome of an accepted edit: the document before and after, and the revision now current.
struct EditResult {
    protocol::SceneDocument before;
    SceneSnapshot after;
    bool changed = false;  // false: the edit was a no-op and the revision did not move
};

// Why the store refused a request; `status` is the HTTP status that fits (404, 409, 412, 400, 500).
class StoreError : public std::runtime_error {
public:
    StoreError(int status, const std::string& message) : std::runtime_error(message), status_(status) {}
    int status() const { return status_; }

private:
    int status_;
};

// A stored file the store could not read at start: moved aside (never deleted or overwritten) and
// reported by health and metrics until an operator repairs or removes it.
struct QuarantinedFile {
    std::string scene_id;  // the scene whose file it was; its id stays taken
    std::string path;      // where the file is now
    std::string error;     // why it could not be read
};

// The highest revision the store hands out: JSON numbers stay exact in every client up to 2^53 - 1.
constexpr uint64_t kMaxRevision = (uint64_t{1} << 53) - 1;

struct MeshEntry {
    std::string name;
    mesh::MeshReport report;
};

// Validation of an imported index grid, in the words a user needs; throws StoreError(400).
void validate_index_grid(const IndexGrid& grid);

// True for a name usable as a scene id ([a-z0-9-]{1,32}) or as a mesh name ([A-Za-z0-9_.-]{1,64}, not
// "." or "..").
bool valid_scene_id(const std::string& id);
bool valid_mesh_name(const std::string& name);

// A report as the JSON the API answers with.
nlohmann::json to_json(const mesh::MeshReport& report);

class SceneStore {
public:
    // Opens (creating if needed) the data directory, locks it against a second daemon (StoreError(409)
    // naming the holder's pid) and loads every persisted scene, quarantining those it cannot read.
    SceneStore(std::filesystem::path data_dir, protocol::Limits limits, mesh::MeshLimits mesh_limits);
    ~SceneStore();
    SceneStore(const SceneStore&) = delete;
    SceneStore& operator=(const SceneStore&) = delete;

    // Creates a scene from a (possibly partial) document. `id` empty: a random one. Throws
    // protocol::ValidationError, StoreError (400 bad id, 409 taken).
    SceneSnapshot create(const std::string& id, const nlohmann::json& document);
    std::optional<SceneSnapshot> get(const std::string& id) const;
    std::vector<SceneSnapshot> list() const;
    size_t size() const;
    // Deletes a scene and its index grid; false when unknown.
    bool remove(const std::string& id);

    // Applies a merge patch atomically. `if_match`: the revision the client edited (412 otherwise).
    // Throws protocol::ValidationError (nothing changes), StoreError (404, 412, 500).
    EditResult patch(const std::string& id, const nlohmann::json& merge_patch,
                     std::optional<uint64_t> if_match = std::nullopt);

    // Parses, inspects and stores an OBJ upload, replacing one of the same name. Throws mesh::MeshError,
    // StoreError(400) for a bad name.
    MeshEntry put_mesh(const std::string& name, const std::string& obj_text);
    std::vector<MeshEntry> list_meshes() const;
    // The mesh named `name` (with or without the "upload:" prefix); nullptr when unknown; RenderError
    // saying why when it is stored but cannot be read.
    std::shared_ptr<const mesh::Mesh> mesh(const std::string& name) const;

    // Stores `grid` under the scene's id and points the scene at it (a new revision). Throws StoreError.
    EditResult put_index_grid(const std::string& scene_id, IndexGrid grid);
    // The grid stored for scene `name`; nullptr when unknown, RenderError when it cannot be read.
    std::shared_ptr<const IndexGrid> grid(const std::string& name) const;

    // The scene files found unreadable at start, moved to <data dir>/quarantine.
    const std::vector<QuarantinedFile>& quarantined() const { return quarantined_; }

    // Lookups for the renderer (called on the render thread).
    Assets assets() const;

    const protocol::Limits& limits() const { return limits_; }
    const std::filesystem::path& data_dir() const { return data_dir_; }

private:
    struct Entry {
        std::mutex edit_mutex;  // serializes edits of this scene (validate, persist, publish)
        bool deleted = false;   // guarded by edit_mutex: a removed scene takes no more edits
        SceneSnapshot current;  // written with both mutexes held, read with either
    };

    std::shared_ptr<Entry> find(const std::string& id) const;
    EditResult apply(const std::shared_ptr<Entry>& entry, const nlohmann::json& merge_patch,
                     std::optional<uint64_t> if_match);
    void persist_scene(const SceneSnapshot& snapshot) const;
    void load_scenes();
    void quarantine(const std::filesystem::path& path, const std::string& id, const std::string& error);
    void lock_data_dir();
    std::filesystem::path scene_path(const std::string& id) const;
    std::filesystem::path mesh_path(const std::string& name) const;
    std::filesystem::path grid_path(const std::string& name) const;

    std::filesystem::path data_dir_;
    protocol::Limits limits_;
    mesh::MeshLimits mesh_limits_;
    int lock_fd_ = -1;                         // holds the data directory's lock for the store's life
    std::vector<QuarantinedFile> quarantined_;  // written only while loading

    mutable std::mutex mutex_;  // guards scenes_ and every Entry::current
    std::map<std::string, std::shared_ptr<Entry>> scenes_;
    mutable std::mutex asset_mutex_;  // guards the asset caches and serializes asset file writes
    mutable std::map<std::string, std::shared_ptr<const mesh::Mesh>> meshes_;  // loaded lazily
    mutable std::map<std::string, std::shared_ptr<const IndexGrid>> grids_;    // loaded lazily
};

// Writes `bytes` to `path` so that a crash leaves either the old or the new file: temp file, fsync,
// rename, fsync of the directory. Throws StoreError(500).
void write_file_atomically(const std::filesystem::path& path, const void* bytes, size_t size);

}  // namespace refract::scene
