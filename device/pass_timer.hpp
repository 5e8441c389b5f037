#pragma once
// Device time of named passes (issue 35, Deliver 1): a timestamp at the start and one at the end
// of each pass, written into the frame's command buffer, read back after the frame's fence.
// Host time (set-up, recording, waiting on the fence) is the caller's to measure with a clock;
// these are the device's own times, so the two can be told apart.
//
// Frame protocol (one thread, one PassTimer per frame in flight):
//   timer.reset(cb);                 // first thing in the command buffer
//   timer.begin(cb, "draw"); ... timer.end(cb);
//   ... submit, wait for the fence ...
//   for (const PassTime& t : timer.results()) use(t.name, t.ms);
//
// Where the device's queue has no timestamps (timestampValidBits == 0), available() is false,
// begin/end record nothing and results() is empty: a missing time is absent, never 0 ms.
#include <vulkan/vulkan.h>

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace voxtier {

class VulkanDevice;

struct PassTime {
    std::string name;
    double ms = 0.0; ///< device time from the pass's begin to its end
};

/// Milliseconds between two raw timestamps of a counter with `validBits` valid bits (the rest
/// undefined) ticking every `periodNs` nanoseconds, allowing for one wrap of the counter.
double timestampDeltaMs(std::uint64_t begin, std::uint64_t end, std::uint32_t validBits,
                        double periodNs);

class PassTimer {
  public:
    /// Room for `maxPasses` passes per frame. `forceUnavailable` makes it behave as on a device
    /// without timestamps (tests).
    explicit PassTimer(VulkanDevice& device, std::uint32_t maxPasses = 32,
                       bool forceUnavailable = false);
    ~PassTimer();
    PassTimer(const PassTimer&) = delete;
    PassTimer& operator=(const PassTimer&) = delete;

    /// The device's queue writes timestamps.
    bool available() const { return pool_ != VK_NULL_HANDLE; }
    /// Resets the query pool and forgets the previous frame's passes. Record it outside a render
    /// pass, before any begin().
    void reset(VkCommandBuffer cb);
    /// Opens pass `name` (passes may nest; end() closes the innermost open one). Beyond maxPasses
    /// a pass is not timed (it will be absent from results()).
    void begin(VkCommandBuffer cb, std::string_view name);
    void end(VkCommandBuffer cb);

    /// After the fence of the frame that recorded them: every closed pass in begin order, with
    /// its device time. Empty when unavailable. Throws VulkanError if the results are not ready
    /// (the frame has not completed).
    std::vector<PassTime> results() const;
    /// The time of the first pass called `name`, or nullopt when it was not timed.
    std::optional<double> ms(std::string_view name) const;

  private:
    VkDevice device_ = VK_NULL_HANDLE;
    VkQueryPool pool_ = VK_NULL_HANDLE;
    std::uint32_t maxPasses_ = 0;
    std::uint32_t validBits_ = 0;
    double periodNs_ = 1.0;
    struct Pass {
        std::string name;
        std::uint32_t query; ///< begin timestamp; end is query + 1
        bool closed = false;
    };
    std::vector<Pass> passes_;
    /// One entry per open begin(), innermost last: its index in passes_, or nullopt when it got
    /// no queries (unavailable, or past maxPasses).
    std::vector<std::optional<std::size_t>> open_;
};

} // namespace voxtier
