#include "daemon/harness.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <signal.h>
#include <spawn.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <stdexcept>
#include <thread>

extern char** environ;

namespace refract::test {

namespace fs = std::filesystem;

namespace {

// The refractd the tests start: REFRACT_SANITIZED_REFRACTD where it is set, else this build's.
std::string refractd_path() {
    const char* sanitized = std::getenv("REFRACT_SANITIZED_REFRACTD");
    return sanitized && *sanitized ? sanitized : REFRACTD_PATH;
}

// Starts refractd with `args`, its stdout and stderr appended to `log`; its pid.
pid_t spawn_refractd(const std::vector<std::string>& args, const fs::path& log) {
    const std::string path = refractd_path();
    std::vector<std::string> all = {path};
    all.insert(all.end(), args.begin(), args.end());
    std::vector<char*> argv;
    for (auto& arg : all) argv.push_back(arg.data());
    argv.push_back(nullptr);
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, log.c_str(), O_WRONLY | O_CREAT | O_APPEND,
                                     0644);
    posix_spawn_file_actions_adddup2(&actions, STDOUT_FILENO, STDERR_FILENO);
    pid_t pid = -1;
    int error = posix_spawn(&pid, path.c_str(), &actions, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&actions);
    if (error != 0) throw std::runtime_error("cannot spawn " + path);
    return pid;
}

}  // namespace

bool daemon_sanitized() {
#if defined(__SANITIZE_ADDRESS__)
    return true;
#else
    const char* sanitized = std::getenv("REFRACT_SANITIZED_REFRACTD");
    return sanitized && *sanitized;
#endif
}

std::string read_file(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
}

bool wait_until(const std::function<bool()>& done, std::chrono::milliseconds limit,
                std::chrono::milliseconds interval) {
    const auto end = std::chrono::steady_clock::now() + limit;
    while (!done()) {
        if (std::chrono::steady_clock::now() > end) return false;
        std::this_thread::sleep_for(interval);
    }
    return true;
}

TempDir::TempDir() {
    std::string pattern = (fs::temp_directory_path() / "refractd-test-XXXXXX").string();
    if (!::mkdtemp(pattern.data())) throw std::runtime_error("mkdtemp failed");
    path_ = pattern;
}

TempDir::~TempDir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
}

uint16_t free_port() {
    int fd = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    address.sin_port = 0;
    ::bind(fd, reinterpret_cast<sockaddr*>(&address), sizeof address);
    socklen_t length = sizeof address;
    ::getsockname(fd, reinterpret_cast<sockaddr*>(&address), &length);
    ::close(fd);
    return ntohs(address.sin_port);
}

Daemon::Daemon(fs::path data_dir, std::vector<std::string> extra_args)
    : data_dir_(std::move(data_dir)), extra_args_(std::move(extra_args)) {
    log_path_ = data_dir_;
    log_path_ += ".log";
    // A port taken between free_port() and the daemon's bind: try again with others.
    for (int attempt = 0; attempt < 3; ++attempt) {
        start();
        if (pid_ > 0) return;
    }
    throw std::runtime_error("refractd did not start:\n" + log());
}

Daemon::~Daemon() {
    if (pid_ <= 0) return;
    // Every test also checks that the daemon stops cleanly (and, under sanitizers, without reports).
    int status = stop();
    if (status != 0) ADD_FAILURE() << "refractd exited with status " << status << ":\n" << log();
}

void Daemon::start() {
    port_ = free_port();
    do {
        ws_port_ = free_port();
    } while (ws_port_ == port_);
    // No examples (a folder that is not there): with the repository's, every daemon would warm up loading
    // each of them while its test runs (seconds of both cores); a test of that names a folder of its own.
    fs::path no_examples = data_dir_;
    no_examples += ".no-examples";
    std::vector<std::string> args = {
        "--port",     std::to_string(port_), "--ws-port",         std::to_string(ws_port_),
        "--data-dir", data_dir_.string(),    "--request-timeout", "120",
        "--examples-dir", no_examples.string()};
    args.insert(args.end(), extra_args_.begin(), extra_args_.end());
    pid_ = spawn_refractd(args, log_path_);

    // Ready when /api/health answers; Vulkan start-up with validation on lavapipe takes a few seconds.
    auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
    while (std::chrono::steady_clock::now() < deadline) {
        int status = 0;
        if (::waitpid(pid_, &status, WNOHANG) == pid_) {
            pid_ = -1;  // exited (port taken?)
            return;
        }
        httplib::Client probe("127.0.0.1", port_);
        probe.set_connection_timeout(1, 0);
        if (auto res = probe.Get("/api/health"); res && res->status == 200) return;
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    kill9();
    throw std::runtime_error("refractd did not answer /api/health within 60 s:\n" + log());
}

bool Daemon::wait_until_warm(std::chrono::seconds limit) const {
    httplib::Client probe = client();
    // Every 50 ms, not 5: each probe is a request the warming daemon answers and logs.
    return wait_until(
        [&] {
            const auto res = probe.Get("/api/health");
            return res && res->status == 200 &&
                   nlohmann::json::parse(res->body).value("warming_up", true) == false;
        },
        limit, std::chrono::milliseconds(50));
}

int64_t Daemon::rss_bytes() const {
    const long kib = memory_kib(pid_, "VmRSS");
    return kib < 0 ? -1 : int64_t{kib} * 1024;
}

long memory_kib(pid_t pid, const std::string& field) {
    std::ifstream status("/proc/" + std::to_string(pid) + "/status");
    std::string line;
    while (std::getline(status, line))
        if (line.compare(0, field.size() + 1, field + ":") == 0) return std::stol(line.substr(field.size() + 1));
    return -1;
}

bool Daemon::running() {
    if (pid_ <= 0) return false;
    int status = 0;
    if (::waitpid(pid_, &status, WNOHANG) == pid_) {
        pid_ = -1;
        return false;
    }
    return true;
}

int Daemon::stop(int signal) {
    if (pid_ <= 0) return -1;
    ::kill(pid_, signal);
    auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
    int status = 0;
    while (std::chrono::steady_clock::now() < deadline) {
        if (::waitpid(pid_, &status, WNOHANG) == pid_) {
            pid_ = -1;
            return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    kill9();
    return -1;
}

void Daemon::kill9() {
    if (pid_ <= 0) return;
    ::kill(pid_, SIGKILL);
    int status = 0;
    ::waitpid(pid_, &status, 0);
    pid_ = -1;
}

httplib::Client Daemon::client() const {
    httplib::Client client("127.0.0.1", port_);
    client.set_connection_timeout(5, 0);
    client.set_read_timeout(150, 0);
    client.set_write_timeout(30, 0);
    return client;
}

std::string Daemon::log() const {
    std::ifstream in(log_path_);
    std::ostringstream text;
    text << in.rdbuf();
    return text.str();
}

int connect_loopback(uint16_t port) {
    int fd = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    address.sin_port = htons(port);
    if (::connect(fd, reinterpret_cast<sockaddr*>(&address), sizeof address) != 0) {
        ::close(fd);
        return -1;
    }
    timeval timeout{30, 0};
    ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof timeout);
    return fd;
}

std::string raw_http(uint16_t port, const std::string& request) {
    int fd = connect_loopback(port);
    if (fd < 0) return {};
    ::send(fd, request.data(), request.size(), MSG_NOSIGNAL);
    std::string answer;
    char buffer[4096];
    for (;;) {
        ssize_t n = ::recv(fd, buffer, sizeof buffer, 0);
        if (n <= 0) break;
        answer.append(buffer, static_cast<size_t>(n));
    }
    ::close(fd);
    return answer;
}

std::pair<int, std::string> run_refractd(const std::vector<std::string>& args, std::chrono::seconds timeout) {
    TempDir dir;
    fs::path log_path = dir.path() / "refractd.log";
    pid_t pid = spawn_refractd(args, log_path);
    int status = 0;
    int exit_status = -1;
    auto deadline = std::chrono::steady_clock::now() + timeout;
    for (;;) {
        if (::waitpid(pid, &status, WNOHANG) == pid) {
            exit_status = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
            break;
        }
        if (std::chrono::steady_clock::now() > deadline) {
            ::kill(pid, SIGKILL);
            ::waitpid(pid, &status, 0);
            break;
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    std::ifstream in(log_path);
    std::ostringstream text;
    text << in.rdbuf();
    return {exit_status, text.str()};
}

}  // namespace refract::test
