#pragma once
// Internal: the intersect context the baker passes to Embree. It extends RTCIntersectContext
// (Embree passes the pointer through to user-geometry callbacks unchanged), so the box
// callback gets the view's exact reciprocal direction without recomputing it per call.
#include <embree3/rtcore.h>
#include <glm/glm.hpp>

namespace voxtier::detail {

struct BakeIntersectContext {
    RTCIntersectContext base; // must stay first
    glm::vec3 dir{0.0f};
    glm::vec3 invDir{0.0f}; // 0 where dir is 0
};

} // namespace voxtier::detail
