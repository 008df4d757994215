// The embedded scene store, the daemon's default: every scene document with its revision, the uploaded
// meshes, environments and volumes and the imported index grids, each persisted under the data directory before an edit is
// acknowledged. One daemon per data directory (it is locked).
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

#include "store/store.h"

namespace refract::scene {

class SceneStore final : public Store {
public:
    // Opens (creating if needed) the data directory, locks it against a second daemon (StoreError(in_use)
    // naming the holder's pid) and loads every persisted scene, quarantining those it cannot read.
    // Uploaded assets stay on disk; at most `max_host_memory` bytes of them are held decoded.
    SceneStore(std::filesystem::path data_dir, protocol::Limits limits, mesh::MeshLimits mesh_limits,
               uint64_t max_host_memory = kDefaultMaxHostMemory);
    ~SceneStore();
    SceneStore(const SceneStore&) = delete;
    SceneStore& operator=(const SceneStore&) = delete;

    // Creates a scene from a (possibly partial) document. `id` empty: a random one. Throws
    // protocol::ValidationError, StoreError (invalid id, taken).
    SceneSnapshot create(const std::string& id, const nlohmann::json& document) override;
    std::optional<SceneSnapshot> get(const std::string& id) const override;
    std::vector<SceneSnapshot> list() const override;
    size_t size() const override;
    // Deletes a scene and its index grid; false when unknown.
    bool remove(const std::string& id) override;

    // Applies a merge patch atomically. `if_match`: the revision the client edited (stale_revision
    // otherwise). Throws protocol::ValidationError (nothing changes), StoreError (not_found,
    // stale_revision, out_of_revisions, broken).
    EditResult patch(const std::string& id, const nlohmann::json& merge_patch,
                     std::optional<uint64_t> if_match = std::nullopt) override;

    // Parses, inspects and stores an OBJ upload, replacing one of the same name. Throws mesh::MeshError,
    // StoreError(invalid) for a bad name.
    MeshEntry put_mesh(const std::string& name, const std::string& obj_text) override;
    std::vector<MeshEntry> list_meshes() const override;
    // The mesh named `name` (with or without the "upload:" prefix); nullptr when unknown; RenderError
    // saying why when it is stored but cannot be read.
    std::shared_ptr<const mesh::Mesh> mesh(const std::string& name) const override;
    bool remove_mesh(const std::string& name) override;

    // Decodes and stores an environment upload as it came (its bytes, and its size in a report beside it).
    EnvironmentEntry put_environment(const std::string& name, const std::string& bytes) override;
    std::vector<EnvironmentEntry> list_stored_environments() const override;
    std::shared_ptr<const image::EnvironmentMap> stored_environment(const std::string& name) const override;
    bool remove_environment(const std::string& name) override;

    // Checks and stores a volume upload as it came (NAME.vdb, its report in NAME.json beside it).
    VolumeEntry put_volume(const std::string& name, const std::string& bytes) override;
    std::vector<VolumeEntry> list_volumes() const override;
    bool remove_volume(const std::string& name) override;
    std::optional<volume::VolumeReport> volume_report(const std::string& name) const override;
    std::shared_ptr<const volume::DensityGrid> density(const std::string& name, const std::string& grid) const override;

    // Stores `grid` under the scene's id and points the scene at it (a new revision). Throws StoreError.
    EditResult put_index_grid(const std::string& scene_id, IndexGrid grid) override;
    // The grid stored for scene `name`; nullptr when unknown, RenderError when it cannot be read.
    std::shared_ptr<const IndexGrid> grid(const std::string& name) const override;
    bool remove_index_grid(const std::string& scene_id) override;

    // The scene files found unreadable at start, moved to <data dir>/quarantine.
    const std::vector<QuarantinedFile>& quarantined() const override { return quarantined_; }

    const protocol::Limits& limits() const override { return limits_; }
    std::string location() const override { return "data dir " + data_dir_.string(); }
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
    std::filesystem::path environment_path(const std::string& name) const;
    std::filesystem::path volume_path(const std::string& name) const;
    bool has_environment(const std::string& name) const;  // uploaded under `name` (not decoded)
    // The reports (NAME.json) under <data dir>/`kind` whose stored file (NAME + `ending`) exists, by name;
    // unreadable ones are skipped with a line on stderr. The caller holds asset_mutex_.
    std::vector<std::pair<std::string, nlohmann::json>> stored_reports(const char* kind,
                                                                       const std::filesystem::path& ending) const;
    // The asset stored at `path` as (kind, name), decoded from the file by `decode` unless the cache holds
    // the version stored; nullptr when there is no file, RenderError saying why when it cannot be read.
    template <typename T, typename Decode>
    std::shared_ptr<const T> load(AssetKind kind, const std::string& name, const std::filesystem::path& path,
                                  const std::string& what, Decode decode) const;
    // The version of (kind, name) this process has stored, 0 for one stored by an earlier run, and the next
    // one for a write or deletion. The caller holds asset_mutex_.
    uint64_t version_of(AssetKind kind, const std::string& name) const;
    uint64_t next_version(AssetKind kind, const std::string& name);
    // Deletes an uploaded asset (its `main_file` and the report beside it, NAME.json) unless a scene uses it
    // (AssetInUse naming them and `what`), and tells the listeners; false when there is none.
    bool remove_upload(AssetKind kind, const std::string& name, const std::filesystem::path& main_file,
                       const std::string& what, StoreEvent::Kind event);

    std::filesystem::path data_dir_;
    protocol::Limits limits_;
    mesh::MeshLimits mesh_limits_;
    int lock_fd_ = -1;                         // holds the data directory's lock for the store's life
    std::vector<QuarantinedFile> quarantined_;  // written only while loading

    mutable std::mutex mutex_;  // guards scenes_ and every Entry::current
    std::map<std::string, std::shared_ptr<Entry>> scenes_;
    mutable std::mutex asset_mutex_;  // guards versions_ and serializes asset file writes and deletions
    // Bumped by every write and deletion of an asset: a decode of older bytes, finished after a newer
    // upload, is never cached over it.
    std::map<std::pair<AssetKind, std::string>, uint64_t> versions_;
    uint64_t last_version_ = 0;
    mutable AssetCache cache_;  // decoded assets, loaded lazily
};

// Writes `bytes` to `path` so that a crash leaves either the old or the new file: temp file, fsync,
// rename, fsync of the directory. Throws StoreError(broken).
void write_file_atomically(const std::filesystem::path& path, const void* bytes, size_t size);

}  // namespace refract::scene
