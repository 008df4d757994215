// refractd's command line: where it listens, what it may spend, where it keeps its data.
#pragma once

#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

namespace refract::http {

struct DaemonConfig {
    std::string bind = "127.0.0.1";
    uint16_t port = 8080;
    uint16_t ws_port = 0;  // 0: port + 1
    std::string device;    // substring of the device name; empty: REFRACT_DEVICE or the best device
    std::string data_dir = "./refract-data";
    std::string store;      // postgresql:// URL of the shared store; empty: the embedded store in data_dir
    std::string token;      // non-empty: Bearer token required by everything but /api/health and static files
    bool open = false;      // --open: serve beyond loopback without a token (said loudly at start)
    std::string web_root;   // static files served at /
    std::string examples_dir;  // example scene documents served at /api/examples
    size_t max_scenes = 8;  // scenes whose GPU state stays resident (LRU)
    uint64_t max_device_memory = uint64_t{4} << 30;  // bytes of device memory for resident scenes (LRU)
    uint64_t max_host_memory = uint64_t{1} << 30;  // bytes of decoded uploads held in memory (LRU)
    size_t max_body = size_t{64} << 20;  // bytes of one request body
    size_t max_queue = 16;               // requests waiting for a frame, all scenes together
    uint32_t max_resolution = 256;       // volume voxels along the longest axis
    uint32_t max_photons = 1u << 22;
    uint32_t max_image = 2048;        // pixels per image side
    unsigned request_timeout_s = 60;  // longest wait for a frame
    unsigned stop_timeout_s = 10;     // longest orderly stop after SIGINT or SIGTERM (http/stop_deadline.h)
    unsigned threads = 32;            // HTTP worker threads; a frame request holds one while it waits

    uint16_t effective_ws_port() const { return ws_port != 0 ? ws_port : static_cast<uint16_t>(port + 1); }
};

// A command line that cannot be used; the message names the flag.
class ConfigError : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

// What parse_command_line found: a config to run with, or a request for help.
struct CommandLine {
    DaemonConfig config;
    bool help = false;
};

// True for an address only this machine can reach (127.0.0.0/8, ::1, localhost).
bool is_loopback(const std::string& address);

// Parses argv (without argv[0]); `defaults` supplies the web root baked in at build time. Throws ConfigError.
CommandLine parse_command_line(const std::vector<std::string>& args, DaemonConfig defaults);

// The text `refractd --help` prints.
std::string usage_text(const DaemonConfig& defaults);

}  // namespace refract::http
