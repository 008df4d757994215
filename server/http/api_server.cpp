#include "http/api_server.h"

#include <atomic>
#include <cctype>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <optional>
#include <sstream>

#include "http/examples.h"
#include "http/gltf_scenes.h"
#include "gltf/gltf_error.h"
#include "http/http_server.h"
#include "http/static_files.h"
#include "image/exr.h"
#include "render/invalidation.h"
#include "volume/builtin_volumes.h"
#include "volume/vdb_check.h"

namespace refract::http {

namespace {

using json = nlohmann::json;

void send_json(Response& res, int status, const json& body) {
    res.status = status;
    res.set_content(dump_json(body), "application/json");
}

void send_error(Response& res, int status, const std::string& message) {
    send_json(res, status, {{"error", message}});
}

void send_validation_error(Response& res, const protocol::ValidationError& e) {
    send_json(res, 422, {{"error", e.what()}, {"pointer", e.pointer()}, {"rule", e.rule()}});
}

// The store's refusal or failure, with the status http_status() gives its reason.
void send_store_error(Response& res, const scene::StoreError& e) {
    send_error(res, http_status(e.failure()), e.what());
}

// The media type of a Content-Type header, lower-cased, without parameters.
std::string media_type(const Request& req) {
    std::string type = req.get_header_value("Content-Type");
    type = type.substr(0, type.find(';'));
    while (!type.empty() && type.back() == ' ') type.pop_back();
    for (char& c : type) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return type;
}

bool is_json_type(const std::string& type) {
    return type == "application/json" || type == "application/merge-patch+json";
}

std::optional<uint64_t> query_uint(const Request& req, const char* name, uint64_t min, uint64_t max,
                                   Response& res, bool& bad) {
    if (!req.has_param(name)) return std::nullopt;
    std::string text = req.get_param_value(name);
    uint64_t value = 0;
    auto [rest, error] = std::from_chars(text.data(), text.data() + text.size(), value);
    if (error != std::errc() || rest != text.data() + text.size() || text.empty() || value < min ||
        value > max) {
        send_error(res, 400,
                   std::string("query parameter '") + name + "' must be an integer in [" +
                       std::to_string(min) + ", " + std::to_string(max) + "]");
        bad = true;
        return std::nullopt;
    }
    return value;
}

// "x,y,z" as three finite numbers.
std::optional<protocol::Vec3> parse_vec3(const std::string& text) {
    protocol::Vec3 v{};
    const char* p = text.data();
    const char* end = text.data() + text.size();
    for (size_t i = 0; i < 3; ++i) {
        auto [rest, error] = std::from_chars(p, end, v[i]);
        if (error != std::errc() || !std::isfinite(v[i])) return std::nullopt;
        p = rest;
        if (i < 2) {
            if (p == end || *p != ',') return std::nullopt;
            ++p;
        }
    }
    if (p != end) return std::nullopt;
    return v;
}

json scene_json(const scene::SceneSnapshot& s) {
    return {{"id", s.id}, {"revision", s.revision}, {"scene", protocol::to_json(s.document)}};
}

std::string etag(uint64_t revision) {
    // Built by appending: GCC 12 reports a false -Wrestrict for "\"" + std::string (its bug 105329).
    std::string tag = "\"";
    tag += std::to_string(revision);
    tag += '"';
    return tag;
}

// True when the request carries the token (or none is needed); else 401 is answered.
bool authorized(Service& service, const Request& req, Response& res) {
    if (service.authorized(req.get_header_value("Authorization"), req.get_param_value("token"))) return true;
    res.set_header("WWW-Authenticate", "Bearer");
    send_error(res, 401, "missing or wrong bearer token");
    return false;
}

// The server's limits from the daemon's flags; every answer is logged and counted.
HttpServerOptions server_options(Service& service, std::function<void(UpgradePtr)> upgrades) {
    const DaemonConfig& c = service.config();
    HttpServerOptions o;
    o.bind = c.bind;
    o.port = c.port;
    o.workers = c.threads;
    o.max_body = c.max_body;
    o.on_upgrade = std::move(upgrades);
    // A body is read only from a client that may send it: refusing from the header costs no memory.
    o.before_body = [&service](const Request& req, Response& res) { return authorized(service, req, res); };
    o.error_body = [](const std::string& message) { return dump_json({{"error", message}}); };
    o.on_answer = [&service](const Request& req, int status, double ms) {
        std::string method = req.method.empty() ? std::string("-") : req.method;
        std::string path = req.path.empty() ? std::string("-") : req.path;
        service.metrics().record_request(method, route_of(req.path), status);
        std::fprintf(stderr, "refractd: %s %s %d %.1f ms\n", method.c_str(), path.c_str(), status, ms);
    };
    return o;
}

}  // namespace

struct ApiServer::Impl {
    Service& service;
    HttpServer server;
    std::atomic<unsigned> frame_waiters{0};  // worker threads blocked waiting for a frame

    Impl(Service& s, std::function<void(UpgradePtr)> upgrades)
        : service(s), server(server_options(s, std::move(upgrades))) {}

    const DaemonConfig& config() const { return service.config(); }

    bool authorize(const Request& req, Response& res) { return authorized(service, req, res); }

    // ---------------------------------------------------------------------------------------------------
    // The routes, in the order they are matched: the first whose method and pattern fit answers, so the
    // catch-alls come last.

    using Answer = void (Impl::*)(const Request&, Response&);

    void route(const char* method, const std::string& pattern, Handler handler) {
        // A store that cannot answer (a shared database gone away: 503) fails the request with its reason
        // wherever in a route it is asked.
        server.route(method, pattern, [handler = std::move(handler)](const Request& req, Response& res) {
            try {
                handler(req, res);
            } catch (const scene::StoreError& e) {
                send_store_error(res, e);
            }
        });
    }

    // A route anyone may use.
    void route(const char* method, const std::string& pattern, Answer answer) {
        route(method, pattern,
              [this, answer](const Request& req, Response& res) { (this->*answer)(req, res); });
    }

    // A route for clients with the token (when one is configured); any other gets 401 and nothing else.
    void route_authorized(const char* method, const std::string& pattern, Answer answer) {
        route(method, pattern, [this, answer](const Request& req, Response& res) {
            if (authorize(req, res)) (this->*answer)(req, res);
        });
    }

    void routes() {
        // The daemon itself: health for anyone, metrics with the token.
        route("GET", "/api/health", &Impl::get_health);
        route_authorized("GET", "/metrics", &Impl::get_metrics);
        // Scenes: their documents, and edits to them.
        route_authorized("GET", "/api/scenes", &Impl::list_scenes);
        route_authorized("POST", "/api/scenes", &Impl::create_scene);
        route_authorized("GET", R"(/api/scenes/([^/]+))", &Impl::get_scene);
        route_authorized("PATCH", R"(/api/scenes/([^/]+))", &Impl::patch_scene);
        route_authorized("DELETE", R"(/api/scenes/([^/]+))", &Impl::delete_scene);
        // Frames: of the scene as it is, or after an edit sent with the request.
        route_authorized("GET", R"(/api/scenes/([^/]+)/scene\.glb)", &Impl::get_scene_glb);
        route_authorized("GET", R"(/api/scenes/([^/]+)/frame\.png)", &Impl::get_frame);
        route_authorized("GET", R"(/api/scenes/([^/]+)/frame\.exr)", &Impl::get_frame_exr);
        route_authorized("POST", R"(/api/scenes/([^/]+)/frame\.png)", &Impl::edit_and_get_frame);
        // Uploads: a scene's imported index grid, meshes, environment maps, volumes.
        route_authorized("PUT", R"(/api/scenes/([^/]+)/index-field)", &Impl::put_index_field);
        route_authorized("DELETE", R"(/api/scenes/([^/]+)/index-field)", &Impl::delete_index_field);
        route_authorized("GET", "/api/meshes", &Impl::list_meshes);
        route_authorized("PUT", R"(/api/meshes/([^/]+))", &Impl::put_mesh);
        route_authorized("DELETE", R"(/api/meshes/([^/]+))", &Impl::delete_mesh);
        route_authorized("GET", "/api/environments", &Impl::list_environments);
        route_authorized("GET", R"(/api/environments/([^/]+))", &Impl::get_environment);
        route_authorized("PUT", R"(/api/environments/([^/]+))", &Impl::put_environment);
        route_authorized("DELETE", R"(/api/environments/([^/]+))", &Impl::delete_environment);
        route_authorized("GET", "/api/volumes", &Impl::list_volumes);
        route_authorized("PUT", R"(/api/volumes/([^/]+))", &Impl::put_volume);
        route_authorized("DELETE", R"(/api/volumes/([^/]+))", &Impl::delete_volume);
        // Example scenes (logic in http/examples.cpp).
        route_authorized("GET", "/api/examples", &Impl::list_examples);
        route_authorized("GET", R"(/api/examples/([^/]+))", &Impl::get_example);
        // Whether an endpoint exists is told only to a client that may use it.
        route_authorized("*", R"(/api/.*)", &Impl::unknown_endpoint);
        route("GET", R"(/.*)", &Impl::serve_static);
    }

    // ---------------------------------------------------------------------------------------------------
    // The daemon itself

    void get_health(const Request& req, Response& res) {
        json health = service.health();
        // Behind a proxy (which adds X-Forwarded-For, as deploy/haproxy does) the WebSocket port is
        // not reachable: upgrades go through the proxy's one port, which the HTTP port also serves.
        if (req.has_header("X-Forwarded-For")) health["ws_on_http_port"] = true;
        send_json(res, 200, health);
    }

    void get_metrics(const Request&, Response& res) {
        res.set_content(service.metrics().prometheus_text(service.gauges()), "text/plain; version=0.0.4");
    }

    // ---------------------------------------------------------------------------------------------------
    // Scenes

    // Parses a JSON body; false (and 400 sent) when it is not JSON. JSON has no NaN: such a body is
    // malformed.
    static bool parse_json(const std::string& body, Response& res, json& out) {
        try {
            out = parse_json_document(body);
            return true;
        } catch (const std::exception& e) {
            send_error(res, 400, std::string("malformed JSON: ") + e.what());
            return false;
        }
    }

    std::optional<scene::SceneSnapshot> find_scene(const std::string& id, Response& res) {
        std::optional<scene::SceneSnapshot> snapshot;
        if (scene::valid_scene_id(id)) snapshot = service.store().get(id);
        if (!snapshot) send_error(res, 404, "scene '" + id + "' does not exist");
        return snapshot;
    }

    // Applies a merge patch from a request body (If-Match honoured); nullopt with the answer sent on failure.
    std::optional<scene::EditResult> edit(const Request& req, Response& res, const std::string& id,
                                          const std::string& body) {
        std::string type = media_type(req);
        if (type != "application/merge-patch+json") {
            send_error(res, 415, "edits need Content-Type: application/merge-patch+json");
            return std::nullopt;
        }
        std::optional<uint64_t> if_match;
        try {
            if_match = parse_if_match(req.get_header_value("If-Match"));
        } catch (const std::invalid_argument& e) {
            send_error(res, 400, e.what());
            return std::nullopt;
        }
        json patch;
        if (!parse_json(body, res, patch)) return std::nullopt;
        try {
            return service.store().patch(id, patch, if_match);
        } catch (const protocol::ValidationError& e) {
            send_validation_error(res, e);
        } catch (const scene::StoreError& e) {
            send_store_error(res, e);
        }
        return std::nullopt;
    }

    void list_scenes(const Request&, Response& res) {
        json list = json::array();
        for (const auto& scene : service.store().list())
            list.push_back({{"id", scene.id}, {"revision", scene.revision}});
        send_json(res, 200, {{"scenes", list}});
    }

    void create_scene(const Request& req, Response& res) {
        const std::string& body = req.body;
        if (media_type(req) == "model/gltf-binary" || media_type(req) == "model/gltf+json") return import_scene(req, res);
        if (!body.empty() && !is_json_type(media_type(req))) {
            send_error(res, 415,
                       "a scene needs Content-Type: application/json (a document), model/gltf-binary (.glb) or "
                       "model/gltf+json (.gltf)");
            return;
        }
        json document = json::object();
        if (!body.empty() && !parse_json(body, res, document)) return;
        try {
            scene::SceneSnapshot created = service.store().create(req.get_param_value("id"), document);
            res.set_header("Location", "/api/scenes/" + created.id);
            res.set_header("ETag", etag(created.revision));
            send_json(res, 201, scene_json(created));
        } catch (const protocol::ValidationError& e) {
            send_validation_error(res, e);
        } catch (const scene::StoreError& e) {
            send_store_error(res, e);
        }
    }

    // A glTF body: the scene it maps to, with the meshes it uploaded and what it said that has no meaning here.
    void import_scene(const Request& req, Response& res) {
        try {
            GltfImport imported = import_gltf_scene(service, req.get_param_value("id"), req.body);
            res.set_header("Location", "/api/scenes/" + imported.created.id);
            res.set_header("ETag", etag(imported.created.revision));
            json answer = scene_json(imported.created);
            answer["meshes"] = imported.meshes;
            answer["warnings"] = imported.warnings;
            send_json(res, 201, answer);
        } catch (const gltf::GltfError& e) {
            send_json(res, 422, {{"error", e.what()}, {"gltf_path", e.path()}});
        } catch (const protocol::ValidationError& e) {
            send_validation_error(res, e);
        } catch (const mesh::MeshError& e) {
            send_error(res, 400, std::string("unusable glTF mesh: ") + e.what());
        } catch (const scene::StoreError& e) {
            send_store_error(res, e);
        }
    }

    void get_scene_glb(const Request& req, Response& res) {
        auto snapshot = find_scene(req.matches[1], res);
        if (!snapshot) return;
        try {
            const std::string glb = export_gltf_scene(service, snapshot->document);
            res.set_header("ETag", etag(snapshot->revision));
            res.set_header("Content-Disposition", "attachment; filename=\"" + snapshot->id + ".glb\"");
            res.status = 200;
            res.set_content(glb, "model/gltf-binary");
        } catch (const std::invalid_argument& e) {
            send_error(res, 422, e.what());
        }
    }

    void get_scene(const Request& req, Response& res) {
        auto snapshot = find_scene(req.matches[1], res);
        if (!snapshot) return;
        res.set_header("ETag", etag(snapshot->revision));
        send_json(res, 200, scene_json(*snapshot));
    }

    void patch_scene(const Request& req, Response& res) {
        std::string id = req.matches[1];
        if (!find_scene(id, res)) return;
        auto result = edit(req, res, id, req.body);
        if (!result) return;
        json invalidated = pass_list(
            result->changed ? scene::passes_invalidated(result->before, result->after.document) : 0);
        json answer = scene_json(result->after);
        answer["invalidated"] = invalidated;
        res.set_header("ETag", etag(result->after.revision));
        send_json(res, 200, answer);
    }

    void delete_scene(const Request& req, Response& res) {
        std::string id = req.matches[1];
        try {
            if (!scene::valid_scene_id(id) || !service.store().remove(id)) {
                send_error(res, 404, "scene '" + id + "' does not exist");
                return;
            }
        } catch (const scene::StoreError& e) {
            send_store_error(res, e);
            return;
        }
        service.queue().forget_scene(id);
        res.status = 204;
    }

    // ---------------------------------------------------------------------------------------------------
    // Frames

    void get_frame(const Request& req, Response& res) {
        auto snapshot = find_scene(req.matches[1], res);
        if (!snapshot) return;
        auto options = frame_options(req, res);
        if (!options) return;
        answer_frame(req, res, *snapshot, *options);
    }

    // The frame's linear radiance as OpenEXR: a frame of its own in the queue (it reads the radiance back).
    void get_frame_exr(const Request& req, Response& res) {
        auto snapshot = find_scene(req.matches[1], res);
        if (!snapshot) return;
        auto options = frame_options(req, res);
        if (!options) return;
        options->render.linear = true;
        answer_frame(req, res, *snapshot, *options);
    }

    // A body is an edit, applied before the frame renders; without one this is get_frame.
    void edit_and_get_frame(const Request& req, Response& res) {
        std::string id = req.matches[1];
        auto snapshot = find_scene(id, res);
        if (!snapshot) return;
        auto options = frame_options(req, res);  // before the edit: a bad query changes nothing
        if (!options) return;
        if (!req.body.empty()) {
            auto result = edit(req, res, id, req.body);
            if (!result) return;
            snapshot = result->after;
        }
        answer_frame(req, res, *snapshot, *options, !req.body.empty());
    }

    struct FrameQuery {
        std::optional<uint64_t> width, height;
        scene::FrameOptions render;  // quality, budget, refinement level
    };

    // The frame's query parameters (width, height, quality, budget_ms, level); nullopt with 400 sent
    // when invalid.
    std::optional<FrameQuery> frame_options(const Request& req, Response& res) {
        FrameQuery options;
        bool bad = false;
        options.width = query_uint(req, "width", 1, config().max_image, res, bad);
        if (bad) return std::nullopt;
        options.height = query_uint(req, "height", 1, config().max_image, res, bad);
        if (bad) return std::nullopt;
        if (req.has_param("quality")) {
            std::string q = req.get_param_value("quality");
            if (q == "interactive") {
                options.render.quality = scene::Quality::interactive;
            } else if (q != "still") {
                send_error(res, 400, "query parameter 'quality' must be 'interactive' or 'still'");
                return std::nullopt;
            }
        }
        auto budget = query_uint(req, "budget_ms", static_cast<uint64_t>(scene::kMinBudgetMs),
                                 static_cast<uint64_t>(scene::kMaxBudgetMs), res, bad);
        if (bad) return std::nullopt;
        if (budget) options.render.budget_ms = static_cast<double>(*budget);
        auto level = query_uint(req, "level", 1, scene::kMaxRefinementLevel, res, bad);
        if (bad) return std::nullopt;
        if (level) options.render.level = static_cast<uint32_t>(*level);
        return options;
    }

    // Renders `snapshot` at the requested size and quality through the render queue and answers the PNG.
    // `edited`: the request's edit made this revision; an answer without a frame then still says so.
    void answer_frame(const Request& req, Response& res, const scene::SceneSnapshot& snapshot,
                      const FrameQuery& options, bool edited = false) {
        if (edited) res.set_header("ETag", etag(snapshot.revision));
        const auto& width = options.width;
        const auto& height = options.height;
        scene::FrameRequest request{snapshot.id, snapshot.revision, snapshot.document, options.render};
        if (width) request.document.image.width = static_cast<uint32_t>(*width);
        if (height) request.document.image.height = static_cast<uint32_t>(*height);

        // Waiting holds a worker thread: keep a few free so that the rest of the API stays responsive.
        struct Holding {
            std::atomic<unsigned>& count;
            ~Holding() { count.fetch_sub(1); }
        } holding{frame_waiters};
        bool threads_left = frame_waiters.fetch_add(1) + 4 < config().threads;
        std::optional<scene::FrameOutcome> outcome;
        if (threads_left)
            outcome = service.queue().render_and_wait(
                std::move(request), std::chrono::seconds(config().request_timeout_s), req.client_gone);
        if (!outcome) {
            res.set_header("Retry-After", "1");
            if (edited) return answer_edit_without_frame(res, snapshot, "the render queue is full");
            send_error(res, 503, "the render queue is full; retry shortly");
            return;
        }
        using Status = scene::FrameOutcome::Status;
        switch (outcome->status) {
            case Status::ok:
                break;
            case Status::unrenderable:
                send_error(res, 422, outcome->error);
                return;
            case Status::gone:
                send_error(res, 404, outcome->error);
                return;
            case Status::device_error:
                send_error(res, 500, outcome->error);
                return;
            case Status::no_device:
            case Status::superseded:  // only refinement the WebSocket pushes gives way
            case Status::abandoned:   // only frames whose askers left are abandoned
            case Status::timed_out:
            case Status::shutting_down:
                res.set_header("Retry-After", "5");
                if (edited) return answer_edit_without_frame(res, snapshot, outcome->error);
                send_error(res, 503, outcome->error);
                return;
        }
        const scene::FrameResult& frame = *outcome->frame;
        res.headers.clear();
        res.status = 200;
        res.set_header("X-Refract-Revision", std::to_string(outcome->revision));
        res.set_header("X-Refract-Passes", outcome->cached ? "" : scene::pass_names(frame.rerun));
        res.set_header("X-Refract-Voxelized", outcome->cached ? "" : comma_list(frame.voxelized));
        res.set_header("X-Refract-Cached", outcome->cached ? "1" : "0");
        res.set_header("ETag", etag(outcome->revision));
        res.set_header("Cache-Control", "no-store");
        res.set_header("X-Refract-Level", std::to_string(frame.level));
        res.set_header("X-Refract-Samples", std::to_string(frame.refinement.samples_per_pixel));
        res.set_header("X-Refract-Photons", std::to_string(frame.photons));
        if (!outcome->cached) {
            std::string timing = server_timing(frame);
            if (!timing.empty()) res.set_header("Server-Timing", timing);
        }
        if (!options.render.linear) {
            res.set_content(reinterpret_cast<const char*>(frame.png.data()), frame.png.size(), "image/png");
            return;
        }
        if (frame.linear.size() != size_t{frame.width} * frame.height) return send_error(res, 500, "the frame has no radiance");
        // The header describes the asked revision's camera and exposure (a newer revision answering has its own).
        res.set_content(image::encode_exr(std::span<const float>(&frame.linear[0].x, frame.linear.size() * 4), frame.width,
                                          frame.height,
                                          image::frame_attributes(snapshot.document, frame.level, frame.photons, outcome->revision)),
                        "image/x-exr");
    }

    // 202: the edit is committed (its revision and ETag say which) but no frame comes with it; the client
    // fetches the frame later rather than repeating the edit.
    static void answer_edit_without_frame(Response& res, const scene::SceneSnapshot& snapshot,
                                          const std::string& why) {
        json answer = scene_json(snapshot);
        answer["frame_error"] = why + "; the edit is applied, GET the frame later";
        send_json(res, 202, answer);
    }

    // ---------------------------------------------------------------------------------------------------
    // Uploads: a scene's imported index grid, meshes, environment maps, volumes

    // The grid's sides and bounds in the query, its values (little-endian float32, x fastest) the body.
    void put_index_field(const Request& req, Response& res) {
        const std::string id = req.matches[1];
        const std::string& body = req.body;
        if (!find_scene(id, res)) return;
        bool bad = false;
        scene::IndexGrid grid;
        const char* names[3] = {"nx", "ny", "nz"};
        uint32_t* sides[3] = {&grid.nx, &grid.ny, &grid.nz};
        for (size_t i = 0; i < 3; ++i) {
            if (!req.has_param(names[i])) {
                send_error(res, 400, std::string("query parameter '") + names[i] + "' is required");
                return;
            }
            auto side = query_uint(req, names[i], 2, 512, res, bad);
            if (bad) return;
            *sides[i] = static_cast<uint32_t>(*side);
        }
        auto min = parse_vec3(req.get_param_value("min"));
        auto max = parse_vec3(req.get_param_value("max"));
        if (!min || !max) {
            send_error(res, 400,
                       "query parameters 'min' and 'max' must each be three finite numbers 'x,y,z'");
            return;
        }
        grid.bounds.min = *min;
        grid.bounds.max = *max;
        size_t count = size_t{grid.nx} * grid.ny * grid.nz;
        if (body.size() != count * sizeof(float)) {
            send_error(res, 400,
                       "the body holds " + std::to_string(body.size()) +
                           " bytes; nx*ny*nz float32 values are " + std::to_string(count * sizeof(float)) +
                           " bytes");
            return;
        }
        grid.n.resize(count);
        std::memcpy(grid.n.data(), body.data(), body.size());  // little-endian float32, x fastest
        try {
            scene::EditResult result = service.store().put_index_grid(id, std::move(grid));
            json answer = scene_json(result.after);
            answer["invalidated"] =
                pass_list(scene::passes_invalidated(result.before, result.after.document) |
                          scene::kIndexField | scene::kOctree | scene::kPhotons | scene::kView |
                          scene::kToneMap);
            res.set_header("ETag", etag(result.after.revision));
            send_json(res, 200, answer);
        } catch (const scene::StoreError& e) {
            send_store_error(res, e);
        } catch (const protocol::ValidationError& e) {
            send_validation_error(res, e);
        }
    }

    void delete_index_field(const Request& req, Response& res) {
        const std::string id = req.matches[1];
        remove_asset(
            res, [&] { return service.store().remove_index_grid(id); },
            "scene '" + id + "' has no imported index grid");
    }

    void list_meshes(const Request&, Response& res) {
        json list = json::array();
        for (const auto& entry : service.store().list_meshes()) {
            json item = scene::to_json(entry.report);
            item["name"] = entry.name;
            item["reference"] = "upload:" + entry.name;
            list.push_back(item);
        }
        send_json(res, 200, {{"meshes", list}});
    }

    void put_mesh(const Request& req, Response& res) {
        std::string name = req.matches[1];
        try {
            scene::MeshEntry entry = service.store().put_mesh(name, req.body);
            service.queue().forget_cached_frames();
            json answer = scene::to_json(entry.report);
            answer["name"] = entry.name;
            answer["reference"] = "upload:" + entry.name;
            send_json(res, 201, answer);
        } catch (const mesh::MeshError& e) {
            send_error(res, 400, std::string("unusable OBJ: ") + e.what());
        } catch (const scene::StoreError& e) {
            send_store_error(res, e);
        }
    }

    void delete_mesh(const Request& req, Response& res) {
        const std::string name = req.matches[1];
        remove_asset(
            res, [&] { return service.store().remove_mesh(name); }, "no uploaded mesh named '" + name + "'");
    }

    void list_environments(const Request&, Response& res) {
        json list = json::array();
        for (const auto& entry : service.store().list_environments())
            list.push_back({{"name", entry.name},
                            {"width", entry.width},
                            {"height", entry.height},
                            {"built_in", entry.built_in}});
        send_json(res, 200, {{"environments", list}});
    }

    // One environment with what a client balances lights against: its irradiance on a surface facing up.
    void get_environment(const Request& req, Response& res) {
        const std::string name = req.matches[1];
        try {
            const auto map = service.store().environment(name);
            if (!map) {
                send_error(res, 404, "no environment named '" + name + "'");
                return;
            }
            send_json(res, 200,
                      {{"name", name},
                       {"width", map->width},
                       {"height", map->height},
                       {"built_in", image::built_in_environment(name) != nullptr},
                       {"irradiance", image::horizontal_irradiance(*map)}});
        } catch (const scene::StoreError& e) {
            send_store_error(res, e);
        } catch (const scene::RenderError& e) {
            send_error(res, 500, e.what());
        }
    }

    void put_environment(const Request& req, Response& res) {
        std::string name = req.matches[1];
        try {
            scene::EnvironmentEntry entry = service.store().put_environment(name, req.body);
            service.queue().forget_cached_frames();
            send_json(res, 201,
                      {{"name", entry.name},
                       {"width", entry.width},
                       {"height", entry.height},
                       {"built_in", false}});
        } catch (const image::EnvironmentError& e) {
            send_error(res, 400, std::string("unusable environment: ") + e.what());
        } catch (const scene::StoreError& e) {
            send_store_error(res, e);
        }
    }

    void delete_environment(const Request& req, Response& res) {
        const std::string name = req.matches[1];
        if (image::built_in_environment(name)) {
            res.set_header("Allow", "GET");
            send_error(res, 405, "\"" + name + "\" is a built-in environment; it cannot be deleted");
            return;
        }
        remove_asset(
            res, [&] { return service.store().remove_environment(name); },
            "no uploaded environment named '" + name + "'");
    }

    void list_volumes(const Request&, Response& res) {
        json builtin = json::array(), list = json::array();
        for (const std::string& name : volume::builtin_volume_names()) {
            json item = volume::to_json(*volume::builtin_volume_report(name));
            item["name"] = name;
            builtin.push_back(item);
        }
        for (const auto& entry : service.store().list_volumes()) {
            json item = volume::to_json(entry.report);
            item["name"] = entry.name;
            list.push_back(item);
        }
        send_json(res, 200, {{"volumes", list}, {"builtin", builtin}});
    }

    // A re-upload changes the frames of the scenes whose volumes name it: cached frames are forgotten, as
    // after a mesh upload.
    void put_volume(const Request& req, Response& res) {
        std::string name = req.matches[1];
        if (volume::is_builtin_volume(name)) {
            send_error(res, 409, "'" + name + "': names starting \"builtin.\" are the built-in volumes': upload under another name");
            return;
        }
        try {
            scene::VolumeEntry entry = service.store().put_volume(name, req.body);
            service.queue().forget_cached_frames();
            json answer = volume::to_json(entry.report);
            answer["name"] = entry.name;
            send_json(res, 201, answer);
        } catch (const volume::VolumeError& e) {
            send_error(res, 400, std::string("unusable volume: ") + e.what());
        } catch (const volume::CheckUnavailable& e) {
            send_error(res, 503, e.what());
        } catch (const scene::StoreError& e) {
            send_store_error(res, e);
        }
    }

    void delete_volume(const Request& req, Response& res) {
        const std::string name = req.matches[1];
        if (volume::is_builtin_volume(name)) {
            send_error(res, 409, "'" + name + "': names starting \"builtin.\" are the built-in volumes': they cannot be deleted");
            return;
        }
        remove_asset(
            res, [&] { return service.store().remove_volume(name); }, "no uploaded volume named '" + name + "'");
    }

    // Answers a DELETE of an asset: 204 when `remove` deleted it, 404 with `unknown` when there was none,
    // 409 with the ids of the scenes that still use it.
    template <typename Remove>
    void remove_asset(Response& res, Remove remove, const std::string& unknown) {
        try {
            if (!remove()) {
                send_error(res, 404, unknown);
                return;
            }
        } catch (const scene::AssetInUse& e) {
            send_json(res, http_status(e.failure()), {{"error", e.what()}, {"scenes", e.scenes()}});
            return;
        }
        // Frames rendered with it answer no more, as after an upload (none should use it: nothing names it).
        service.queue().forget_cached_frames();
        res.status = 204;
    }

    // ---------------------------------------------------------------------------------------------------
    // Examples, and what no other route answers

    void list_examples(const Request&, Response& res) {
        send_json(res, 200, examples_index(config().examples_dir));
    }

    void get_example(const Request& req, Response& res) {
        ExampleFile example = read_example(config().examples_dir, req.matches[1]);
        if (example.status == 200)
            send_json(res, 200, example.document);
        else
            send_error(res, example.status, example.error);
    }

    void unknown_endpoint(const Request& req, Response& res) {
        send_error(res, 404, "no such endpoint: " + req.path);
    }

    void serve_static(const Request& req, Response& res) {
        if (config().web_root.empty()) {
            send_error(res, 404, "no web root configured");
            return;
        }
        StaticFile file = resolve_static(config().web_root, req.path);
        if (file.status != 200) {
            send_error(res, file.status, file.status == 400 ? "bad path" : "not found: " + req.path);
            return;
        }
        std::ifstream in(file.path, std::ios::binary);
        if (!in) {
            send_error(res, 404, "not found: " + req.path);
            return;
        }
        std::ostringstream content;
        content << in.rdbuf();
        res.status = 200;
        res.set_content(content.str(), file.content_type);
    }
};

ApiServer::ApiServer(Service& service, std::function<void(UpgradePtr)> upgrades)
    : impl_(std::make_unique<Impl>(service, std::move(upgrades))) {
    impl_->routes();
}

ApiServer::~ApiServer() = default;

void ApiServer::bind() {
    impl_->server.bind();
}

void ApiServer::serve() {
    impl_->server.serve();
}

void ApiServer::stop() {
    impl_->server.stop();
}

}  // namespace refract::http
