#include "baker/bake/bake_shard.h"

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>

#include <nlohmann/json.hpp>

#include "baker/util/atomic_file.h"

namespace nrad {
namespace {

constexpr char kMagic[8] = {'N', 'R', 'A', 'D', 'P', 'A', 'R', 'T'};
constexpr uint32_t kPartVersion = 2;  // 2: the traced samples' counts carry the noisy points' extra paths

template <class T>
T load(const uint8_t* p) {
    T v;
    std::memcpy(&v, p, sizeof(T));
    return v;
}
template <class T>
void store(uint8_t* p, T v) {
    std::memcpy(p, &v, sizeof(T));
}

std::string hex(uint64_t v) {
    char s[17];
    std::snprintf(s, sizeof s, "%016llx", (unsigned long long)v);
    return s;
}

std::string shardName(const ShardId& s) { return "shard " + std::to_string(s.index) + " of " + std::to_string(s.count); }

struct PartFile {
    ShardPartHeader header;
    uint64_t payloadSize = 0;
    uint32_t payloadCrc = 0;
};

// The header of `path`, checked, and the stream left at the payload.
PartFile readHeader(const std::string& path, std::ifstream& in) {
    in.open(path, std::ios::binary);
    if (!in) throw IoError(path + ": cannot be read: " + std::strerror(errno));
    uint8_t h[kPartHeaderSize];
    in.read(reinterpret_cast<char*>(h), kPartHeaderSize);
    if (size_t(in.gcount()) < sizeof kMagic || std::memcmp(h, kMagic, sizeof kMagic) != 0)
        throw ShardPartError(path + ": not a part of a shard bake (no NRADPART at its start)");
    if (size_t(in.gcount()) < kPartHeaderSize) throw ShardPartError(path + ": truncated (the header ends early)");
    if (format::crc32(h, 52) != load<uint32_t>(h + 52)) throw ShardPartError(path + ": damaged (header CRC mismatch)");
    if (load<uint32_t>(h + 8) != kPartVersion)
        throw ShardPartError(path + ": a part of version " + std::to_string(load<uint32_t>(h + 8)) + "; this nrad reads version " +
                             std::to_string(kPartVersion));
    PartFile f;
    const uint32_t kind = load<uint32_t>(h + 12);
    if (kind != uint32_t(ShardPartKind::TracedSamples) && kind != uint32_t(ShardPartKind::Networks))
        throw ShardPartError(path + ": unknown part kind " + std::to_string(kind));
    f.header.kind = ShardPartKind(kind);
    f.header.shard = {load<uint32_t>(h + 16), load<uint32_t>(h + 20)};
    if (f.header.shard.count == 0 || f.header.shard.count > kMaxShards || f.header.shard.index >= f.header.shard.count)
        throw ShardPartError(path + ": shard " + std::to_string(f.header.shard.index) + " of " + std::to_string(f.header.shard.count) +
                             " is not a shard");
    f.header.sceneHash = load<uint64_t>(h + 24);
    f.header.settingsHash = load<uint64_t>(h + 32);
    f.payloadSize = load<uint64_t>(h + 40);
    f.payloadCrc = load<uint32_t>(h + 48);
    return f;
}

// The payload, from where `in` stands (its start): its CRC checked, read in pieces; kept in `payload` if given.
void readPayload(const std::string& path, std::ifstream& in, const PartFile& f, std::vector<uint8_t>* payload) {
    std::vector<uint8_t> buffer(size_t(std::min<uint64_t>(f.payloadSize, 1 << 20)));
    if (payload) payload->reserve(size_t(std::min<uint64_t>(f.payloadSize, uint64_t(1) << 32)));
    uint64_t left = f.payloadSize;
    uint32_t crc = 0;
    while (left > 0) {
        const size_t n = size_t(std::min<uint64_t>(left, buffer.size()));
        in.read(reinterpret_cast<char*>(buffer.data()), std::streamsize(n));
        if (size_t(in.gcount()) != n) throw ShardPartError(path + ": truncated (the payload ends early)");
        crc = format::crc32(buffer.data(), n, crc);
        if (payload) payload->insert(payload->end(), buffer.begin(), buffer.begin() + ptrdiff_t(n));
        left -= n;
    }
    if (in.peek() != std::ifstream::traits_type::eof()) throw ShardPartError(path + ": bytes after the payload");
    if (crc != f.payloadCrc) throw ShardPartError(path + ": damaged (payload CRC mismatch)");
}

// The whole payload of `path`, checked; its header into `header`.
std::vector<uint8_t> readPayload(const std::string& path, ShardPartHeader& header) {
    std::ifstream in;
    const PartFile f = readHeader(path, in);
    header = f.header;
    {
        std::ifstream probe(path, std::ios::binary | std::ios::ate);
        if (uint64_t(probe.tellg()) != kPartHeaderSize + f.payloadSize)
            throw ShardPartError(path + ": truncated (" + std::to_string(uint64_t(probe.tellg())) + " bytes, the header announces " +
                                 std::to_string(kPartHeaderSize + f.payloadSize) + ")");
    }
    std::vector<uint8_t> payload;
    readPayload(path, in, f, &payload);
    return payload;
}

}  // namespace

bool parseShardId(const std::string& text, ShardId& id) {
    const size_t slash = text.find('/');
    if (slash == std::string::npos || slash == 0 || slash + 1 == text.size()) return false;
    const std::string k = text.substr(0, slash), n = text.substr(slash + 1);
    if (k.size() > 6 || n.size() > 6 || k.find_first_not_of("0123456789") != std::string::npos ||
        n.find_first_not_of("0123456789") != std::string::npos)
        return false;
    const unsigned long kk = std::stoul(k), nn = std::stoul(n);
    if (nn == 0 || nn > kMaxShards || kk >= nn) return false;
    id = {uint32_t(kk), uint32_t(nn)};
    return true;
}

const char* shardPartKindName(ShardPartKind kind) {
    return kind == ShardPartKind::TracedSamples ? "traced samples (stage 1)" : "networks (stage 2)";
}

void writeShardPart(const std::string& path, const ShardPartHeader& header, const std::vector<uint8_t>& payload) {
    uint8_t h[kPartHeaderSize] = {};
    std::memcpy(h, kMagic, sizeof kMagic);
    store<uint32_t>(h + 8, kPartVersion);
    store<uint32_t>(h + 12, uint32_t(header.kind));
    store<uint32_t>(h + 16, header.shard.index);
    store<uint32_t>(h + 20, header.shard.count);
    store<uint64_t>(h + 24, header.sceneHash);
    store<uint64_t>(h + 32, header.settingsHash);
    store<uint64_t>(h + 40, payload.size());
    store<uint32_t>(h + 48, format::crc32(payload.data(), payload.size()));
    store<uint32_t>(h + 52, format::crc32(h, 52));
    writeFileAtomically(path, [&](const std::string& tmp) {
        std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
        out.write(reinterpret_cast<const char*>(h), kPartHeaderSize);
        out.write(reinterpret_cast<const char*>(payload.data()), std::streamsize(payload.size()));
        out.close();
        if (!out) throw IoError(tmp + ": write failed: " + std::strerror(errno));
    });
}

ShardPartHeader readShardPartHeader(const std::string& path, bool verifyPayload) {
    std::ifstream in;
    const PartFile f = readHeader(path, in);
    if (verifyPayload) readPayload(path, in, f, nullptr);
    return f.header;
}

void checkShardSet(const std::vector<std::string>& paths, const std::vector<ShardPartHeader>& headers, const ShardPartHeader* expected) {
    if (paths.empty()) throw ShardPartError("no parts given");
    const ShardPartHeader& first = expected ? *expected : headers.front();
    const std::string theFirst = expected ? "this bake" : "the first";
    for (size_t i = expected ? 0 : 1; i < headers.size(); ++i) {
        const ShardPartHeader& h = headers[i];
        std::string why;
        if (h.kind != first.kind)
            why = std::string("its kind is ") + shardPartKindName(h.kind) + ", " + theFirst + "'s " + shardPartKindName(first.kind);
        else if (h.shard.count != first.shard.count)
            why = "it is one of " + std::to_string(h.shard.count) + " shards, " + theFirst + " one of " + std::to_string(first.shard.count);
        else if (h.sceneHash != first.sceneHash)
            why = "scene hash " + hex(h.sceneHash) + ", " + theFirst + "'s " + hex(first.sceneHash) + " (another scene or lighting)";
        else if (h.settingsHash != first.settingsHash)
            why = "settings hash " + hex(h.settingsHash) + ", " + theFirst + "'s " + hex(first.settingsHash) + " (other bake settings)";
        if (!why.empty())
            throw ShardPartError(paths[i] + ": " + (expected ? "not of this bake" : "not of the bake of " + paths.front()) + ": " + why);
    }
    std::vector<size_t> at(first.shard.count, SIZE_MAX);
    for (size_t i = 0; i < headers.size(); ++i) {
        size_t& seen = at[headers[i].shard.index];
        if (seen != SIZE_MAX)
            throw ShardPartError(paths[seen] + " and " + paths[i] + " are both " + shardName(headers[i].shard) +
                                 " (each shard once)");
        seen = i;
    }
    std::string missing;
    size_t count = 0;
    for (uint32_t k = 0; k < first.shard.count; ++k)
        if (at[k] == SIZE_MAX) {
            if (++count <= 8) missing += (missing.empty() ? "" : ", ") + std::to_string(k);
        }
    if (count > 0)
        throw ShardPartError(std::string(count == 1 ? "shard " : "shards ") + missing + (count > 8 ? ", ..." : "") + " of " +
                             std::to_string(first.shard.count) + " missing among the parts of " + shardPartKindName(first.kind) +
                             " (" + std::to_string(count) + " of " + std::to_string(first.shard.count) + "): bake " +
                             (count == 1 ? "it with --shard " + missing : "them with --shard K") + "/" +
                             std::to_string(first.shard.count) + (first.kind == ShardPartKind::TracedSamples ? " --trace-only" : ""));
}

std::vector<uint8_t> tracedSamplesPayload(const std::vector<std::vector<uint8_t>>& messages) {
    ByteWriter w;
    w.put<uint64_t>(messages.size());
    for (const std::vector<uint8_t>& m : messages) w.putVector(m);
    return std::move(w.bytes);
}

std::vector<uint8_t> networksPayload(const std::vector<uint32_t>& trained, const std::vector<uint8_t>& assetBytes) {
    ByteWriter w;
    w.putVector(trained);
    w.putVector(assetBytes);
    return std::move(w.bytes);
}

// ----- the shard's group

struct ShardGroup::Part {
    std::string path;
    uint64_t messages = 0, next = 0;  // how many, and which allGather reads next
    uint64_t offset = 0;  // of the next message in the file
};

ShardGroup::ShardGroup(ShardId shard, const std::vector<std::string>& tracedParts) : shard_(shard) {
    for (const std::string& path : tracedParts) {
        auto p = std::make_unique<Part>();
        p->path = path;
        std::ifstream in;
        const PartFile f = readHeader(path, in);
        uint64_t n = 0;
        in.read(reinterpret_cast<char*>(&n), sizeof n);
        if (!in || f.payloadSize < sizeof n) throw ShardPartError(path + ": truncated (no message count)");
        p->messages = n;
        p->offset = kPartHeaderSize + sizeof n;
        // Every message's size within the payload, and the messages the whole payload.
        uint64_t at = sizeof n;
        for (uint64_t m = 0; m < n; ++m) {
            uint64_t bytes = 0;
            in.seekg(std::streamoff(kPartHeaderSize + at));
            in.read(reinterpret_cast<char*>(&bytes), sizeof bytes);
            if (!in || bytes > f.payloadSize - at - sizeof bytes || f.payloadSize - at < sizeof bytes)
                throw ShardPartError(path + ": damaged (message " + std::to_string(m) + " runs past the payload)");
            at += sizeof bytes + bytes;
        }
        if (at != f.payloadSize) throw ShardPartError(path + ": damaged (bytes after its last message)");
        if (!parts_.empty() && n != parts_.front()->messages)
            throw ShardPartError(path + ": " + std::to_string(n) + " messages, " + parts_.front()->path + " " +
                                 std::to_string(parts_.front()->messages) + " (parts of different bakes)");
        parts_.push_back(std::move(p));
    }
}

ShardGroup::~ShardGroup() = default;

std::vector<std::vector<uint8_t>> ShardGroup::allGather(const std::vector<uint8_t>& mine) const {
    if (parts_.empty() || recording_) {
        recorded_.push_back(mine);
        return {};
    }
    std::vector<std::vector<uint8_t>> all;
    for (const std::unique_ptr<Part>& p : parts_) {
        if (p->next == p->messages)
            throw ShardPartError(p->path + ": " + std::to_string(p->messages) + " messages, fewer than this bake's tracing sends "
                                 "(a part of another nrad build?)");
        std::ifstream in(p->path, std::ios::binary);
        in.seekg(std::streamoff(p->offset));
        uint64_t n = 0;
        in.read(reinterpret_cast<char*>(&n), sizeof n);
        if (!in || n > (uint64_t(1) << 40)) throw ShardPartError(p->path + ": truncated (a message ends early)");
        std::vector<uint8_t> m(static_cast<size_t>(n));
        in.read(reinterpret_cast<char*>(m.data()), std::streamsize(n));
        if (size_t(in.gcount()) != m.size()) throw ShardPartError(p->path + ": truncated (a message ends early)");
        p->offset += sizeof n + n;
        ++p->next;
        all.push_back(std::move(m));
    }
    return all;
}

void ShardGroup::startRecording() const {
    for (const std::unique_ptr<Part>& p : parts_)
        if (p->next != p->messages)
            throw ShardPartError(p->path + ": " + std::to_string(p->messages) + " messages, more than this bake's tracing sends "
                                 "(a part of another nrad build?)");
    recording_ = true;
}

// ----- merge

format::Asset mergeNetworkParts(const std::vector<std::string>& paths) {
    std::vector<ShardPartHeader> headers(paths.size());
    for (size_t i = 0; i < paths.size(); ++i) {  // every header first (a part at a time is held after that)
        headers[i] = readShardPartHeader(paths[i], false);
        if (headers[i].kind != ShardPartKind::Networks)
            throw ShardPartError(paths[i] + ": a part of " + shardPartKindName(headers[i].kind) +
                                 "; merge takes the networks' parts (bake --shard K/N without --trace-only)");
    }
    checkShardSet(paths, headers);
    std::vector<size_t> order(paths.size());  // part of shard k
    for (size_t i = 0; i < paths.size(); ++i) order[headers[i].shard.index] = i;

    format::Asset merged;
    std::vector<uint8_t> owned;  // per network: 1 once a shard trained it
    nlohmann::json meta;
    nlohmann::json heldOut;
    for (size_t k = 0; k < order.size(); ++k) {
        const std::string& path = paths[order[k]];
        ShardPartHeader header;
        const std::vector<uint8_t> payload = readPayload(path, header);
        ByteReader in(payload);
        std::vector<uint32_t> trained;
        std::vector<uint8_t> bytes;
        try {
            trained = in.getVector<uint32_t>();
            bytes = in.getVector<uint8_t>();
        } catch (const std::runtime_error&) {
            throw ShardPartError(path + ": damaged (its payload ends early)");
        }
        format::Asset a;
        const format::DecodeStatus status = format::decode(bytes.data(), bytes.size(), a);
        if (status != format::DecodeStatus::Ok)
            throw ShardPartError(path + ": its asset does not decode: " + format::decodeStatusString(status));
        nlohmann::json m = a.metadata.empty() ? nlohmann::json() : nlohmann::json::parse(a.metadata, nullptr, false);
        if (m.is_discarded()) throw ShardPartError(path + ": its asset's metadata is not JSON");
        nlohmann::json h;
        if (m.is_object() && m.contains("held_out_relmse")) {
            h = m["held_out_relmse"];
            m.erase("held_out_relmse");
            bool numbers = h.is_array() && h.size() == a.voxels.size();
            for (size_t v = 0; numbers && v < h.size(); ++v) numbers = h[v].is_number() || h[v].is_null();
            if (!numbers) throw ShardPartError(path + ": its held-out errors are not a number per network");
        }
        if (k > 0 && h.is_null() != heldOut.is_null())
            throw ShardPartError(path + ": " + (h.is_null() ? "no held-out errors where " + paths[order[0]] + " has them"
                                                              : "held-out errors where " + paths[order[0]] + " has none"));
        const size_t per = a.topology.parameterCount();
        if (k == 0) {
            merged = a;
            meta = m;
            heldOut = h;
            owned.assign(a.voxels.size(), 0);
        } else {
            // Every shard computed the same partition: anything else is a part of another build or a damaged one.
            const bool same = a.header.flags == merged.header.flags && std::memcmp(&a.grid, &merged.grid, sizeof a.grid) == 0 &&
                              a.topology.hiddenWidths == merged.topology.hiddenWidths &&
                              a.topology.weightEncoding == merged.topology.weightEncoding &&
                              a.topology.outputTransform == merged.topology.outputTransform &&
                              a.voxels.size() == merged.voxels.size() && a.leafCount == merged.leafCount &&
                              a.tree.size() == merged.tree.size() && m == meta &&
                              a.volumeWeights == merged.volumeWeights &&  // (every shard trains the volume whole)
                              a.glossyWeights == merged.glossyWeights;
            bool sameCells = same;
            for (size_t v = 0; sameCells && v < a.voxels.size(); ++v) sameCells = a.voxels[v].index == merged.voxels[v].index;
            sameCells = sameCells && a.volumeVoxels.size() == merged.volumeVoxels.size();
            for (size_t v = 0; sameCells && v < a.volumeVoxels.size(); ++v)
                sameCells = a.volumeVoxels[v].index == merged.volumeVoxels[v].index && a.volumeVoxels[v].scale == merged.volumeVoxels[v].scale;
            sameCells = sameCells && a.glossyVoxels.size() == merged.glossyVoxels.size();
            for (size_t v = 0; sameCells && v < a.glossyVoxels.size(); ++v)
                sameCells = a.glossyVoxels[v].index == merged.glossyVoxels[v].index && a.glossyVoxels[v].scale == merged.glossyVoxels[v].scale;
            for (size_t t = 0; sameCells && t < a.tree.size(); ++t)
                sameCells = a.tree[t].axis == merged.tree[t].axis && a.tree[t].split == merged.tree[t].split &&
                            a.tree[t].child == merged.tree[t].child && a.tree[t].hard == merged.tree[t].hard;
            if (!sameCells)
                throw ShardPartError(path + ": its partition or settings differ from " + paths[order[0]] +
                                     "'s (every shard of a bake computes the same; parts of different nrad builds?)");
        }
        for (uint32_t v : trained) {
            if (v >= merged.voxels.size() || owned[v])
                throw ShardPartError(path + ": network " + std::to_string(v) + (v >= merged.voxels.size() ? " out of range" : " trained by two shards"));
            owned[v] = 1;
            merged.voxels[v].scale = a.voxels[v].scale;
            std::copy(a.weights.begin() + ptrdiff_t(v * per), a.weights.begin() + ptrdiff_t((v + 1) * per),
                      merged.weights.begin() + ptrdiff_t(v * per));
            if (!heldOut.is_null()) heldOut[v] = h[v];
        }
    }
    for (size_t v = 0; v < owned.size(); ++v)
        if (!owned[v]) throw ShardPartError("network " + std::to_string(v) + " was trained by no shard (parts of different nrad builds?)");
    if (!heldOut.is_null()) meta["held_out_relmse"] = heldOut;
    if (!merged.metadata.empty()) merged.metadata = meta.dump();
    return merged;
}

}  // namespace nrad
