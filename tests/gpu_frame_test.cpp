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

// A frame submitted in two parts (GpuFrame::submitSoFar: the device starts on the first while
// the host prepares the rest): the second part sees what the first wrote, once a frame.
TEST_F(GpuFramesTest, AFrameSubmittedInTwoPartsReadsWhatBothWrote) {
    GpuFrame& f = frames_->begin(8, 8);
    f.recordClearPlanes(0x11111111u, true);
    f.submitSoFar();
    EXPECT_THROW(f.submitSoFar(), std::logic_error);
    // The first half of the colour plane overwritten by the second part, after the first's fill.
    vkCmdFillBuffer(f.commandBuffer(), f.planes(), 0, f.planeBytes() / 2, 0x22222222u);
    f.recordReadback(true);
    f.submit();
    const Image img = f.read(true);
    ASSERT_EQ(img.pixelCount(), 64u);
    for (std::size_t p = 0; p < img.pixelCount(); ++p)
        ASSERT_EQ(std::uint32_t(img.color[p]), p < 32 ? 0x22222222u : 0x11111111u) << p;
    // Its device time in two spans, not the gap between the parts (lavapipe has timestamps).
    ASSERT_TRUE(f.timer().available());
    EXPECT_TRUE(f.timer().ms("frame").has_value());
    EXPECT_TRUE(f.timer().ms("frame_rest").has_value());
    // The slot's next frame, in one part again.
    GpuFrame& g = submitFilled(8, 0x33333333u);
    GpuFrame& h = submitFilled(8, 0x44444444u);
    EXPECT_EQ(h.slot(), f.slot());
    expectFilled(g.read(true), 8, 0x33333333u);
    expectFilled(h.read(true), 8, 0x44444444u);
}

// A frame abandoned after its first part (an exception while the host prepared the rest): its
// slot's next frame waits for that part and draws as any other.
TEST_F(GpuFramesTest, AFrameAbandonedAfterItsFirstPartFreesItsSlot) {
    GpuFrame& a = frames_->begin(8, 8);
    a.recordClearPlanes(0x11111111u, true);
    a.submitSoFar();
    GpuFrame& b = submitFilled(8, 0x22222222u);
    expectFilled(b.read(true), 8, 0x22222222u);
    GpuFrame& c = submitFilled(8, 0x33333333u);
    EXPECT_EQ(c.slot(), a.slot());
    expectFilled(c.read(true), 8, 0x33333333u);
}

} // namespace
} // namespace voxtier
