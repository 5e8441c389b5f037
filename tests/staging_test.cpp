// Buffers placed by class, and the two ways data reaches a buffer the shaders read
// (device/staging_ring.hpp): written directly into mapped device memory (lavapipe's only type is
// device-local and host-visible), and, with staging forced, copied from the staging ring by
// commands in the frame's command buffer. Every path is checked by a real round trip: the data is
// copied on the device into a Readback buffer and compared byte for byte with what was written.
// Validation (with synchronization validation) runs throughout and must stay silent.
#include "device/staging_ring.hpp"
#include "device/vulkan_device.hpp"
#include "device_test_support.hpp"

#include <gtest/gtest.h>

#include <cstring>
#include <numeric>
#include <vector>

namespace voxtier {
namespace {

/// Shader data the tests copy out again to check it (TRANSFER_SRC).
constexpr VkBufferUsageFlags kReadAndCopy =
    VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_SRC_BIT;

std::vector<std::uint8_t> pattern(std::size_t n, std::uint8_t seed) {
    std::vector<std::uint8_t> v(n);
    for (std::size_t i = 0; i < n; ++i) v[i] = std::uint8_t(seed + i * 7 + (i >> 8));
    return v;
}

/// Records a copy of `src` into `readback` after whatever wrote `src` (transfer or host).
void recordCopyToReadback(VkCommandBuffer cb, const VulkanBuffer& src, VulkanBuffer& readback,
                          VkDeviceSize bytes) {
    bufferBarrier(cb, src.handle(), VK_PIPELINE_STAGE_TRANSFER_BIT | VK_PIPELINE_STAGE_HOST_BIT,
                  VK_ACCESS_TRANSFER_WRITE_BIT | VK_ACCESS_HOST_WRITE_BIT,
                  VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_READ_BIT);
    VkBufferCopy copy{0, 0, bytes};
    vkCmdCopyBuffer(cb, src.handle(), readback.handle(), 1, &copy);
    bufferBarrier(cb, readback.handle(), VK_PIPELINE_STAGE_TRANSFER_BIT,
                  VK_ACCESS_TRANSFER_WRITE_BIT, VK_PIPELINE_STAGE_HOST_BIT,
                  VK_ACCESS_HOST_READ_BIT);
}

std::vector<std::uint8_t> readBack(VulkanBuffer& readback, VkDeviceSize bytes) {
    readback.invalidateForRead();
    const auto* p = static_cast<const std::uint8_t*>(readback.mapped());
    return std::vector<std::uint8_t>(p, p + bytes);
}

TEST(Buffers, ReadbackIsHostCachedAndMapped) {
    auto log = std::make_shared<VulkanMessageLog>();
    {
        VulkanDevice device(test::validatedDevice(false), log);
        VulkanBuffer readback(device, 1024, 0, BufferClass::Readback);
        EXPECT_NE(readback.mapped(), nullptr);
        EXPECT_TRUE(readback.placement().flags & VK_MEMORY_PROPERTY_HOST_CACHED_BIT)
            << memoryPropertyNames(readback.placement().flags);
        EXPECT_EQ(readback.placement().hostWrite, HostWrite::None);
        // The host does not write a readback buffer.
        const std::uint8_t byte = 1;
        EXPECT_THROW(readback.write(0, &byte, 1), VulkanError);
    }
    EXPECT_EQ(log->count(), 0u) << log->joined();
}

TEST(Buffers, LegacyHostVisibleConstructorKeepsItsPlacement) {
    VulkanDeviceOptions o;
    o.echoMessages = false;
    VulkanDevice device(o);
    VulkanBuffer host(device, 256, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, true);
    EXPECT_NE(host.mapped(), nullptr);
    EXPECT_EQ(host.placement().flags & 0x6u, 0x6u); // HOST_VISIBLE|HOST_COHERENT
    EXPECT_EQ(host.placement().hostWrite, HostWrite::Direct);
    VulkanBuffer local(device, 256, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, false);
    EXPECT_EQ(local.mapped(), nullptr);
    EXPECT_TRUE(local.placement().flags & VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT);
}

TEST(Buffers, DirectWriteRoundTripsThroughTheDevice) {
    auto log = std::make_shared<VulkanMessageLog>();
    {
        VulkanDevice device(test::validatedDevice(false), log);
        const VkDeviceSize n = 4096 + 13;
        VulkanBuffer shaderData(device, n, kReadAndCopy, BufferClass::ShaderRead);
        ASSERT_EQ(shaderData.placement().hostWrite, HostWrite::Direct)
            << "lavapipe's memory is device-local and host-visible";
        ASSERT_NE(shaderData.mapped(), nullptr);
        VulkanBuffer readback(device, n, 0, BufferClass::Readback);
        StagingRing ring(device, 1024);
        test::CommandRecorder rec(device);
        ring.beginFrame(1);
        const auto data = pattern(std::size_t(n), 3);
        EXPECT_EQ(uploadToBuffer(ring, rec.cb, shaderData, 0, data.data(), n), HostWrite::Direct);
        EXPECT_EQ(ring.copiesThisFrame(), 0u); // nothing went through the ring
        recordCopyToReadback(rec.cb, shaderData, readback, n);
        rec.submit();
        ring.retire(1);
        EXPECT_EQ(readBack(readback, n), data);
        // Out of range is refused, not written past the end.
        EXPECT_THROW(shaderData.write(n - 4, data.data(), 8), VulkanError);
    }
    EXPECT_EQ(log->count(), 0u) << log->joined();
}

TEST(Buffers, ForcedStagingUploadsThroughTheRing) {
    auto log = std::make_shared<VulkanMessageLog>();
    {
        VulkanDevice device(test::validatedDevice(true), log);
        ASSERT_TRUE(device.forcesStaging());
        const VkDeviceSize n = 3000;
        VulkanBuffer shaderData(device, n, kReadAndCopy, BufferClass::ShaderRead);
        EXPECT_EQ(shaderData.placement().hostWrite, HostWrite::Staged);
        EXPECT_EQ(shaderData.mapped(), nullptr) << "a staged buffer is not the host's to write";
        const auto data = pattern(std::size_t(n), 11);
        EXPECT_THROW(shaderData.write(0, data.data(), n), VulkanError);

        VulkanBuffer readback(device, n, 0, BufferClass::Readback);
        StagingRing ring(device, 8192);
        test::CommandRecorder rec(device);
        ring.beginFrame(1);
        // In two pieces, the second at an offset, as a partial update would be.
        EXPECT_EQ(uploadToBuffer(ring, rec.cb, shaderData, 0, data.data(), 1000),
                  HostWrite::Staged);
        EXPECT_EQ(uploadToBuffer(ring, rec.cb, shaderData, 1000, data.data() + 1000, n - 1000),
                  HostWrite::Staged);
        EXPECT_EQ(ring.copiesThisFrame(), 2u);
        EXPECT_EQ(ring.bytesThisFrame(), n);
        ring.recordBarrier(rec.cb, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_READ_BIT);
        recordCopyToReadback(rec.cb, shaderData, readback, n);
        rec.submit();
        ring.retire(1);
        EXPECT_EQ(ring.bytesInUse(), 0u);
        EXPECT_EQ(readBack(readback, n), data);
        EXPECT_THROW(uploadToBuffer(ring, rec.cb, shaderData, n - 1, data.data(), 2), VulkanError);
    }
    EXPECT_EQ(log->count(), 0u) << log->joined();
}

// Two frames in flight, each with its own command buffer and fence point: frame 2's uploads must
// not overwrite frame 1's staging space before frame 1 has executed, and retired space is reused.
TEST(Buffers, RingKeepsInFlightFramesApartAndReusesRetiredSpace) {
    auto log = std::make_shared<VulkanMessageLog>();
    {
        VulkanDevice device(test::validatedDevice(true), log);
        const VkDeviceSize n = 1000;
        StagingRing ring(device, 2048 + 64);
        VulkanBuffer a(device, n, kReadAndCopy, BufferClass::ShaderRead);
        VulkanBuffer b(device, n, kReadAndCopy, BufferClass::ShaderRead);
        VulkanBuffer readA(device, n, 0, BufferClass::Readback);
        VulkanBuffer readB(device, n, 0, BufferClass::Readback);
        test::CommandRecorder frame1(device), frame2(device);
        const auto dataA = pattern(std::size_t(n), 1), dataB = pattern(std::size_t(n), 2);

        ring.beginFrame(1);
        ring.upload(frame1.cb, a.handle(), 0, dataA.data(), n);
        ring.recordBarrier(frame1.cb, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_READ_BIT);
        recordCopyToReadback(frame1.cb, a, readA, n);
        ring.beginFrame(2); // frame 1 not yet submitted, let alone retired
        ring.upload(frame2.cb, b.handle(), 0, dataB.data(), n);
        ring.recordBarrier(frame2.cb, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_READ_BIT);
        recordCopyToReadback(frame2.cb, b, readB, n);
        EXPECT_EQ(ring.growths(), 0u);
        EXPECT_GE(ring.bytesInUse(), 2 * n);
        frame1.submit();
        ring.retire(1);
        frame2.submit();
        EXPECT_EQ(readBack(readA, n), dataA);
        EXPECT_EQ(readBack(readB, n), dataB);

        // Frame 3 needs space that only frame 1's retirement freed (the ring holds two frames'
        // worth): it fits without growing, wrapping to the start.
        ring.beginFrame(3);
        ring.upload(frame1.cb, a.handle(), 0, dataB.data(), n);
        EXPECT_EQ(ring.growths(), 0u);
        ring.recordBarrier(frame1.cb, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_READ_BIT);
        recordCopyToReadback(frame1.cb, a, readA, n);
        frame1.submit();
        ring.retire(3);
        EXPECT_EQ(ring.bytesInUse(), 0u);
        EXPECT_EQ(readBack(readA, n), dataB);
    }
    EXPECT_EQ(log->count(), 0u) << log->joined();
}

TEST(Buffers, RingGrowsInsteadOfFailingAndKeepsEarlierUploadsValid) {
    auto log = std::make_shared<VulkanMessageLog>();
    {
        VulkanDevice device(test::validatedDevice(true), log);
        StagingRing ring(device, 256);
        const VkDeviceSize small = 200, big = 5000;
        VulkanBuffer a(device, small, kReadAndCopy, BufferClass::ShaderRead);
        VulkanBuffer b(device, big, kReadAndCopy, BufferClass::ShaderRead);
        VulkanBuffer readA(device, small, 0, BufferClass::Readback);
        VulkanBuffer readB(device, big, 0, BufferClass::Readback);
        const auto dataA = pattern(std::size_t(small), 5), dataB = pattern(std::size_t(big), 6);
        test::CommandRecorder rec(device);
        ring.beginFrame(7);
        ring.upload(rec.cb, a.handle(), 0, dataA.data(), small); // in the first buffer
        ring.upload(rec.cb, b.handle(), 0, dataB.data(), big);   // does not fit: grows
        EXPECT_EQ(ring.growths(), 1u);
        EXPECT_GE(ring.capacity(), big);
        ring.recordBarrier(rec.cb, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_READ_BIT);
        recordCopyToReadback(rec.cb, a, readA, small);
        recordCopyToReadback(rec.cb, b, readB, big);
        rec.submit();
        ring.retire(7);
        EXPECT_EQ(readBack(readA, small), dataA);
        EXPECT_EQ(readBack(readB, big), dataB);
    }
    EXPECT_EQ(log->count(), 0u) << log->joined();
}

// Many pieces for one buffer in one copy command (the far pass's snapshot uploads): side by side
// in the ring, each where it belongs in the buffer, a piece of zero bytes skipped, the ring grown
// where they do not fit together.
TEST(Buffers, PiecesUploadedTogetherLandWhereEachBelongsInOneCopy) {
    auto log = std::make_shared<VulkanMessageLog>();
    {
        VulkanDevice device(test::validatedDevice(true), log);
        const VkDeviceSize n = 6000;
        VulkanBuffer shaderData(device, n, kReadAndCopy, BufferClass::ShaderRead);
        VulkanBuffer readback(device, n, 0, BufferClass::Readback);
        StagingRing ring(device, 1024);
        test::CommandRecorder rec(device);
        const auto data = pattern(std::size_t(n), 23);
        // Out of order and with a gap that stays as the first upload left it.
        const auto first = pattern(std::size_t(n), 99);
        ring.beginFrame(1);
        ring.upload(rec.cb, shaderData.handle(), 0, first.data(), n);
        ring.recordBarrier(rec.cb, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT);
        const StagedPiece pieces[] = {{data.data() + 4000, 2000, 4000},
                                      {data.data() + 10, 0, 10},
                                      {data.data(), 1500, 0},
                                      {data.data() + 2500, 1000, 2500}};
        ring.uploadAll(rec.cb, shaderData.handle(), pieces);
        EXPECT_EQ(ring.copiesThisFrame(), 2u);
        EXPECT_EQ(ring.bytesThisFrame(), n + 4500);
        EXPECT_GE(ring.growths(), 1u);
        ring.recordBarrier(rec.cb, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_READ_BIT);
        recordCopyToReadback(rec.cb, shaderData, readback, n);
        rec.submit();
        ring.retire(1);
        std::vector<std::uint8_t> expected = first;
        for (const StagedPiece& p : pieces)
            std::memcpy(expected.data() + p.dstOffset, p.data, std::size_t(p.bytes));
        EXPECT_EQ(readBack(readback, n), expected);
        // Nothing to upload records nothing.
        ring.beginFrame(2);
        ring.uploadAll(rec.cb, shaderData.handle(), {});
        EXPECT_EQ(ring.copiesThisFrame(), 0u);
        ring.retire(2);
    }
    EXPECT_EQ(log->count(), 0u) << log->joined();
}

TEST(Buffers, FrameIdsMustIncreaseAndUploadsNeedAFrame) {
    VulkanDeviceOptions o;
    o.echoMessages = false;
    o.forceStaging = true;
    VulkanDevice device(o);
    StagingRing ring(device, 1024);
    VulkanBuffer a(device, 16, kReadAndCopy, BufferClass::ShaderRead);
    const std::uint8_t bytes[16] = {};
    EXPECT_THROW(ring.upload(VK_NULL_HANDLE, a.handle(), 0, bytes, 16), std::logic_error);
    ring.beginFrame(5);
    EXPECT_THROW(ring.beginFrame(5), std::logic_error);
}

} // namespace
} // namespace voxtier
