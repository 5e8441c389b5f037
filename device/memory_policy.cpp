#include "device/memory_policy.hpp"

#include <cstdio>

namespace voxtier {

namespace {

// Not in older headers under these names everywhere; the values are the spec's.
constexpr VkMemoryPropertyFlags kDeviceCoherentAmd = 0x40;
constexpr VkMemoryPropertyFlags kDeviceUncachedAmd = 0x80;
constexpr VkMemoryPropertyFlags kNeverForBuffers = VK_MEMORY_PROPERTY_LAZILY_ALLOCATED_BIT |
                                                   VK_MEMORY_PROPERTY_PROTECTED_BIT |
                                                   kDeviceCoherentAmd | kDeviceUncachedAmd;

constexpr VkMemoryPropertyFlags kDL = VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT;
constexpr VkMemoryPropertyFlags kHV = VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT;
constexpr VkMemoryPropertyFlags kHC = VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;
constexpr VkMemoryPropertyFlags kCached = VK_MEMORY_PROPERTY_HOST_CACHED_BIT;

bool usable(const VkPhysicalDeviceMemoryProperties& m, std::uint32_t typeBits, std::uint32_t i) {
    const VkMemoryType& t = m.memoryTypes[i];
    return (typeBits & (1u << i)) && !(t.propertyFlags & kNeverForBuffers) &&
           t.heapIndex < m.memoryHeapCount && m.memoryHeaps[t.heapIndex].size > 0;
}

VkDeviceSize largestDeviceLocalHeap(const VkPhysicalDeviceMemoryProperties& m) {
    VkDeviceSize largest = 0;
    for (std::uint32_t h = 0; h < m.memoryHeapCount; ++h)
        if ((m.memoryHeaps[h].flags & VK_MEMORY_HEAP_DEVICE_LOCAL_BIT) &&
            m.memoryHeaps[h].size > largest)
            largest = m.memoryHeaps[h].size;
    return largest;
}

/// Device-local, host-visible and on a heap at least half the largest device-local heap: the
/// whole of video memory is mappable (resizable BAR) or video memory is system memory (UMA).
/// Half rather than equal: drivers report the BAR heap a little smaller than VRAM, or split it.
bool largeHostVisibleDeviceLocal(const VkPhysicalDeviceMemoryProperties& m, std::uint32_t i) {
    const VkMemoryType& t = m.memoryTypes[i];
    return (t.propertyFlags & (kDL | kHV)) == (kDL | kHV) &&
           2 * m.memoryHeaps[t.heapIndex].size >= largestDeviceLocalHeap(m);
}

/// The usable type with the highest score among those `eligible` accepts; ties go to the lower
/// index (the spec orders types so that earlier ones are no slower for the same properties).
template <class Eligible, class Score>
std::optional<std::uint32_t> best(const VkPhysicalDeviceMemoryProperties& m, std::uint32_t typeBits,
                                  Eligible eligible, Score score) {
    std::optional<std::uint32_t> chosen;
    int chosenScore = 0;
    for (std::uint32_t i = 0; i < m.memoryTypeCount; ++i) {
        if (!usable(m, typeBits, i) || !eligible(i)) continue;
        const int s = score(m.memoryTypes[i].propertyFlags);
        if (!chosen || s > chosenScore) {
            chosen = i;
            chosenScore = s;
        }
    }
    return chosen;
}

std::optional<std::uint32_t> deviceOnlyType(const VkPhysicalDeviceMemoryProperties& m,
                                            std::uint32_t typeBits) {
    // Device-local, and preferably invisible to the host so it does not take BAR space.
    auto dl = best(
        m, typeBits, [&](std::uint32_t i) { return (m.memoryTypes[i].propertyFlags & kDL) != 0; },
        [](VkMemoryPropertyFlags f) { return (f & kHV) ? 0 : 1; });
    if (dl) return dl;
    // No device-local type allowed for this resource: any usable type still works.
    return best(
        m, typeBits, [](std::uint32_t) { return true; }, [](VkMemoryPropertyFlags) { return 0; });
}

} // namespace

const char* bufferClassName(BufferClass c) {
    switch (c) {
    case BufferClass::ShaderRead:
        return "ShaderRead";
    case BufferClass::DeviceOnly:
        return "DeviceOnly";
    case BufferClass::Staging:
        return "Staging";
    case BufferClass::Readback:
        return "Readback";
    }
    return "?";
}

const char* hostWriteName(HostWrite w) {
    switch (w) {
    case HostWrite::None:
        return "none";
    case HostWrite::Direct:
        return "direct";
    case HostWrite::Staged:
        return "staged";
    }
    return "?";
}

bool hasLargeHostVisibleDeviceMemory(const VkPhysicalDeviceMemoryProperties& memory,
                                     std::uint32_t typeBits) {
    for (std::uint32_t i = 0; i < memory.memoryTypeCount; ++i)
        if (usable(memory, typeBits, i) && largeHostVisibleDeviceLocal(memory, i)) return true;
    return false;
}

std::optional<MemoryPlacement> placeBuffer(const VkPhysicalDeviceMemoryProperties& m,
                                           std::uint32_t typeBits, BufferClass c,
                                           const PlacementOptions& options) {
    std::optional<std::uint32_t> type;
    HostWrite write = HostWrite::None;
    bool map = false;
    switch (c) {
    case BufferClass::ShaderRead:
        if (!options.forceStaging)
            type = best(
                m, typeBits, [&](std::uint32_t i) { return largeHostVisibleDeviceLocal(m, i); },
                // Coherent first: no flush per write.
                [](VkMemoryPropertyFlags f) { return (f & kHC) ? 1 : 0; });
        if (type) {
            write = HostWrite::Direct;
            map = true;
        } else {
            type = deviceOnlyType(m, typeBits);
            write = HostWrite::Staged;
        }
        break;
    case BufferClass::DeviceOnly:
        type = deviceOnlyType(m, typeBits);
        break;
    case BufferClass::Staging:
        // Coherent, in system memory (not the BAR window or VRAM), write-combined rather than
        // cached: the host writes it once, sequentially.
        type = best(
            m, typeBits,
            [&](std::uint32_t i) { return (m.memoryTypes[i].propertyFlags & kHV) != 0; },
            [](VkMemoryPropertyFlags f) {
                return ((f & kHC) ? 4 : 0) + ((f & kDL) ? 0 : 2) + ((f & kCached) ? 0 : 1);
            });
        write = HostWrite::Direct;
        map = true;
        break;
    case BufferClass::Readback:
        // Host-cached above all (reads at cache speed), then coherent, then in system memory.
        type = best(
            m, typeBits,
            [&](std::uint32_t i) { return (m.memoryTypes[i].propertyFlags & kHV) != 0; },
            [](VkMemoryPropertyFlags f) {
                return ((f & kCached) ? 4 : 0) + ((f & kHC) ? 2 : 0) + ((f & kDL) ? 0 : 1);
            });
        map = true;
        break;
    }
    if (!type) return std::nullopt;
    MemoryPlacement p;
    p.typeIndex = *type;
    p.flags = m.memoryTypes[*type].propertyFlags;
    p.heapIndex = m.memoryTypes[*type].heapIndex;
    p.heapSize = m.memoryHeaps[p.heapIndex].size;
    p.hostWrite = write;
    p.mapped = map;
    const bool coherent = (p.flags & kHC) != 0;
    p.flushAfterWrite = map && write == HostWrite::Direct && !coherent;
    p.invalidateBeforeRead = map && c == BufferClass::Readback && !coherent;
    return p;
}

std::string memoryPropertyNames(VkMemoryPropertyFlags flags) {
    static constexpr struct {
        VkMemoryPropertyFlags bit;
        const char* name;
    } kNames[] = {{VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT, "DEVICE_LOCAL"},
                  {VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT, "HOST_VISIBLE"},
                  {VK_MEMORY_PROPERTY_HOST_COHERENT_BIT, "HOST_COHERENT"},
                  {VK_MEMORY_PROPERTY_HOST_CACHED_BIT, "HOST_CACHED"},
                  {VK_MEMORY_PROPERTY_LAZILY_ALLOCATED_BIT, "LAZILY_ALLOCATED"},
                  {VK_MEMORY_PROPERTY_PROTECTED_BIT, "PROTECTED"},
                  {kDeviceCoherentAmd, "DEVICE_COHERENT_AMD"},
                  {kDeviceUncachedAmd, "DEVICE_UNCACHED_AMD"},
                  {0x100, "RDMA_CAPABLE_NV"}};
    std::string out;
    VkMemoryPropertyFlags named = 0;
    for (const auto& n : kNames) {
        named |= n.bit;
        if (!(flags & n.bit)) continue;
        if (!out.empty()) out += '|';
        out += n.name;
    }
    if (flags & ~named) {
        char hex[16];
        std::snprintf(hex, sizeof hex, "0x%x", unsigned(flags & ~named));
        out += (out.empty() ? "" : "|") + std::string(hex);
    }
    return out.empty() ? "NONE" : out;
}

std::string describePlacement(const MemoryPlacement& p) {
    char heap[64];
    const double gib = double(p.heapSize) / double(1ull << 30);
    if (gib >= 1.0)
        std::snprintf(heap, sizeof heap, "%.2f GiB", gib);
    else
        std::snprintf(heap, sizeof heap, "%.0f MiB", double(p.heapSize) / double(1ull << 20));
    std::string s = "type " + std::to_string(p.typeIndex) + " (" + memoryPropertyNames(p.flags) +
                    "), heap " + std::to_string(p.heapIndex) + " of " + heap;
    if (p.hostWrite != HostWrite::None)
        s += std::string(", host writes ") +
             (p.hostWrite == HostWrite::Direct ? "directly" : "through staging");
    if (p.flushAfterWrite) s += " (flushed)";
    if (p.invalidateBeforeRead) s += ", host reads after an invalidate";
    return s;
}

} // namespace voxtier
