// ThreadScope: TBB global_control plus an observer that sets FTZ/DAZ on each worker thread.
#include "baker/util/threads.h"

#include <thread>

#if defined(__linux__)
#include <sched.h>
#endif

#include <tbb/global_control.h>
#include <tbb/task_scheduler_observer.h>

#if defined(__x86_64__) || defined(_M_X64) || defined(__i386__)
#include <pmmintrin.h>
#include <xmmintrin.h>
#endif

namespace nrad {

void enableFlushToZero() {
#if defined(__x86_64__) || defined(_M_X64) || defined(__i386__)
    _MM_SET_FLUSH_ZERO_MODE(_MM_FLUSH_ZERO_ON);
    _MM_SET_DENORMALS_ZERO_MODE(_MM_DENORMALS_ZERO_ON);
#endif
}

namespace {
class FlushToZeroObserver : public tbb::task_scheduler_observer {
public:
    FlushToZeroObserver() { observe(true); }
    ~FlushToZeroObserver() override { observe(false); }
    void on_scheduler_entry(bool) override { enableFlushToZero(); }
};
}  // namespace

struct ThreadScope::Impl {
    tbb::global_control control;
    FlushToZeroObserver observer;
    explicit Impl(int n) : control(tbb::global_control::max_allowed_parallelism, size_t(n)) {}
};

int coresAvailable() {
#if defined(__linux__)
    cpu_set_t set;
    CPU_ZERO(&set);
    if (sched_getaffinity(0, sizeof set, &set) == 0 && CPU_COUNT(&set) > 0) return CPU_COUNT(&set);
#endif
    const int hw = int(std::thread::hardware_concurrency());
    return hw > 0 ? hw : 1;
}

ThreadScope::ThreadScope(int threads) {
    int hw = int(std::thread::hardware_concurrency());
    threads_ = threads > 0 ? threads : (hw > 0 ? hw : 1);
    impl_ = std::make_unique<Impl>(threads_);
    enableFlushToZero();
}

ThreadScope::~ThreadScope() = default;

}  // namespace nrad
