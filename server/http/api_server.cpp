#include "http/api_server.h"

#include <httplib.h>

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
#include "http/static_files.h"
#include "scene/passes.h"

namespace refract::http {

namespace {

using httplib::ContentReader;
using httplib::Request;
using httplib::Response;
using json = nlohmann::json;
using Clock = std::chrono::steady_clock;

// When the request on this worker thread started (set by the pre-routing handler, read by the logger).
thread_local std::optional<Clock::time_point> t_request_start;

void send_json(Response& res, int status, const json& body) {
    res.status = status;
    res.set_content(body.dump(), "application/json");
}

void send_error(Response& res, int status, const std::string& message) {
    send_json(res, status, {{"error", message}});
}

void send_validation_error(Response& res, const protocol::ValidationError& e) {
    send_json(res, 422, {{"error", e.what()}, {"pointer", e.pointer()}, {"rule", e.rule()}});
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

}  // namespace

struct ApiServer::Impl {
    Service& service;
    httplib::Server server;
    std::atomic<unsigned> frame_waiters{0};  // worker threads blocked waiting for a frame

    explicit Impl(Service& s) : service(s) {}

    const DaemonConfig& config() const { return service.config(); }

    bool authorize(const Request& req, Response& res) {
        if (service.authorized(req.get_header_value("Authorization"), req.get_param_value("token")))
            return true;
        res.set_header("WWW-Authenticate", "Bearer");
        send_error(res, 401, "missing or wrong bearer token");
        return false;
    }

    // Reads the body through `reader`, at most --max-body bytes. False (and the answer sent) on failure.
    bool read_body(const Request& req, Response& res, const ContentReader& reader, std::string& body) {
        bool chunked = req.get_header_value("Transfer-Encoding").find("chunked") != std::string::npos;
        if (!req.has_header("Content-Length") && !chunked) return true;  // no body at all
        // A chunked body over the limit is drained (up to a bound) rather than cut off, so that its rest is
        // not read as the next request on the connection. (cpp-httplib skips a too-long Content-Length
        // itself.)
        const size_t limit = config().max_body;
        const size_t drain_limit = limit * 4;
        size_t received = 0;
        bool ok = reader([&](const char* data, size_t length) {
            received += length;
            if (received <= limit) body.append(data, length);
            return received <= drain_limit;
        });
        if (received > limit || res.status == 413) {
            body.clear();
            send_error(res, 413,
                       "request body is larger than " + std::to_string(limit) + " bytes (--max-body)");
            return false;
        }
        if (!ok) {
            send_error(res, 400, "could not read the request body");
            return false;
        }
        return true;
    }

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
            send_error(res, 412, e.what());
            return std::nullopt;
        }
        json patch;
        if (!parse_json(body, res, patch)) return std::nullopt;
        try {
            return service.store().patch(id, patch, if_match);
        } catch (const protocol::ValidationError& e) {
            send_validation_error(res, e);
        } catch (const scene::StoreError& e) {
            send_error(res, e.status(), e.what());
        }
        return std::nullopt;
    }

    struct FrameOptions {
        std::optional<uint64_t> width, height;
        scene::Quality quality = scene::Quality::still;
    };

    // The frame's query parameters (width, height, quality); nullopt with 400 sent when invalid.
    std::optional<FrameOptions> frame_options(const Request& req, Response& res) {
        FrameOptions options;
        bool bad = false;
        options.width = query_uint(req, "width", 1, config().max_image, res, bad);
        if (bad) return std::nullopt;
        options.height = query_uint(req, "height", 1, config().max_image, res, bad);
        if (bad) return std::nullopt;
        if (req.has_param("quality")) {
            std::string q = req.get_param_value("quality");
            if (q == "interactive") {
                options.quality = scene::Quality::interactive;
            } else if (q != "still") {
                send_error(res, 400, "query parameter 'quality' must be 'interactive' or 'still'");
                return std::nullopt;
            }
        }
        return options;
    }

    // Renders `snapshot` at the requested size and quality through the render queue and answers the PNG.
    void answer_frame(Response& res, const scene::SceneSnapshot& snapshot, const FrameOptions& options) {
        scene::Quality quality = options.quality;
        const auto& width = options.width;
        const auto& height = options.height;
        scene::FrameRequest request{snapshot.id, snapshot.revision, snapshot.document, quality};
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
            outcome = service.queue().render_and_wait(std::move(request),
                                                      std::chrono::seconds(config().request_timeout_s));
        if (!outcome) {
            res.set_header("Retry-After", "1");
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
            case Status::timed_out:
            case Status::shutting_down:
                res.set_header("Retry-After", "5");
                send_error(res, 503, outcome->error);
                return;
        }
        const scene::FrameResult& frame = *outcome->frame;
        res.status = 200;
        res.set_header("X-Refract-Revision", std::to_string(outcome->revision));
        res.set_header("X-Refract-Passes", outcome->cached ? "" : scene::pass_names(frame.rerun));
        res.set_header("X-Refract-Cached", outcome->cached ? "1" : "0");
        res.set_header("ETag", etag(outcome->revision));
        res.set_header("Cache-Control", "no-store");
        if (!outcome->cached) {
            std::string timing = server_timing(frame);
            if (!timing.empty()) res.set_header("Server-Timing", timing);
        }
        res.set_content(reinterpret_cast<const char*>(frame.png.data()), frame.png.size(), "image/png");
    }

    void routes() {
        auto& s = server;

        s.Get("/api/health",
              [this](const Request&, Response& res) { send_json(res, 200, service.health()); });

        s.Get("/metrics", [this](const Request& req, Response& res) {
            if (!authorize(req, res)) return;
            res.set_content(service.metrics().prometheus_text(service.gauges()), "text/plain; version=0.0.4");
        });

        s.Get("/api/scenes", [this](const Request& req, Response& res) {
            if (!authorize(req, res)) return;
            json list = json::array();
            for (const auto& scene : service.store().list())
                list.push_back({{"id", scene.id}, {"revision", scene.revision}});
            send_json(res, 200, {{"scenes", list}});
        });

        s.Post("/api/scenes", [this](const Request& req, Response& res, const ContentReader& reader) {
            std::string body;
            if (!read_body(req, res, reader, body) || !authorize(req, res)) return;
            if (!body.empty() && !is_json_type(media_type(req))) {
                send_error(res, 415, "a scene document needs Content-Type: application/json");
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
                send_error(res, e.status(), e.what());
            }
        });

        s.Get(R"(/api/scenes/([^/]+))", [this](const Request& req, Response& res) {
            if (!authorize(req, res)) return;
            auto snapshot = find_scene(req.matches[1], res);
            if (!snapshot) return;
            res.set_header("ETag", etag(snapshot->revision));
            send_json(res, 200, scene_json(*snapshot));
        });

        s.Patch(
            R"(/api/scenes/([^/]+))", [this](const Request& req, Response& res, const ContentReader& reader) {
                std::string body;
                if (!read_body(req, res, reader, body) || !authorize(req, res)) return;
                std::string id = req.matches[1];
                if (!find_scene(id, res)) return;
                auto result = edit(req, res, id, body);
                if (!result) return;
                json invalidated = pass_list(
                    result->changed ? scene::passes_invalidated(result->before, result->after.document) : 0);
                json answer = scene_json(result->after);
                answer["invalidated"] = invalidated;
                res.set_header("ETag", etag(result->after.revision));
                send_json(res, 200, answer);
            });

        s.Delete(R"(/api/scenes/([^/]+))", [this](const Request& req, Response& res) {
            if (!authorize(req, res)) return;
            std::string id = req.matches[1];
            try {
                if (!scene::valid_scene_id(id) || !service.store().remove(id)) {
                    send_error(res, 404, "scene '" + id + "' does not exist");
                    return;
                }
            } catch (const scene::StoreError& e) {
                send_error(res, e.status(), e.what());
                return;
            }
            service.queue().forget_scene(id);
            res.status = 204;
        });

        s.Get(R"(/api/scenes/([^/]+)/frame\.png)", [this](const Request& req, Response& res) {
            if (!authorize(req, res)) return;
            auto snapshot = find_scene(req.matches[1], res);
            if (!snapshot) return;
            auto options = frame_options(req, res);
            if (!options) return;
            answer_frame(res, *snapshot, *options);
        });

        s.Post(R"(/api/scenes/([^/]+)/frame\.png)",
               [this](const Request& req, Response& res, const ContentReader& reader) {
                   std::string body;
                   if (!read_body(req, res, reader, body) || !authorize(req, res)) return;
                   std::string id = req.matches[1];
                   auto snapshot = find_scene(id, res);
                   if (!snapshot) return;
                   auto options = frame_options(req, res);  // before the edit: a bad query changes nothing
                   if (!options) return;
                   if (!body.empty()) {
                       auto result = edit(req, res, id, body);
                       if (!result) return;
                       snapshot = result->after;
                   }
                   answer_frame(res, *snapshot, *options);
               });

        s.Put(R"(/api/scenes/([^/]+)/index-field)",
              [this](const Request& req, Response& res, const ContentReader& reader) {
                  std::string body;
                  if (!read_body(req, res, reader, body) || !authorize(req, res)) return;
                  put_index_field(req, res, req.matches[1], body);
              });

        s.Get("/api/meshes", [this](const Request& req, Response& res) {
            if (!authorize(req, res)) return;
            json list = json::array();
            for (const auto& entry : service.store().list_meshes()) {
                json item = scene::to_json(entry.report);
                item["name"] = entry.name;
                item["reference"] = "upload:" + entry.name;
                list.push_back(item);
            }
            send_json(res, 200, {{"meshes", list}});
        });

        s.Put(R"(/api/meshes/([^/]+))",
              [this](const Request& req, Response& res, const ContentReader& reader) {
                  std::string body;
                  if (!read_body(req, res, reader, body) || !authorize(req, res)) return;
                  std::string name = req.matches[1];
                  try {
                      scene::MeshEntry entry = service.store().put_mesh(name, body);
                      service.queue().forget_cached_frames();
                      json answer = scene::to_json(entry.report);
                      answer["name"] = entry.name;
                      answer["reference"] = "upload:" + entry.name;
                      send_json(res, 201, answer);
                  } catch (const mesh::MeshError& e) {
                      send_error(res, 400, std::string("unusable OBJ: ") + e.what());
                  } catch (const scene::StoreError& e) {
                      send_error(res, e.status(), e.what());
                  }
              });

        // Example scenes (logic in http/examples.cpp).
        s.Get("/api/examples", [this](const Request& req, Response& res) {
            if (authorize(req, res)) send_json(res, 200, examples_index(config().examples_dir));
        });
        s.Get(R"(/api/examples/([^/]+))", [this](const Request& req, Response& res) {
            if (!authorize(req, res)) return;
            ExampleFile example = read_example(config().examples_dir, req.matches[1].str());
            if (example.status == 200) send_json(res, 200, example.document);
            else send_error(res, example.status, example.error);
        });

        s.Get(R"(/api/.*)", [](const Request& req, Response& res) {
            send_error(res, 404, "no such endpoint: " + req.path);
        });

        s.Get(R"(/.*)", [this](const Request& req, Response& res) { serve_static(req, res); });
    }

    void put_index_field(const Request& req, Response& res, const std::string& id, const std::string& body) {
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
            send_error(res, e.status(), e.what());
        } catch (const protocol::ValidationError& e) {
            send_validation_error(res, e);
        }
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

    void install_hooks() {
        server.set_pre_routing_handler([](const Request&, Response&) {
            t_request_start = Clock::now();
            return httplib::Server::HandlerResponse::Unhandled;
        });
        // Every error gets a JSON body, including those cpp-httplib answers itself (404, 413, 400).
        server.set_error_handler(httplib::Server::HandlerWithResponse([](const Request&, Response& res) {
            if (res.body.empty()) {
                std::string reason = res.status == 413   ? "request body is too large (--max-body)"
                                     : res.status == 404 ? "not found"
                                     : res.status == 400 ? "bad request"
                                                         : "error " + std::to_string(res.status);
                send_json(res, res.status, {{"error", reason}});
            }
            return httplib::Server::HandlerResponse::Handled;
        }));
        server.set_exception_handler([](const Request&, Response& res, std::exception_ptr ep) {
            std::string what = "internal error";
            try {
                if (ep) std::rethrow_exception(ep);
            } catch (const std::exception& e) {
                what = std::string("internal error: ") + e.what();
            } catch (...) {
            }
            send_error(res, 500, what);
        });
        server.set_logger([this](const Request& req, const Response& res) {
            // Requests refused before routing (unparseable, too long) have no start time.
            char ms[32] = "-";
            if (t_request_start)
                std::snprintf(
                    ms, sizeof ms, "%.1f",
                    std::chrono::duration<double, std::milli>(Clock::now() - *t_request_start).count());
            t_request_start.reset();
            std::string method = req.method.empty() ? std::string("-") : req.method;
            std::string path = req.path.empty() ? std::string("-") : req.path;
            service.metrics().record_request(method, route_of(req.path), res.status);
            std::fprintf(stderr, "refractd: %s %s %d %s ms\n", method.c_str(), path.c_str(), res.status, ms);
        });
    }
};

ApiServer::ApiServer(Service& service) : impl_(std::make_unique<Impl>(service)) {
    unsigned threads = service.config().threads;
    impl_->server.new_task_queue = [threads] { return new httplib::ThreadPool(threads); };
    impl_->server.set_payload_max_length(service.config().max_body);
    impl_->server.set_keep_alive_timeout(5);
    impl_->server.set_read_timeout(10, 0);
    impl_->server.set_write_timeout(10, 0);
    impl_->install_hooks();
    impl_->routes();
}

ApiServer::~ApiServer() = default;

void ApiServer::bind() {
    const DaemonConfig& c = impl_->config();
    if (!impl_->server.bind_to_port(c.bind, c.port))
        throw std::runtime_error("cannot listen on " + c.bind + ":" + std::to_string(c.port));
}

void ApiServer::serve() {
    impl_->server.listen_after_bind();
}

void ApiServer::stop() {
    impl_->server.stop();
}

}  // namespace refract::http
