#include "store/pg_scene_store.h"

#include <poll.h>

#include <charconv>
#include <iostream>

#include "store/index_grid_file.h"
#include "store/pg_schema.h"
#include "volume/vdb_check.h"

namespace refract::scene {

namespace {

// Connections the request threads may hold at once, per replica: three replicas and their listeners
// stay well inside PostgreSQL's default max_connections (100).
constexpr size_t kPoolSize = 16;
// How long the listener waits for the database to come back between attempts.
constexpr auto kListenerRetry = std::chrono::seconds(1);
// An edit whose conditional update lost to another replica's (no If-Match) is retried on the new
// revision; past this many losses the scene is too contended to wait for.
constexpr int kMaxEditAttempts = 16;

std::string dump(const protocol::SceneDocument& document) {
    return protocol::to_json(document).dump();
}

std::string text_of(uint64_t number) {
    return std::to_string(number);
}

// Announcements of deleted assets, sent by the deleting transaction (the tables' triggers announce
// uploads only): "deleted-mesh NAME", "deleted-environment NAME", "deleted-grid SCENE", "deleted-volume NAME".
constexpr std::string_view kDeletedMesh = "deleted-mesh", kDeletedEnvironment = "deleted-environment",
                           kDeletedGrid = "deleted-grid", kDeletedVolume = "deleted-volume";

// A payload of refract_notify() (pg_schema.cpp) or of a deletion as an event, and whether it deletes an
// asset; nullopt for one this build does not know.
std::optional<std::pair<StoreEvent, bool>> parse_notification(std::string_view payload) {
    const size_t space = payload.find(' ');
    if (space == std::string_view::npos) return std::nullopt;
    const std::string_view kind = payload.substr(0, space), rest = payload.substr(space + 1);
    const auto event = [&](StoreEvent::Kind k, bool deletion) {
        return std::pair{StoreEvent{k, std::string(rest), 0}, deletion};
    };
    if (kind == "deleted") return event(StoreEvent::Kind::deleted, false);
    if (kind == "mesh") return event(StoreEvent::Kind::mesh, false);
    if (kind == "environment") return event(StoreEvent::Kind::environment, false);
    if (kind == "volume") return event(StoreEvent::Kind::volume, false);
    if (kind == kDeletedMesh) return event(StoreEvent::Kind::mesh, true);
    if (kind == kDeletedEnvironment) return event(StoreEvent::Kind::environment, true);
    if (kind == kDeletedGrid) return event(StoreEvent::Kind::grid, true);
    if (kind == kDeletedVolume) return event(StoreEvent::Kind::volume, true);
    const size_t split = rest.find(' ');
    uint64_t revision = 0;
    if (kind != "revision" || split == std::string_view::npos ||
        std::from_chars(rest.data() + split + 1, rest.data() + rest.size(), revision).ec != std::errc())
        return std::nullopt;
    return std::pair{StoreEvent{StoreEvent::Kind::revision, std::string(rest.substr(0, split)), revision}, false};
}

AssetKind asset_kind(StoreEvent::Kind kind) {
    return kind == StoreEvent::Kind::mesh     ? AssetKind::mesh
           : kind == StoreEvent::Kind::grid   ? AssetKind::grid
           : kind == StoreEvent::Kind::volume ? AssetKind::volume
                                              : AssetKind::environment;
}

}  // namespace

PgSceneStore::PgSceneStore(const std::string& url, protocol::Limits limits, mesh::MeshLimits mesh_limits,
                           uint64_t max_host_memory)
    : pool_(url, kPoolSize), limits_(limits), mesh_limits_(mesh_limits), cache_(max_host_memory) {
    {
        pg::Pool::Lease connection = pool_.acquire();
        pg::migrate(*connection);
        location_ = "postgresql " + connection->describe();
    }
    listener_ = std::thread([this] { listen(); });
}

PgSceneStore::~PgSceneStore() {
    stopping_ = true;
    listener_.join();
}

SceneSnapshot PgSceneStore::snapshot(const std::string& id, uint64_t revision, const std::string& document) const {
    SceneSnapshot result{id, revision, {}};
    nlohmann::json stored = nlohmann::json::parse(document);
    try {
        result.document = protocol::parse_scene(stored, limits_);
    } catch (const protocol::ValidationError&) {
        // Committed under another replica's looser limits: it was valid when acknowledged.
        result.document = protocol::parse_scene(stored);
    }
    return result;
}

SceneSnapshot PgSceneStore::create(const std::string& id, const nlohmann::json& document) {
    if (!id.empty() && !valid_scene_id(id))
        throw StoreError(StoreFailure::invalid, "scene id must match [a-z0-9-]{1,32}");
    protocol::SceneDocument parsed = protocol::parse_scene(document, limits_);
    std::string text = dump(parsed);
    pg::Pool::Lease connection = pool_.acquire();
    check_environment(parsed, [&](const std::string& name) { return has_environment(*connection, name); });
    check_volumes(parsed, [&](const std::string& name) { return volume_report(*connection, name); });
    for (;;) {
        std::string chosen = id.empty() ? random_hex_id() : id;
        pg::Result inserted = connection->exec(
            "INSERT INTO scenes (id, revision, document) VALUES ($1, 1, $2::jsonb) ON CONFLICT (id) DO NOTHING",
            {{chosen}, {text}}, "creating scene '" + chosen + "'");
        if (inserted.affected() == 1) return {chosen, 1, parsed};
        if (!id.empty()) throw StoreError(StoreFailure::taken, "scene '" + id + "' already exists");
    }
}

std::optional<SceneSnapshot> PgSceneStore::get(const std::string& id) const {
    pg::Pool::Lease connection = pool_.acquire();
    pg::Result row = connection->exec("SELECT revision, document::text FROM scenes WHERE id = $1", {{id}},
                                      "reading scene '" + id + "'");
    if (row.rows() == 0) return std::nullopt;
    return snapshot(id, row.number(0, 0), row.text(0, 1));
}

std::vector<SceneSnapshot> PgSceneStore::list() const {
    pg::Pool::Lease connection = pool_.acquire();
    return all_scenes(*connection);
}

std::vector<SceneSnapshot> PgSceneStore::all_scenes(pg::Connection& connection) const {
    pg::Result rows =
        connection.exec("SELECT id, revision, document::text FROM scenes ORDER BY id", {}, "listing scenes");
    std::vector<SceneSnapshot> all;
    for (int i = 0; i < rows.rows(); ++i) all.push_back(snapshot(rows.text(i, 0), rows.number(i, 1), rows.text(i, 2)));
    return all;
}

size_t PgSceneStore::size() const {
    pg::Pool::Lease connection = pool_.acquire();
    return connection->exec("SELECT count(*) FROM scenes", {}, "counting scenes").number(0, 0);
}

bool PgSceneStore::remove(const std::string& id) {
    pg::Pool::Lease connection = pool_.acquire();
    // The scene's index grid goes with it (ON DELETE CASCADE).
    return connection->exec("DELETE FROM scenes WHERE id = $1", {{id}}, "deleting scene '" + id + "'").affected() == 1;
}

EditResult PgSceneStore::patch(const std::string& id, const nlohmann::json& merge_patch,
                               std::optional<uint64_t> if_match) {
    pg::Pool::Lease connection = pool_.acquire();
    for (int attempt = 0; attempt < kMaxEditAttempts; ++attempt) {
        std::optional<SceneSnapshot> current;
        {
            pg::Result row = connection->exec("SELECT revision, document::text FROM scenes WHERE id = $1", {{id}},
                                              "reading scene '" + id + "'");
            if (row.rows() == 0)
                throw StoreError(StoreFailure::not_found, "scene '" + id + "' does not exist");
            current = snapshot(id, row.number(0, 0), row.text(0, 1));
        }
        if (if_match && *if_match != current->revision)
            throw StoreError(
                StoreFailure::stale_revision,
                "scene is at revision " + text_of(current->revision) + ", not " + text_of(*if_match));
        EditResult result;
        result.before = current->document;
        result.after = *current;
        result.after.document = protocol::apply_merge_patch(current->document, merge_patch, limits_);
        result.changed = !(result.after.document == current->document);
        if (!result.changed) return result;
        if (!(result.after.document.environment == current->document.environment))
            check_environment(result.after.document,
                              [&](const std::string& name) { return has_environment(*connection, name); });
        if (!(result.after.document.volumes == current->document.volumes))
            check_volumes(result.after.document,
                          [&](const std::string& name) { return volume_report(*connection, name); });
        result.after.revision = next_revision(current->revision);
        // Optimistic concurrency: the update takes only if nobody committed since the read. Zero rows
        // means another replica won: with If-Match that is the client's 412, without it we edit the
        // newer revision. The statement is its own transaction: its success is the commit.
        uint64_t affected = 0;
        try {
            affected = connection
                           ->exec("UPDATE scenes SET document = $2::jsonb, revision = revision + 1 "
                                  "WHERE id = $1 AND revision = $3",
                                  {{id}, {dump(result.after.document)}, {text_of(current->revision)}},
                                  "committing revision " + text_of(result.after.revision) + " of scene '" + id + "'")
                           .affected();
        } catch (const StoreError& e) {
            if (e.failure() != StoreFailure::unavailable) throw;
            // The answer was lost, not necessarily the edit: acknowledge it if it committed, and say
            // which it was when it did not.
            switch (outcome_of_lost_update(*connection, result.after)) {
                case LostUpdate::committed:
                    return result;
                case LostUpdate::not_applied:
                    throw StoreError(StoreFailure::unavailable,
                                     std::string(e.what()) + "; the edit was not applied");
                case LostUpdate::unknown:
                    throw StoreError(StoreFailure::unavailable,
                                     std::string(e.what()) +
                                         "; whether the edit was applied is unknown until the database "
                                         "answers again: GET the scene to see its revision");
            }
        }
        if (affected == 1) return result;  // the trigger's NOTIFY tells every replica's viewers
        if (if_match)
            throw StoreError(StoreFailure::stale_revision, "scene moved past revision " + text_of(*if_match) +
                                                               " while this edit was applied");
    }
    throw StoreError(StoreFailure::unavailable,
                     "scene '" + id + "' is edited too fast to apply this edit; try again");
}

PgSceneStore::LostUpdate PgSceneStore::outcome_of_lost_update(const pg::Connection& lost,
                                                               const SceneSnapshot& after) const {
    try {
        pg::Connection check(pool_.url());
        // Once the server process that ran the update has exited, its transaction is settled one way or
        // the other (it cannot commit later); then the row says which. PostgreSQL 14+ waits for the exit.
        const std::string pid = std::to_string(lost.backend_pid());
        constexpr std::string_view kLostProcess =
            " FROM pg_stat_activity WHERE pid = $1::int AND backend_start = $2::timestamptz";
        check.exec("SELECT pg_terminate_backend(pid, 5000)" + std::string(kLostProcess), {{pid}, {lost.backend_start()}},
                   "ending the lost connection's server process");
        if (check.exec("SELECT 1" + std::string(kLostProcess), {{pid}, {lost.backend_start()}}, "checking it ended")
                .rows() != 0)
            return LostUpdate::unknown;
        pg::Result row = check.exec("SELECT revision, document::text FROM scenes WHERE id = $1", {{after.id}},
                                    "reading scene '" + after.id + "'");
        if (row.rows() == 0) return LostUpdate::unknown;  // deleted since: what came first cannot be told
        const uint64_t revision = row.number(0, 0);
        if (revision < after.revision) return LostUpdate::not_applied;
        if (revision == after.revision)  // the same number by another writer means ours lost the race
            return snapshot(after.id, revision, row.text(0, 1)).document == after.document ? LostUpdate::committed
                                                                                         : LostUpdate::not_applied;
        return LostUpdate::unknown;  // edited again since: ours may be in between
    } catch (const std::exception&) {
        return LostUpdate::unknown;
    }
}

MeshEntry PgSceneStore::put_mesh(const std::string& name, const std::string& obj_text) {
    auto parsed = parse_mesh_upload(name, obj_text, mesh_limits_, cache_);
    const uint64_t size = host_bytes(*parsed);
    MeshEntry entry{name, mesh::inspect(*parsed)};
    pg::Pool::Lease connection = pool_.acquire();
    // bytea, not text: an OBJ file need not be UTF-8.
    pg::Result stored = connection->exec(
        "INSERT INTO meshes (name, obj, report) VALUES ($1, $2, $3::jsonb) ON CONFLICT (name) DO UPDATE "
        "SET obj = EXCLUDED.obj, report = EXCLUDED.report, version = meshes.version + 1 RETURNING version",
        {{name}, {obj_text, true}, {to_json(entry.report).dump()}}, "storing mesh '" + name + "'");
    cache_.insert(AssetKind::mesh, name, stored.number(0, 0), std::move(parsed), size);
    return entry;
}

std::vector<MeshEntry> PgSceneStore::list_meshes() const {
    pg::Pool::Lease connection = pool_.acquire();
    pg::Result rows = connection->exec("SELECT name, report::text FROM meshes ORDER BY name", {}, "listing meshes");
    std::vector<MeshEntry> all;
    for (int i = 0; i < rows.rows(); ++i)
        all.push_back({rows.text(i, 0), report_from_json(nlohmann::json::parse(rows.text(i, 1)))});
    return all;
}

// Where an asset lives: its table, key column and bytes column, and its name in errors.
struct PgSceneStore::AssetTable {
    std::string_view table, key, data, what;
};

template <typename T, typename Parse>
std::shared_ptr<const T> PgSceneStore::load_asset(AssetKind kind, const AssetTable& where, const std::string& key,
                                                  Parse parse) const {
    const std::string what = std::string(where.what) + " '" + key + "'";
    const std::string condition = " FROM " + std::string(where.table) + " WHERE " + std::string(where.key) + " = $1";
    pg::Pool::Lease connection = pool_.acquire();
    pg::Result version = connection->exec("SELECT version" + condition, {{key}}, "looking up " + what);
    if (version.rows() == 0) return nullptr;
    // A re-upload between the two reads leaves the older version number with the newer bytes: the
    // next lookup parses again, nothing worse.
    const uint64_t stored_version = version.number(0, 0);
    if (auto cached = cache_.find<T>(kind, key, stored_version)) return cached;
    pg::Result row = connection->exec("SELECT " + std::string(where.data) + condition, {{key}}, "reading " + what, true);
    if (row.rows() == 0) return nullptr;
    std::shared_ptr<const T> loaded;
    try {
        loaded = std::make_shared<const T>(parse(row.bytes(0, 0)));
    } catch (const std::exception& e) {
        throw RenderError("stored " + what + " cannot be read: " + e.what());
    }
    const uint64_t size = host_bytes(*loaded);
    return cache_.insert(kind, key, stored_version, std::move(loaded), size);
}

bool PgSceneStore::remove_asset(AssetKind kind, const AssetTable& where, const std::string& key,
                                const std::string& what, const std::string& notification) {
    const std::string condition = " FROM " + std::string(where.table) + " WHERE " + std::string(where.key) + " = $1";
    pg::Pool::Lease connection = pool_.acquire();
    const bool removed = pg::in_transaction(*connection, "deleting " + what, [&] {
        // The row stays locked until the commit: an upload of the same name waits for the deletion.
        if (connection->exec("SELECT 1" + condition + " FOR UPDATE", {{key}}, "looking up " + what).rows() == 0)
            return false;
        check_unused(all_scenes(*connection), kind, key, what);
        connection->exec("DELETE" + condition, {{key}}, "deleting " + what);
        connection->exec("SELECT pg_notify('refract_scenes', $1)", {{notification + " " + key}},
                         "announcing the deletion of " + what);
        return true;
    });
    if (removed) cache_.forget(kind, key);
    return removed;
}

std::shared_ptr<const mesh::Mesh> PgSceneStore::mesh(const std::string& name_or_reference) const {
    std::string name = strip_upload_prefix(name_or_reference);
    if (!valid_mesh_name(name)) return nullptr;
    return load_asset<mesh::Mesh>(AssetKind::mesh, {"meshes", "name", "obj", "mesh"}, name,
                                  [this](const std::string& obj) { return mesh::parse_obj(obj, mesh_limits_); });
}

bool PgSceneStore::remove_mesh(const std::string& name_or_reference) {
    const std::string name = strip_upload_prefix(name_or_reference);
    if (!valid_mesh_name(name)) return false;
    return remove_asset(AssetKind::mesh, {"meshes", "name", "obj", "mesh"}, name, "mesh '" + name + "'",
                        std::string(kDeletedMesh));
}

EnvironmentEntry PgSceneStore::put_environment(const std::string& name, const std::string& bytes) {
    auto decoded = decode_environment_upload(name, bytes, cache_);
    EnvironmentEntry entry{name, decoded->width, decoded->height, false};
    pg::Pool::Lease connection = pool_.acquire();
    pg::Result stored = connection->exec(
        "INSERT INTO environments (name, data, width, height) VALUES ($1, $2, $3, $4) ON CONFLICT (name) DO UPDATE "
        "SET data = EXCLUDED.data, width = EXCLUDED.width, height = EXCLUDED.height, "
        "version = environments.version + 1 RETURNING version",
        {{name}, {bytes, true}, {std::to_string(entry.width)}, {std::to_string(entry.height)}},
        "storing environment '" + name + "'");
    const uint64_t size = host_bytes(*decoded);
    cache_.insert(AssetKind::environment, name, stored.number(0, 0), std::move(decoded), size);
    return entry;
}

bool PgSceneStore::has_environment(pg::Connection& connection, const std::string& name) const {
    return connection.exec("SELECT 1 FROM environments WHERE name = $1", {{name}}, "looking up environment '" + name + "'")
               .rows() > 0;
}

std::vector<EnvironmentEntry> PgSceneStore::list_stored_environments() const {
    pg::Pool::Lease connection = pool_.acquire();
    pg::Result rows = connection->exec("SELECT name, width, height FROM environments ORDER BY name", {},
                                       "listing environments");
    std::vector<EnvironmentEntry> all;
    for (int i = 0; i < rows.rows(); ++i)
        all.push_back({rows.text(i, 0), static_cast<uint32_t>(rows.number(i, 1)), static_cast<uint32_t>(rows.number(i, 2)),
                       false});
    return all;
}

std::shared_ptr<const image::EnvironmentMap> PgSceneStore::stored_environment(const std::string& name) const {
    if (!valid_mesh_name(name)) return nullptr;
    return load_asset<image::EnvironmentMap>(AssetKind::environment, {"environments", "name", "data", "environment"},
                                             name, [](const std::string& bytes) { return image::decode_environment(bytes); });
}

bool PgSceneStore::remove_environment(const std::string& name) {
    if (!valid_mesh_name(name) || image::built_in_environment(name)) return false;
    return remove_asset(AssetKind::environment, {"environments", "name", "data", "environment"}, name,
                        "environment '" + name + "'", std::string(kDeletedEnvironment));
}

VolumeEntry PgSceneStore::put_volume(const std::string& name, const std::string& bytes) {
    VolumeEntry entry{name, inspect_volume_upload(name, bytes, limits_)};
    pg::Pool::Lease connection = pool_.acquire();
    connection->exec(
        "INSERT INTO volumes (name, data, report) VALUES ($1, $2, $3::jsonb) ON CONFLICT (name) DO UPDATE "
        "SET data = EXCLUDED.data, report = EXCLUDED.report, version = volumes.version + 1",
        {{name}, {bytes, true}, {volume::to_json(entry.report).dump()}}, "storing volume '" + name + "'");
    return entry;
}

std::vector<VolumeEntry> PgSceneStore::list_volumes() const {
    pg::Pool::Lease connection = pool_.acquire();
    pg::Result rows = connection->exec("SELECT name, report::text FROM volumes ORDER BY name", {}, "listing volumes");
    std::vector<VolumeEntry> all;
    for (int i = 0; i < rows.rows(); ++i)
        all.push_back({rows.text(i, 0), volume::volume_report_from_json(nlohmann::json::parse(rows.text(i, 1)))});
    return all;
}

bool PgSceneStore::remove_volume(const std::string& name) {
    if (!valid_mesh_name(name)) return false;
    return remove_asset(AssetKind::volume, {"volumes", "name", "data", "volume"}, name, "volume '" + name + "'",
                        std::string(kDeletedVolume));
}

std::optional<volume::VolumeReport> PgSceneStore::volume_report(pg::Connection& connection,
                                                                const std::string& name) const {
    pg::Result row = connection.exec("SELECT report::text FROM volumes WHERE name = $1", {{name}},
                                     "looking up volume '" + name + "'");
    if (row.rows() == 0) return std::nullopt;
    return volume::volume_report_from_json(nlohmann::json::parse(row.text(0, 0)));
}

std::optional<volume::VolumeReport> PgSceneStore::volume_report(const std::string& name) const {
    if (!valid_mesh_name(name)) return std::nullopt;
    pg::Pool::Lease connection = pool_.acquire();
    return volume_report(*connection, name);
}

std::shared_ptr<const volume::DensityGrid> PgSceneStore::density(const std::string& name, const std::string& grid) const {
    if (!valid_mesh_name(name)) return nullptr;
    pg::Pool::Lease connection = pool_.acquire();
    pg::Result version = connection->exec("SELECT version FROM volumes WHERE name = $1", {{name}},
                                          "looking up volume '" + name + "'");
    if (version.rows() == 0) return nullptr;
    // One cache entry per grid, under the volume's version, as load_asset keeps one per asset.
    const std::string key = name + "/" + grid;
    const uint64_t stored_version = version.number(0, 0);
    if (auto cached = cache_.find<volume::DensityGrid>(AssetKind::volume, key, stored_version)) return cached;
    pg::Result row = connection->exec("SELECT data FROM volumes WHERE name = $1", {{name}},
                                      "reading volume '" + name + "'", true);
    if (row.rows() == 0) return nullptr;
    std::shared_ptr<const volume::DensityGrid> exported;
    try {
        exported = std::make_shared<const volume::DensityGrid>(
            volume::export_density_apart(row.bytes(0, 0), grid, volume::limits_for_resolution(limits_.max_resolution)));
    } catch (const std::exception& e) {
        throw RenderError("stored volume '" + name + "' grid '" + grid + "' cannot be read: " + e.what());
    }
    const uint64_t size = host_bytes(*exported);
    return cache_.insert(AssetKind::volume, key, stored_version, std::move(exported), size);
}

EditResult PgSceneStore::put_index_grid(const std::string& scene_id, IndexGrid grid) {
    validate_index_grid(grid);
    cache_.check_fits("the index grid", host_bytes(grid));
    std::vector<char> bytes = encode_grid(grid);
    pg::Pool::Lease connection = pool_.acquire();
    EditResult result = pg::in_transaction(*connection, "storing the index grid of scene '" + scene_id + "'", [&] {
        pg::Result row = connection->exec("SELECT revision, document::text FROM scenes WHERE id = $1 FOR UPDATE",
                                          {{scene_id}}, "reading scene '" + scene_id + "'");
        if (row.rows() == 0)
            throw StoreError(StoreFailure::not_found, "scene '" + scene_id + "' does not exist");
        SceneSnapshot current = snapshot(scene_id, row.number(0, 0), row.text(0, 1));
        EditResult edit;
        edit.before = current.document;
        edit.after = current;
        edit.after.document = protocol::apply_merge_patch(
            current.document, {{"object", {{"index_field", "grid"}, {"grid", scene_id}}}}, limits_);
        // Same document, new grid contents: still a new revision, so clients see the change.
        edit.after.revision = next_revision(current.revision);
        edit.changed = true;
        connection->exec(
            "INSERT INTO grids (scene_id, data) VALUES ($1, $2) ON CONFLICT (scene_id) DO UPDATE "
            "SET data = EXCLUDED.data, version = grids.version + 1",
            {{scene_id}, {std::string_view(bytes.data(), bytes.size()), true}}, "storing the index grid");
        connection->exec("UPDATE scenes SET document = $2::jsonb, revision = revision + 1 WHERE id = $1",
                         {{scene_id}, {dump(edit.after.document)}}, "pointing the scene at its grid");
        return edit;
    });
    cache_.forget(AssetKind::grid, scene_id);  // parsed again, with its new version, when the renderer asks
    return result;
}

std::shared_ptr<const IndexGrid> PgSceneStore::grid(const std::string& name) const {
    if (!valid_scene_id(name)) return nullptr;
    return load_asset<IndexGrid>(AssetKind::grid, {"grids", "scene_id", "data", "index grid"}, name,
                                 [](const std::string& bytes) { return decode_grid(bytes); });
}

bool PgSceneStore::remove_index_grid(const std::string& scene_id) {
    if (!valid_scene_id(scene_id)) return false;
    return remove_asset(AssetKind::grid, {"grids", "scene_id", "data", "index grid"}, scene_id,
                        "the index grid of scene '" + scene_id + "'", std::string(kDeletedGrid));
}

void PgSceneStore::listen() {
    for (bool first = true; !stopping_;) {
        try {
            pg::Connection connection(pool_.url());
            connection.exec("LISTEN refract_scenes", "listening for edits");
            // Whatever was announced while this connection was down is lost: say so.
            if (!first) publish({StoreEvent::Kind::missed, {}, 0});
            first = false;
            while (!stopping_) {
                pollfd fd{PQsocket(connection.raw()), POLLIN, 0};
                if (::poll(&fd, 1, 250) < 0) continue;
                if (PQconsumeInput(connection.raw()) == 0)
                    throw StoreError(
                        StoreFailure::unavailable,
                        std::string("lost the notification connection: ") + PQerrorMessage(connection.raw()));
                while (PGnotify* note = PQnotifies(connection.raw())) {
                    std::optional<std::pair<StoreEvent, bool>> event = parse_notification(note->extra);
                    PQfreemem(note);
                    if (!event) continue;
                    // A deletion by any replica: nothing asks for the asset again, so nothing would replace it.
                    if (event->second) cache_.forget(asset_kind(event->first.kind), event->first.name);
                    publish(event->first);
                }
            }
        } catch (const std::exception& e) {
            // Viewers miss the edits made while the database is away; their next message or frame
            // request reads the newest revision.
            std::cerr << "refractd: scene notifications paused: " << e.what() << "\n";
            for (auto waited = std::chrono::milliseconds(0); !stopping_ && waited < kListenerRetry;
                 waited += std::chrono::milliseconds(100))
                std::this_thread::sleep_for(std::chrono::milliseconds(100));
        }
    }
}

}  // namespace refract::scene
