// Fuzzes the scene document: parse_scene, to_json and apply_merge_patch. The input is JSON: a scene, or
// [scene, patch]. Invariants: only ValidationError (or a JSON syntax error) is thrown; an accepted
// document survives to_json -> parse_scene unchanged; an accepted patch gives a document that does too,
// applying it again changes nothing (RFC 7396 patches are idempotent), and a document patched with its
// own JSON or with {} is itself.
#include <cstddef>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "fuzz_check.h"
#include "protocol/scene_document.h"

using refract::protocol::SceneDocument;
using refract::protocol::ValidationError;

namespace {

// As the daemon parses a request body: nesting is limited, so the recursive consumers are bounded.
std::optional<nlohmann::json> parse_bounded(const uint8_t* data, size_t size) {
    try {
        return nlohmann::json::parse(data, data + size,
                                     [](int depth, nlohmann::json::parse_event_t, nlohmann::json&) {
                                         if (depth > 16) throw std::invalid_argument("too deep");
                                         return true;
                                     });
    } catch (const nlohmann::json::exception&) {
    } catch (const std::invalid_argument&) {
    }
    return std::nullopt;
}

void check_round_trip(const SceneDocument& d) {
    const nlohmann::json j = refract::protocol::to_json(d);
    const SceneDocument again = refract::protocol::parse_scene(j);
    REFRACT_FUZZ_CHECK(again == d);
    REFRACT_FUZZ_CHECK(refract::protocol::to_json(again) == j);
}

std::optional<SceneDocument> try_parse(const nlohmann::json& j) {
    try {
        return refract::protocol::parse_scene(j);
    } catch (const ValidationError& e) {
        REFRACT_FUZZ_CHECK(!e.rule().empty());
        return std::nullopt;
    }
}

void check_patch(const SceneDocument& base, const nlohmann::json& patch) {
    std::optional<SceneDocument> patched;
    try {
        patched = refract::protocol::apply_merge_patch(base, patch);
    } catch (const ValidationError& e) {
        REFRACT_FUZZ_CHECK(!e.rule().empty());
        return;
    }
    check_round_trip(*patched);
    REFRACT_FUZZ_CHECK(refract::protocol::apply_merge_patch(*patched, patch) == *patched);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    const std::optional<nlohmann::json> input = parse_bounded(data, size);
    if (!input) return 0;
    const bool pair = input->is_array() && input->size() == 2;
    const nlohmann::json& scene = pair ? (*input)[0] : *input;
    const nlohmann::json& patch = pair ? (*input)[1] : *input;

    const std::optional<SceneDocument> document = try_parse(scene);
    if (document) {
        check_round_trip(*document);
        REFRACT_FUZZ_CHECK(refract::protocol::apply_merge_patch(*document, nlohmann::json::object()) ==
                           *document);
        REFRACT_FUZZ_CHECK(refract::protocol::apply_merge_patch(
                               *document, refract::protocol::to_json(*document)) == *document);
    }
    check_patch(document.value_or(SceneDocument{}), patch);
    return 0;
}
