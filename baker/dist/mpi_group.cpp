#include "baker/dist/mpi_group.h"

#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <stdexcept>

#include <mpi.h>

namespace nrad {

MpiGroup::MpiGroup() {
    int provided = 0;
    if (MPI_Init_thread(nullptr, nullptr, MPI_THREAD_FUNNELED, &provided) != MPI_SUCCESS)
        throw std::runtime_error("MPI_Init_thread failed");
    MPI_Comm_rank(MPI_COMM_WORLD, &rank_);
    MPI_Comm_size(MPI_COMM_WORLD, &size_);
}

MpiGroup::~MpiGroup() { MPI_Finalize(); }

int MpiGroup::processesOnThisMachine() const {
    MPI_Comm local;
    if (MPI_Comm_split_type(MPI_COMM_WORLD, MPI_COMM_TYPE_SHARED, rank_, MPI_INFO_NULL, &local) != MPI_SUCCESS) return 1;
    int n = 1;
    MPI_Comm_size(local, &n);
    MPI_Comm_free(&local);
    return n;
}

std::vector<std::vector<uint8_t>> MpiGroup::allGather(const std::vector<uint8_t>& mine) const {
    const double start = MPI_Wtime();
    const size_t n = size_t(size_);
    uint64_t own = mine.size();
    std::vector<uint64_t> sizes(n);
    MPI_Allgather(&own, 1, MPI_UINT64_T, sizes.data(), 1, MPI_UINT64_T, MPI_COMM_WORLD);
    std::vector<std::vector<uint8_t>> all(n);
    for (size_t r = 0; r < n; ++r) all[r].resize(size_t(sizes[r]));
    // In rounds of at most 1 GiB from each process, and 2 GiB in all (MPI's counts and offsets are int), until
    // every process has sent all.
    const uint64_t kPiece = std::min<uint64_t>(uint64_t(1) << 30, uint64_t(INT32_MAX) / n);
    const uint64_t longest = *std::max_element(sizes.begin(), sizes.end());
    std::vector<int> counts(n), offsets(n);
    std::vector<uint8_t> buffer;
    for (uint64_t at = 0; at < longest; at += kPiece) {
        size_t total = 0;
        for (size_t r = 0; r < n; ++r) {
            counts[r] = int(std::min(kPiece, sizes[r] - std::min(at, sizes[r])));
            offsets[r] = int(total);
            total += size_t(counts[r]);
        }
        buffer.resize(total);
        MPI_Allgatherv(mine.data() + std::min<uint64_t>(at, own), counts[size_t(rank_)], MPI_BYTE, buffer.data(), counts.data(),
                       offsets.data(), MPI_BYTE, MPI_COMM_WORLD);
        for (size_t r = 0; r < n; ++r)
            std::copy(buffer.begin() + offsets[r], buffer.begin() + offsets[r] + counts[r], all[r].begin() + ptrdiff_t(at));
    }
    seconds_ += MPI_Wtime() - start;
    return all;
}

}  // namespace nrad
