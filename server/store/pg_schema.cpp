#include "store/pg_schema.h"

#include <array>
#include <string>

namespace refract::scene::pg {

namespace {

// Any constant of our own: serializes refractd's migrations, never anyone else's locks.
constexpr std::string_view kMigrationLock = "SELECT pg_advisory_xact_lock(7352418160519011)";

// Migration N brings the schema from version N to N + 1; never edit one that has shipped.
//
// Version 1. The revision rules live in the database, so no writer (another replica, a script) can
// break them: ids as the daemon accepts them (lower case only, so ids differing in case cannot both
// exist), revisions in [1, 2^53 - 1], a new scene at 1 and each update exactly one more than the row
// held. Every committed change is announced on channel refract_scenes, to every replica: "revision ID N",
// "deleted ID", "mesh NAME" (NOTIFY payloads are small: never the document).
constexpr std::array<std::string_view, kSchemaVersion> kMigrations = {R"sql(
CREATE TABLE scenes (
    id text PRIMARY KEY CONSTRAINT scene_id_format CHECK (id ~ '^[a-z0-9-]{1,32}$'),
    revision bigint NOT NULL CONSTRAINT revision_range CHECK (revision BETWEEN 1 AND 9007199254740991),
    document jsonb NOT NULL,
    updated_at timestamptz NOT NULL DEFAULT now()
);
CREATE FUNCTION refract_scene_revision() RETURNS trigger LANGUAGE plpgsql AS $$
BEGIN
    IF TG_OP = 'INSERT' AND NEW.revision <> 1 THEN
        RAISE EXCEPTION 'scene %: a new scene starts at revision 1, not %', NEW.id, NEW.revision;
    END IF;
    IF TG_OP = 'UPDATE' AND NEW.revision <> OLD.revision + 1 THEN
        RAISE EXCEPTION 'scene %: revision % cannot follow %', NEW.id, NEW.revision, OLD.revision;
    END IF;
    NEW.updated_at := now();
    RETURN NEW;
END $$;
CREATE TRIGGER scenes_revision BEFORE INSERT OR UPDATE ON scenes
    FOR EACH ROW EXECUTE FUNCTION refract_scene_revision();
CREATE TABLE meshes (
    name text PRIMARY KEY CONSTRAINT mesh_name_format
        CHECK (name ~ '^[A-Za-z0-9_.-]{1,64}$' AND name NOT IN ('.', '..')),
    obj bytea NOT NULL,
    report jsonb NOT NULL,
    version bigint NOT NULL DEFAULT 1
);
CREATE TABLE grids (
    scene_id text PRIMARY KEY REFERENCES scenes (id) ON DELETE CASCADE,
    data bytea NOT NULL,
    version bigint NOT NULL DEFAULT 1
);
CREATE FUNCTION refract_notify() RETURNS trigger LANGUAGE plpgsql AS $$
BEGIN
    IF TG_TABLE_NAME = 'meshes' THEN
        PERFORM pg_notify('refract_scenes', 'mesh ' || NEW.name);
    ELSIF TG_OP = 'DELETE' THEN
        PERFORM pg_notify('refract_scenes', 'deleted ' || OLD.id);
    ELSE
        PERFORM pg_notify('refract_scenes', 'revision ' || NEW.id || ' ' || NEW.revision);
    END IF;
    RETURN NULL;
END $$;
CREATE TRIGGER scenes_notify AFTER INSERT OR UPDATE OR DELETE ON scenes
    FOR EACH ROW EXECUTE FUNCTION refract_notify();
CREATE TRIGGER meshes_notify AFTER INSERT OR UPDATE ON meshes
    FOR EACH ROW EXECUTE FUNCTION refract_notify();
)sql",
// Version 2. Uploaded environment maps, as uploaded (.hdr or .exr bytes) with their size; each upload is
// announced as "environment NAME".
R"sql(
CREATE TABLE environments (
    name text PRIMARY KEY CONSTRAINT environment_name_format
        CHECK (name ~ '^[A-Za-z0-9_.-]{1,64}$' AND name NOT IN ('.', '..')),
    data bytea NOT NULL,
    width integer NOT NULL,
    height integer NOT NULL,
    version bigint NOT NULL DEFAULT 1
);
CREATE OR REPLACE FUNCTION refract_notify() RETURNS trigger LANGUAGE plpgsql AS $$
BEGIN
    IF TG_TABLE_NAME = 'meshes' THEN
        PERFORM pg_notify('refract_scenes', 'mesh ' || NEW.name);
    ELSIF TG_TABLE_NAME = 'environments' THEN
        PERFORM pg_notify('refract_scenes', 'environment ' || NEW.name);
    ELSIF TG_OP = 'DELETE' THEN
        PERFORM pg_notify('refract_scenes', 'deleted ' || OLD.id);
    ELSE
        PERFORM pg_notify('refract_scenes', 'revision ' || NEW.id || ' ' || NEW.revision);
    END IF;
    RETURN NULL;
END $$;
CREATE TRIGGER environments_notify AFTER INSERT OR UPDATE ON environments
    FOR EACH ROW EXECUTE FUNCTION refract_notify();
)sql",
// Version 3. Uploaded volumes (OpenVDB files) as uploaded, with the report GET /api/volumes lists (their
// uploads are announced from version 4).
R"sql(
CREATE TABLE volumes (
    name text PRIMARY KEY CONSTRAINT volume_name_format
        CHECK (name ~ '^[A-Za-z0-9_.-]{1,64}$' AND name NOT IN ('.', '..')),
    data bytea NOT NULL,
    report jsonb NOT NULL,
    version bigint NOT NULL DEFAULT 1
);
)sql",
// Version 4. Volume uploads are announced as "volume NAME", as meshes' and environments' are: other
// replicas forget the frames they cached of scenes that name the volume.
R"sql(
CREATE OR REPLACE FUNCTION refract_notify() RETURNS trigger LANGUAGE plpgsql AS $$
BEGIN
    IF TG_TABLE_NAME = 'meshes' THEN
        PERFORM pg_notify('refract_scenes', 'mesh ' || NEW.name);
    ELSIF TG_TABLE_NAME = 'environments' THEN
        PERFORM pg_notify('refract_scenes', 'environment ' || NEW.name);
    ELSIF TG_TABLE_NAME = 'volumes' THEN
        PERFORM pg_notify('refract_scenes', 'volume ' || NEW.name);
    ELSIF TG_OP = 'DELETE' THEN
        PERFORM pg_notify('refract_scenes', 'deleted ' || OLD.id);
    ELSE
        PERFORM pg_notify('refract_scenes', 'revision ' || NEW.id || ' ' || NEW.revision);
    END IF;
    RETURN NULL;
END $$;
CREATE TRIGGER volumes_notify AFTER INSERT OR UPDATE ON volumes
    FOR EACH ROW EXECUTE FUNCTION refract_notify();
)sql"};

}  // namespace

void migrate(Connection& connection) {
    in_transaction(connection, "migrating the schema", [&] {
        connection.exec(kMigrationLock, "taking the migration lock");
        connection.exec("CREATE TABLE IF NOT EXISTS refract_schema ("
                        " one boolean PRIMARY KEY DEFAULT true CHECK (one),"
                        " version integer NOT NULL)",
                        "creating the schema version table");
        Result found = connection.exec("SELECT version FROM refract_schema", "reading the schema version");
        const uint64_t version = found.rows() == 0 ? 0 : found.number(0, 0);
        if (version > kSchemaVersion)
            throw StoreError(StoreFailure::broken,
                             "the database's schema is version " + std::to_string(version) +
                                 ", newer than this refractd's " + std::to_string(kSchemaVersion) +
                                 "; refusing to start (run the refractd that migrated it, or a newer one)");
        for (uint64_t step = version; step < kSchemaVersion; ++step)
            connection.exec_script(kMigrations[step], "migrating the schema to version " + std::to_string(step + 1));
        connection.exec("INSERT INTO refract_schema (version) VALUES (" + std::to_string(kSchemaVersion) +
                            ") ON CONFLICT (one) DO UPDATE SET version = EXCLUDED.version",
                        "recording the schema version");
        return 0;
    });
}

}  // namespace refract::scene::pg
