// One of the two translation units that include Boost.Beast (it compiles slowly).
#include "http/ws_server.h"

#include <algorithm>
#include <atomic>
#include <charconv>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/asio/strand.hpp>
#include <boost/asio/thread_pool.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>
#include <cstdio>
#include <deque>
#include <map>
#include <mutex>
#include <optional>
#include <set>
#include <thread>
#include <vector>

#include "http/upgrade.h"
#include "protocol/animation.h"

namespace refract::http {

namespace {

namespace beast = boost::beast;
namespace bhttp = boost::beast::http;
namespace websocket = boost::beast::websocket;
namespace net = boost::asio;
using tcp = net::ip::tcp;
using json = nlohmann::json;

constexpr size_t kMaxMessageBytes = size_t{4} << 20;  // one edit message; scenes are small documents
constexpr size_t kMaxSessions = 256;                  // open connections, handshakes included
constexpr size_t kMaxQueuedErrors = 64;               // unsent error messages per session
constexpr auto kIdleBeforeStill = std::chrono::milliseconds(250);
constexpr size_t kMaxSeqBytes = 256;                  // a string `seq`; it is echoed in every answer
constexpr int64_t kMaxPlayFps = 60;                   // frames per second a played animation may ask for

// Plays started, by every session: each play's frames are keyed apart in the render queue.
std::atomic<uint64_t> plays_started{0};

}  // namespace

// Checks plays off the I/O threads: applying each keyframe's patch in turn takes seconds for 10,000
// keyframes over a scene of many objects, which would hold up every session served by that thread. One
// thread; the plays waiting for it hold their messages, at most four of the largest's worth together.
struct PlayChecker {
    static constexpr size_t kMaxWaitingBytes = 4 * kMaxMessageBytes;
    net::thread_pool pool{1};
    std::atomic<size_t> waiting_bytes{0};
};

namespace {

// The value of `name` in a query string ("a=1&token=x"), decoded; empty when absent.
std::string query_value(std::string_view query, std::string_view name) {
    while (!query.empty()) {
        size_t amp = query.find('&');
        std::string_view pair = query.substr(0, amp);
        size_t eq = pair.find('=');
        if (pair.substr(0, eq) == name && eq != std::string_view::npos)
            return percent_decode(pair.substr(eq + 1), true);
        if (amp == std::string_view::npos) break;
        query.remove_prefix(amp + 1);
    }
    return {};
}

// The scene id of "/api/scenes/{id}/ws"; empty when the path is anything else.
std::string scene_of_path(std::string_view path) {
    constexpr std::string_view prefix = "/api/scenes/";
    constexpr std::string_view suffix = "/ws";
    if (path.size() <= prefix.size() + suffix.size() || path.substr(0, prefix.size()) != prefix ||
        path.substr(path.size() - suffix.size()) != suffix)
        return {};
    std::string id(path.substr(prefix.size(), path.size() - prefix.size() - suffix.size()));
    return scene::valid_scene_id(id) ? id : std::string();
}

// A number in its shortest round-trip form ("86400", "0.25"), as a person would write it.
std::string shortest(double value) {
    char digits[32];
    const auto end = std::to_chars(digits, digits + sizeof digits, value).ptr;
    return std::string(digits, end);
}

// A camera as a render queue key: every member, shortest round-trip form.
std::string camera_key(const protocol::Camera& camera) {
    std::string key;
    for (const protocol::Vec3& v : {camera.position, camera.target, camera.up})
        for (double x : v) key += shortest(x) + ',';
    return key + shortest(camera.fov_deg);
}

// Numbers the sessions, from 1, across all threads.
uint64_t next_session_number() {
    static std::atomic<uint64_t> sessions{0};
    return sessions.fetch_add(1) + 1;
}

}  // namespace

// One client connection: the upgrade handshake, then a read loop and a write queue, all on one strand.
class WsSession;

// What a session tells the server about itself: the registry keeps who views which scene.
struct SessionEvents {
    std::function<void(WsSession*)> closed;                        // its destructor
    std::function<void(WsSession*, const std::string&)> viewing;   // the handshake is done: it views a scene
    std::function<void(WsSession*)> left;                          // its connection ended
    std::function<void(WsSession*, const std::string&, uint64_t)> edited;  // it made a revision of a scene
};

class WsSession : public std::enable_shared_from_this<WsSession> {
public:
    WsSession(tcp::socket socket, Service& service, PlayChecker& checker, SessionEvents events)
        : ws_(std::move(socket)),
          timer_(ws_.get_executor()),
          idle_timer_(ws_.get_executor()),
          service_(service),
          checker_(checker),
          events_(std::move(events)) {
        service_.ws_sessions.fetch_add(1);
    }
    ~WsSession() {
        service_.ws_sessions.fetch_sub(1);
        if (events_.closed) events_.closed(this);
    }

    // The scene's viewers on this daemon are now `count` (one joined or left). Safe from any thread.
    void viewers_changed(size_t count) {
        net::post(ws_.get_executor(), [self = shared_from_this(), count] {
            if (!self->closing_) self->send_text({{"type", "viewers"}, {"count", count}});
        });
    }

    // Another viewer's message made `revision` of this session's scene. Safe from any thread.
    void edited_by_another(uint64_t revision) {
        net::post(ws_.get_executor(), [self = shared_from_this(), revision] {
            if (!self->closing_ && !self->play_) self->send_text({{"type", "edited"}, {"revision", revision}, {"by", "viewer"}});
        });
    }

    void start() {
        net::dispatch(ws_.get_executor(), [self = shared_from_this()] { self->read_upgrade(); });
    }

    // Answers an upgrade the HTTP server has read already.
    void start_upgraded(bhttp::request<bhttp::string_body> request) {
        net::dispatch(ws_.get_executor(),
                      [self = shared_from_this(), request = std::move(request)]() mutable {
                          self->upgrade_request_ = std::move(request);
                          self->answer_upgrade();
                      });
    }

    // Revision `revision` of scene `id` is committed (by anyone, on any replica): a viewer of that scene
    // gets its frame (from its own view) unless it has asked for or rendered that revision already. nullopt: announcements
    // may have been lost, every viewer gets a frame of what is current. Safe from any thread.
    void scene_changed(std::optional<std::pair<std::string, uint64_t>> revision) {
        net::post(ws_.get_executor(), [self = shared_from_this(), revision] {
            // A played animation is its own scene's frames; edits show once it stops.
            if (!self->viewing_ || self->closing_ || self->want_frame_ || self->play_) return;
            if (revision && (revision->first != self->scene_id_ || revision->second <= self->submitted_revision_))
                return;
            if (revision && self->sees_no_change(revision->second)) return;
            self->idle_timer_.cancel();
            self->newer_message_->store(true);  // a refinement level in flight gives way
            self->wanted_seq_ = nullptr;        // nobody on this session asked: no seq to echo
            self->wanted_options_ = {scene::Quality::interactive, self->budget_ms_, 1};
            self->want_frame_ = true;
            self->submit_frame();
        });
    }

    // Whether `revision` of the scene looks, through this session's view, like the document of its last
    // frame: an edit of what its own view replaces (the scene's camera, under a viewer's own camera)
    // renders nothing for it. The revision counts as seen.
    bool sees_no_change(uint64_t revision) {
        if (!last_seen_) return false;
        std::optional<scene::SceneSnapshot> current;
        try {
            current = service_.store().get(scene_id_);
        } catch (const scene::StoreError&) {
            return false;  // the frame's own read says what is wrong
        }
        if (!current || current->revision != revision || protocol::seen_through(current->document, view_) != *last_seen_)
            return false;
        submitted_revision_ = revision;
        return true;
    }

    // Drops the connection (daemon shutdown); safe from any thread.
    void close() {
        net::post(ws_.get_executor(), [self = shared_from_this()] {
            self->closing_ = true;
            self->gone_->store(true);
            self->timer_.cancel();
            self->idle_timer_.cancel();
            beast::error_code ignored;
            beast::get_lowest_layer(self->ws_).socket().shutdown(tcp::socket::shutdown_both, ignored);
            beast::get_lowest_layer(self->ws_).close();
        });
    }

private:
    // The settings a message may set for the session from then on (budget_ms, refine, view, temporal).
    struct Settings {
        double budget_ms = scene::kDefaultBudgetMs;
        uint32_t refine_to = scene::kMaxRefinementLevel;
        protocol::View view;
        bool temporal = false;
    };

    // An animation played into this viewer (protocol/animation.h): its frames are rendered from the
    // animation's documents, never stored; the scene's own document is untouched.
    struct Play {
        protocol::Animation animation;
        double fps = 24.0;
        uint64_t frames = 1;  // frame i shows time i / fps, up to the last keyframe
        uint64_t id = 0;
        // When frame 0 was submitted: the animation's clock starts with its first frame, not with the
        // message (a refinement level in flight then would otherwise skip the frames it outlasted).
        std::optional<std::chrono::steady_clock::time_point> start;
        uint64_t next = 0;      // the first frame not yet rendered
        uint64_t rendered = 0;  // frames pushed
        json seq;
        // A keyframe moves the camera (a fly-through): its frames take the viewer's size, not its camera.
        bool moves_camera = false;
    };
    struct PlayedFrame {
        uint64_t play = 0, index = 0, frames = 0;
        double time = 0.0;
    };

    struct Outgoing {
        bool binary = false;
        std::shared_ptr<const std::string> text;          // text messages
        std::shared_ptr<const scene::FrameResult> frame;  // binary: the PNG of a frame
    };

    void read_upgrade() {
        beast::get_lowest_layer(ws_).expires_after(std::chrono::seconds(10));
        parser_.emplace();
        parser_->header_limit(16 * 1024);
        parser_->body_limit(16 * 1024);
        bhttp::async_read(
            beast::get_lowest_layer(ws_), buffer_, *parser_,
            [self = shared_from_this()](beast::error_code ec, size_t) { self->on_upgrade(ec); });
    }

    void refuse(bhttp::status status, const std::string& message) {
        auto res = std::make_shared<bhttp::response<bhttp::string_body>>(status, 11);
        res->set(bhttp::field::content_type, "application/json");
        res->set(bhttp::field::connection, "close");
        res->body() = dump_json({{"error", message}});
        res->prepare_payload();
        log(static_cast<int>(status));
        bhttp::async_write(
            beast::get_lowest_layer(ws_), *res, [self = shared_from_this(), res](beast::error_code, size_t) {
                beast::error_code ignored;
                beast::get_lowest_layer(self->ws_).socket().shutdown(tcp::socket::shutdown_both, ignored);
            });
    }

    void log(int status) {
        service_.metrics().record_request("GET", "/api/scenes/{id}/ws", status);
        std::fprintf(stderr, "refractd: GET %s %d (websocket)\n", path_.c_str(), status);
    }

    void on_upgrade(beast::error_code ec) {
        if (ec) return;  // the client went away or sent garbage; nothing to answer
        upgrade_request_ = parser_->release();
        answer_upgrade();
    }

    void answer_upgrade() {
        const auto& req = upgrade_request_;
        std::string_view target(req.target().data(), req.target().size());
        size_t question = target.find('?');
        path_ = std::string(target.substr(0, question));
        std::string_view query =
            question == std::string_view::npos ? std::string_view() : target.substr(question + 1);

        if (!websocket::is_upgrade(req))
            return refuse(bhttp::status::bad_request, "expected a WebSocket upgrade");
        if (service_.ws_sessions.load() > kMaxSessions)
            return refuse(bhttp::status::service_unavailable, "too many WebSocket sessions");
        std::string authorization(req[bhttp::field::authorization]);
        if (!service_.authorized(authorization, query_value(query, "token")))
            return refuse(bhttp::status::unauthorized, "missing or wrong bearer token");
        scene_id_ = scene_of_path(path_);
        std::optional<scene::SceneSnapshot> viewed;
        try {
            if (!scene_id_.empty()) viewed = service_.store().get(scene_id_);
        } catch (const scene::StoreError& e) {
            return refuse(bhttp::status::service_unavailable, e.what());
        }
        if (!viewed) return refuse(bhttp::status::not_found, "no scene at " + path_);
        // Edits are pushed from here on: an announcement of this revision or an older one that arrives
        // late (another replica's NOTIFY) is not news to this viewer.
        submitted_revision_ = viewed->revision;

        beast::get_lowest_layer(ws_).expires_never();
        ws_.set_option(websocket::stream_base::timeout::suggested(beast::role_type::server));
        ws_.read_message_max(kMaxMessageBytes);
        ws_.async_accept(req, [self = shared_from_this()](beast::error_code accept_ec) {
            if (accept_ec) return;
            self->viewing_ = true;
            if (self->events_.viewing) self->events_.viewing(self.get(), self->scene_id_);
            self->log(101);
            self->read_message();
        });
    }

    void read_message() {
        ws_.async_read(incoming_, [self = shared_from_this()](beast::error_code ec, size_t) {
            if (ec) {
                self->closing_ = true;
                self->gone_->store(true);
                self->timer_.cancel();
                self->idle_timer_.cancel();
                if (self->events_.left) self->events_.left(self.get());
                return;
            }
            std::string text = beast::buffers_to_string(self->incoming_.data());
            self->incoming_.consume(self->incoming_.size());
            self->on_message(text, self->ws_.got_text());
            self->read_message();
        });
    }

    // An error: `pointer` and `rule` (what the value broke, without the pointer) for a validation error.
    void send_error(const json& seq, const std::string& message, std::optional<std::string> pointer = {},
                    std::optional<std::string> rule = {}) {
        json error = {{"type", "error"}, {"seq", seq}, {"error", message}};
        if (pointer) error["pointer"] = *pointer;
        if (rule) error["rule"] = *rule;
        send_text(error);
    }

    // Queues a text message. A client that sends and never reads must not grow the queue: past the
    // bound, the oldest go.
    void send_text(const json& message) {
        if (outbox_.size() >= kMaxQueuedErrors) outbox_.pop_front();
        outbox_.push_back({false, std::make_shared<const std::string>(dump_json(message)), nullptr});
        write_next();
    }

    void on_message(const std::string& text, bool is_text) {
        messages_.fetch_add(1);  // a play still being checked is superseded
        json seq = nullptr;
        json message;
        try {
            if (!is_text) throw std::invalid_argument("messages must be text JSON");
            message = parse_json_document(text);
            if (!message.is_object()) throw std::invalid_argument("a message must be a JSON object");
        } catch (const std::exception& e) {
            service_.metrics().record_ws_message(true);
            return send_error(seq, std::string("malformed message: ") + e.what());
        }
        if (message.contains("seq")) {
            const json& given = message["seq"];
            if (!given.is_null() && !given.is_number() &&
                !(given.is_string() && given.get_ref<const std::string&>().size() <= kMaxSeqBytes)) {
                service_.metrics().record_ws_message(true);
                return send_error(nullptr, "seq must be a number or a string of at most " +
                                               std::to_string(kMaxSeqBytes) + " bytes");
            }
            seq = given;
        }
        const json type = message.contains("type") ? message["type"] : json("edit");
        if (type != "edit" && type != "play" && type != "stop") {
            service_.metrics().record_ws_message(true);
            return send_error(seq, "type must be \"edit\" (the default), \"play\" or \"stop\"");
        }
        scene::Quality quality = scene::Quality::interactive;
        if (message.contains("quality")) {
            const json& q = message["quality"];
            if (q == "still") {
                quality = scene::Quality::still;
            } else if (q != "interactive") {
                service_.metrics().record_ws_message(true);
                return send_error(seq, "quality must be \"interactive\" or \"still\"");
            }
        }
        // Session settings: checked whole before anything (the patch included) is applied.
        Settings settings{budget_ms_, refine_to_, view_, temporal_};
        double& budget_ms = settings.budget_ms;
        uint32_t& refine_to = settings.refine_to;
        if (message.contains("budget_ms")) {
            const json& b = message["budget_ms"];
            if (!b.is_number() || !(b.get<double>() >= scene::kMinBudgetMs && b.get<double>() <= scene::kMaxBudgetMs)) {
                service_.metrics().record_ws_message(true);
                return send_error(seq, "budget_ms must be a number of milliseconds in [10, 10000]");
            }
            budget_ms = b.get<double>();
        }
        if (message.contains("refine")) {
            const json& r = message["refine"];
            if (!r.is_number_unsigned() || r.get<uint64_t>() > scene::kMaxRefinementLevel) {
                service_.metrics().record_ws_message(true);
                return send_error(seq, "refine must be the highest refinement level to push, an integer in [0, " +
                                           std::to_string(scene::kMaxRefinementLevel) + "]");
            }
            refine_to = static_cast<uint32_t>(r.get<uint64_t>());
        }
        if (message.contains("temporal")) {
            const json& t = message["temporal"];
            if (!t.is_boolean()) {
                service_.metrics().record_ws_message(true);
                return send_error(seq, "temporal must be true or false", "/temporal");
            }
            settings.temporal = t.get<bool>();
        }
        if (message.contains("view")) {
            // The viewer's own image size and camera: refused whole, with a pointer into the message.
            try {
                const json& v = message["view"];
                settings.view = v.is_null() ? protocol::View{} : protocol::parse_view(v, service_.store().limits());
            } catch (const protocol::ValidationError& e) {
                service_.metrics().record_ws_message(true);
                return send_error(seq, e.what(), e.pointer(), e.rule());
            }
        }
        if (type == "play") {
            double fps = 24.0;
            try {
                fps = play_fps(message);
            } catch (const protocol::ValidationError& e) {
                service_.metrics().record_ws_message(true);
                return send_error(seq, e.what(), e.pointer(), e.rule());  // a pointer into the message
            }
            return check_play(std::move(message), text.size(), seq, quality, settings, fps);
        }
        if (type == "stop" && message.contains("patch")) {
            service_.metrics().record_ws_message(true);
            return send_error(seq, "stop takes no patch", "/patch");
        }
        if (message.contains("patch")) {
            try {
                const scene::EditResult edit = service_.store().patch(scene_id_, message["patch"]);
                if (edit.changed && events_.edited) events_.edited(this, scene_id_, edit.after.revision);
            } catch (const protocol::ValidationError& e) {
                service_.metrics().record_ws_message(true);
                return send_error(seq, e.what(), e.pointer(), e.rule());  // a pointer into the scene document
            } catch (const scene::StoreError& e) {
                service_.metrics().record_ws_message(true);
                return send_error(seq, e.what());
            }
        }
        begin(seq, type == "stop", quality, settings, std::nullopt);
    }

    // A message accepted: its session settings taken, the play it starts (if any) playing, and its frame
    // asked for (`stop`: none).
    void begin(const json& seq, bool stop, scene::Quality quality, const Settings& settings, std::optional<Play> play) {
        service_.metrics().record_ws_message(false);
        budget_ms_ = settings.budget_ms;
        refine_to_ = settings.refine_to;
        view_ = settings.view;
        temporal_ = settings.temporal;
        // Any message ends the animation playing (latest wins); `stop` asks for nothing more.
        if (play_) stop_play(seq);
        if (stop) return;
        play_ = std::move(play);
        // Latest wins: remember only the newest request; the frame after the one in flight renders it.
        // Any message stops refinement: the frame it asks for comes next.
        idle_timer_.cancel();
        newer_message_->store(true);
        wanted_seq_ = seq;
        unanswered_seq_ = seq;
        // A still asked for gives way to this session's next message too (or to an edit of its scene it
        // must show, scene_changed), whose frame then answers it: loading another scene, or a drag begun
        // again, waits for one part of it, not all of it.
        wanted_options_ = quality == scene::Quality::still ? yielding_to_newer_message(1)
                                                           : scene::FrameOptions{quality, budget_ms_, 1};
        // A still starts this session's refinement: from the level the resident state gives for the work
        // of level 1 (after a camera drag, the batches already in its grid), which the next levels follow.
        wanted_options_.resume_up_to = refine_to_;
        want_frame_ = true;
        submit_frame();
    }

    // Checks a play against the scene as it is now on the PlayChecker's thread, then begins it here
    // unless a newer message came meanwhile (which supersedes it, as it would end it playing).
    void check_play(json message, size_t bytes, const json& seq, scene::Quality quality, const Settings& settings,
                    double fps) {
        if (checker_.waiting_bytes.fetch_add(bytes) + bytes > PlayChecker::kMaxWaitingBytes) {
            checker_.waiting_bytes.fetch_sub(bytes);
            service_.metrics().record_ws_message(true);
            return send_error(seq, "other plays are being checked; send this one again shortly");
        }
        const uint64_t ticket = messages_.load();
        net::post(checker_.pool, [self = shared_from_this(), message = std::move(message), bytes, seq, quality,
                                  settings, fps, ticket]() mutable {
            std::optional<Play> play;
            std::optional<protocol::ValidationError> refused;
            if (ticket == self->messages_.load()) {
                try {
                    play = self->make_play(message["keyframes"], seq, fps, ticket);
                } catch (const protocol::ValidationError& e) {
                    refused = e;
                }
            }
            message = nullptr;  // its memory goes before the next check's
            self->checker_.waiting_bytes.fetch_sub(bytes);
            net::post(self->ws_.get_executor(), [self, seq, quality, settings, ticket, play = std::move(play),
                                                 refused = std::move(refused)]() mutable {
                if (self->closing_ || ticket != self->messages_.load()) return;
                if (refused) {
                    self->service_.metrics().record_ws_message(true);
                    return self->send_error(seq, refused->what(), refused->pointer(), refused->rule());
                }
                self->begin(seq, false, quality, settings, std::move(play));
            });
        });
    }

    // After a frame, with nothing newer asked for: keep improving it. A still frame (holding `level`) is
    // followed by the next refinement level (renderer.h) up to the session's `refine`; an interactive
    // frame, after kIdleBeforeStill without another message, by the still frame (the user has let go).
    // `refine` 0 pushes only the frames asked for.
    void refine_after(const json& seq, const scene::FrameOptions& rendered, uint32_t level, uint64_t revision) {
        if (want_frame_ || closing_ || refine_to_ == 0) return;
        std::optional<scene::SceneSnapshot> current;
        try {
            current = service_.store().get(scene_id_);
        } catch (const scene::StoreError&) {
            return;  // the store is away: refinement waits for the next message
        }
        // A newer revision this view shows no change in (the scene's camera, under a camera of its own)
        // pushed no frame (sees_no_change): the frame stands for it, and refines on.
        if (!current) return;
        if (current->revision != revision &&
            !(last_seen_ && protocol::seen_through(current->document, view_) == *last_seen_))
            return;
        if (rendered.quality == scene::Quality::still) {
            if (level >= refine_to_) return;
            wanted_seq_ = seq;
            wanted_options_ = yielding_still(level + 1);
            // Viewers of one scene share its radiance grid: a level below the batches another view's
            // refinement put there takes those batches instead of tracing anew.
            wanted_options_.resume_up_to = refine_to_;
            want_frame_ = true;
            return submit_frame();
        }
        idle_timer_.expires_after(kIdleBeforeStill);
        idle_timer_.async_wait([self = shared_from_this(), seq](beast::error_code ec) {
            if (ec || self->want_frame_ || self->in_flight_ || self->closing_) return;
            self->wanted_seq_ = seq;
            self->wanted_options_ = self->yielding_still(1);
            self->wanted_options_.resume_up_to = self->refine_to_;
            self->want_frame_ = true;
            self->submit_frame();
        });
    }

    // A still frame this session pushes unasked (the one after a drag, or a refinement level): it gives
    // way after any part of its work when this session's next message waits (here: one frame in flight a
    // session) or another frame does that is not a refinement level, so that a drag resumed a moment
    // after a pause waits for one part of the still, not all of it.
    scene::FrameOptions yielding_still(uint32_t level) {
        newer_message_ = std::make_shared<std::atomic<bool>>(false);
        return {scene::Quality::still, budget_ms_, level, [newer = newer_message_, &queue = service_.queue()] {
                    return newer->load() || queue.queued_ahead_of_refinement() > 0;
                }};
    }

    // A still frame a viewer asked for: it gives way to this session's next message only (other work waits
    // for it, as for any frame asked for).
    scene::FrameOptions yielding_to_newer_message(uint32_t level) {
        newer_message_ = std::make_shared<std::atomic<bool>>(false);
        return {scene::Quality::still, budget_ms_, level, [newer = newer_message_] { return newer->load(); }};
    }

    void submit_frame() {
        if (in_flight_ || !want_frame_ || closing_) return;
        std::optional<scene::SceneSnapshot> snapshot;
        try {
            snapshot = service_.store().get(scene_id_);
        } catch (const scene::StoreError& e) {
            // A shared store's database is away: the session stays open and the next message retries.
            want_frame_ = false;
            return send_error(wanted_seq_, e.what());
        }
        if (!snapshot) {
            want_frame_ = false;
            return send_error(wanted_seq_, "the scene was deleted");
        }
        submitted_revision_ = std::max(submitted_revision_, snapshot->revision);
        // The session's own view: frames at its size and from its camera, keyed apart by that camera.
        scene::FrameRequest request{snapshot->id, snapshot->revision, protocol::seen_through(snapshot->document, view_),
                                    wanted_options_, {}, view_.camera ? camera_key(*view_.camera) : std::string()};
        last_seen_ = play_ ? std::nullopt : std::optional(request.document);
        std::optional<PlayedFrame> played;
        if (play_) {
            // Played in real time: the frame due now, skipping those the renderer could not keep up with;
            // a frame not yet due waits for its time.
            if (!play_->start) play_->start = std::chrono::steady_clock::now();
            const auto elapsed = std::chrono::steady_clock::now() - *play_->start;
            const auto due_now = static_cast<uint64_t>(std::chrono::duration<double>(elapsed).count() * play_->fps);
            const uint64_t index = std::min(std::max(play_->next, due_now), play_->frames - 1);
            const auto due = *play_->start + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                                std::chrono::duration<double>(static_cast<double>(index) / play_->fps));
            if (due > std::chrono::steady_clock::now()) {
                timer_.expires_at(due);
                timer_.async_wait([self = shared_from_this()](beast::error_code ec) {
                    if (!ec) self->submit_frame();
                });
                return;
            }
            const double time = static_cast<double>(index) / play_->fps;
            try {
                protocol::View view = view_;
                if (play_->moves_camera) view.camera.reset();
                request.document = protocol::seen_through(play_->animation.at(time), view);
            } catch (const protocol::ValidationError& e) {
                want_frame_ = false;
                const json seq = play_->seq;
                play_.reset();
                return send_error(seq, "the animation's document at " + shortest(time) + " s: " + e.what());
            }
            request.playback = std::to_string(play_->id);
            played = PlayedFrame{play_->id, index, play_->frames, time};
        } else if (temporal_ && request.options.quality == scene::Quality::interactive) {
            // The session's drags reuse what it was shown (render/temporal_history.h); a played frame is
            // another scene state each time, with nothing to reuse.
            request.options.history = history_key_;
        }
        json seq = wanted_seq_;
        scene::FrameOptions options = wanted_options_;
        auto self = shared_from_this();
        bool accepted = service_.queue().submit(
            std::move(request),
            [self, seq, options, played](const scene::FrameOutcome& outcome) {
                net::post(self->ws_.get_executor(),
                          [self, seq, options, played, outcome] { self->on_frame(seq, options, outcome, played); });
            },
            gone_, scene::Admission::one_per_caller);
        if (!accepted) {
            // Queue full: try again shortly rather than dropping the newest state.
            timer_.expires_after(std::chrono::milliseconds(50));
            timer_.async_wait([self](beast::error_code ec) {
                if (!ec) self->submit_frame();
            });
            return;
        }
        in_flight_ = true;
        want_frame_ = false;
    }

    void on_frame(const json& seq, const scene::FrameOptions& options, const scene::FrameOutcome& outcome,
                  const std::optional<PlayedFrame>& played) {
        in_flight_ = false;
        if (closing_) return;
        if (played && (!play_ || play_->id != played->play)) return submit_frame();  // stopped meanwhile
        const scene::Quality quality = options.quality;
        if (outcome.status == scene::FrameOutcome::Status::superseded) {
            // Refinement gave way to a newer request, which is queued; it resumes after that request's frame.
            // A frame asked for that gave way to a push (scene_changed) is answered by the pushed frame.
            if (!seq.is_null() && seq == unanswered_seq_ && wanted_seq_.is_null()) wanted_seq_ = seq;
        } else if (outcome.status != scene::FrameOutcome::Status::ok) {
            if (seq == unanswered_seq_) unanswered_seq_ = nullptr;
            send_error(seq, outcome.error);
        } else {
            if (seq == unanswered_seq_) unanswered_seq_ = nullptr;
            const scene::FrameResult& frame = *outcome.frame;
            json header = {{"type", "frame"},
                           {"seq", seq},
                           {"revision", outcome.revision},
                           {"passes", pass_list(outcome.cached ? 0 : frame.rerun)},
                           {"voxelized", outcome.cached ? std::vector<std::string>{} : frame.voxelized},
                           {"timings", outcome.cached ? json::object() : timings_json(frame)},
                           {"width", frame.width},
                           {"height", frame.height},
                           {"quality", scene::to_string(quality)},
                           {"cached", outcome.cached},
                           {"level", frame.level},
                           {"photon_batches", frame.refinement.photon_batches},
                           {"samples_per_pixel", frame.refinement.samples_per_pixel},
                           {"photons", frame.photons},
                           {"refine", refine_to_}};
            if (quality == scene::Quality::interactive) {
                header["budget_ms"] = options.budget_ms;
                header["traced_width"] = frame.traced_width;
                header["traced_height"] = frame.traced_height;
                header["still_eye_rays"] = frame.still_eye_rays;
            }
            if (played) {
                const bool last = played->index + 1 == played->frames;
                header["play"] = {{"frame", played->index}, {"frames", played->frames}, {"time", played->time},
                                  {"last", last}};
                ++play_->rendered;
                play_->next = played->index + 1;
                if (last) play_.reset();
                else want_frame_ = true;
            }
            // A slow reader gets the newest frame only: an unsent older one is dropped, never queued.
            pending_frame_ = {std::make_shared<const std::string>(dump_json(header)), outcome.frame};
            write_next();
            if (!played) refine_after(seq, options, frame.level, outcome.revision);
        }
        submit_frame();
    }

    // The frame rate of a `play` message, after the checks that need no scene. Throws ValidationError with
    // a pointer into the message.
    static double play_fps(const json& message) {
        if (message.contains("patch")) throw protocol::ValidationError("/patch", "play takes no patch");
        if (!message.contains("keyframes")) throw protocol::ValidationError("/keyframes", "play needs keyframes");
        if (!message.contains("fps")) return 24.0;
        const json& f = message["fps"];
        if (!f.is_number_unsigned() || f.get<uint64_t>() < 1 || f.get<uint64_t>() > kMaxPlayFps)
            throw protocol::ValidationError("/fps", "must be an integer in [1, " + std::to_string(kMaxPlayFps) + "]");
        return static_cast<double>(f.get<uint64_t>());
    }

    // The play of `keyframes` over the scene as it is now (any thread), unless message `ticket` is no longer
    // the newest. Throws ValidationError with a pointer into the message.
    Play make_play(const json& keyframes, const json& seq, double fps, uint64_t ticket) const {
        std::optional<scene::SceneSnapshot> current;
        try {
            current = service_.store().get(scene_id_);
        } catch (const scene::StoreError& e) {
            throw protocol::ValidationError("", e.what());
        }
        if (!current) throw protocol::ValidationError("", "the scene was deleted");
        try {
            // Given up when the session ends or a newer message supersedes the play.
            protocol::Animation animation(current->document, keyframes, service_.store().limits(), [this, ticket] {
                return !gone_->load() && ticket == messages_.load();
            });
            const auto frames = static_cast<uint64_t>(std::floor(animation.duration() * fps)) + 1;
            const bool moves_camera = std::any_of(keyframes.begin(), keyframes.end(), [](const json& keyframe) {
                return keyframe.is_object() && keyframe.contains("patch") && keyframe["patch"].is_object() &&
                       keyframe["patch"].contains("camera");
            });
            return Play{std::move(animation), fps, frames, ++plays_started, std::nullopt, 0, 0, seq, moves_camera};
        } catch (const protocol::ValidationError& e) {
            std::string pointer = "/keyframes";
            pointer += e.pointer();
            throw protocol::ValidationError(pointer, e.rule());
        }
    }

    // Ends the animation playing, telling the viewer how far it got; `seq` is the message that ended it.
    void stop_play(const json& seq) {
        json stopped = {{"type", "stopped"}, {"seq", seq}, {"play_seq", play_->seq}, {"frames", play_->rendered}};
        play_.reset();
        want_frame_ = false;
        pending_frame_.reset();  // an unsent played frame: the viewer asked for no more of them
        outbox_.push_back({false, std::make_shared<const std::string>(dump_json(stopped)), nullptr});
        write_next();
    }

    void write_next() {
        if (writing_ || closing_) return;
        Outgoing next;
        if (png_after_header_) {
            next = {true, nullptr, std::move(png_after_header_)};
            png_after_header_.reset();
        } else if (!outbox_.empty()) {
            next = std::move(outbox_.front());
            outbox_.pop_front();
        } else if (pending_frame_) {
            next = {false, std::move(pending_frame_->first), nullptr};
            png_after_header_ = std::move(pending_frame_->second);
            pending_frame_.reset();
        } else {
            return;
        }
        writing_ = true;
        current_ = std::move(next);
        ws_.binary(current_.binary);
        auto done = [self = shared_from_this()](beast::error_code ec, size_t) {
            self->writing_ = false;
            self->current_ = {};
            if (ec) {
                self->closing_ = true;
                self->gone_->store(true);
                if (self->events_.left) self->events_.left(self.get());
                return;
            }
            self->write_next();
        };
        if (current_.binary)
            ws_.async_write(net::buffer(current_.frame->png.data(), current_.frame->png.size()),
                            std::move(done));
        else
            ws_.async_write(net::buffer(*current_.text), std::move(done));
    }

    websocket::stream<beast::tcp_stream> ws_;
    net::steady_timer timer_;
    net::steady_timer idle_timer_;  // from an interactive frame to the still one (refine_after)
    Service& service_;
    PlayChecker& checker_;
    SessionEvents events_;
    beast::flat_buffer buffer_;
    beast::flat_buffer incoming_;
    std::optional<bhttp::request_parser<bhttp::string_body>> parser_;
    bhttp::request<bhttp::string_body> upgrade_request_;  // kept until the handshake's answer is written
    std::string path_;
    std::string scene_id_;

    bool closing_ = false;
    bool viewing_ = false;            // the handshake is done: edits of scene_id_ are pushed
    uint64_t submitted_revision_ = 0;  // the newest revision this session has rendered or is rendering
    bool in_flight_ = false;
    bool want_frame_ = false;
    json wanted_seq_ = nullptr;
    json unanswered_seq_ = nullptr;  // the newest message whose frame (or error) has not been sent
    scene::FrameOptions wanted_options_{scene::Quality::interactive};
    // Names this session's temporal history in the renderer: unique for the daemon's life, unlike its address.
    const std::string history_key_ = "session " + std::to_string(next_session_number());
    double budget_ms_ = scene::kDefaultBudgetMs;           // this session's interactive frame budget
    protocol::View view_;  // this session's own image size and camera (none: the document's)
    // The document of the session's last frame as its view showed it (none while playing).
    std::optional<protocol::SceneDocument> last_seen_;
    uint32_t refine_to_ = scene::kMaxRefinementLevel;      // the last refinement level pushed
    // Interactive frames at the viewer's size by temporal reuse (render/temporal_history.h) rather than at
    // the budget's size: off by default, as on two CPU cores its fixed cost outweighs what it reuses
    // (docs/interactive.md).
    bool temporal_ = false;
    // Set by a message that arrives while a refinement level renders: the level gives way to it.
    std::shared_ptr<std::atomic<bool>> newer_message_ = std::make_shared<std::atomic<bool>>(false);
    std::optional<Play> play_;  // the animation playing, if any
    // Messages received: a play checked meanwhile is begun only if none came after it (check_play).
    std::atomic<uint64_t> messages_{0};
    // Set when the connection ends: the render queue drops or abandons this session's frames.
    scene::Withdrawn gone_ = std::make_shared<std::atomic<bool>>(false);

    bool writing_ = false;
    Outgoing current_;
    std::deque<Outgoing> outbox_;
    std::optional<std::pair<std::shared_ptr<const std::string>, std::shared_ptr<const scene::FrameResult>>>
        pending_frame_;
    std::shared_ptr<const scene::FrameResult> png_after_header_;
};

// The live sessions, shared with each session so that the last one can leave after the server is gone;
// and which scene each views, so that a scene's viewers hear of each other (their count, their edits).
struct SessionRegistry {
    std::mutex mutex;
    std::set<WsSession*> live;
    std::vector<std::weak_ptr<WsSession>> refs;
    std::map<WsSession*, std::string> viewing;  // sessions past their handshake, and their scene

    // `session` views `scene` from now on: every viewer of it is told their number.
    void joined(WsSession* session, const std::string& scene) {
        std::vector<std::shared_ptr<WsSession>> told;  // released after the lock (see tell)
        std::lock_guard lock(mutex);
        viewing[session] = scene;
        tell(scene, nullptr, told, [count = viewers_of(scene)](WsSession& s) { s.viewers_changed(count); });
    }
    // `session` views nothing any more (its connection ended, or it is gone): the others are told.
    void left(WsSession* session) {
        std::vector<std::shared_ptr<WsSession>> told;
        std::lock_guard lock(mutex);
        auto it = viewing.find(session);
        if (it == viewing.end()) return;
        const std::string scene = it->second;
        viewing.erase(it);
        tell(scene, nullptr, told, [count = viewers_of(scene)](WsSession& s) { s.viewers_changed(count); });
    }
    // `by`'s message made `revision` of `scene`: its other viewers are told.
    void edited(WsSession* by, const std::string& scene, uint64_t revision) {
        std::vector<std::shared_ptr<WsSession>> told;
        std::lock_guard lock(mutex);
        tell(scene, by, told, [revision](WsSession& s) { s.edited_by_another(revision); });
    }

private:
    size_t viewers_of(const std::string& scene) const {
        return static_cast<size_t>(std::count_if(viewing.begin(), viewing.end(), [&](const auto& v) { return v.second == scene; }));
    }
    // Calls `what` for each live viewer of `scene` but `except` (under the lock; `what` only posts). The
    // references go to `told`, released after the lock: a last reference's destructor takes the lock.
    template <typename What>
    void tell(const std::string& scene, WsSession* except, std::vector<std::shared_ptr<WsSession>>& told, What what) {
        for (const auto& ref : refs) {
            auto session = ref.lock();
            if (!session || session.get() == except) continue;
            auto it = viewing.find(session.get());
            if (it == viewing.end() || it->second != scene) continue;
            what(*session);
            told.push_back(std::move(session));
        }
    }
};

struct WsServer::Impl {
    Service& service;
    net::io_context ioc;
    std::optional<net::executor_work_guard<net::io_context::executor_type>> work;
    tcp::acceptor acceptor{ioc};
    std::vector<std::thread> threads;
    std::shared_ptr<SessionRegistry> registry = std::make_shared<SessionRegistry>();
    net::steady_timer accept_retry{ioc};
    bool started = false;
    std::atomic<bool> stopped{false};
    std::optional<scene::Subscription> edits;  // committed revisions, pushed to the sessions viewing them
    PlayChecker checker;

    explicit Impl(Service& s) : service(s) {}

    // A session for `socket`, known to the registry so that stop() can close it.
    std::shared_ptr<WsSession> open_session(tcp::socket socket) {
        beast::error_code ignored;
        socket.set_option(tcp::no_delay(true), ignored);
        SessionEvents events;
        events.closed = [registry = registry](WsSession* gone) {
            registry->left(gone);
            std::lock_guard lock(registry->mutex);
            registry->live.erase(gone);
        };
        events.viewing = [registry = registry](WsSession* s, const std::string& scene) { registry->joined(s, scene); };
        events.left = [registry = registry](WsSession* s) { registry->left(s); };
        events.edited = [registry = registry](WsSession* by, const std::string& scene, uint64_t revision) {
            registry->edited(by, scene, revision);
        };
        auto session = std::make_shared<WsSession>(std::move(socket), service, checker, std::move(events));
        std::lock_guard lock(registry->mutex);
        registry->live.insert(session.get());
        std::erase_if(registry->refs, [](const auto& ref) { return ref.expired(); });
        registry->refs.push_back(session);
        return session;
    }

    void accept() {
        acceptor.async_accept(net::make_strand(ioc), [this](beast::error_code ec, tcp::socket socket) {
            if (ec) {
                if (ec == net::error::operation_aborted || !acceptor.is_open()) return;
                // Out of descriptors (or another passing failure): wait a little rather than spin.
                accept_retry.expires_after(std::chrono::milliseconds(50));
                accept_retry.async_wait([this](beast::error_code wait_ec) {
                    if (!wait_ec) accept();
                });
                return;
            }
            open_session(std::move(socket))->start();
            accept();
        });
    }
};

WsServer::WsServer(Service& service) : impl_(std::make_unique<Impl>(service)) {}

WsServer::~WsServer() {
    stop();
}

void WsServer::start() {
    const DaemonConfig& c = impl_->service.config();
    beast::error_code ec;
    auto address = net::ip::make_address(c.bind, ec);
    if (ec) throw std::runtime_error("cannot parse --bind address '" + c.bind + "'");
    tcp::endpoint endpoint(address, c.effective_ws_port());
    auto& acceptor = impl_->acceptor;
    acceptor.open(endpoint.protocol(), ec);
    if (!ec) acceptor.set_option(net::socket_base::reuse_address(true), ec);
    if (!ec) acceptor.bind(endpoint, ec);
    if (!ec) acceptor.listen(net::socket_base::max_listen_connections, ec);
    if (ec)
        throw std::runtime_error("cannot listen for WebSocket on " + c.bind + ":" +
                                 std::to_string(c.effective_ws_port()) + ": " + ec.message());
    impl_->work.emplace(impl_->ioc.get_executor());
    impl_->started = true;
    // Every committed revision (from this daemon or, with a shared store, any replica) goes to each
    // session, which keeps it only if it views that scene: a few hundred sessions at most.
    impl_->edits.emplace(impl_->service.store().on_change([registry = impl_->registry](const scene::StoreEvent& event) {
        using Kind = scene::StoreEvent::Kind;
        if (event.kind != Kind::revision && event.kind != Kind::missed) return;
        // Released after the lock: a last reference's destructor takes the registry's lock itself.
        std::vector<std::shared_ptr<WsSession>> told;
        std::lock_guard lock(registry->mutex);
        for (const auto& ref : registry->refs) {
            if (auto session = ref.lock()) {
                if (event.kind == Kind::missed) session->scene_changed(std::nullopt);
                else session->scene_changed(std::pair{event.name, event.revision});
                told.push_back(std::move(session));
            }
        }
    }));
    impl_->accept();
    for (int i = 0; i < 2; ++i) impl_->threads.emplace_back([this] { impl_->ioc.run(); });
}

void WsServer::adopt(UpgradePtr upgrade) {
    if (impl_->stopped || !impl_->started) return;  // the connection closes with `upgrade`
    impl_->open_session(std::move(upgrade->socket))->start_upgraded(std::move(upgrade->request));
}

void WsServer::stop() {
    if (impl_->stopped || !impl_->started) return;
    impl_->stopped = true;
    impl_->edits.reset();  // no more posts to sessions: their io_context is stopping
    net::post(impl_->ioc, [this] {
        beast::error_code ignored;
        impl_->acceptor.close(ignored);
    });
    std::vector<std::shared_ptr<WsSession>> open;
    {
        std::lock_guard lock(impl_->registry->mutex);
        for (auto& ref : impl_->registry->refs)
            if (auto session = ref.lock()) open.push_back(std::move(session));
    }
    for (auto& session : open) session->close();
    open.clear();
    impl_->work.reset();
    // Give sessions a moment to close their sockets, then stop whatever is left.
    auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(500);
    while (std::chrono::steady_clock::now() < deadline) {
        {
            std::lock_guard lock(impl_->registry->mutex);
            if (impl_->registry->live.empty()) break;
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    impl_->checker.pool.stop();
    impl_->checker.pool.join();
    impl_->ioc.stop();
    for (auto& thread : impl_->threads) thread.join();
    impl_->threads.clear();
}

}  // namespace refract::http
