// The HTTP API (served by HttpServer): scenes, edits, frames, meshes, index grids, health, metrics, static
// files. Handlers validate through protocol, change state through the scene store and get frames from the
// render queue; none of them touches Vulkan.
#pragma once

#include <functional>
#include <memory>

#include "http/http_server.h"
#include "http/service.h"

namespace refract::http {

class ApiServer {
public:
    // `upgrades` takes the WebSocket upgrades that arrive on the HTTP port (unset: they get 404).
    explicit ApiServer(Service& service, std::function<void(UpgradePtr)> upgrades = {});
    ~ApiServer();
    ApiServer(const ApiServer&) = delete;
    ApiServer& operator=(const ApiServer&) = delete;

    // Binds the configured address and port. Throws std::runtime_error when that fails.
    void bind();
    // Serves until stop(); runs on a thread of its own.
    void serve();
    void stop();

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

}  // namespace refract::http
