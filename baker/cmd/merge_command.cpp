// `nrad merge`: the parts of a shard bake (bake --shard K/N) -> one .nrad asset, the one-process bake's bytes.
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include <nrad/format.h>

#include "baker/bake/bake_shard.h"
#include "baker/cmd/commands.h"
#include "baker/util/atomic_file.h"

namespace nrad {

namespace {

struct MergeOptions {
    std::vector<std::string> parts;
    std::string output;
    bool quiet = false;
};

int runMerge(const MergeOptions& o) {
    if (int code = checkOutputsForCommand("merge", {o.output})) return code;
    format::Asset asset;
    try {
        asset = mergeNetworkParts(o.parts);
    } catch (const ShardPartError& e) {
        std::fprintf(stderr, "nrad merge: %s\n", e.what());
        return kExitBadInput;
    } catch (const IoError& e) {  // a part that cannot be read
        std::fprintf(stderr, "nrad merge: %s\n", e.what());
        return kExitBadInput;
    }
    const std::vector<uint8_t> bytes = format::encode(asset);
    try {
        writeBytesAtomically(o.output, bytes);
    } catch (const IoError& e) {
        std::fprintf(stderr, "nrad merge: %s\n", e.what());
        return kExitIo;
    }
    if (!o.quiet)
        std::printf("merged %zu parts -> %s: %zu bytes, %zu networks\n", o.parts.size(), o.output.c_str(), bytes.size(),
                    asset.voxels.size());
    return kExitOk;
}

}  // namespace

std::function<int()> addMergeCommand(CLI::App& app) {
    auto o = std::make_shared<MergeOptions>();
    CLI::App* cmd = app.add_subcommand("merge", "Merge the parts of a shard bake (bake --shard K/N) into one asset (.nrad)");
    cmd->add_option("parts", o->parts, "The networks' parts of all N shards, each once (any order)")->required();
    cmd->add_option("-o,--output", o->output, "Output asset (.nrad)")->required();
    cmd->add_flag("-q,--quiet", o->quiet, "No summary line");
    return [o]() { return runMerge(*o); };
}

}  // namespace nrad
