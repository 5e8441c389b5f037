#include "compose/backdrop.hpp"

#include "core/sprite_kernel.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <optional>

namespace voxtier {

namespace {

unsigned mix(unsigned a, unsigned b, double w) {
    return unsigned(std::lround(double(a) + (double(b) - double(a)) * w));
}

/// Distance in metres from `v` to the nearest multiple of `spacing`.
double offLine(double v, double spacing) {
    return std::abs(v - spacing * std::round(v / spacing));
}

} // namespace

Rgba8 groundPixel(const GroundPlane& g, const CameraFrame& cam, Rgba8 background, int x, int y) {
    // The ray through a pixel-grid point meets the plane y = height in front of the eye, or not.
    const double px = cam.pixelScale();
    const auto hitAt = [&](double sx, double sy, double* distance) -> std::optional<glm::dvec3> {
        const glm::dvec3 dir = cam.forward + (sx - 0.5 * cam.width) * px * cam.right -
                               (sy - 0.5 * cam.height) * px * cam.up;
        const double t = (g.height - cam.eye.y) / dir.y;
        if (!(t > 0.0) || !std::isfinite(t)) return std::nullopt;
        if (distance) *distance = t * glm::length(dir);
        return cam.eye + t * dir;
    };
    double distance = 0.0;
    const auto hit = hitAt(x + 0.5, y + 0.5, &distance);
    if (!hit) return background;
    const double weight = std::clamp(1.0 - distance / g.fadeDistance, 0.0, 1.0);
    // A line is at least as wide as the pixel's footprint on the ground along each axis, so lines
    // seen at a grazing angle stay visible instead of falling between pixel centres.
    glm::dvec2 footprint(g.spacing);
    const auto right = hitAt(x + 1.5, y + 0.5, nullptr), down = hitAt(x + 0.5, y + 1.5, nullptr);
    if (right && down)
        footprint = glm::max(glm::abs(glm::dvec2(right->x - hit->x, right->z - hit->z)),
                             glm::abs(glm::dvec2(down->x - hit->x, down->z - hit->z)));
    const bool line = g.lineWidth > 0.0 &&
                      (offLine(hit->x, g.spacing) < 0.5 * std::max(g.lineWidth, footprint.x) ||
                       offLine(hit->z, g.spacing) < 0.5 * std::max(g.lineWidth, footprint.y));
    const Rgba8 c = line ? g.lineColor : g.color;
    return packRgba(mix(channel(background, 0), channel(c, 0), weight),
                    mix(channel(background, 1), channel(c, 1), weight),
                    mix(channel(background, 2), channel(c, 2), weight),
                    mix(channel(background, 3), 255, weight));
}

void drawBackdrop(const Scene& scene, const CameraFrame& cam, Image& image) {
    const Rgba8 background = scene.render.background;
    if (!scene.ground && channel(background, 3) == 255) return;
    // A colour-only frame (FrameOptions::depthAndIds false) has no id plane: sprites write
    // alpha 255, and the frame cleared its targets to a colour that is not opaque where this
    // fills anything in.
    const bool byAlpha = image.id.empty();
    tbb::parallel_for(0, image.height, [&](int y) {
        for (int x = 0; x < image.width; ++x) {
            const std::size_t p = image.index(x, y);
            if (byAlpha ? channel(image.color[p], 3) == 255 : image.id[p] != kernel::VT_NO_ENTITY)
                continue;
            image.color[p] =
                scene.ground ? groundPixel(*scene.ground, cam, background, x, y) : background;
        }
    });
}

} // namespace voxtier
