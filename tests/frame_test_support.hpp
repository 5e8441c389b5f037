#pragma once
// Helpers shared by the suites that render whole frames through compose/frame.hpp.
#include "compose/frame.hpp"

namespace voxtier::test {

/// Frame options with the near tier drawn by the CPU reference (identical to Vulkan by the near
/// tier's own suite), so that paths of dozens of frames stay fast.
inline FrameOptions cpuNear() {
    FrameOptions o;
    o.nearBackend = NearBackend::Reference;
    // The error-budget planner's cost bound adapts to measured times; a test must not depend
    // on timing (tests/error_budget_test.cpp gives it fixed costs where it tests it).
    o.costAwareBakes = false;
    return o;
}

} // namespace voxtier::test
