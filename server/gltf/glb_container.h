// The checks a glTF gets before any library parses it: the GLB container's header and chunks, and every
// URI (a daemon reads no files on a client's behalf: only data: URIs and the GLB's own chunk).
#pragma once

#include <cstddef>
#include <string_view>

#include <nlohmann/json.hpp>

namespace refract::gltf {

struct ImportLimits {
    // A data: URI's payload. The file itself is bounded by whoever reads it (the HTTP body limit).
    size_t max_bytes = 64u << 20;
};

// True when `bytes` starts like a GLB ('glTF' magic) rather than glTF JSON.
bool is_glb(std::string_view bytes);

// The glTF JSON of `bytes` (a .glb's JSON chunk, or the whole .gltf), parsed. Throws GltfError at "(glb)"
// for a bad header, a truncated or overlong chunk, a JSON chunk that is not first; at the URI's path
// ("/buffers/0/uri") for an external URI or a data: URI over limits.max_bytes; at "" for JSON that does
// not parse, is not an object or nests more than 64 levels deep.
nlohmann::json checked_json(std::string_view bytes, const ImportLimits& limits);

}  // namespace refract::gltf
