#include "apps/progress.hpp"

#include <chrono>
#include <cstdio>
#include <unistd.h>

namespace voxtier::cli {

namespace {

constexpr auto kQuietFor = std::chrono::seconds(2);
constexpr auto kEvery = std::chrono::seconds(1);

} // namespace

Progress::Progress(std::string what, std::size_t total) : what_(std::move(what)), total_(total) {
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

void Progress::tick() {
    const auto start = std::chrono::steady_clock::now();
    std::unique_lock<std::mutex> lock(mutex_);
    if (wake_.wait_for(lock, kQuietFor, [this] { return stop_; })) return;
    do {
        const double s =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        const std::size_t d = done_.load(std::memory_order_relaxed);
        char left[48] = "";
        // The time left from the mean time per unit so far; unknown before the first one ends.
        if (d > 0 && d < total_)
            std::snprintf(left, sizeof left, ", ~%.0f s left", s / double(d) * double(total_ - d));
        std::fprintf(stderr, "\r\033[Kvoxtier: %s %zu/%zu, %.0f s%s", what_.c_str(), d, total_, s,
                     left);
        std::fflush(stderr);
        shown_ = true;
    } while (!wake_.wait_for(lock, kEvery, [this] { return stop_; }));
}

} // namespace voxtier::cli
