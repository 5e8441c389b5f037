#pragma once
// Wall time for the timing figures (frame, bake and bench milliseconds): one clock, one unit.
// steady_clock because a figure must not jump when the system clock is set.
#include <chrono>

namespace voxtier {

/// Milliseconds from `t0` (a steady_clock::now()) to now.
inline double msSince(std::chrono::steady_clock::time_point t0) {
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

} // namespace voxtier
