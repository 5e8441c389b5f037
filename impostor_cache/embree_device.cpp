#include "impostor_cache/detail/embree_device.hpp"

#include "impostor_cache/embree_error.hpp"

#include <atomic>
#include <mutex>
#include <string>

namespace voxtier::detail {

namespace {

std::atomic<std::int64_t> gBytes{0};

/// The first error the callback saw and nobody has checked yet. Process-wide, not per thread:
/// Embree's pending code is per thread, and a brick build on a TBB worker must still fail the
/// scene build checked on the calling thread.
struct PendingError {
    std::mutex mutex;
    RTCError code = RTC_ERROR_NONE;
    std::string message;
};
PendingError gPending;

void onError(void*, RTCError code, const char* message) {
    // Embree calls this on the failing thread and it cannot throw through C: keep the first
    // error for the next throwOnEmbreeError.
    std::lock_guard lock(gPending.mutex);
    if (gPending.code != RTC_ERROR_NONE) return;
    gPending.code = code;
    gPending.message = message ? message : "";
}

bool onMemory(void*, ssize_t bytes, bool) {
    gBytes.fetch_add(std::int64_t(bytes), std::memory_order_relaxed);
    return true;
}

const char* errorName(RTCError code) {
    switch (code) {
    case RTC_ERROR_NONE:
        return "RTC_ERROR_NONE";
    case RTC_ERROR_UNKNOWN:
        return "RTC_ERROR_UNKNOWN";
    case RTC_ERROR_INVALID_ARGUMENT:
        return "RTC_ERROR_INVALID_ARGUMENT";
    case RTC_ERROR_INVALID_OPERATION:
        return "RTC_ERROR_INVALID_OPERATION";
    case RTC_ERROR_OUT_OF_MEMORY:
        return "RTC_ERROR_OUT_OF_MEMORY";
    case RTC_ERROR_UNSUPPORTED_CPU:
        return "RTC_ERROR_UNSUPPORTED_CPU";
    case RTC_ERROR_CANCELLED:
        return "RTC_ERROR_CANCELLED";
    }
    return "RTC_ERROR_?";
}

[[noreturn]] void throwFailure(const std::string& what, RTCError code, std::string message) {
    std::string text = "embree: " + what + " failed: " + errorName(code);
    if (!message.empty()) text += ": " + message;
    for (char& c : text)
        if (c == '\n' || c == '\r') c = ' ';
    throw EmbreeError(text, int(code));
}

struct Device {
    RTCDevice handle = nullptr;
    Device() : handle(newEmbreeDevice(nullptr)) {}
    ~Device() { rtcReleaseDevice(handle); }
};

} // namespace

RTCDevice newEmbreeDevice(const char* config) {
    RTCDevice device = rtcNewDevice(config);
    if (!device) {
        // No device, so no callback: the code is all Embree gives.
        const std::string call =
            config ? "rtcNewDevice(\"" + std::string(config) + "\")" : "rtcNewDevice";
        throwFailure(call, rtcGetDeviceError(nullptr), "");
    }
    rtcSetDeviceErrorFunction(device, onError, nullptr);
    rtcSetDeviceMemoryMonitorFunction(device, onMemory, nullptr);
    return device;
}

RTCDevice embreeDevice() {
    static Device device; // thread-safe initialisation; released at exit
    return device.handle;
}

std::int64_t embreeBytesInUse() {
    return gBytes.load(std::memory_order_relaxed);
}

void throwOnEmbreeError(const char* what) {
    const RTCError own = rtcGetDeviceError(embreeDevice()); // also clears this thread's code
    RTCError code = RTC_ERROR_NONE;
    std::string message;
    {
        std::lock_guard lock(gPending.mutex);
        std::swap(code, gPending.code);
        std::swap(message, gPending.message);
    }
    if (code == RTC_ERROR_NONE) code = own;
    if (code != RTC_ERROR_NONE) throwFailure(what, code, std::move(message));
}

} // namespace voxtier::detail
