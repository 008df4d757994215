// Fuzzes what the WebSocket handler does with a message's text before it touches a session. There is no
// pure function for the message's rules (they sit inside the session's on_message), so this repeats
// them: http::parse_json_document, an object, "quality" "interactive" or "still", a "view" read with
// protocol::parse_view, and a "patch" applied to a scene with protocol::apply_merge_patch. Invariants:
// only the exceptions on_message catches are thrown, a refused view names a pointer under /view, an
// accepted one gives a document that survives to_json -> parse_scene unchanged, and so does an accepted
// patch.
#include <cstddef>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>

#include "fuzz_check.h"
#include "http/service.h"
#include "protocol/scene_document.h"

using refract::protocol::SceneDocument;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    nlohmann::json message;
    try {
        message = refract::http::parse_json_document(std::string(reinterpret_cast<const char*>(data), size));
    } catch (const nlohmann::json::exception&) {
        return 0;
    } catch (const std::invalid_argument&) {
        return 0;
    }
    if (!message.is_object()) return 0;
    if (message.contains("seq")) (void)message["seq"].dump();  // echoed back in every answer
    if (message.contains("quality")) {
        const nlohmann::json& quality = message["quality"];
        if (quality != "still" && quality != "interactive") return 0;
    }
    if (message.contains("view") && !message["view"].is_null()) {
        try {
            const refract::protocol::View view = refract::protocol::parse_view(message["view"], {});
            REFRACT_FUZZ_CHECK(view.width >= 1 && view.width <= 4096 && view.height >= 1 && view.height <= 4096);
            const SceneDocument seen = refract::protocol::seen_through(SceneDocument{}, view);
            REFRACT_FUZZ_CHECK(refract::protocol::parse_scene(refract::protocol::to_json(seen)) == seen);
        } catch (const refract::protocol::ValidationError& e) {
            REFRACT_FUZZ_CHECK(!e.rule().empty() && e.pointer().rfind("/view", 0) == 0);
            return 0;
        }
    }
    const auto patch = message.find("patch");
    if (patch == message.end()) return 0;
    SceneDocument patched;
    try {
        patched = refract::protocol::apply_merge_patch(SceneDocument{}, *patch);
    } catch (const refract::protocol::ValidationError& e) {
        REFRACT_FUZZ_CHECK(!e.rule().empty());
        return 0;
    }
    REFRACT_FUZZ_CHECK(refract::protocol::parse_scene(refract::protocol::to_json(patched)) == patched);
    return 0;
}
