// Atomic outputs (issue 37): a failed write names the OS's reason and leaves nothing; a write killed midway
// leaves a recognisable temporary that the next write of the same output removes; a folder (validate's
// report) is replaced whole or not at all; outputs are checked before any work.
#include "baker/util/atomic_file.h"

#include <csignal>
#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>
#include <sys/resource.h>
#include <unistd.h>

#include "support/test_paths.h"

namespace nrad {
namespace {

namespace fs = std::filesystem;

size_t entries(const std::string& dir) { return size_t(std::distance(fs::directory_iterator(dir), fs::directory_iterator())); }

std::string read(const std::string& path) {
    std::ifstream f(path);
    return std::string((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
}

TEST(AtomicFile, StaleTemporariesOfTheSameOutputAreRemoved) {
    const std::string dir = test::temporaryDirectory(), out = dir + "/scene.nrad";
    // A process that no longer exists (a PID above pid_max is never running), an earlier version's name, a live
    // process's temporary (ours: it may be writing right now) and another output's temporary.
    std::ofstream(out + ".nrad-partial-2147483646-0") << "killed mid-write";
    std::ofstream(out + ".tmp-12345") << "old name";
    const std::string live = out + ".nrad-partial-" + std::to_string(::getpid()) + "-999999";
    std::ofstream(live) << "being written";
    std::ofstream(dir + "/other.nrad.nrad-partial-2147483646-0") << "another output";
    writeTextAtomically(out, "asset");
    EXPECT_EQ(read(out), "asset");
    EXPECT_FALSE(fs::exists(out + ".nrad-partial-2147483646-0"));
    EXPECT_FALSE(fs::exists(out + ".tmp-12345"));
    EXPECT_TRUE(fs::exists(live));
    EXPECT_TRUE(fs::exists(dir + "/other.nrad.nrad-partial-2147483646-0"));
}

// A full disk, made with RLIMIT_FSIZE (writes past it fail with EFBIG): the message has the OS's reason, and
// neither the output nor a temporary is left.
TEST(AtomicFile, AFailedWriteNamesTheReasonAndLeavesNothing) {
    const std::string dir = test::temporaryDirectory(), out = dir + "/big.bin";
    rlimit old{};
    ASSERT_EQ(::getrlimit(RLIMIT_FSIZE, &old), 0);
    auto previous = std::signal(SIGXFSZ, SIG_IGN);
    rlimit small = old;
    small.rlim_cur = 4096;
    ASSERT_EQ(::setrlimit(RLIMIT_FSIZE, &small), 0);
    std::string message;
    try {
        writeBytesAtomically(out, std::vector<uint8_t>(100000, 7));
    } catch (const IoError& e) {
        message = e.what();
    }
    ::setrlimit(RLIMIT_FSIZE, &old);
    std::signal(SIGXFSZ, previous);
    EXPECT_NE(message.find(out + ": write failed: File too large"), std::string::npos) << message;
    EXPECT_EQ(entries(dir), 0u);
}

TEST(AtomicFile, AFolderIsReplacedWholeOrNotAtAll) {
    const std::string dir = test::temporaryDirectory(), report = dir + "/report";
    writeFolderAtomically(report, [](const std::string& tmp) {
        writeTextAtomically(tmp + "/a.txt", "first");
        writeTextAtomically(tmp + "/b.txt", "first");
    });
    EXPECT_EQ(read(report + "/a.txt"), "first");
    // A write that fails midway: the first report stays as it was, and nothing else is left.
    EXPECT_THROW(writeFolderAtomically(report,
                                       [](const std::string& tmp) {
                                           writeTextAtomically(tmp + "/a.txt", "second");
                                           throw IoError(tmp + "/b.txt: write failed: No space left on device");
                                       }),
                 IoError);
    EXPECT_EQ(read(report + "/a.txt"), "first");
    EXPECT_EQ(entries(dir), 1u);
    // A write that succeeds replaces it whole (b.txt is not carried over).
    writeFolderAtomically(report, [](const std::string& tmp) { writeTextAtomically(tmp + "/a.txt", "third"); });
    EXPECT_EQ(read(report + "/a.txt"), "third");
    EXPECT_FALSE(fs::exists(report + "/b.txt"));
    EXPECT_EQ(entries(dir), 1u);
}

TEST(AtomicFile, OutputsAreCheckedBeforeTheWork) {
    const std::string dir = test::temporaryDirectory();
    EXPECT_EQ(checkOutputFile(dir + "/a.nrad").problem, OutputProblem::kNone);
    EXPECT_EQ(checkOutputFile(dir).problem, OutputProblem::kIsFolder);
    OutputCheck c = checkOutputFile("/nonexistent-dir/x.nrad");
    EXPECT_EQ(c.problem, OutputProblem::kCannotCreate);
    EXPECT_EQ(c.message, "/nonexistent-dir/x.nrad: cannot create file: No such file or directory");
    EXPECT_EQ(checkOutputFolder(dir + "/report").problem, OutputProblem::kNone);
    std::ofstream(dir + "/file") << "x";
    EXPECT_EQ(checkOutputFolder(dir + "/file").problem, OutputProblem::kIsFile);
    EXPECT_EQ(checkOutputFolder(dir + "/file/report").problem, OutputProblem::kCannotCreate);
    EXPECT_EQ(checkOutputFolder("/proc/rep").problem, OutputProblem::kCannotCreate);
    // The checks leave nothing behind.
    EXPECT_EQ(entries(dir), 1u);
}

}  // namespace
}  // namespace nrad
