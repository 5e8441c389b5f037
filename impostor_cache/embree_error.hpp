#pragma once
// The one error channel for Embree (core/error.hpp lists the channels). Embree reports a failure
// through the error callback registered on the process's device (impostor_cache/embree_device.cpp)
// and a pending error code; the far tier checks after each build and throws EmbreeError naming
// what failed, the code and Embree's own message. It never continues after a failed call.
// Embree-free, like every public header of this module.
#include <stdexcept>
#include <string>

namespace voxtier {

/// An Embree call failed (or no device could be created). what() is one line:
/// "embree: <what> failed: <RTC_ERROR_...>[: <Embree's message>]".
class EmbreeError : public std::runtime_error {
  public:
    EmbreeError(const std::string& message, int code) : std::runtime_error(message), code_(code) {}
    /// The RTCError value.
    int code() const { return code_; }

  private:
    int code_;
};

} // namespace voxtier
