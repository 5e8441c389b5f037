#pragma once
// Work done so far inside one long call, for another thread to poll (the CLI's progress line):
// the callee adds to `total` what it learns it will do and to `done` what it finished, a few
// times per call (per band of rows, not per pixel), so counting costs nothing measurable.
// Relaxed atomics: a reader sees a recent count, not a consistent pair.
#include <atomic>
#include <cstdint>

namespace voxtier {

struct WorkProgress {
    std::atomic<std::uint64_t> done{0}, total{0};
    /// Before the next call (a caller's own thread; a poller may still read either value).
    void reset() {
        done.store(0, std::memory_order_relaxed);
        total.store(0, std::memory_order_relaxed);
    }
};

} // namespace voxtier
