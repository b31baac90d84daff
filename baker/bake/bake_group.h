// The processes one bake runs on: MPI ranks (baker/dist/), or this process alone. bakeScene asks them for
// two things only: its share of a list of work, and everyone's results, in rank order, on every process.
// Every process computes what is not shared (the points, the partition) identically, so a bake on any number
// of processes gives the bytes of the one-process bake.
#pragma once

#include <cstddef>
#include <cstdint>
#include <algorithm>
#include <cstring>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

namespace nrad {

class BakeGroup {
public:
    virtual ~BakeGroup() = default;
    virtual int rank() const = 0;
    virtual int size() const = 0;
    // Every process's bytes, in rank order, on every process (collective: every process calls it, in the same order).
    // Nothing (an empty list) where the processes do not meet: a shard that records what it would send (bake_shard.h).
    virtual std::vector<std::vector<uint8_t>> allGather(const std::vector<uint8_t>& mine) const = 0;
    // Whether this process traces its share of the points; false: allGather hands it every process's, its own
    // included (a shard replaying the traced samples of a first stage).
    virtual bool traces() const { return true; }
    // Whether allGather is called at all: with other processes, or for a shard, which records or replays.
    virtual bool exchanges() const { return size() > 1; }
    // Seconds spent in allGather so far: waiting for the other processes, then exchanging.
    virtual double exchangeSeconds() const { return 0.0; }
};

// Whether this process was started by an MPI launcher (Open MPI's mpirun, or PMI/PMIx: Slurm's srun).
bool launchedByMpi();

// Items [first, last) of a list.
struct Share {
    size_t first = 0, last = 0;
};

// Items [0, count) in blocks of `block`, block b to process b % size: each process's share spread over the whole
// list (points in list order are near each other in the scene and cost alike, so contiguous shares are unequal).
struct BlockShares {
    size_t count = 0, block = 1;
    int size = 1;
    size_t blocks() const { return (count + block - 1) / block; }
    // The blocks of process `rank`, and its j-th one.
    size_t blocksOf(int rank) const {
        const size_t n = blocks(), r = size_t(rank), s = size_t(size);
        return n > r ? (n - r + s - 1) / s : 0;
    }
    Share blockOf(int rank, size_t j) const {
        const size_t b = j * size_t(size) + size_t(rank);
        return {b * block, std::min(count, (b + 1) * block)};
    }
};

// The owner of each item: largest cost first (equal costs: lower index first), each to the process with the
// least cost so far (equal: the lower rank). The same on every process.
std::vector<int> assignByCost(const std::vector<double>& costs, int size);

// Bytes in, bytes out: trivially copyable values and vectors of them, native layout (every process of a bake
// runs the same build on the same architecture).
class ByteWriter {
public:
    template <class T>
    void put(const T& v) {
        static_assert(std::is_trivially_copyable_v<T>);
        const auto* p = reinterpret_cast<const uint8_t*>(&v);
        bytes.insert(bytes.end(), p, p + sizeof(T));
    }
    template <class T>
    void putVector(const std::vector<T>& v) {
        static_assert(std::is_trivially_copyable_v<T>);
        put<uint64_t>(v.size());
        const auto* p = reinterpret_cast<const uint8_t*>(v.data());
        bytes.insert(bytes.end(), p, p + v.size() * sizeof(T));
    }
    void putString(const std::string& s) {
        put<uint64_t>(s.size());
        bytes.insert(bytes.end(), s.begin(), s.end());
    }
    std::vector<uint8_t> bytes;
};

class ByteReader {
public:
    explicit ByteReader(const std::vector<uint8_t>& bytes) : bytes_(bytes) {}
    template <class T>
    T get() {
        static_assert(std::is_trivially_copyable_v<T>);
        T v;
        std::memcpy(&v, take(sizeof(T)), sizeof(T));
        return v;
    }
    template <class T>
    std::vector<T> getVector() {
        const uint64_t n = get<uint64_t>();
        if (n > (bytes_.size() - at_) / sizeof(T)) throw std::runtime_error("bake group: truncated message");
        std::vector<T> v(n);
        if (n) std::memcpy(v.data(), take(n * sizeof(T)), n * sizeof(T));
        return v;
    }
    std::string getString() {
        const uint64_t n = get<uint64_t>();
        const uint8_t* p = take(n);
        return std::string(reinterpret_cast<const char*>(p), n);
    }
    bool done() const { return at_ == bytes_.size(); }

private:
    const uint8_t* take(size_t n) {
        if (n > bytes_.size() - at_) throw std::runtime_error("bake group: truncated message");
        const uint8_t* p = bytes_.data() + at_;
        at_ += n;
        return p;
    }
    const std::vector<uint8_t>& bytes_;
    size_t at_ = 0;
};

}  // namespace nrad
