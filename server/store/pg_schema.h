// The shared store's tables, created and migrated by refractd on start. The schema carries its version;
// a database migrated by a newer refractd is refused rather than written in a shape this one does not know.
#pragma once

#include "store/pg_connection.h"

namespace refract::scene::pg {

// The schema version this build writes.
constexpr int kSchemaVersion = 4;

// Brings the database to kSchemaVersion under an advisory lock (replicas starting together migrate
// once). Throws StoreError: unavailable when unreachable, broken (naming both versions) when the
// database is newer.
void migrate(Connection& connection);

}  // namespace refract::scene::pg
