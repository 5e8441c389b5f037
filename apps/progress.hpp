#pragma once
// A progress line for long runs on a terminal: "voxtier: frames 12/151, 9 s, ~104 s left" on
// stderr, rewritten once a second from 2 s into the run and erased when the run ends. Nothing
// is printed when stderr is not a terminal (a log, a pipe, a test), so output there is exactly
// the status lines. A run shorter than 2 s shows nothing either: a line that flashes for a
// fraction of a second only hides what was on the screen.
// A run of one unit (one frame) shows the progress inside it where the work counts it
// (WorkProgress: the CPU reference's sprite rows), "voxtier: frame 1/1, sprite rows 5.2M/16.4M,
// 9 s, ~18 s left", and what it does after (writing the image); a Vulkan frame is one submit
// and counts nothing: its line gives the time only.
#include "core/work_progress.hpp"

#include <atomic>
#include <condition_variable>
#include <cstddef>
#include <mutex>
#include <string>
#include <thread>

namespace voxtier::cli {

class Progress {
  public:
    /// `what`: the unit counted ("frames", "model frames"); `total`: how many the run has.
    /// `within`: counted inside the current unit, shown when the run has one unit ("sprite rows").
    Progress(std::string what, std::size_t total, const WorkProgress* within = nullptr,
             std::string withinWhat = {});
    /// Erases the line (if one was shown) and stops the ticker.
    ~Progress();
    Progress(const Progress&) = delete;
    Progress& operator=(const Progress&) = delete;
    /// `count` units are finished.
    void done(std::size_t count) { done_.store(count, std::memory_order_relaxed); }
    /// Erases the line until the next tick: call before printing to the terminal, so that a
    /// status line does not start after the progress text.
    void clear();
    /// What the run does now, shown after the counts ("writing out.png"); "" for none.
    void note(std::string text);

  private:
    void tick();

    std::string what_;
    std::size_t total_;
    const WorkProgress* within_;
    std::string withinWhat_;
    std::string note_; ///< under mutex_
    std::atomic<std::size_t> done_{0};
    std::mutex mutex_;
    std::condition_variable wake_;
    bool stop_ = false;
    bool shown_ = false;
    std::thread thread_;
};

} // namespace voxtier::cli
