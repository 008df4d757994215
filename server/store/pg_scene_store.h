// The shared scene store: scene documents, revisions, uploaded assets and index grids in PostgreSQL, so that any
// number of refractd replicas serve the same scenes. The database enforces the revision rules (see
// pg_schema.cpp); an edit is acknowledged only once its transaction has committed. Nothing is cached
// but decoded assets (within a budget of host memory), keyed by their stored version, so a replica always answers with the
// newest committed revision, whoever committed it.
#pragma once

#include <atomic>
#include <map>
#include <thread>

#include "store/pg_connection.h"
#include "store/store.h"

namespace refract::scene {

class PgSceneStore final : public Store {
public:
    // Connects to `url`, migrates the schema (pg_schema.h) and starts listening for other replicas'
    // edits. Throws StoreError: unavailable when the database cannot be reached, broken when its schema
    // is newer.
    // At most `max_host_memory` bytes of decoded assets are held.
    PgSceneStore(const std::string& url, protocol::Limits limits, mesh::MeshLimits mesh_limits,
                 uint64_t max_host_memory = kDefaultMaxHostMemory);
    ~PgSceneStore() override;
    PgSceneStore(const PgSceneStore&) = delete;
    PgSceneStore& operator=(const PgSceneStore&) = delete;

    SceneSnapshot create(const std::string& id, const nlohmann::json& document) override;
    std::optional<SceneSnapshot> get(const std::string& id) const override;
    std::vector<SceneSnapshot> list() const override;
    size_t size() const override;
    bool remove(const std::string& id) override;
    EditResult patch(const std::string& id, const nlohmann::json& merge_patch,
                     std::optional<uint64_t> if_match = std::nullopt) override;
    MeshEntry put_mesh(const std::string& name, const std::string& obj_text) override;
    std::vector<MeshEntry> list_meshes() const override;
    std::shared_ptr<const mesh::Mesh> mesh(const std::string& name) const override;
    bool remove_mesh(const std::string& name) override;
    EnvironmentEntry put_environment(const std::string& name, const std::string& bytes) override;
    std::vector<EnvironmentEntry> list_stored_environments() const override;
    std::shared_ptr<const image::EnvironmentMap> stored_environment(const std::string& name) const override;
    bool remove_environment(const std::string& name) override;
    VolumeEntry put_volume(const std::string& name, const std::string& bytes) override;
    std::vector<VolumeEntry> list_volumes() const override;
    bool remove_volume(const std::string& name) override;
    std::optional<volume::VolumeReport> volume_report(const std::string& name) const override;
    std::shared_ptr<const volume::DensityGrid> density(const std::string& name, const std::string& grid) const override;
    EditResult put_index_grid(const std::string& scene_id, IndexGrid grid) override;
    std::shared_ptr<const IndexGrid> grid(const std::string& name) const override;
    bool remove_index_grid(const std::string& scene_id) override;
    const std::vector<QuarantinedFile>& quarantined() const override { return no_quarantine_; }
    const protocol::Limits& limits() const override { return limits_; }
    std::string location() const override { return location_; }

private:
    // A stored document as a snapshot; documents stored under looser limits than this run's are kept.
    SceneSnapshot snapshot(const std::string& id, uint64_t revision, const std::string& document) const;
    // Whether an update whose connection was lost before its answer committed: committed, not
    // applied, or unknown (the database cannot be asked).
    enum class LostUpdate { committed, not_applied, unknown };
    LostUpdate outcome_of_lost_update(const pg::Connection& lost, const SceneSnapshot& after) const;
    // LISTEN refract_scenes on a connection of its own, publishing each notification; reconnects
    // when the database comes back.
    void listen();
    // Whether an environment is stored under `name`, asked on a connection the caller already holds (a
    // second lease from the pool while holding one could wait for ever under load).
    bool has_environment(pg::Connection& connection, const std::string& name) const;
    // The report of the volume `name`, on a connection the caller already holds; nullopt when none.
    std::optional<volume::VolumeReport> volume_report(pg::Connection& connection, const std::string& name) const;

    mutable pg::Pool pool_;
    protocol::Limits limits_;
    mesh::MeshLimits mesh_limits_;
    std::string location_;
    std::vector<QuarantinedFile> no_quarantine_;

    struct AssetTable;
    // The asset stored under `key`, parsed by `parse` from its bytes unless the cache holds the stored
    // version; nullptr when none is stored, RenderError when it cannot be parsed.
    template <typename T, typename Parse>
    std::shared_ptr<const T> load_asset(AssetKind kind, const AssetTable& where, const std::string& key,
                                        Parse parse) const;
    // Deletes the row of `key` in a transaction that first checks no scene names it (AssetInUse) and
    // announces the deletion with `notification` to every replica; false when there is no row.
    bool remove_asset(AssetKind kind, const AssetTable& where, const std::string& key, const std::string& what,
                      const std::string& notification);
    // Every scene, read on a connection the caller holds.
    std::vector<SceneSnapshot> all_scenes(pg::Connection& connection) const;

    // Decoded assets by name and the stored version they were decoded from (the renderer holds on to
    // the pointer: a new pointer is what tells it an asset changed).
    mutable AssetCache cache_;

    std::atomic<bool> stopping_{false};
    std::thread listener_;
};

}  // namespace refract::scene
