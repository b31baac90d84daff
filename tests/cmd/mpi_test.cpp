// `mpirun -n N nrad bake`: the bytes of the one-process bake for any number of processes (grid, budget and
// integral bakes), and a process killed mid-bake ends the launch with an error and no asset.
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "support/test_paths.h"

namespace nrad {
namespace {

namespace fs = std::filesystem;

using test::runCommand;
using test::fileBytes;

// mpirun as CI runs it: as root it must be allowed, two cores take three processes, and no process is bound
// to one core (each bakes with its threads).
std::string mpirun(int processes) {
    return "mpirun --allow-run-as-root --oversubscribe --bind-to none -n " + std::to_string(processes) + " ";
}

std::string exe() { return "'" + test::nradExecutable() + "'"; }

// A small bake of the Cornell box (a few seconds), with the flags of each kind.
std::string bakeArgs(const std::string& flags, const std::string& out) {
    return " bake '" + test::sourcePath("scenes/cornell-box/cornell-box.gltf") + "' -o '" + out +
           "' -q --points 12000 --paths 4 --epochs 80 --patience 30 " + flags;
}

class MpiBake : public testing::TestWithParam<const char*> {};

TEST_P(MpiBake, OneTwoAndThreeProcessesWriteTheOneProcessBytes) {
    ASSERT_EQ(runCommand("mpirun --version").exitCode, 0) << "mpirun is missing (./run.sh installs openmpi-bin)";
    const std::string dir = test::temporaryDirectory(), plain = dir + "/plain.nrad";
    test::CommandResult r = runCommand(exe() + bakeArgs(GetParam(), plain) + " --threads 2");
    ASSERT_EQ(r.exitCode, 0) << r.output;
    const std::string expected = fileBytes(plain);
    ASSERT_GT(expected.size(), 1000u);
    for (int n : {1, 2, 3}) {
        const std::string out = dir + "/mpi" + std::to_string(n) + ".nrad";
        r = runCommand(mpirun(n) + exe() + bakeArgs(GetParam(), out) + " --threads 1");
        ASSERT_EQ(r.exitCode, 0) << n << " processes: " << r.output;
        EXPECT_TRUE(fileBytes(out) == expected) << n << " processes: the asset differs from the one-process bake";
        if (n > 1) {
            EXPECT_NE(r.output.find("processes: " + std::to_string(n) + " (MPI)"), std::string::npos) << r.output;
        }
        // One summary line: only the first process prints.
        size_t lines = 0;
        for (size_t at = r.output.find("baked "); at != std::string::npos; at = r.output.find("baked ", at + 1)) ++lines;
        EXPECT_EQ(lines, 1u) << r.output;
    }
}

INSTANTIATE_TEST_SUITE_P(Kinds, MpiBake,
                         testing::Values("", "--budget 12K", "--training integral --generations 2 --generation-points 6000",
                                         "--volume-points 60 --volume-paths 2"),
                         [](const testing::TestParamInfo<const char*>& p) {
                             return std::string(p.index == 0 ? "Grid" : p.index == 1 ? "Budget" : p.index == 2 ? "Integral" : "Volume");
                         });

// The processes of the running launch whose command line names `marker`, and the rank of each.
std::vector<std::pair<pid_t, int>> ranksNaming(const std::string& marker) {
    std::vector<std::pair<pid_t, int>> found;
    for (const fs::directory_entry& e : fs::directory_iterator("/proc")) {
        const std::string name = e.path().filename().string();
        if (name.find_first_not_of("0123456789") != std::string::npos) continue;
        std::string cmdline = fileBytes(e.path().string() + "/cmdline"), environ = fileBytes(e.path().string() + "/environ");
        if (cmdline.find(marker) == std::string::npos || cmdline.find("mpirun") != std::string::npos) continue;
        const std::string key = std::string("OMPI_COMM_WORLD_RANK=");
        const size_t at = environ.find(key);
        if (at == std::string::npos) continue;
        found.push_back({pid_t(std::stol(name)), std::atoi(environ.c_str() + at + key.size())});
    }
    return found;
}

TEST(Mpi, AProcessKilledMidBakeEndsTheLaunchWithAnErrorAndNoAsset) {
    const std::string dir = test::temporaryDirectory(), out = dir + "/killed.nrad", log = dir + "/log.txt";
    // A bake of tens of seconds on one thread per process, started in the background.
    const std::string cmd = mpirun(2) + exe() + " bake '" + test::sourcePath("scenes/cornell-box/cornell-box.gltf") + "' -o '" + out +
                            "' -q --threads 1 > '" + log + "' 2>&1";
    const pid_t child = fork();
    ASSERT_GE(child, 0);
    if (child == 0) {
        execl("/bin/sh", "sh", "-c", cmd.c_str(), static_cast<char*>(nullptr));
        _exit(127);
    }
    pid_t victim = 0;
    for (int i = 0; i < 200 && victim == 0; ++i) {  // up to 20 s for the processes to start
        std::this_thread::sleep_for(std::chrono::milliseconds(100));
        for (auto [pid, rank] : ranksNaming(out))
            if (rank == 1) victim = pid;
    }
    ASSERT_NE(victim, 0) << fileBytes(log);
    std::this_thread::sleep_for(std::chrono::seconds(2));  // well into the sampling
    ASSERT_EQ(kill(victim, SIGKILL), 0);
    int status = 0;
    ASSERT_EQ(waitpid(child, &status, 0), child);
    const std::string output = fileBytes(log);
    EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) != 0) << output;
    EXPECT_FALSE(fs::exists(out)) << output;
    for (const fs::directory_entry& e : fs::directory_iterator(dir))  // no partial file either
        EXPECT_EQ(e.path().filename().string().find("killed.nrad"), std::string::npos) << e.path();
    EXPECT_NE(output.find("rank 1"), std::string::npos) << "the launcher does not say which process ended: " << output;
    EXPECT_NE(output.find("signal 9"), std::string::npos) << output;
    EXPECT_TRUE(ranksNaming(out).empty()) << "processes of the launch are left running";
}

}  // namespace
}  // namespace nrad
