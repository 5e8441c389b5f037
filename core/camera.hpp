#pragma once
// Camera conventions (CONTRACT.md §2): world is right-handed, Y-up, metres; the camera looks
// along -Z of its view space; framebuffer row 0 is the top row; pixel centres sit at k + 0.5.
// Depth is reversed-Z with an infinite far plane: clip depth = zNear / viewDepth, 1 at the
// near plane, 0 at infinity, so "nearest wins" means "largest depth wins" (docs/CONTRACT.md §3.8).
#include <glm/glm.hpp>

namespace voxtier {

struct Camera {
    glm::dvec3 position{0.0, 2.0, 10.0};
    glm::dvec3 target{0.0};
    glm::dvec3 up{0.0, 1.0, 0.0};
    double fovYDeg = 50.0;
    int width = 960;
    int height = 540;
    double zNear = 0.05;
};

/// Everything per-frame code needs from a camera, derived once in double precision.
struct CameraFrame {
    glm::dvec3 eye;
    glm::dvec3 forward, right, up; ///< orthonormal, right = forward x up
    double tanHalfFovY;
    int width, height;
    double zNear;
    /// World-space extent of one pixel at view depth 1 (square pixels).
    double pixelScale() const { return 2.0 * tanHalfFovY / double(height); }
    /// Focal length in pixels: a length L at view depth z covers L * focalPx() / z pixels.
    double focalPx() const { return 0.5 * double(height) / tanHalfFovY; }
};

/// Throws InputError(file "camera") when the camera is degenerate (target == position, up
/// parallel to the view direction, non-finite values, fov outside (0, 179), bad image size).
CameraFrame makeCameraFrame(const Camera& camera);

/// Camera-relative view-space coordinates (x right, y up, z = depth along forward).
inline glm::dvec3 viewFromCameraRelative(const CameraFrame& c, glm::dvec3 rel) {
    return {glm::dot(rel, c.right), glm::dot(rel, c.up), glm::dot(rel, c.forward)};
}

/// Vulkan clip coordinates of a camera-relative world point: reversed-Z, infinite far plane,
/// y down (row 0 at the top). z/w = zNear / depth.
glm::dvec4 clipFromCameraRelative(const CameraFrame& c, glm::dvec3 rel);

} // namespace voxtier
