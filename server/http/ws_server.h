// The WebSocket endpoint ws://host:ws_port/api/scenes/{id}/ws (Boost.Beast, on a port of its own, and on
// the HTTP port too, where HttpServer hands upgrades over): each text message may carry a merge patch;
// frames come back as a JSON header followed by the PNG. Latest wins: one frame in flight per session,
// newer edits coalesce.
#pragma once

#include <memory>

#include "http/http_server.h"
#include "http/service.h"

namespace refract::http {

class WsServer {
public:
    explicit WsServer(Service& service);
    ~WsServer();
    WsServer(const WsServer&) = delete;
    WsServer& operator=(const WsServer&) = delete;

    // Binds the configured address and WebSocket port and starts serving. Throws std::runtime_error.
    void start();
    // Serves an upgrade that arrived on the HTTP port (same path, same answers); its session stays on the
    // HTTP server's I/O threads. Safe from any thread; after stop() the connection is just closed.
    void adopt(UpgradePtr upgrade);
    // Stops accepting, drops every session and joins the I/O threads. Idempotent.
    void stop();

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

}  // namespace refract::http
