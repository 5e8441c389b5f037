// Named device timestamps (device/pass_timer.hpp): the tick arithmetic on its own, and passes
// timed on lavapipe: every closed pass is reported once, in begin order, a nested pass lies
// within its parent, a pass past the pool's size is absent rather than 0, and on a queue without
// timestamps nothing is reported at all. No assertion depends on how fast anything runs.
#include "device/pass_timer.hpp"
#include "device/vulkan_device.hpp"
#include "device_test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace voxtier {
namespace {

TEST(PassTimerTicks, DeltaScalesByThePeriod) {
    EXPECT_DOUBLE_EQ(timestampDeltaMs(1000, 3000, 64, 1.0), 2000e-6);
    EXPECT_DOUBLE_EQ(timestampDeltaMs(0, 1'000'000, 64, 52.0833), 52.0833);
}

TEST(PassTimerTicks, OnlyTheValidBitsCountAndOneWrapIsUndone) {
    // A 36-bit counter (Intel's) that wrapped between the two stamps: 10 ticks before the top,
    // 5 after, 15 in all. Garbage above bit 35 is ignored.
    const std::uint64_t top = std::uint64_t(1) << 36;
    EXPECT_DOUBLE_EQ(timestampDeltaMs(top - 10, 5, 36, 1.0), 15e-6);
    EXPECT_DOUBLE_EQ(
        timestampDeltaMs((top - 10) | (std::uint64_t(0xABC) << 40), 5 | (top << 3), 36, 1.0),
        15e-6);
    EXPECT_DOUBLE_EQ(timestampDeltaMs(~std::uint64_t(0), 0, 64, 1.0), 1e-6);
}

TEST(PassTimer, NamedPassesAreTimedOnTheDevice) {
    auto log = std::make_shared<VulkanMessageLog>();
    {
        VulkanDevice device(test::validatedDevice(), log);
        ASSERT_GT(device.timestampValidBits(), 0u) << "lavapipe writes timestamps";
        PassTimer timer(device, 8);
        ASSERT_TRUE(timer.available());
        const VkDeviceSize n = 8 << 20;
        VulkanBuffer src(device, n,
                         VK_BUFFER_USAGE_TRANSFER_SRC_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                         BufferClass::DeviceOnly);
        VulkanBuffer dst(device, n, VK_BUFFER_USAGE_TRANSFER_DST_BIT, BufferClass::DeviceOnly);
        test::CommandRecorder f(device);
        timer.reset(f.cb);
        timer.begin(f.cb, "frame");
        timer.begin(f.cb, "copy");
        vkCmdFillBuffer(f.cb, src.handle(), 0, n, 0x01020304u);
        bufferBarrier(f.cb, src.handle(), VK_PIPELINE_STAGE_TRANSFER_BIT,
                      VK_ACCESS_TRANSFER_WRITE_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT,
                      VK_ACCESS_TRANSFER_READ_BIT);
        VkBufferCopy copy{0, 0, n};
        vkCmdCopyBuffer(f.cb, src.handle(), dst.handle(), 1, &copy);
        timer.end(f.cb); // copy
        timer.begin(f.cb, "empty");
        timer.end(f.cb);
        timer.end(f.cb); // frame
        f.submit();

        const std::vector<PassTime> times = timer.results();
        ASSERT_EQ(times.size(), 3u);
        EXPECT_EQ(times[0].name, "frame");
        EXPECT_EQ(times[1].name, "copy");
        EXPECT_EQ(times[2].name, "empty");
        for (const PassTime& t : times) EXPECT_TRUE(std::isfinite(t.ms) && t.ms >= 0.0) << t.name;
        // The frame's stamps enclose the copy's: its time cannot be shorter.
        EXPECT_GE(times[0].ms, times[1].ms);
        ASSERT_TRUE(timer.ms("copy").has_value());
        EXPECT_EQ(*timer.ms("copy"), times[1].ms);
        EXPECT_FALSE(timer.ms("never begun").has_value());
    }
    EXPECT_EQ(log->count(), 0u) << log->joined();
}

TEST(PassTimer, PassesBeyondThePoolAreAbsentNotZero) {
    auto log = std::make_shared<VulkanMessageLog>();
    {
        VulkanDevice device(test::validatedDevice(), log);
        PassTimer timer(device, 2);
        for (int frame = 0; frame < 2; ++frame) { // the pool is reused frame after frame
            test::CommandRecorder f(device);
            timer.reset(f.cb);
            for (const char* name : {"a", "b", "c"}) {
                timer.begin(f.cb, name);
                timer.end(f.cb);
            }
            f.submit();
            const std::vector<PassTime> times = timer.results();
            ASSERT_EQ(times.size(), 2u);
            EXPECT_EQ(times[1].name, "b");
            EXPECT_FALSE(timer.ms("c").has_value());
        }
    }
    EXPECT_EQ(log->count(), 0u) << log->joined();
}

TEST(PassTimer, WithoutTimestampsNothingIsReported) {
    VulkanDeviceOptions o;
    o.echoMessages = false;
    VulkanDevice device(o);
    PassTimer timer(device, 4, /*forceUnavailable=*/true);
    EXPECT_FALSE(timer.available());
    test::CommandRecorder f(device);
    timer.reset(f.cb);
    timer.begin(f.cb, "draw");
    timer.end(f.cb);
    f.submit();
    EXPECT_TRUE(timer.results().empty());
    EXPECT_FALSE(timer.ms("draw").has_value());
}

} // namespace
} // namespace voxtier
