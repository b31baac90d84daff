// Thread-pool control: a scope that limits TBB to N threads and puts every worker (and the caller) in
// flush-to-zero / denormals-are-zero mode, so results do not depend on which thread ran what.
#pragma once

#include <memory>

namespace nrad {

// Sets FTZ and DAZ on the calling thread (x86; a no-op elsewhere).
void enableFlushToZero();

// The cores this process may run on (its affinity mask; every hardware thread where there is none), at least 1.
int coresAvailable();

class ThreadScope {
public:
    // threads == 0: use every hardware thread.
    explicit ThreadScope(int threads);
    ~ThreadScope();
    ThreadScope(const ThreadScope&) = delete;
    ThreadScope& operator=(const ThreadScope&) = delete;
    int threads() const { return threads_; }

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
    int threads_ = 0;
};

}  // namespace nrad
