// Shards: one bake split among processes that never meet (a farm's array job: Slurm, Kubernetes indexed jobs),
// each writing a part file that the next stage reads; a failed shard is run again alone. Two stages, the first
// optional:
//   1. traced samples: shard K of N traces its share of the points (the blocks an MPI rank K of N would trace)
//      and writes them as a part;
//   2. networks: shard K of N reads every stage-1 part (or, without them, traces every point itself), computes
//      the partition (as every shard does, identically) and trains its share of the networks (the networks an
//      MPI rank K of N would train), writing the asset with only those networks filled in, as a part;
// then mergeNetworkParts fills one asset from all stage-2 parts: the bytes of the one-process bake.
//
// A part file (native little-endian; every shard runs the same build):
//   0  char[8]  "NRADPART"
//   8  u32      version (2; a part of another version is refused)
//   12 u32      kind (ShardPartKind)
//   16 u32      shard index K, 20 u32 shard count N
//   24 u64      scene hash (sceneHash), 32 u64 settings hash (the caller's: every setting that changes the bytes)
//   40 u64      payload size, 48 u32 payload CRC-32, 52 u32 CRC-32 of bytes 0..51
//   56          payload: traced samples: u64 message count, then each message as u64 size and its bytes (what a
//               bake group's allGather would have carried, in call order); networks: u64 count and u32 indices
//               (into the asset's voxels) of the networks this shard trained, then u64 size and the asset's bytes.
#pragma once

#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include <nrad/format.h>

#include "baker/bake/bake_group.h"

namespace nrad {

struct ShardId {
    uint32_t index = 0, count = 1;
};
// "K/N" with 0 <= K < N <= kMaxShards; false if not.
constexpr uint32_t kMaxShards = 65536;
bool parseShardId(const std::string& text, ShardId& id);

constexpr size_t kPartHeaderSize = 56;

enum class ShardPartKind : uint32_t { TracedSamples = 1, Networks = 2 };
const char* shardPartKindName(ShardPartKind kind);

struct ShardPartHeader {
    ShardPartKind kind = ShardPartKind::Networks;
    ShardId shard;
    uint64_t sceneHash = 0, settingsHash = 0;
};

// A part file that is not one, is damaged, or does not belong with the others: what() names the file(s) and
// what is wrong.
class ShardPartError : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

// Writes a part atomically (IoError on failure).
void writeShardPart(const std::string& path, const ShardPartHeader& header, const std::vector<uint8_t>& payload);
// The header of a part file, its payload's CRC checked (read in pieces, not held) unless !verifyPayload (the
// header's own CRC always); ShardPartError if the file is not a part or is damaged, IoError if it cannot be read.
ShardPartHeader readShardPartHeader(const std::string& path, bool verifyPayload = true);

// Checks that `headers` (of files `paths`) are the N shards of one bake, each once: the kind, count, scene and
// settings of `expected` (nullptr: of the first), no index twice, none missing. ShardPartError naming the files
// otherwise.
void checkShardSet(const std::vector<std::string>& paths, const std::vector<ShardPartHeader>& headers,
                   const ShardPartHeader* expected = nullptr);

// Stage 1's messages as a part's payload, and stage 2's (the networks trained and the asset).
std::vector<uint8_t> tracedSamplesPayload(const std::vector<std::vector<uint8_t>>& messages);
std::vector<uint8_t> networksPayload(const std::vector<uint32_t>& trained, const std::vector<uint8_t>& assetBytes);

// A bake group for a shard: rank K of N. With stage-1 parts it first replays them: allGather returns their
// messages, call by call, every shard's in shard order (`traces()` is false: this process traces none of the
// points itself); after startRecording() (and from the start without parts) allGather records what it is given and
// returns nothing (what a stage-1 shard traced; the networks a stage-2 shard trained).
class ShardGroup : public BakeGroup {
public:
    // tracedParts: the stage-1 part files, in shard order (checkShardSet first), each message's size checked
    // against its payload; none: nothing to replay. ShardPartError, IoError.
    ShardGroup(ShardId shard, const std::vector<std::string>& tracedParts);
    ~ShardGroup() override;
    int rank() const override { return int(shard_.index); }
    int size() const override { return int(shard_.count); }
    bool traces() const override { return parts_.empty(); }
    bool exchanges() const override { return true; }
    // ShardPartError where a part runs out of messages.
    std::vector<std::vector<uint8_t>> allGather(const std::vector<uint8_t>& mine) const override;
    // Ends the replay; ShardPartError unless every part's messages were all used.
    void startRecording() const;
    // What allGather recorded, in call order.
    const std::vector<std::vector<uint8_t>>& recorded() const { return recorded_; }

private:
    struct Part;
    ShardId shard_;
    std::vector<std::unique_ptr<Part>> parts_;
    mutable bool recording_ = false;
    mutable std::vector<std::vector<uint8_t>> recorded_;
};

// One asset from the networks' parts of all N shards (`paths`, any order): the asset of shard 0 with every
// network, its scale and its held-out error (in the metadata) taken from the shard that trained it. ShardPartError
// for a missing, duplicated, foreign or damaged part, or parts whose partitions disagree.
format::Asset mergeNetworkParts(const std::vector<std::string>& paths);

}  // namespace nrad
