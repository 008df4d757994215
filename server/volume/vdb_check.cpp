#include "volume/vdb_check.h"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/mman.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <nlohmann/json.hpp>
#include <vector>

extern char** environ;

namespace refract::volume {

namespace {

// An answer is one letter and its text: R and the report's JSON, D and a grid's export
// (density_export.h), E and the reason the file was refused, F and what went wrong in the check itself
// (OpenVDB out of memory, say).
constexpr char kReport = 'R', kDensity = 'D', kRefused = 'E', kFailed = 'F';

class Descriptor {
public:
    explicit Descriptor(int fd = -1) : fd_(fd) {}
    Descriptor(const Descriptor&) = delete;
    Descriptor& operator=(const Descriptor&) = delete;
    ~Descriptor() { reset(); }
    int get() const { return fd_; }
    void reset() {
        if (fd_ >= 0) ::close(fd_);
        fd_ = -1;
    }

private:
    int fd_;
};

std::string failure(const std::string& what, int error) {
    return "volume checks: " + what + ": " + std::strerror(error);
}

void write_all(int fd, std::string_view data) {
    for (size_t done = 0; done < data.size();) {
        const ssize_t n = ::write(fd, data.data() + done, data.size() - done);
        if (n < 0 && errno == EINTR) continue;
        if (n < 0) throw CheckUnavailable(failure("holding the file for its check", errno));
        done += static_cast<size_t>(n);
    }
}

// Reads the child's answer until it closes its end or `most` bytes came (the caller then stops the
// child, and refuses an answer cut short as not its form); false when `deadline` came first.
bool read_answer(int fd, std::string& answer, std::chrono::steady_clock::time_point deadline, size_t most) {
    char buffer[65536];
    for (;;) {
        const auto left =
            std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
        if (left.count() <= 0) return false;
        pollfd readable{fd, POLLIN, 0};
        const int ready = ::poll(&readable, 1, static_cast<int>(left.count()));
        if (ready < 0 && errno == EINTR) continue;
        if (ready == 0) return false;
        if (ready < 0) return true;
        const ssize_t n = ::read(fd, buffer, sizeof buffer);
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0) return true;
        answer.append(buffer, std::min(static_cast<size_t>(n), most - answer.size()));
        if (answer.size() == most) return true;
    }
}

// Starts `program` with `arguments` after its name, `input` as its standard input and `output` as its
// standard output.
pid_t start_check(const std::filesystem::path& program, std::vector<std::string> arguments, int input, int output) {
    std::string path = program.string();
    std::vector<char*> argv{path.data()};
    for (std::string& argument : arguments) argv.push_back(argument.data());
    argv.push_back(nullptr);
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_adddup2(&actions, input, STDIN_FILENO);
    posix_spawn_file_actions_adddup2(&actions, output, STDOUT_FILENO);
    pid_t child = -1;
    const int error = ::posix_spawn(&child, path.c_str(), &actions, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&actions);
    if (error != 0) throw CheckUnavailable(failure("cannot start " + path, error));
    return child;
}

}  // namespace

std::filesystem::path check_program() {
    if (const char* set = std::getenv("REFRACT_VDB_CHECK"); set != nullptr && *set != '\0') return set;
    std::error_code error;
    const std::filesystem::path self = std::filesystem::read_symlink("/proc/self/exe", error);
    if (error) throw CheckUnavailable("volume checks: cannot find the running program: " + error.message());
    return self.parent_path() / "refract-vdb-check";
}

namespace {

// The checker's answer for `bytes` with `arguments`, at most `most` bytes; throws VolumeError or
// CheckUnavailable when there is none.
std::string run_check(std::string_view bytes, std::vector<std::string> arguments, size_t most,
                      const std::filesystem::path& program, std::chrono::seconds time_limit) {
    // The file reaches the child from memory, written whole before it starts, so neither side ever
    // waits for the other to empty a pipe.
    Descriptor input(::memfd_create("refract-volume-upload", MFD_CLOEXEC));
    if (input.get() < 0) throw CheckUnavailable(failure("memfd_create", errno));
    write_all(input.get(), bytes);
    if (::lseek(input.get(), 0, SEEK_SET) != 0) throw CheckUnavailable(failure("lseek", errno));
    int pipe_fds[2];
    if (::pipe2(pipe_fds, O_CLOEXEC) != 0) throw CheckUnavailable(failure("pipe", errno));
    Descriptor answer_in(pipe_fds[0]), answer_out(pipe_fds[1]);

    const pid_t child = start_check(program, std::move(arguments), input.get(), answer_out.get());
    answer_out.reset();
    input.reset();
    std::string answer;
    const bool answered = read_answer(answer_in.get(), answer, std::chrono::steady_clock::now() + time_limit, most);
    if (!answered || answer.size() == most) ::kill(child, SIGKILL);
    int status = 0;
    while (::waitpid(child, &status, 0) < 0 && errno == EINTR) {
    }
    if (!answered)
        throw VolumeError("not checked within " + std::to_string(time_limit.count()) + " s (refused)");
    if (answer.empty()) {
        if (WIFSIGNALED(status))
            throw VolumeError("OpenVDB crashed reading it (signal " + std::to_string(WTERMSIG(status)) + ")");
        throw CheckUnavailable("volume checks: " + program.string() + " ended without an answer (exit status " +
                               std::to_string(WIFEXITED(status) ? WEXITSTATUS(status) : -1) + ")");
    }
    if (answer[0] == kRefused) throw VolumeError(answer.substr(1));
    if (answer[0] == kFailed) throw VolumeError("its check failed: " + answer.substr(1));
    return answer;
}

[[noreturn]] void not_its_form(const std::filesystem::path& program) {
    throw CheckUnavailable("volume checks: " + program.string() + " answered in a form not its own");
}

}  // namespace

VolumeReport inspect_vdb_apart(std::string_view bytes, const VolumeLimits& limits,
                               const std::filesystem::path& program, std::chrono::seconds time_limit) {
    // A report lists at most max_grids grids of a few hundred bytes each.
    const size_t most = 4096 + size_t{limits.max_grids} * 1024;
    const std::string answer = run_check(
        bytes, {std::to_string(limits.max_box_voxels), std::to_string(limits.max_grids)}, most, program, time_limit);
    if (answer[0] != kReport) not_its_form(program);
    try {
        return volume_report_from_json(nlohmann::json::parse(answer.substr(1)));
    } catch (const nlohmann::json::exception&) {
        not_its_form(program);
    }
}

DensityGrid export_density_apart(std::string_view bytes, const std::string& grid, const VolumeLimits& limits,
                                 uint64_t max_leaves, const std::filesystem::path& program,
                                 std::chrono::seconds time_limit) {
    // One byte past the largest export it may send: an answer cut there is refused for its size.
    const size_t most = 1 + kDensityHeaderBytes + static_cast<size_t>(max_leaves) * kDensityLeafBytes + 1;
    const std::string answer = run_check(bytes,
                                         {std::to_string(limits.max_box_voxels), std::to_string(limits.max_grids), grid,
                                          std::to_string(max_leaves)},
                                         most, program, time_limit);
    if (answer[0] != kDensity) not_its_form(program);
    return decode_density(std::string_view(answer).substr(1), max_leaves);
}

std::string export_answer(std::string_view bytes, const std::string& grid, const VolumeLimits& limits,
                          uint64_t max_leaves) {
    try {
        return kDensity + encode_density(export_density(bytes, grid, limits, max_leaves));
    } catch (const VolumeError& e) {
        return kRefused + std::string(e.what());
    } catch (const std::exception& e) {
        return kFailed + std::string(e.what());
    }
}

std::string check_answer(std::string_view bytes, const VolumeLimits& limits) {
    try {
        return kReport + to_json(inspect_vdb(bytes, limits)).dump();
    } catch (const VolumeError& e) {
        return kRefused + std::string(e.what());
    } catch (const std::exception& e) {
        return kFailed + std::string(e.what());
    }
}

}  // namespace refract::volume
