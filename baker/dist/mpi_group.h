// The processes of an MPI launch (`mpirun -n N nrad bake ...`) as a BakeGroup. Only baker/dist/ sees MPI.
#pragma once

#include <memory>

#include "baker/bake/bake_group.h"

namespace nrad {

// MPI from construction (MPI_Init_thread, funneled: only the calling thread talks to MPI) to destruction
// (MPI_Finalize), and MPI_COMM_WORLD as a BakeGroup. Messages of any size (sent in pieces of at most 1 GiB).
class MpiGroup : public BakeGroup {
public:
    MpiGroup();
    ~MpiGroup() override;
    MpiGroup(const MpiGroup&) = delete;
    MpiGroup& operator=(const MpiGroup&) = delete;
    int rank() const override { return rank_; }
    int size() const override { return size_; }
    std::vector<std::vector<uint8_t>> allGather(const std::vector<uint8_t>& mine) const override;
    // The processes of the launch on this machine (this one included).
    int processesOnThisMachine() const;
    // Seconds this process spent in allGather: waiting for the others, then the exchange itself.
    double exchangeSeconds() const override { return seconds_; }

private:
    int rank_ = 0, size_ = 1;
    mutable double seconds_ = 0.0;
};

}  // namespace nrad
