#include "apps/progress.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <optional>
#include <unistd.h>
#include <utility>

namespace voxtier::cli {

namespace {

constexpr auto kQuietFor = std::chrono::seconds(2);
constexpr auto kEvery = std::chrono::seconds(1);

} // namespace

Progress::Progress(std::string what, std::size_t total, const WorkProgress* within,
                   std::string withinWhat)
    : what_(std::move(what)), total_(total), within_(within), withinWhat_(std::move(withinWhat)) {
    if (isatty(STDERR_FILENO)) thread_ = std::thread([this] { tick(); });
}

Progress::~Progress() {
    if (!thread_.joinable()) return;
    {
        std::lock_guard<std::mutex> lock(mutex_);
        stop_ = true;
    }
    wake_.notify_all();
    thread_.join();
    // Erase the line, so the status lines on stdout (same terminal) read as before.
    if (shown_) std::fprintf(stderr, "\r\033[K");
}

void Progress::clear() {
    if (!thread_.joinable()) return;
    std::lock_guard<std::mutex> lock(mutex_);
    if (shown_) std::fprintf(stderr, "\r\033[K");
    std::fflush(stderr);
    shown_ = false;
}

void Progress::note(std::string text) {
    std::lock_guard<std::mutex> lock(mutex_);
    note_ = std::move(text);
}

namespace {

/// 16384 -> "16384", 5234567 -> "5.2M".
std::string count(std::uint64_t n) {
    char buf[32];
    if (n < 1000000)
        std::snprintf(buf, sizeof buf, "%llu", static_cast<unsigned long long>(n));
    else
        std::snprintf(buf, sizeof buf, "%.1fM", double(n) / 1e6);
    return buf;
}

} // namespace

void Progress::tick() {
    using Clock = std::chrono::steady_clock;
    const auto start = Clock::now();
    // When the counted work inside the unit started (first seen at a tick) and how far it was.
    std::optional<std::pair<Clock::time_point, std::uint64_t>> withinStart;
    std::unique_lock<std::mutex> lock(mutex_);
    if (wake_.wait_for(lock, kQuietFor, [this] { return stop_; })) return;
    do {
        const auto now = Clock::now();
        const double s = std::chrono::duration<double>(now - start).count();
        const std::size_t d = done_.load(std::memory_order_relaxed);
        char left[48] = "";
        std::string inside;
        const std::uint64_t wd = within_ ? within_->done.load(std::memory_order_relaxed) : 0,
                            wt = within_ ? within_->total.load(std::memory_order_relaxed) : 0;
        if (total_ == 1 && wt > 0 && d == 0 && note_.empty()) {
            // One unit: the time left from the rate of the counted work since it was first seen.
            inside = ", " + withinWhat_ + " " + count(std::min(wd, wt)) + "/" + count(wt);
            if (!withinStart) withinStart.emplace(now, wd);
            const double ws = std::chrono::duration<double>(now - withinStart->first).count();
            if (wd > withinStart->second && wd < wt && ws > 0.0)
                std::snprintf(left, sizeof left, ", ~%.0f s left",
                              ws / double(wd - withinStart->second) * double(wt - wd));
        } else if (d > 0 && d < total_) {
            // The time left from the mean time per unit so far; unknown before the first ends.
            std::snprintf(left, sizeof left, ", ~%.0f s left", s / double(d) * double(total_ - d));
        }
        if (!note_.empty()) inside += ", " + note_;
        std::fprintf(stderr, "\r\033[Kvoxtier: %s %zu/%zu%s, %.0f s%s", what_.c_str(), d, total_,
                     inside.c_str(), s, left);
        std::fflush(stderr);
        shown_ = true;
    } while (!wake_.wait_for(lock, kEvery, [this] { return stop_; }));
}

} // namespace voxtier::cli
