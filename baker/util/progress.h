// ProgressBar: a thread-safe per-phase progress indicator on stderr (percent on a TTY line, or a line
// every 10% when stderr is redirected, so logs of unattended runs stay short).
#pragma once

#include <cstdio>
#include <mutex>
#include <string>

#include <unistd.h>

namespace nrad {

class ProgressBar {
public:
    ProgressBar(std::string label, bool enabled)
        : label_(std::move(label)), enabled_(enabled), tty_(isatty(fileno(stderr)) != 0) {}

    void update(double fraction) {
        if (!enabled_) return;
        int percent = int(fraction * 100.0 + 1e-9);
        std::lock_guard<std::mutex> lock(mutex_);
        if (percent <= last_ || (!tty_ && percent / 10 == last_ / 10 && percent != 100)) return;
        last_ = percent;
        if (tty_) {
            int filled = percent / 4;
            std::fprintf(stderr, "\r%-10s [%.*s%*s] %3d%%", label_.c_str(), filled, "#########################", 25 - filled, "", percent);
            if (percent == 100) std::fprintf(stderr, "\n");
        } else {
            std::fprintf(stderr, "%s: %d%%\n", label_.c_str(), percent);
        }
        std::fflush(stderr);
    }

private:
    std::string label_;
    bool enabled_;
    bool tty_;
    int last_ = -1;
    std::mutex mutex_;
};

}  // namespace nrad
