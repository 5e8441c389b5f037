// device/gpu_frame: a frame submitted with a readback keeps its slot until read() has copied it
// out, whatever frames are begun meanwhile (an empty frame the cost model draws, a frame of
// another size), and begin() refuses when every slot holds an unread frame. The validation layer
// stays silent.
#include "device/gpu_frame.hpp"
#include "device_test_support.hpp"

#include <gtest/gtest.h>

#include <memory>
#include <stdexcept>

namespace voxtier {
namespace {

class GpuFramesTest : public ::testing::Test {
  protected:
    void SetUp() override {
        log_ = std::make_shared<VulkanMessageLog>();
        device_ = std::make_unique<VulkanDevice>(test::validatedDevice(), log_);
        frames_ = std::make_unique<GpuFrames>(*device_, 2);
    }
    void TearDown() override {
        frames_.reset();
        device_.reset();
        EXPECT_EQ(log_->count(), 0u) << log_->joined();
    }
    /// Begins a frame, fills its colour plane with `colour` and submits it with a readback.
    GpuFrame& submitFilled(int size, std::uint32_t colour) {
        GpuFrame& f = frames_->begin(size, size);
        f.recordClearPlanes(colour, true);
        f.recordReadback(true);
        f.submit();
        return f;
    }
    static void expectFilled(const Image& img, int size, std::uint32_t colour) {
        ASSERT_EQ(img.width, size);
        ASSERT_EQ(img.height, size);
        for (const Rgba8 c : img.color) ASSERT_EQ(std::uint32_t(c), colour);
    }

    std::shared_ptr<VulkanMessageLog> log_;
    std::unique_ptr<VulkanDevice> device_;
    std::unique_ptr<GpuFrames> frames_;
};

TEST_F(GpuFramesTest, AnUnreadFrameKeepsItsSlotWhileOthersAreBegun) {
    GpuFrame& a = submitFilled(8, 0x11111111u);
    GpuFrame& b = submitFilled(8, 0x22222222u);
    EXPECT_NE(a.slot(), b.slot());
    expectFilled(a.read(true), 8, 0x11111111u);
    // A frame drawn and read in between (the cost model's empty frame) takes a's slot, not b's.
    GpuFrame& c = submitFilled(8, 0x33333333u);
    EXPECT_EQ(c.slot(), a.slot());
    expectFilled(c.read(true), 8, 0x33333333u);
    // And the next one too, at another size: b's frame is still unread.
    GpuFrame& d = submitFilled(16, 0x44444444u);
    EXPECT_EQ(d.slot(), a.slot());
    expectFilled(b.read(true), 8, 0x22222222u);
    expectFilled(d.read(true), 16, 0x44444444u);
}

TEST_F(GpuFramesTest, BeginRefusesWhenEverySlotHoldsAnUnreadFrame) {
    GpuFrame& a = submitFilled(8, 0x11111111u);
    GpuFrame& b = submitFilled(8, 0x22222222u);
    EXPECT_THROW(frames_->begin(8, 8), std::logic_error);
    expectFilled(b.read(true), 8, 0x22222222u);
    GpuFrame& c = submitFilled(8, 0x33333333u);
    EXPECT_EQ(c.slot(), b.slot());
    expectFilled(a.read(true), 8, 0x11111111u);
    expectFilled(c.read(true), 8, 0x33333333u);
}

TEST_F(GpuFramesTest, AFrameWithoutReadbackFreesItsSlotOnceDone) {
    GpuFrame& a = frames_->begin(8, 8);
    a.recordClearPlanes(0x11111111u, true);
    a.submit(); // timed on the device, never read
    GpuFrame& b = submitFilled(8, 0x22222222u);
    GpuFrame& c = submitFilled(8, 0x33333333u); // a's slot: it held nothing to read
    EXPECT_EQ(c.slot(), a.slot());
    expectFilled(b.read(true), 8, 0x22222222u);
    expectFilled(c.read(true), 8, 0x33333333u);
}

} // namespace
} // namespace voxtier
