// The memory placement policy (device/memory_policy.hpp) against the memory-type tables of real
// devices, kept as data in tests/data/vulkan_memory/ (each file cites the vulkaninfo dump it was
// transcribed from). The expected type of each buffer class is read off each table by hand in
// the comments below: where the device offers device memory the host can map in full, shaders
// read it there and the host writes it directly; where it offers only a small BAR window, they
// read device-only memory filled through staging; readback is host-cached.
#include "device/memory_policy.hpp"
#include "device/vulkan_device.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>
#include <map>
#include <string>

namespace voxtier {
namespace {

const std::string kDataDir = std::string(VOXTIER_SOURCE_DIR) + "/tests/data/vulkan_memory/";

/// vulkaninfo's flag names (without MEMORY_PROPERTY_ / _BIT) to bits, written out here rather than
/// taken from the code under test.
VkMemoryPropertyFlags propertyBit(const std::string& name) {
    static const std::map<std::string, VkMemoryPropertyFlags> bits = {
        {"DEVICE_LOCAL", 0x1},         {"HOST_VISIBLE", 0x2},        {"HOST_COHERENT", 0x4},
        {"HOST_CACHED", 0x8},          {"LAZILY_ALLOCATED", 0x10},   {"PROTECTED", 0x20},
        {"DEVICE_COHERENT_AMD", 0x40}, {"DEVICE_UNCACHED_AMD", 0x80}};
    const auto it = bits.find(name);
    if (it == bits.end()) ADD_FAILURE() << "unknown memory property " << name;
    return it == bits.end() ? 0 : it->second;
}

VkMemoryHeapFlags heapBit(const std::string& name) {
    if (name == "DEVICE_LOCAL") return VK_MEMORY_HEAP_DEVICE_LOCAL_BIT;
    if (name == "MULTI_INSTANCE") return VK_MEMORY_HEAP_MULTI_INSTANCE_BIT;
    ADD_FAILURE() << "unknown heap flag " << name;
    return 0;
}

struct Table {
    nlohmann::json json;
    VkPhysicalDeviceMemoryProperties memory{};
};

Table loadTable(const std::string& file) {
    Table t;
    std::ifstream in(kDataDir + file);
    EXPECT_TRUE(in) << kDataDir + file;
    t.json = nlohmann::json::parse(in);
    for (const auto& h : t.json.at("heaps")) {
        VkMemoryHeap& heap = t.memory.memoryHeaps[t.memory.memoryHeapCount++];
        heap.size = h.at("size").get<VkDeviceSize>();
        for (const auto& f : h.at("flags")) heap.flags |= heapBit(f.get<std::string>());
    }
    for (const auto& ty : t.json.at("types")) {
        VkMemoryType& type = t.memory.memoryTypes[t.memory.memoryTypeCount++];
        type.heapIndex = ty.at("heap").get<std::uint32_t>();
        for (const auto& f : ty.at("flags"))
            type.propertyFlags |= propertyBit(f.get<std::string>());
    }
    return t;
}

MemoryPlacement place(const Table& t, BufferClass c, std::uint32_t typeBits = ~0u,
                      bool forceStaging = false) {
    PlacementOptions o;
    o.forceStaging = forceStaging;
    const std::optional<MemoryPlacement> p = placeBuffer(t.memory, typeBits, c, o);
    EXPECT_TRUE(p.has_value()) << bufferClassName(c);
    return p.value_or(MemoryPlacement{});
}

TEST(MemoryPolicyData, EveryTableCitesItsSourceAndIsWellFormed) {
    std::size_t files = 0;
    for (const auto& e : std::filesystem::directory_iterator(kDataDir)) {
        if (e.path().extension() != ".json") continue;
        ++files;
        const Table t = loadTable(e.path().filename().string());
        const std::string source = t.json.at("source").get<std::string>();
        EXPECT_TRUE(source.rfind("https://", 0) == 0 || source.rfind("captured", 0) == 0)
            << e.path() << ": " << source;
        EXPECT_FALSE(t.json.at("device").get<std::string>().empty()) << e.path();
        ASSERT_GT(t.memory.memoryTypeCount, 0u) << e.path();
        for (std::uint32_t i = 0; i < t.memory.memoryTypeCount; ++i)
            EXPECT_LT(t.memory.memoryTypes[i].heapIndex, t.memory.memoryHeapCount) << e.path();
        // The spec's guarantees, which the policy's fallbacks rely on.
        bool coherentHostVisible = false, deviceLocal = false;
        for (std::uint32_t i = 0; i < t.memory.memoryTypeCount; ++i) {
            const VkMemoryPropertyFlags f = t.memory.memoryTypes[i].propertyFlags;
            coherentHostVisible |= (f & 0x6) == 0x6;
            deviceLocal |= (f & 0x1) != 0;
        }
        EXPECT_TRUE(coherentHostVisible && deviceLocal) << e.path();
    }
    EXPECT_GE(files, 4u);
}

// NVIDIA GeForce GTX 1660, no resizable BAR. Types: 0 none (heap 1), 1 DEVICE_LOCAL (heap 0,
// 5.84 GiB), 2 HOST_VISIBLE|COHERENT (heap 1, system), 3 HOST_VISIBLE|COHERENT|CACHED (heap 1),
// 4 DEVICE_LOCAL|HOST_VISIBLE|COHERENT on heap 2 of 214 MiB: the BAR window, not to be used.
TEST(MemoryPolicy, NvidiaWithoutResizableBarStagesShaderDataIntoVideoMemory) {
    const Table t = loadTable("nvidia_gtx1660_small_bar.json");
    EXPECT_FALSE(hasLargeHostVisibleDeviceMemory(t.memory));

    const MemoryPlacement read = place(t, BufferClass::ShaderRead);
    EXPECT_EQ(read.typeIndex, 1u);
    EXPECT_EQ(read.hostWrite, HostWrite::Staged);
    EXPECT_FALSE(read.mapped);
    EXPECT_EQ(read.heapSize, 6271533056u);

    EXPECT_EQ(place(t, BufferClass::DeviceOnly).typeIndex, 1u);

    const MemoryPlacement staging = place(t, BufferClass::Staging);
    EXPECT_EQ(staging.typeIndex, 2u); // system memory, write-combined, coherent
    EXPECT_EQ(staging.hostWrite, HostWrite::Direct);
    EXPECT_TRUE(staging.mapped);
    EXPECT_FALSE(staging.flushAfterWrite);

    const MemoryPlacement readback = place(t, BufferClass::Readback);
    EXPECT_EQ(readback.typeIndex, 3u); // host-cached
    EXPECT_TRUE(readback.mapped);
    EXPECT_FALSE(readback.invalidateBeforeRead); // it is coherent too
}

// NVIDIA GeForce RTX 5080 with resizable BAR: type 4 is DEVICE_LOCAL|HOST_VISIBLE|COHERENT on
// heap 0, the whole 15.92 GiB of video memory.
TEST(MemoryPolicy, ResizableBarIsWrittenDirectly) {
    const Table t = loadTable("nvidia_rtx5080_resizable_bar.json");
    EXPECT_TRUE(hasLargeHostVisibleDeviceMemory(t.memory));

    const MemoryPlacement read = place(t, BufferClass::ShaderRead);
    EXPECT_EQ(read.typeIndex, 4u);
    EXPECT_EQ(read.hostWrite, HostWrite::Direct);
    EXPECT_TRUE(read.mapped);
    EXPECT_EQ(read.heapIndex, 0u);
    EXPECT_FALSE(read.flushAfterWrite);

    // Device-only data stays out of the host-visible type (type 1, same heap).
    EXPECT_EQ(place(t, BufferClass::DeviceOnly).typeIndex, 1u);
    EXPECT_EQ(place(t, BufferClass::Staging).typeIndex, 2u);
    EXPECT_EQ(place(t, BufferClass::Readback).typeIndex, 3u);

    // The test override, and a resource that may not live in type 4, both fall back to staging.
    const MemoryPlacement forced = place(t, BufferClass::ShaderRead, ~0u, true);
    EXPECT_EQ(forced.typeIndex, 1u);
    EXPECT_EQ(forced.hostWrite, HostWrite::Staged);
    const MemoryPlacement restricted = place(t, BufferClass::ShaderRead, ~(1u << 4));
    EXPECT_EQ(restricted.typeIndex, 1u);
    EXPECT_EQ(restricted.hostWrite, HostWrite::Staged);
}

// AMD Radeon (AMD proprietary driver) with a 256 MiB BAR window (heap 2, type 2) and AMD's
// device-coherent types 4-7, which need a device feature and are never picked.
TEST(MemoryPolicy, AmdWithoutResizableBarStagesAndAvoidsDeviceCoherentTypes) {
    const Table t = loadTable("amd_radeon_small_bar.json");
    EXPECT_FALSE(hasLargeHostVisibleDeviceMemory(t.memory));
    const MemoryPlacement read = place(t, BufferClass::ShaderRead);
    EXPECT_EQ(read.typeIndex, 0u);
    EXPECT_EQ(read.hostWrite, HostWrite::Staged);
    EXPECT_EQ(place(t, BufferClass::DeviceOnly).typeIndex, 0u);
    EXPECT_EQ(place(t, BufferClass::Staging).typeIndex, 1u);
    EXPECT_EQ(place(t, BufferClass::Readback).typeIndex, 3u);
    // Allowed only the device-coherent variants, a class has nothing it may use.
    const std::uint32_t amdOnly = 0xF0;
    PlacementOptions o;
    EXPECT_FALSE(placeBuffer(t.memory, amdOnly, BufferClass::Staging, o).has_value());
    EXPECT_FALSE(placeBuffer(t.memory, amdOnly, BufferClass::Readback, o).has_value());
}

// Intel Xe (Tiger Lake) integrated: one heap, one type that is device-local, host-visible,
// coherent and cached. Everything lives there and the host writes shader data directly.
TEST(MemoryPolicy, IntegratedGpuWritesDirectlyAndReadsBackCached) {
    const Table t = loadTable("intel_xe_tgl_integrated.json");
    EXPECT_TRUE(hasLargeHostVisibleDeviceMemory(t.memory));
    for (BufferClass c : kAllBufferClasses)
        EXPECT_EQ(place(t, c).typeIndex, 0u) << bufferClassName(c);
    EXPECT_EQ(place(t, BufferClass::ShaderRead).hostWrite, HostWrite::Direct);
    EXPECT_TRUE(place(t, BufferClass::ShaderRead).mapped);
    EXPECT_FALSE(place(t, BufferClass::DeviceOnly).mapped);
    EXPECT_FALSE(place(t, BufferClass::Readback).invalidateBeforeRead);
    // Forced staging: the same memory, but not mapped, so the upload must go through a copy.
    const MemoryPlacement forced = place(t, BufferClass::ShaderRead, ~0u, true);
    EXPECT_EQ(forced.hostWrite, HostWrite::Staged);
    EXPECT_FALSE(forced.mapped);
}

TEST(MemoryPolicy, LavapipeTableIsLikeAnIntegratedGpu) {
    const Table t = loadTable("lavapipe_mesa_22_3_6.json");
    EXPECT_TRUE(hasLargeHostVisibleDeviceMemory(t.memory));
    EXPECT_EQ(place(t, BufferClass::ShaderRead).hostWrite, HostWrite::Direct);
    EXPECT_EQ(place(t, BufferClass::Readback).flags & 0x8u, 0x8u);
}

// Not a dump: the two host-visible types Mesa's anv offers on Atom GPUs without a shared LLC
// (coherent but uncached, and cached but not coherent), the case where readback must
// invalidate and the other classes must not need a flush.
TEST(MemoryPolicy, CachedButNotCoherentReadbackIsInvalidated) {
    VkPhysicalDeviceMemoryProperties m{};
    m.memoryHeapCount = 1;
    m.memoryHeaps[0] = {2ull << 30, VK_MEMORY_HEAP_DEVICE_LOCAL_BIT};
    m.memoryTypeCount = 2;
    m.memoryTypes[0] = {0x1 | 0x2 | 0x4, 0}; // DEVICE_LOCAL|HOST_VISIBLE|HOST_COHERENT
    m.memoryTypes[1] = {0x1 | 0x2 | 0x8, 0}; // DEVICE_LOCAL|HOST_VISIBLE|HOST_CACHED
    const auto readback = placeBuffer(m, ~0u, BufferClass::Readback);
    ASSERT_TRUE(readback);
    EXPECT_EQ(readback->typeIndex, 1u);
    EXPECT_TRUE(readback->invalidateBeforeRead);
    const auto read = placeBuffer(m, ~0u, BufferClass::ShaderRead);
    ASSERT_TRUE(read);
    EXPECT_EQ(read->typeIndex, 0u);
    EXPECT_FALSE(read->flushAfterWrite);
    // Only the non-coherent type allowed: host writes are flushed.
    const auto staging = placeBuffer(m, 1u << 1, BufferClass::Staging);
    ASSERT_TRUE(staging);
    EXPECT_TRUE(staging->flushAfterWrite);
}

TEST(MemoryPolicy, NamesAndDescriptionsReadLikeVulkaninfo) {
    EXPECT_EQ(memoryPropertyNames(0), "NONE");
    EXPECT_EQ(memoryPropertyNames(0x7), "DEVICE_LOCAL|HOST_VISIBLE|HOST_COHERENT");
    EXPECT_EQ(memoryPropertyNames(0xc1), "DEVICE_LOCAL|DEVICE_COHERENT_AMD|DEVICE_UNCACHED_AMD");
    const Table t = loadTable("nvidia_rtx5080_resizable_bar.json");
    EXPECT_EQ(describePlacement(place(t, BufferClass::ShaderRead)),
              "type 4 (DEVICE_LOCAL|HOST_VISIBLE|HOST_COHERENT), heap 0 of 15.92 GiB, host writes "
              "directly");
    const Table small = loadTable("nvidia_gtx1660_small_bar.json");
    EXPECT_EQ(describePlacement(place(small, BufferClass::ShaderRead)),
              "type 1 (DEVICE_LOCAL), heap 0 of 5.84 GiB, host writes through staging");
}

// The lavapipe table in the data folder is this machine's: the live device reports the same
// types and heap flags (heap sizes follow the machine's memory, so they are not compared).
TEST(MemoryPolicy, LiveLavapipeMatchesItsCapturedTable) {
    VulkanDeviceOptions o;
    o.echoMessages = false;
    VulkanDevice device(o);
    if (!device.isCpu()) GTEST_SKIP() << "the device is " << device.name() << ", not lavapipe";
    const Table t = loadTable("lavapipe_mesa_22_3_6.json");
    const VkPhysicalDeviceMemoryProperties& live = device.memoryProperties();
    ASSERT_EQ(live.memoryTypeCount, t.memory.memoryTypeCount);
    ASSERT_EQ(live.memoryHeapCount, t.memory.memoryHeapCount);
    for (std::uint32_t i = 0; i < live.memoryTypeCount; ++i) {
        EXPECT_EQ(live.memoryTypes[i].propertyFlags, t.memory.memoryTypes[i].propertyFlags);
        EXPECT_EQ(live.memoryTypes[i].heapIndex, t.memory.memoryTypes[i].heapIndex);
    }
    for (std::uint32_t h = 0; h < live.memoryHeapCount; ++h)
        EXPECT_EQ(live.memoryHeaps[h].flags, t.memory.memoryHeaps[h].flags);
}

} // namespace
} // namespace voxtier
