#pragma once
// Wall time for the timing figures (frame, bake and bench milliseconds): one clock, one unit.
// steady_clock because a figure must not jump when the system clock is set.
#include <chrono>

namespace voxtier {

/// Milliseconds from `t0` (a steady_clock::now()) to now.
inline double msSince(std::chrono::steady_clock::time_point t0) {
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

/// msSince(`from`), and `from` moved to now: steps timed one after another, one clock read each.
inline double lapMs(std::chrono::steady_clock::time_point& from) {
    const auto now = std::chrono::steady_clock::now();
    const double ms = std::chrono::duration<double, std::milli>(now - from).count();
    from = now;
    return ms;
}

} // namespace voxtier
