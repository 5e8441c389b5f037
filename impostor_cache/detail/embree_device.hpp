#pragma once
// Internal to impostor_cache (not installed): the one Embree device of the process, its error
// callback and memory monitor, and the FTZ/DAZ scope every Embree call runs in.
#include <embree3/rtcore.h>

#include <cstdint>
#include <xmmintrin.h>

namespace voxtier::detail {

/// Created on first use (newEmbreeDevice(nullptr)); released at process exit.
RTCDevice embreeDevice();
/// A device made with rtcNewDevice(config), the error callback and the memory monitor
/// registered. Throws EmbreeError (impostor_cache/embree_error.hpp) when Embree refuses.
RTCDevice newEmbreeDevice(const char* config);
/// Bytes Embree currently holds (device memory monitor).
std::int64_t embreeBytesInUse();
/// The check after Embree calls: throws EmbreeError naming `what`, with the code and Embree's
/// message, if any thread's call reported an error since the last check (then clears it).
void throwOnEmbreeError(const char* what);

/// Embree's traversal is only fast with denormals flushed (its own advice: set FTZ and DAZ in
/// every thread that calls it). The previous MXCSR is restored on exit, because the code
/// around the call emulates the near kernel's float arithmetic exactly, and that kernel runs
/// without FTZ/DAZ.
class FlushDenormalsScope {
  public:
    FlushDenormalsScope() : saved_(_mm_getcsr()) { _mm_setcsr(saved_ | kFtzDaz); }
    ~FlushDenormalsScope() { _mm_setcsr(saved_); }
    FlushDenormalsScope(const FlushDenormalsScope&) = delete;
    FlushDenormalsScope& operator=(const FlushDenormalsScope&) = delete;

  private:
    static constexpr unsigned kFtzDaz = 0x8040u; // MXCSR bits 15 (FTZ) and 6 (DAZ)
    unsigned saved_;
};

} // namespace voxtier::detail
