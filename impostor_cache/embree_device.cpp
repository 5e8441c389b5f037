#include "impostor_cache/detail/embree_device.hpp"

#include <atomic>
#include <cstdio>
#include <stdexcept>
#include <string>

namespace voxtier::detail {

namespace {

std::atomic<std::int64_t> gBytes{0};

void onError(void*, RTCError code, const char* message) {
    // Embree calls this on the failing thread; it cannot throw through C. The message goes to
    // stderr and the code stays pending for throwOnEmbreeError.
    std::fprintf(stderr, "voxtier: embree error %d: %s\n", int(code), message ? message : "");
}

bool onMemory(void*, ssize_t bytes, bool) {
    gBytes.fetch_add(std::int64_t(bytes), std::memory_order_relaxed);
    return true;
}

struct Device {
    RTCDevice handle = nullptr;
    Device() {
        handle = rtcNewDevice(nullptr);
        if (!handle)
            throw std::runtime_error("embree: rtcNewDevice failed (error " +
                                     std::to_string(int(rtcGetDeviceError(nullptr))) + ")");
        rtcSetDeviceErrorFunction(handle, onError, nullptr);
        rtcSetDeviceMemoryMonitorFunction(handle, onMemory, nullptr);
    }
    ~Device() { rtcReleaseDevice(handle); }
};

} // namespace

RTCDevice embreeDevice() {
    static Device device; // thread-safe initialisation; released at exit
    return device.handle;
}

std::int64_t embreeBytesInUse() {
    return gBytes.load(std::memory_order_relaxed);
}

void throwOnEmbreeError(const char* what) {
    const RTCError e = rtcGetDeviceError(embreeDevice());
    if (e != RTC_ERROR_NONE)
        throw std::runtime_error(std::string("embree: ") + what + " failed (error " +
                                 std::to_string(int(e)) + ")");
}

} // namespace voxtier::detail
