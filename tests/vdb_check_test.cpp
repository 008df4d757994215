// Volume files checked in a program of their own (volume/vdb_check.h): the same answers as the check in
// this process, and a check that hangs, crashes, is missing or answers nonsense ends with a reason.
#include "volume/vdb_check.h"

#include <gtest/gtest.h>

#include <sys/wait.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include "volume/vdb_samples.h"

namespace refract::volume {
namespace {

const std::filesystem::path kChecker = REFRACT_VDB_CHECK_PROGRAM;

template <typename Error>
std::string error_of(const std::string& bytes, const std::filesystem::path& program,
                     std::chrono::seconds limit = std::chrono::seconds(30)) {
    try {
        inspect_vdb_apart(bytes, {}, program, limit);
    } catch (const Error& e) {
        return e.what();
    }
    return "(no such error)";
}

// A stand-in for a checker, as a shell script in the test's temporary directory.
std::filesystem::path script(const std::string& name, const std::string& body) {
    const auto path = std::filesystem::path(testing::TempDir()) / name;
    std::ofstream(path) << "#!/bin/sh\n" << body << "\n";
    std::filesystem::permissions(path, std::filesystem::perms::owner_all);
    return path;
}

TEST(VdbCheck, AnswersAsTheCheckInThisProcessDoes) {
    const std::string file = test::density_sphere_vdb(6, true);
    EXPECT_EQ(inspect_vdb_apart(file, {}, kChecker), inspect_vdb(file, {}));
    // The limits reach the checker: a box of 13^3 voxels is over a limit of 1000.
    std::string in_process;
    try {
        inspect_vdb(file, {.max_box_voxels = 1000});
    } catch (const VolumeError& e) {
        in_process = e.what();
    }
    ASSERT_NE(in_process.find("more than the daemon's limit of 1000"), std::string::npos) << in_process;
    try {
        inspect_vdb_apart(file, {.max_box_voxels = 1000}, kChecker);
        ADD_FAILURE() << "accepted over the limit";
    } catch (const VolumeError& e) {
        EXPECT_EQ(e.what(), in_process);
    }
    // A large file passes through whole (more than a pipe holds).
    const std::string large = test::density_sphere_vdb(40);
    ASSERT_GT(large.size(), size_t{1} << 17);
    EXPECT_EQ(inspect_vdb_apart(large, {}, kChecker), inspect_vdb(large, {}));
}

TEST(VdbCheck, RefusesWhatTheCheckInThisProcessRefusesForTheSameReason) {
    const std::string stream = test::as_stream_vdb(false);
    for (size_t cut : {size_t{0}, size_t{7}, stream.size() / 2, stream.size() - 1}) {
        const std::string bytes = stream.substr(0, cut);
        std::string in_process;
        try {
            inspect_vdb(bytes, {});
        } catch (const VolumeError& e) {
            in_process = e.what();
        }
        EXPECT_EQ(error_of<VolumeError>(bytes, kChecker), in_process) << cut;
    }
}

TEST(VdbCheck, AHangingCheckIsStoppedAndTheFileRefused) {
    const auto start = std::chrono::steady_clock::now();
    EXPECT_EQ(error_of<VolumeError>("x", script("hangs", "exec sleep 60"), std::chrono::seconds(1)),
              "not checked within 1 s (refused)");
    EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(20));
}

TEST(VdbCheck, ACrashIsTheFilesRefusalAndAnythingElseTheInstallationsFault) {
    EXPECT_EQ(error_of<VolumeError>("x", script("crashes", "kill -SEGV $$")),
              "OpenVDB crashed reading it (signal 11)");
    EXPECT_NE(error_of<CheckUnavailable>("x", "/nonexistent/refract-vdb-check").find("cannot start"),
              std::string::npos);
    EXPECT_NE(error_of<CheckUnavailable>("x", script("silent", "exit 3")).find("without an answer (exit status 3)"),
              std::string::npos);
    EXPECT_NE(error_of<CheckUnavailable>("x", script("chatty", "echo hello")).find("in a form not its own"),
              std::string::npos);
}

TEST(VdbCheck, TheProgramRefusesArgumentsItDoesNotTake) {
    for (const char* arguments : {"", " 100", " 100 8 9", " -1 8", " 100 x", " 100 4294967296", " --export 100 8",
                                  " 100 8 density x", " 100 8 density 1 2"}) {
        const std::string command = kChecker.string() + arguments + " < /dev/null > /dev/null 2>&1";
        const int status = std::system(command.c_str());
        ASSERT_TRUE(WIFEXITED(status)) << arguments;
        EXPECT_EQ(WEXITSTATUS(status), 2) << arguments;
    }
}

TEST(VdbCheck, TheProgramIsFoundBesideTheRunningOneUnlessNamed) {
    const auto beside = std::filesystem::read_symlink("/proc/self/exe").parent_path() / "refract-vdb-check";
    ::unsetenv("REFRACT_VDB_CHECK");
    EXPECT_EQ(check_program(), beside);
    ::setenv("REFRACT_VDB_CHECK", kChecker.c_str(), 1);
    EXPECT_EQ(check_program(), kChecker);
    ::unsetenv("REFRACT_VDB_CHECK");
}

}  // namespace
}  // namespace refract::volume
