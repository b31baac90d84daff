// `nrad bake --shard K/N` and `nrad merge`: shards run as separate processes, in one stage or two, merge into the
// one-process bake's bytes; a shard run again writes the same part; merge and the second stage refuse missing,
// duplicated, foreign and damaged parts with exact messages and leave no output.
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "baker/bake/bake_shard.h"
#include "support/test_paths.h"

namespace nrad {
namespace {

namespace fs = std::filesystem;

using test::fileBytes;
using test::runCommand;

std::string exe() { return "'" + test::nradExecutable() + "'"; }

// A small bake of the Cornell box (under a second), with the flags of each kind.
std::string bake(const std::string& flags, const std::string& out) {
    return exe() + " bake '" + test::sourcePath("scenes/cornell-box/cornell-box.gltf") + "' -o '" + out +
           "' -q --points 12000 --paths 4 --epochs 80 --patience 30 " + flags;
}

std::string merge(const std::vector<std::string>& parts, const std::string& out) {
    std::string c = exe() + " merge -o '" + out + "'";
    for (const std::string& p : parts) c += " '" + p + "'";
    return c;
}

// Runs `command`, expecting exit code `code`; returns its output.
std::string expectExit(const std::string& command, int code) {
    const test::CommandResult r = runCommand(command);
    EXPECT_EQ(r.exitCode, code) << command << "\n" << r.output;
    return r.output;
}

class ShardBake : public testing::TestWithParam<const char*> {};

TEST_P(ShardBake, ShardsInOneOrTwoStagesMergeIntoTheOneProcessBytes) {
    const std::string dir = test::temporaryDirectory(), plain = dir + "/plain.nrad";
    expectExit(bake(GetParam(), plain) + " --threads 2", 0);
    const std::string expected = fileBytes(plain);
    ASSERT_GT(expected.size(), 1000u);

    // One stage: every shard traces every point, trains its share of the networks.
    std::vector<std::string> parts;
    for (int k : {2, 0, 1}) {  // any order, as a farm runs them
        parts.push_back(dir + "/one-" + std::to_string(k) + ".part");
        expectExit(bake(GetParam(), parts.back()) + " --threads 1 --shard " + std::to_string(k) + "/3", 0);
    }
    expectExit(merge(parts, dir + "/one.nrad"), 0);
    EXPECT_TRUE(fileBytes(dir + "/one.nrad") == expected) << "one-stage shards merged differ from the one-process bake";

    // Two stages: each shard traces its share of the points, then each trains its networks on all of them.
    fs::create_directory(dir + "/traced");
    for (int k = 0; k < 4; ++k)
        expectExit(bake(GetParam(), dir + "/traced/t" + std::to_string(k) + ".part") + " --threads 1 --trace-only --shard " +
                       std::to_string(k) + "/4",
                   0);
    parts.clear();
    for (int k = 0; k < 4; ++k) {
        parts.push_back(dir + "/two-" + std::to_string(k) + ".part");
        expectExit(bake(GetParam(), parts.back()) + " --threads 2 --traced '" + dir + "/traced' --shard " + std::to_string(k) + "/4", 0);
    }
    expectExit(merge(parts, dir + "/two.nrad"), 0);
    EXPECT_TRUE(fileBytes(dir + "/two.nrad") == expected) << "two-stage shards merged differ from the one-process bake";

    // A failed shard is run again alone: the same part, whatever its threads.
    const std::string again = dir + "/again.part";
    expectExit(bake(GetParam(), again) + " --threads 1 --traced '" + dir + "/traced' --shard 1/4", 0);
    EXPECT_TRUE(fileBytes(again) == fileBytes(parts[1])) << "a shard run again wrote other bytes";
}

std::string kindName(const testing::TestParamInfo<const char*>& p) {
    static const char* const names[] = {"Grid", "Budget", "Volume", "BudgetVolume"};
    return names[p.index];
}

INSTANTIATE_TEST_SUITE_P(Kinds, ShardBake,
                         testing::Values("", "--budget 12K", "--volume-points 60 --volume-paths 2 --nee learned",
                                         "--budget 12K --volume-points 60 --volume-paths 2"),
                         kindName);

// The parts of a two-shard grid bake, made once for the refusal tests.
class ShardParts : public testing::Test {
protected:
    static void SetUpTestSuite() {
        dir_ = new std::string(test::temporaryDirectory());
        fs::create_directory(*dir_ + "/traced");
        for (int k = 0; k < 2; ++k) {
            expectExit(bake("", part(k)) + " --shard " + std::to_string(k) + "/2", 0);
            expectExit(bake("", traced(k)) + " --trace-only --shard " + std::to_string(k) + "/2", 0);
        }
        expectExit(bake("--seed 7", *dir_ + "/other-seed-1.part") + " --shard 1/2", 0);
        expectExit(bake("", *dir_ + "/of-three-1.part") + " --shard 1/3", 0);
    }
    static void TearDownTestSuite() { delete dir_; }
    static std::string part(int k) { return *dir_ + "/part-" + std::to_string(k) + ".part"; }
    static std::string traced(int k) { return *dir_ + "/traced/t" + std::to_string(k) + ".part"; }
    static std::string dir() { return *dir_; }
    // merge of `parts` refused with exit code 3 and `message`, and no asset written.
    static void expectRefused(const std::vector<std::string>& parts, const std::string& message) {
        const std::string out = dir() + "/merged.nrad";
        const std::string output = expectExit(merge(parts, out), 3);
        EXPECT_EQ(output, "nrad merge: " + message + "\n");
        EXPECT_FALSE(fs::exists(out));
    }
    static std::string* dir_;
};
std::string* ShardParts::dir_ = nullptr;

TEST_F(ShardParts, MergeRefusesAMissingPart) {
    expectRefused({part(1)}, "shard 0 of 2 missing among the parts of networks (stage 2) (1 of 2): bake it with --shard 0/2");
}

TEST_F(ShardParts, MergeRefusesADuplicatedPart) {
    const std::string copy = dir() + "/copy-1.part";
    fs::copy_file(part(1), copy, fs::copy_options::overwrite_existing);
    expectRefused({part(0), part(1), copy}, part(1) + " and " + copy + " are both shard 1 of 2 (each shard once)");
}

TEST_F(ShardParts, MergeRefusesForeignParts) {
    const std::string output = expectExit(merge({part(0), dir() + "/other-seed-1.part"}, dir() + "/merged.nrad"), 3);
    EXPECT_EQ(output.find("nrad merge: " + dir() + "/other-seed-1.part: not of the bake of " + part(0) + ": settings hash "), 0u) << output;
    EXPECT_NE(output.find("(other bake settings)"), std::string::npos) << output;
    expectRefused({part(0), dir() + "/of-three-1.part"},
                  dir() + "/of-three-1.part: not of the bake of " + part(0) + ": it is one of 3 shards, the first one of 2");
    expectRefused({part(0), traced(1)}, traced(1) + ": a part of traced samples (stage 1); merge takes the networks' parts "
                                                    "(bake --shard K/N without --trace-only)");
    const std::string asset = dir() + "/plain.nrad";
    expectExit(bake("", asset), 0);
    expectRefused({part(0), asset}, asset + ": not a part of a shard bake (no NRADPART at its start)");
}

TEST_F(ShardParts, MergeRefusesDamagedParts) {
    const std::string bytes = fileBytes(part(1));
    const std::string bad = dir() + "/damaged-1.part";
    std::string flipped = bytes;
    flipped[bytes.size() / 2] = char(flipped[bytes.size() / 2] ^ 0x10);
    std::ofstream(bad, std::ios::binary).write(flipped.data(), std::streamsize(flipped.size()));
    expectRefused({part(0), bad}, bad + ": damaged (payload CRC mismatch)");
    std::ofstream(bad, std::ios::binary | std::ios::trunc).write(bytes.data(), std::streamsize(bytes.size() - 9));
    expectRefused({part(0), bad}, bad + ": truncated (" + std::to_string(bytes.size() - 9) + " bytes, the header announces " +
                                      std::to_string(bytes.size()) + ")");
    std::ofstream(bad, std::ios::binary | std::ios::trunc).write(bytes.data(), 30);
    expectRefused({part(0), bad}, bad + ": truncated (the header ends early)");
}

TEST_F(ShardParts, APartIsNotAnAsset) {
    const std::string output = expectExit(exe() + " info '" + part(0) + "'", 3);
    EXPECT_NE(output.find(part(0) + ": "), std::string::npos) << output;
}

TEST_F(ShardParts, TheSecondStageRefusesAMissingOrForeignTracedPart) {
    const std::string traced = dir() + "/traced", out = dir() + "/stage2.part";
    EXPECT_EQ(expectExit(bake("", out) + " --traced '" + traced + "' --shard 0/3", 3),
              "nrad bake: " + traced + "/t0.part: not of this bake: it is one of 2 shards, this bake one of 3\n");
    const std::string lone = dir() + "/lone";
    fs::create_directory(lone);
    fs::copy_file(this->traced(1), lone + "/t1.part");
    fs::copy_file(part(0), lone + "/part-0.part");  // networks' parts in the folder are passed over
    EXPECT_EQ(expectExit(bake("", out) + " --traced '" + lone + "' --shard 0/2", 3),
              "nrad bake: shard 0 of 2 missing among the parts of traced samples (stage 1) (1 of 2): bake it with --shard 0/2 "
              "--trace-only\n");
    EXPECT_EQ(expectExit(bake("--seed 7", out) + " --traced '" + traced + "' --shard 0/2", 3).find("nrad bake: " + traced +
                                                                                                    "/t0.part: not of this bake: settings hash "),
              0u);
    EXPECT_FALSE(fs::exists(out));
}

TEST(ShardFlags, AreRefusedWhereTheyCannotWork) {
    const std::string dir = test::temporaryDirectory(), out = dir + "/x.part";
    EXPECT_EQ(expectExit(bake("--training integral --generations 2", out) + " --shard 0/2", 2),
              "nrad bake: --shard: shards bake with Monte Carlo training only: training within the integral equation exchanges "
              "the networks between its rounds (bake it on MPI processes with mpirun, or shard it with --training monte-carlo)\n");
    for (const char* bad : {"2/2", "1", "0/0", "a/b", "0/65537"})
        EXPECT_EQ(expectExit(bake("", out) + " --shard " + bad, 2),
                  std::string("nrad bake: --shard ") + bad + ": not K/N with 0 <= K < N <= 65536 (shard K of N, counted from 0)\n");
    EXPECT_EQ(expectExit(bake("", out) + " --trace-only", 2), "nrad bake: --trace-only needs --shard K/N\n");
    EXPECT_EQ(expectExit(bake("", out) + " --traced " + dir, 2), "nrad bake: --traced needs --shard K/N\n");
    EXPECT_EQ(expectExit(bake("", out) + " --trace-only --traced " + dir + " --shard 0/2", 2),
              "nrad bake: --trace-only (stage 1) and --traced (stage 2) are two runs of a shard, not one\n");
    EXPECT_FALSE(fs::exists(out));
}

// Parts whose CRC is right but whose messages are not what a bake sends (forged, or of another build).
TEST(ShardGroupReplay, RefusesMessagesThatDoNotFit) {
    const std::string dir = test::temporaryDirectory(), path = dir + "/t0.part";
    ShardPartHeader h;
    h.kind = ShardPartKind::TracedSamples;
    h.shard = {0, 1};
    ByteWriter w;  // one message announcing more bytes than the payload holds
    w.put<uint64_t>(1);
    w.put<uint64_t>(uint64_t(1) << 39);
    writeShardPart(path, h, w.bytes);
    try {
        ShardGroup group({0, 1}, {path});
        FAIL() << "a message running past the payload was accepted";
    } catch (const ShardPartError& e) {
        EXPECT_EQ(std::string(e.what()), path + ": damaged (message 0 runs past the payload)");
    }
    writeShardPart(path, h, tracedSamplesPayload({{1, 2, 3}}));  // one message: a replay of two calls runs short
    {
        const ShardGroup group({0, 1}, {path});
        EXPECT_FALSE(group.traces());
        const std::vector<std::vector<uint8_t>> first = group.allGather({});
        ASSERT_EQ(first.size(), 1u);
        EXPECT_EQ(first[0], (std::vector<uint8_t>{1, 2, 3}));
        EXPECT_THROW(group.allGather({}), ShardPartError);
    }
    {
        const ShardGroup group({0, 1}, {path});  // a message left unused when the recording starts
        EXPECT_THROW(group.startRecording(), ShardPartError);
    }
    {
        const ShardGroup group({0, 1}, {path});
        group.allGather({});
        group.startRecording();
        EXPECT_TRUE(group.allGather({7}).empty());
        EXPECT_EQ(group.recorded(), (std::vector<std::vector<uint8_t>>{{7}}));
    }
}

TEST(ShardId, ParsesKOfN) {
    ShardId id;
    ASSERT_TRUE(parseShardId("0/1", id));
    EXPECT_EQ(id.index, 0u);
    EXPECT_EQ(id.count, 1u);
    ASSERT_TRUE(parseShardId("511/512", id));
    EXPECT_EQ(id.index, 511u);
    EXPECT_EQ(id.count, 512u);
    for (const char* bad : {"", "/", "1/", "/1", "1/1", "3/2", "0/0", "0/65537", "1 /2", "+1/2", "1/2/3", "9999999/99999999"})
        EXPECT_FALSE(parseShardId(bad, id)) << bad;
}

}  // namespace
}  // namespace nrad
