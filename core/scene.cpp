#include "core/scene.hpp"

#include <algorithm>

namespace voxtier {

const char* toString(SelectorMetric m) {
    switch (m) {
    case SelectorMetric::Distance:
        return "distance";
    case SelectorMetric::RadiusPx:
        return "radius_px";
    case SelectorMetric::ErrorPx:
        return "error_px";
    case SelectorMetric::ErrorBudget:
        return "error_budget";
    }
    return "?";
}

Camera Scene::cameraAt(double t) const {
    Camera c = camera;
    if (!path || path->keys.empty()) return c;
    const auto& keys = path->keys;
    auto apply = [&](const CameraKey& k) {
        c.position = k.position;
        c.target = k.target;
        if (k.up) c.up = *k.up;
        if (k.fovYDeg) c.fovYDeg = *k.fovYDeg;
    };
    if (t <= keys.front().time) {
        apply(keys.front());
        return c;
    }
    if (t >= keys.back().time) {
        apply(keys.back());
        return c;
    }
    const auto hi = std::upper_bound(keys.begin(), keys.end(), t,
                                     [](double v, const CameraKey& k) { return v < k.time; });
    const CameraKey& b = *hi;
    const CameraKey& a = *(hi - 1);
    const double s = (t - a.time) / (b.time - a.time);
    c.position = glm::mix(a.position, b.position, s);
    c.target = glm::mix(a.target, b.target, s);
    const glm::dvec3 upA = a.up.value_or(camera.up), upB = b.up.value_or(camera.up);
    c.up = glm::mix(upA, upB, s);
    const double fovA = a.fovYDeg.value_or(camera.fovYDeg),
                 fovB = b.fovYDeg.value_or(camera.fovYDeg);
    c.fovYDeg = fovA + (fovB - fovA) * s;
    return c;
}

} // namespace voxtier
