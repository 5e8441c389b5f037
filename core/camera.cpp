#include "core/camera.hpp"

#include "core/error.hpp"

#include <cmath>

namespace voxtier {

namespace {
bool finite3(glm::dvec3 v) {
    return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}
} // namespace

CameraFrame makeCameraFrame(const Camera& cam) {
    if (!finite3(cam.position) || !finite3(cam.target) || !finite3(cam.up))
        throw InputError("", "camera", "position, target and up must be finite");
    if (!(cam.fovYDeg > 0.0 && cam.fovYDeg < 179.0))
        throw InputError("", "camera.fov_y", "vertical field of view must be in (0, 179) degrees");
    if (cam.width < 1 || cam.height < 1 || cam.width > Limits::kMaxImageDim ||
        cam.height > Limits::kMaxImageDim)
        throw InputError("", "camera.size",
                         "image size must be 1.." + std::to_string(Limits::kMaxImageDim) +
                             " per axis");
    if (!(cam.zNear > 0.0 && std::isfinite(cam.zNear)))
        throw InputError("", "camera.near", "near plane must be a positive finite distance");
    const glm::dvec3 view = cam.target - cam.position;
    const double len = glm::length(view);
    if (!(len > 0.0)) throw InputError("", "camera.target", "target equals position");
    CameraFrame f;
    f.eye = cam.position;
    f.forward = view / len;
    const glm::dvec3 r = glm::cross(f.forward, cam.up);
    const double rl = glm::length(r);
    if (!(rl > 1e-9 * glm::length(cam.up)))
        throw InputError("", "camera.up", "up is zero or parallel to the view direction");
    f.right = r / rl;
    f.up = glm::cross(f.right, f.forward);
    f.tanHalfFovY = std::tan(glm::radians(cam.fovYDeg) * 0.5);
    f.width = cam.width;
    f.height = cam.height;
    f.zNear = cam.zNear;
    return f;
}

glm::dvec4 clipFromCameraRelative(const CameraFrame& c, glm::dvec3 rel) {
    const glm::dvec3 v = viewFromCameraRelative(c, rel);
    const double aspect = double(c.width) / double(c.height);
    return {v.x / (c.tanHalfFovY * aspect), -v.y / c.tanHalfFovY, c.zNear, v.z};
}

} // namespace voxtier
