#include "http/daemon_config.h"

#include <arpa/inet.h>

#include <charconv>
#include <fstream>
#include <limits>
#include <sstream>

namespace refract::http {

namespace {

uint64_t parse_unsigned(const std::string& flag, const std::string& text, uint64_t min, uint64_t max,
                        bool allow_suffix = false) {
    uint64_t value = 0;
    const char* begin = text.data();
    const char* end = text.data() + text.size();
    auto [rest, error] = std::from_chars(begin, end, value);
    if (error != std::errc() || rest == begin)
        throw ConfigError(flag + " needs a number, got '" + text + "'");
    if (rest != end) {
        std::string suffix(rest, end);
        uint64_t scale = 0;
        if (allow_suffix && (suffix == "K" || suffix == "k")) scale = uint64_t{1} << 10;
        if (allow_suffix && (suffix == "M" || suffix == "m")) scale = uint64_t{1} << 20;
        if (allow_suffix && (suffix == "G" || suffix == "g")) scale = uint64_t{1} << 30;
        if (scale == 0) throw ConfigError(flag + " needs a number, got '" + text + "'");
        if (value > std::numeric_limits<uint64_t>::max() / scale) throw ConfigError(flag + " is too large");
        value *= scale;
    }
    if (value < min || value > max)
        throw ConfigError(flag + " must be between " + std::to_string(min) + " and " + std::to_string(max));
    return value;
}

// The token in `path` (a mounted Secret): its first line, without the newline editors add.
std::string read_token_file(const std::string& path) {
    std::ifstream in(path);
    std::string token;
    if (!in || !std::getline(in, token)) throw ConfigError("--token-file " + path + " cannot be read");
    while (!token.empty() && (token.back() == '\r' || token.back() == ' ')) token.pop_back();
    if (token.empty()) throw ConfigError("--token-file " + path + " holds no token on its first line");
    return token;
}

}  // namespace

bool is_loopback(const std::string& address) {
    if (address == "localhost") return true;
    in_addr v4{};
    if (::inet_pton(AF_INET, address.c_str(), &v4) == 1) return (ntohl(v4.s_addr) >> 24) == 127;
    in6_addr v6{};
    return ::inet_pton(AF_INET6, address.c_str(), &v6) == 1 && IN6_IS_ADDR_LOOPBACK(&v6);
}

CommandLine parse_command_line(const std::vector<std::string>& args, DaemonConfig defaults) {
    CommandLine result;
    result.config = std::move(defaults);
    DaemonConfig& c = result.config;
    for (size_t i = 0; i < args.size(); ++i) {
        std::string flag = args[i];
        std::string value;
        bool has_inline_value = false;
        if (size_t eq = flag.find('='); flag.rfind("--", 0) == 0 && eq != std::string::npos) {
            value = flag.substr(eq + 1);
            flag = flag.substr(0, eq);
            has_inline_value = true;
        }
        if (flag == "--help" || flag == "-h") {
            result.help = true;
            continue;
        }
        auto next = [&]() -> std::string {
            if (has_inline_value) return value;
            if (i + 1 >= args.size()) throw ConfigError(flag + " needs a value");
            return args[++i];
        };
        if (flag == "--bind") {
            c.bind = next();
        } else if (flag == "--port") {
            c.port = static_cast<uint16_t>(parse_unsigned(flag, next(), 1, 65535));
        } else if (flag == "--ws-port") {
            c.ws_port = static_cast<uint16_t>(parse_unsigned(flag, next(), 1, 65535));
        } else if (flag == "--device") {
            c.device = next();
        } else if (flag == "--data-dir") {
            c.data_dir = next();
        } else if (flag == "--store") {
            c.store = next();
            if (c.store.rfind("postgresql://", 0) != 0 && c.store.rfind("postgres://", 0) != 0)
                throw ConfigError("--store takes a postgresql:// URL (without it, scenes are kept under --data-dir)");
        } else if (flag == "--token") {
            c.token = next();
        } else if (flag == "--token-file") {
            c.token = read_token_file(next());
        } else if (flag == "--open") {
            c.open = true;
        } else if (flag == "--web-root") {
            c.web_root = next();
        } else if (flag == "--examples-dir") {
            c.examples_dir = next();
        } else if (flag == "--max-scenes") {
            c.max_scenes = parse_unsigned(flag, next(), 1, 1024);
        } else if (flag == "--max-device-memory") {
            c.max_device_memory = parse_unsigned(flag, next(), uint64_t{64} << 20, uint64_t{1} << 40, true);
        } else if (flag == "--max-host-memory") {
            c.max_host_memory = parse_unsigned(flag, next(), uint64_t{16} << 20, uint64_t{1} << 40, true);
        } else if (flag == "--max-body") {
            c.max_body = parse_unsigned(flag, next(), 1024, uint64_t{4} << 30, true);
        } else if (flag == "--max-queue") {
            c.max_queue = parse_unsigned(flag, next(), 1, 100000);
        } else if (flag == "--max-resolution") {
            c.max_resolution = static_cast<uint32_t>(parse_unsigned(flag, next(), 32, 512));
        } else if (flag == "--max-photons") {
            c.max_photons = static_cast<uint32_t>(parse_unsigned(flag, next(), 1, uint64_t{1} << 24, true));
        } else if (flag == "--max-image") {
            c.max_image = static_cast<uint32_t>(parse_unsigned(flag, next(), 1, 4096));
        } else if (flag == "--request-timeout") {
            c.request_timeout_s = static_cast<unsigned>(parse_unsigned(flag, next(), 1, 3600));
        } else if (flag == "--stop-timeout") {
            c.stop_timeout_s = static_cast<unsigned>(parse_unsigned(flag, next(), 1, 3600));
        } else if (flag == "--threads") {
            c.threads = static_cast<unsigned>(parse_unsigned(flag, next(), 8, 256));
        } else {
            throw ConfigError("unknown argument '" + args[i] + "' (see --help)");
        }
    }
    if (c.ws_port != 0 && c.ws_port == c.port) throw ConfigError("--ws-port must differ from --port");
    // Beyond loopback anyone on the network could edit scenes and spend the device: that takes a token,
    // or saying explicitly that the daemon is meant to be open.
    if (!result.help && !is_loopback(c.bind) && c.token.empty() && !c.open)
        throw ConfigError("--bind " + c.bind + " listens beyond this machine without a token: give --token T or "
                          "--token-file FILE (or --open to serve without one)");
    if (c.ws_port == 0 && c.port == 65535) throw ConfigError("--port 65535 needs an explicit --ws-port");
    return result;
}

std::string usage_text(const DaemonConfig& d) {
    std::ostringstream out;
    out << "usage: refractd [options]\n"
        << "Long-running Refract render daemon: scene documents over HTTP, frames as PNG, edits over "
           "WebSocket.\n\n"
        << "  --bind ADDR            address to listen on (default " << d.bind << ")\n"
        << "  --port N               HTTP port (default " << d.port << ")\n"
        << "  --ws-port N            WebSocket port (default: HTTP port + 1)\n"
        << "  --device NAME          use the Vulkan device whose name contains NAME (or REFRACT_DEVICE)\n"
        << "  --data-dir DIR         where scenes, meshes and index grids persist (default " << d.data_dir
        << ")\n"
        << "  --store URL            keep scenes, meshes and grids in PostgreSQL "
           "(postgresql://USER@HOST:PORT/DB),\n"
        << "                         shared by every replica given the same URL; --data-dir is then unused\n"
        << "  --token T              require 'Authorization: Bearer T' (or ?token=T) on everything but\n"
        << "                         /api/health and static files\n"
        << "  --token-file FILE      the token from the first line of FILE (a mounted secret)\n"
        << "  --open                 allow --bind beyond loopback without a token (refused otherwise)\n"
        << "  --web-root DIR         static files served at / (default " << d.web_root << ")\n"
        << "  --examples-dir DIR     example scenes (NAME.json) served at /api/examples, each one's load\n"
        << "                         warmed up at start (default " << d.examples_dir << ")\n"
        << "  --max-scenes N         scenes kept resident on the GPU, least recently used dropped (default "
        << d.max_scenes << ")\n"
        << "  --max-device-memory BYTES  device memory for resident scenes, K/M/G suffixes allowed; least\n"
        << "                         recently used scenes are dropped to make room (default "
        << (d.max_device_memory >> 20) << "M)\n"
        << "  --max-host-memory BYTES  host memory for decoded uploads (environment maps, meshes, index\n"
        << "                         grids), K/M/G suffixes allowed; least recently used are dropped and\n"
        << "                         decoded again from the store when needed, an upload over the whole\n"
        << "                         budget is refused (default " << (d.max_host_memory >> 20) << "M)\n"
        << "  --max-body BYTES       largest request body, K/M/G suffixes allowed (default " << d.max_body
        << ")\n"
        << "  --max-queue N          requests waiting for frames before 503 (default " << d.max_queue << ")\n"
        << "  --max-resolution N     largest volume resolution (default " << d.max_resolution << ")\n"
        << "  --max-photons N        largest photon count (default " << d.max_photons << ")\n"
        << "  --max-image N          largest image side in pixels (default " << d.max_image << ")\n"
        << "  --request-timeout S    longest wait for a frame in seconds (default " << d.request_timeout_s
        << ")\n"
        << "  --stop-timeout S       longest orderly stop in seconds (default " << d.stop_timeout_s
        << "); past it the daemon\n"
        << "                         exits where it stands (acknowledged edits are stored already)\n"
        << "  --threads N            HTTP worker threads (default " << d.threads << "); frame requests may\n"
        << "                         hold all but 4 of them, the rest keep the API answering\n"
        << "  --help                 print this and exit\n\n"
        << "Stops cleanly on SIGINT or SIGTERM. API: see protocol/README.md, section 'HTTP API'.\n";
    return out.str();
}

}  // namespace refract::http
