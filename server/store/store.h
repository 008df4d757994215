// What the daemon asks of a scene store, whichever keeps the data: the embedded file store
// (scene_store.h, the default) or the shared PostgreSQL store (pg_scene_store.h) that replicas share.
// Thread-safe: any HTTP or WebSocket thread may call it. A store never renders and never touches Vulkan.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "assets/assets.h"
#include "assets/render_error.h"
#include "image/environment_map.h"
#include "mesh/mesh.h"
#include "protocol/scene_document.h"
#include "store/asset_cache.h"
#include "volume/vdb_reader.h"

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

// What went wrong in the store, in the store's own words. The front ends choose how each is answered
// (http/service.h maps them to HTTP statuses); the store knows nothing of HTTP.
enum class StoreFailure {
    invalid,           // a scene id, asset name or index grid the store does not take
    not_found,         // the scene named does not exist
    taken,             // the scene id is taken (by a scene, or by a stored file that could not be read), or
                       // another writer stored the same key first
    in_use,            // an uploaded asset that scenes still name (AssetInUse); a data directory another
                       // refractd holds
    out_of_revisions,  // the scene is at kMaxRevision: no edit can make a new one
    stale_revision,    // the scene is not (or no longer) at the revision the edit was made against
    too_large,         // an asset that could never be held within the daemon's budget for decoded assets
    broken,            // the storage failed: a file that cannot be read, written or decoded, a database
                       // that refused a statement, answered nonsense or has a newer schema
    unavailable,       // a shared store's database cannot be reached or is too busy, or a scene changes too
                       // fast for an edit to land: retrying may succeed
};

// Why the store refused or failed a request: the failure, and a message for the user that says what.
class StoreError : public std::runtime_error {
public:
    StoreError(StoreFailure failure, const std::string& message)
        : std::runtime_error(message), failure_(failure) {}
    StoreFailure failure() const { return failure_; }

private:
    StoreFailure failure_;
};

// A refused deletion: the asset is named by the documents of `scenes` (their ids, sorted).
class AssetInUse : public StoreError {
public:
    AssetInUse(const std::string& message, std::vector<std::string> scenes)
        : StoreError(StoreFailure::in_use, message), scenes_(std::move(scenes)) {}
    const std::vector<std::string>& scenes() const { return scenes_; }

private:
    std::vector<std::string> scenes_;
};

// The host memory decoded assets may hold unless the daemon is told otherwise (--max-host-memory).
inline constexpr uint64_t kDefaultMaxHostMemory = uint64_t{1} << 30;

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

// An uploaded or built-in environment map, as GET /api/environments lists it.
struct EnvironmentEntry {
    std::string name;
    uint32_t width = 0, height = 0;
    bool built_in = false;
};

// An uploaded volume (an OpenVDB file, kept as uploaded), as GET /api/volumes lists it.
struct VolumeEntry {
    std::string name;
    volume::VolumeReport report;
};


// Throws protocol::ValidationError at /environment/image when `document` names an environment that is
// neither built in nor `stored(name)`: a store's create and patch call it before anything is written.
// Existence only: a stored file that cannot be read is the render's error, which names the file.
void check_environment(const protocol::SceneDocument& document,
                       const std::function<bool(const std::string& name)>& stored);

// Throws protocol::ValidationError at /volumes/NAME/asset when a member of `document`'s volumes names a
// volume `stored` does not know (nullopt), or at /volumes/NAME/grid when that volume has no usable float
// grid of the name: a store's create and patch call it before anything is written.
void check_volumes(const protocol::SceneDocument& document,
                   const std::function<std::optional<volume::VolumeReport>(const std::string& name)>& stored);

// The ids of the scenes among `scenes` whose documents name the uploaded asset `name` (a mesh as
// "upload:NAME", an environment image, an imported grid), sorted; throws AssetInUse, with `what` ("mesh
// 'x'"), when there are any.
void check_unused(const std::vector<SceneSnapshot>& scenes, AssetKind kind, const std::string& name,
                  const std::string& what);

// The host memory a decoded asset takes, as the cache counts it.
uint64_t host_bytes(const mesh::Mesh& mesh);
uint64_t host_bytes(const IndexGrid& grid);
uint64_t host_bytes(const image::EnvironmentMap& map);
uint64_t host_bytes(const volume::DensityGrid& grid);

// An upload as both stores take it in, checked before it is kept: a valid name, within the decoded-asset
// budget (`cache`'s check_fits; an environment map on its header, before it is decoded), an environment
// not named as a built-in one. Throws StoreError, or the parser's or decoder's error.
std::shared_ptr<const mesh::Mesh> parse_mesh_upload(const std::string& name, const std::string& obj_text,
                                                    const mesh::MeshLimits& limits, const AssetCache& cache);
std::shared_ptr<const image::EnvironmentMap> decode_environment_upload(const std::string& name, const std::string& bytes,
                                                                       const AssetCache& cache);

// A volume upload checked before it is kept: a valid name, then the whole file in a process of its own
// (volume::inspect_vdb_apart) under the limits of `limits`' max_resolution.
// Throws StoreError(invalid), volume::VolumeError or volume::CheckUnavailable.
volume::VolumeReport inspect_volume_upload(const std::string& name, const std::string& bytes,
                                           const protocol::Limits& limits);

// Validation of an imported index grid, in the words a user needs; throws StoreError(invalid).
void validate_index_grid(const IndexGrid& grid);

// True for a name usable as a scene id ([a-z0-9-]{1,32}) or as a mesh name ([A-Za-z0-9_.-]{1,64}, not
// "." or "..").
bool valid_scene_id(const std::string& id);
bool valid_mesh_name(const std::string& name);

// A report as the JSON the API answers with, and back (for a report a store kept).
nlohmann::json to_json(const mesh::MeshReport& report);
mesh::MeshReport report_from_json(const nlohmann::json& j);

// `revision` + 1; StoreError(out_of_revisions) at kMaxRevision.
uint64_t next_revision(uint64_t revision);
// A mesh reference without its "upload:" prefix.
std::string strip_upload_prefix(const std::string& name);
// Eight random hex digits: the id of a scene created without one.
std::string random_hex_id();

// What a store announces once it is committed (by this process or, for a shared store, by any replica):
// a new revision of a scene, a scene's deletion, a new version or the deletion of an uploaded mesh or
// environment (which changes frames without a new revision), the deletion of an imported grid or of an
// uploaded volume (its upload is not announced yet: other replicas keep the frames they cached of
// scenes that name it); or that
// announcements may have been lost (a shared store's listener reconnected), so whatever was cached may
// be stale.
struct StoreEvent {
    enum class Kind { revision, deleted, mesh, environment, grid, volume, missed };
    Kind kind = Kind::revision;
    std::string name;       // the scene's id, the mesh's, environment's or volume's name, or the grid's scene id
    uint64_t revision = 0;  // Kind::revision only
};
using StoreListener = std::function<void(const StoreEvent&)>;

class Store;

// A registered listener; unregisters it on destruction, after any call in progress has returned.
class Subscription {
public:
    Subscription(const Store* store, uint64_t id) : store_(store), id_(id) {}
    ~Subscription();
    Subscription(Subscription&& other) noexcept : store_(std::exchange(other.store_, nullptr)), id_(other.id_) {}
    Subscription& operator=(Subscription&&) = delete;
    Subscription(const Subscription&) = delete;
    Subscription& operator=(const Subscription&) = delete;

private:
    const Store* store_;
    uint64_t id_;
};

class Store {
public:
    virtual ~Store() = default;

    // Creates a scene from a (possibly partial) document. `id` empty: a random one. Throws
    // protocol::ValidationError, StoreError (invalid id, taken).
    virtual SceneSnapshot create(const std::string& id, const nlohmann::json& document) = 0;
    virtual std::optional<SceneSnapshot> get(const std::string& id) const = 0;
    virtual std::vector<SceneSnapshot> list() const = 0;
    virtual size_t size() const = 0;
    // Deletes a scene and its index grid; false when unknown.
    virtual bool remove(const std::string& id) = 0;

    // Applies a merge patch atomically. `if_match`: the revision the client edited (stale_revision
    // otherwise). Throws protocol::ValidationError (nothing changes), StoreError (not_found,
    // stale_revision, out_of_revisions, broken, unavailable).
    virtual EditResult patch(const std::string& id, const nlohmann::json& merge_patch,
                             std::optional<uint64_t> if_match = std::nullopt) = 0;

    // Parses, inspects and stores an OBJ upload, replacing one of the same name. Throws mesh::MeshError,
    // StoreError(invalid) for a bad name.
    virtual MeshEntry put_mesh(const std::string& name, const std::string& obj_text) = 0;
    virtual std::vector<MeshEntry> list_meshes() const = 0;
    // The mesh named `name` (with or without the "upload:" prefix); nullptr when unknown; RenderError
    // saying why when it is stored but cannot be read.
    virtual std::shared_ptr<const mesh::Mesh> mesh(const std::string& name) const = 0;
    // Deletes the uploaded mesh `name` for good; false when none is stored. Throws AssetInUse while any
    // scene's document names it, and deletes nothing then.
    virtual bool remove_mesh(const std::string& name) = 0;

    // Decodes and stores an environment upload (.hdr or .exr bytes), replacing one of the same name.
    // Throws image::EnvironmentError, StoreError(invalid) for a bad name or a built-in one.
    virtual EnvironmentEntry put_environment(const std::string& name, const std::string& bytes) = 0;
    // The uploaded environments (built-in ones are not stored).
    virtual std::vector<EnvironmentEntry> list_stored_environments() const = 0;
    // The uploaded environment `name`; nullptr when unknown, RenderError when it cannot be read.
    virtual std::shared_ptr<const image::EnvironmentMap> stored_environment(const std::string& name) const = 0;
    // Deletes the uploaded environment `name` for good; false when none is stored (a built-in one never
    // is). Throws AssetInUse while any scene's document names it.
    virtual bool remove_environment(const std::string& name) = 0;
    // Built-in and uploaded environments, by name.
    std::vector<EnvironmentEntry> list_environments() const;
    // The environment named `name`, built in or uploaded; nullptr when unknown.
    std::shared_ptr<const image::EnvironmentMap> environment(const std::string& name) const;

    // Checks and stores a volume upload (.vdb bytes) as it came, replacing one of the same name; what was
    // refused is never stored. Throws volume::VolumeError, StoreError(invalid) for a bad name.
    virtual VolumeEntry put_volume(const std::string& name, const std::string& bytes) = 0;
    virtual std::vector<VolumeEntry> list_volumes() const = 0;
    // Deletes the uploaded volume `name` for good; false when none is stored. Throws AssetInUse while any
    // scene's document names it.
    virtual bool remove_volume(const std::string& name) = 0;
    // The report of the uploaded volume `name`; nullopt when none is stored.
    virtual std::optional<volume::VolumeReport> volume_report(const std::string& name) const = 0;
    // The float grid `grid` of the uploaded volume `name` (volume::export_density_apart), cached with the
    // decoded assets; nullptr when no volume is stored under `name`, RenderError when it cannot be read.
    virtual std::shared_ptr<const volume::DensityGrid> density(const std::string& name, const std::string& grid) const = 0;

    // Stores `grid` under the scene's id and points the scene at it (a new revision). Throws StoreError.
    virtual EditResult put_index_grid(const std::string& scene_id, IndexGrid grid) = 0;
    // The grid stored for scene `name`; nullptr when unknown, RenderError when it cannot be read.
    virtual std::shared_ptr<const IndexGrid> grid(const std::string& name) const = 0;
    // Deletes the grid imported for scene `scene_id` for good; false when it has none. Throws AssetInUse
    // while any scene's document names it (its own, until an edit sets another index field).
    virtual bool remove_index_grid(const std::string& scene_id) = 0;

    // Stored scenes found unreadable at start (the file store's quarantine); empty for other stores.
    virtual const std::vector<QuarantinedFile>& quarantined() const = 0;
    virtual const protocol::Limits& limits() const = 0;
    // Where the data lives, for the start-up line ("data dir ./refract-data", "postgresql db@host:port").
    virtual std::string location() const = 0;

    // Lookups for the renderer (called on the render thread).
    Assets assets() const;


    // Registers `listener` for every event until the subscription goes.
    [[nodiscard]] Subscription on_change(StoreListener listener) const;

protected:
    // Tells every listener. Never throws.
    void publish(const StoreEvent& event) const;

private:
    friend class Subscription;

    mutable std::mutex listeners_mutex_;  // held while listeners run: unsubscribing waits for them
    mutable std::map<uint64_t, StoreListener> listeners_;
    mutable uint64_t next_listener_ = 0;
};

}  // namespace refract::scene
