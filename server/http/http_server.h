// An HTTP/1.1 server (Boost.Beast, asynchronous): a few I/O threads read every request's header within a
// deadline and its body at a minimum rate, and a bounded pool of workers runs the route handlers, which may
// block (waiting for a frame, parsing a mesh). A slow client costs a socket and a timer, never a worker.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace refract::http {

// Case-insensitive ordering of header names.
struct FieldLess {
    bool operator()(std::string_view a, std::string_view b) const;
};

// One request as the routes see it; the path and query values are percent-decoded.
struct Request {
    std::string method;  // "HEAD" is routed as "GET"
    std::string target;  // as received
    std::string path;
    std::multimap<std::string, std::string> params;
    std::multimap<std::string, std::string, FieldLess> headers;
    std::vector<std::string> matches;  // the route's regex groups, [0] the whole path
    std::string body;
    // True once the client has closed its connection (asked while the handler runs; never blocks):
    // work for a client that left can stop. Unset: never.
    std::function<bool()> client_gone;

    bool has_header(const std::string& name) const { return headers.count(name) != 0; }
    // The first value of a header; empty when absent.
    std::string get_header_value(const std::string& name) const;
    bool has_param(const std::string& name) const { return params.count(name) != 0; }
    // The first value of a query parameter; empty when absent.
    std::string get_param_value(const std::string& name) const;
};

// One answer. Without a body, `status` alone is sent.
struct Response {
    int status = 200;
    std::vector<std::pair<std::string, std::string>> headers;
    std::string body;

    void set_header(const std::string& name, const std::string& value);
    void set_content(std::string content, const std::string& content_type);
    void set_content(const char* data, size_t size, const std::string& content_type);
};

using Handler = std::function<void(const Request&, Response&)>;

// A WebSocket upgrade with its connection (defined in http/upgrade.h); the deleter is a function so that
// code which only passes one on needs no Beast.
struct UpgradeRequest;
using UpgradePtr = std::unique_ptr<UpgradeRequest, void (*)(UpgradeRequest*)>;

struct HttpServerOptions {
    std::string bind = "127.0.0.1";
    uint16_t port = 0;
    unsigned workers = 32;    // threads that run route handlers
    unsigned io_threads = 2;  // threads that read and write sockets
    size_t max_body = size_t{64} << 20;
    size_t max_header_bytes = 16 * 1024;  // request line and fields together
    size_t max_header_fields = 100;
    size_t max_connections = 512;             // open at once; more are accepted and closed at once
    size_t max_pending = 1024;                // requests read and waiting for a worker; past it, 503
    std::chrono::seconds header_timeout{10};  // for a whole header, from the first wait for it
    size_t min_body_rate = 256 * 1024;        // bytes per second a body (and an answer) must keep up
    std::chrono::seconds body_grace{10};      // added to the time the minimum rate allows
    // Called with a request's header (no body yet) when it carries a body; false refuses it with the
    // answer the check wrote, and the connection is closed unread.
    std::function<bool(const Request&, Response&)> before_body;
    // Called once per answer, with the time from the first byte of the header to the answer's write.
    std::function<void(const Request&, int status, double ms)> on_answer;
    // Takes over a connection whose request is a WebSocket upgrade; unset: upgrades are routed like any GET.
    std::function<void(UpgradePtr)> on_upgrade;
    // The JSON body of an error the server answers itself (bad request, too large, not found).
    std::function<std::string(const std::string& message)> error_body;
};

namespace detail {
struct HttpServerState;  // defined in http_server.cpp
}

class HttpServer {
public:
    explicit HttpServer(HttpServerOptions options);
    ~HttpServer();
    HttpServer(const HttpServer&) = delete;
    HttpServer& operator=(const HttpServer&) = delete;

    // Adds a route: `pattern` must match the whole decoded path (std::regex); `method` "*" takes every
    // method. The first match wins.
    void route(const std::string& method, const std::string& pattern, Handler handler);

    // Binds and listens (backlog at the system's maximum; SO_REUSEADDR, never SO_REUSEPORT). Throws
    // std::runtime_error naming the address and the reason when that fails.
    void bind();
    // Serves until stop(), on the calling thread and the other I/O threads; then finishes the handlers
    // still running (their answers are dropped) and returns.
    void serve();
    // Stops accepting and drops every connection. Safe from any thread.
    void stop();

private:
    std::unique_ptr<detail::HttpServerState> state_;
};

// Percent-decodes `text`; `plus_is_space` for query strings.
std::string percent_decode(std::string_view text, bool plus_is_space);

}  // namespace refract::http
