#pragma once
// Helpers shared by the suites that render whole frames through compose/frame.hpp.
#include "compose/frame.hpp"

namespace voxtier::test {

/// Frame options with the near tier drawn by the CPU reference (identical to Vulkan by the near
/// tier's own suite), so that paths of dozens of frames stay fast.
inline FrameOptions cpuNear() {
    FrameOptions o;
    o.nearBackend = NearBackend::Reference;
    return o;
}

} // namespace voxtier::test
