// Test harness for refractd: a temporary directory, free loopback ports, and a real daemon process that
// is always stopped (scope guard), with its log kept for failure messages.
#pragma once

#include <httplib.h>
#include <sys/types.h>

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace refract::test {

// True when the daemon the tests start is built with AddressSanitizer: this test binary is (its own
// refractd is then too), or REFRACT_SANITIZED_REFRACTD names one to start instead (scripts/test.sh runs
// the Release tests against the sanitized daemon, so the tests' own code is not rebuilt for it). Its
// allocator keeps freed memory in quarantine and its checks slow the host code several times, so bounds on
// a daemon's memory and on host-bound times are asserted in the Release run (scripts/test.sh runs both).
bool daemon_sanitized();

// A tetrahedron, the smallest closed mesh.
inline constexpr char kTetrahedronObj[] =
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";

// The whole of a file's bytes ("" when unreadable).
std::string read_file(const std::filesystem::path& path);

// Polls `done` every `interval` until it holds (true) or `limit` has passed (false).
bool wait_until(const std::function<bool()>& done, std::chrono::milliseconds limit,
                std::chrono::milliseconds interval = std::chrono::milliseconds(5));

// A fresh directory under the system temp dir, removed with everything in it on destruction.
class TempDir {
public:
    TempDir();
    ~TempDir();
    TempDir(const TempDir&) = delete;
    TempDir& operator=(const TempDir&) = delete;
    const std::filesystem::path& path() const { return path_; }

private:
    std::filesystem::path path_;
};

// A loopback TCP port nobody listens on right now.
uint16_t free_port();

// One refractd process. The constructor starts it and waits until /api/health answers.
class Daemon {
public:
    Daemon(std::filesystem::path data_dir, std::vector<std::string> extra_args = {});
    ~Daemon();
    Daemon(const Daemon&) = delete;
    Daemon& operator=(const Daemon&) = delete;

    // Sends `signal` (SIGTERM or SIGINT) and waits; the exit status (-1 if killed or died by a signal).
    int stop(int signal = 15);
    // SIGKILL and reap: the crash the store must survive.
    void kill9();
    bool running();

    httplib::Client client() const;
    uint16_t port() const { return port_; }
    uint16_t ws_port() const { return ws_port_; }
    pid_t pid() const { return pid_; }
    std::string log() const;
    // Resident set size now (VmRSS), bytes; -1 when the process is gone.
    int64_t rss_bytes() const;
    // Waits until health says the warm-up has ended (it answers health while it compiles pipelines and
    // builds the stored scenes, growing the process meanwhile); false after `limit`.
    bool wait_until_warm(std::chrono::seconds limit = std::chrono::seconds(120)) const;

private:
    void start();

    std::filesystem::path data_dir_;
    std::vector<std::string> extra_args_;
    std::filesystem::path log_path_;
    pid_t pid_ = -1;
    uint16_t port_ = 0;
    uint16_t ws_port_ = 0;
};

// A memory figure of process `pid` from /proc/PID/status ("VmRSS", "VmHWM"), in KiB; -1 when unknown.
long memory_kib(pid_t pid, const std::string& field);

// A TCP connection to 127.0.0.1:port (a blocking socket with a 30 s receive timeout); -1 when refused.
int connect_loopback(uint16_t port);

// Sends `request` verbatim over a fresh connection and returns everything the server answered.
std::string raw_http(uint16_t port, const std::string& request);

// Runs refractd with `args` until it exits (killed after `timeout`); its exit status (-1 when killed or
// signalled) and everything it printed.
std::pair<int, std::string> run_refractd(const std::vector<std::string>& args, std::chrono::seconds timeout);

}  // namespace refract::test
