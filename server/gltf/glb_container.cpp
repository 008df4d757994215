#include "gltf/glb_container.h"

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <string>

#include "gltf/gltf_error.h"

namespace refract::gltf {
namespace {

using nlohmann::json;

constexpr uint32_t kJsonChunk = 0x4E4F534A;  // "JSON"
constexpr uint32_t kBinChunk = 0x004E4942;   // "BIN\0"
// glTF's own structure nests about 6 levels (extensions within materials within the root); extras may
// go deeper, but not this deep.
constexpr size_t kMaxNesting = 64;

uint32_t read_u32(std::string_view bytes, size_t at) {
    uint32_t v = 0;
    std::memcpy(&v, bytes.data() + at, sizeof v);  // GLB is little-endian, as every host we build for
    return v;
}

[[noreturn]] void fail_glb(const std::string& rule) { throw GltfError("(glb)", rule); }

// The JSON chunk's text, after checking that the header's length and every chunk fit the file exactly.
std::string_view glb_json_chunk(std::string_view bytes) {
    if (bytes.size() < 20) fail_glb("a GLB needs a 12-byte header and a JSON chunk; the file has " +
                                    std::to_string(bytes.size()) + " bytes");
    if (read_u32(bytes, 4) != 2) fail_glb("GLB version " + std::to_string(read_u32(bytes, 4)) + " (only 2 is glTF 2.0)");
    const uint32_t length = read_u32(bytes, 8);
    if (length != bytes.size())
        fail_glb("the header says " + std::to_string(length) + " bytes, the file has " + std::to_string(bytes.size()));
    std::string_view json_text;
    size_t at = 12;
    for (size_t chunk = 0; at < bytes.size(); ++chunk) {
        if (bytes.size() - at < 8) fail_glb("chunk " + std::to_string(chunk) + " is truncated: its 8-byte header is cut off");
        const uint32_t chunk_length = read_u32(bytes, at);
        const uint32_t type = read_u32(bytes, at + 4);
        if (chunk_length > bytes.size() - at - 8)
            fail_glb("chunk " + std::to_string(chunk) + " claims " + std::to_string(chunk_length) + " bytes; " +
                     std::to_string(bytes.size() - at - 8) + " are left in the file (truncated)");
        if (chunk == 0 && type != kJsonChunk) fail_glb("the first chunk must be JSON");
        if (chunk == 1 && type != kBinChunk) fail_glb("the second chunk must be BIN");
        if (chunk == 0) json_text = bytes.substr(at + 8, chunk_length);
        at += 8 + size_t{chunk_length};
    }
    return json_text;
}

// Every URI is a data: URI within the limit; anything else names a file or a server.
void check_uris(const json& document, const char* section, const ImportLimits& limits) {
    const auto it = document.find(section);
    if (it == document.end() || !it->is_array()) return;
    for (size_t i = 0; i < it->size(); ++i) {
        const json& item = (*it)[i];
        if (!item.is_object() || !item.contains("uri")) continue;
        const std::string path = "/" + std::string(section) + "/" + std::to_string(i) + "/uri";
        if (!item["uri"].is_string()) throw GltfError(path, "a URI must be a string");
        const std::string& uri = item["uri"].get_ref<const std::string&>();
        if (uri.rfind("data:", 0) != 0)
            throw GltfError(path, "external URI '" + uri.substr(0, 80) +
                                      "' refused: the daemon reads no files for a client; embed the data "
                                      "(a .glb, or a data: URI)");
        // Base64 takes 4 characters for 3 bytes.
        if (uri.size() / 4 * 3 > limits.max_bytes)
            throw GltfError(path, "data: URI of about " + std::to_string(uri.size() / 4 * 3) +
                                      " bytes, over the limit of " + std::to_string(limits.max_bytes));
    }
}

// How deeply arrays and objects nest in JSON text (strings skipped), read without parsing: tinygltf
// copies extras recursively, so a file nested a few hundred thousand levels would exhaust its stack.
size_t nesting(std::string_view text) {
    size_t depth = 0, deepest = 0;
    bool in_string = false;
    for (size_t i = 0; i < text.size(); ++i) {
        const char c = text[i];
        if (in_string) {
            if (c == '\\') ++i;
            else if (c == '"') in_string = false;
        } else if (c == '"') {
            in_string = true;
        } else if (c == '[' || c == '{') {
            deepest = std::max(deepest, ++depth);
        } else if ((c == ']' || c == '}') && depth > 0) {
            --depth;
        }
    }
    return deepest;
}

}  // namespace

bool is_glb(std::string_view bytes) { return bytes.size() >= 4 && bytes.substr(0, 4) == "glTF"; }

json checked_json(std::string_view bytes, const ImportLimits& limits) {
    const std::string_view text = is_glb(bytes) ? glb_json_chunk(bytes) : bytes;
    if (const size_t depth = nesting(text); depth > kMaxNesting)
        throw GltfError("", "the JSON nests " + std::to_string(depth) + " levels deep (at most " +
                                std::to_string(kMaxNesting) + ")");
    json document = json::parse(text.begin(), text.end(), nullptr, false);
    if (document.is_discarded() || !document.is_object()) throw GltfError("", "not glTF: the JSON does not parse to an object");
    check_uris(document, "buffers", limits);
    check_uris(document, "images", limits);
    return document;
}

}  // namespace refract::gltf
