#include "volumetric/near_proxy.hpp"

#include <algorithm>

namespace voxtier {

std::array<glm::dvec4, 8> proxyBoxClipCorners(const CameraFrame& cam, const SpriteSetup& s) {
    // §3.10: model bounds grown by one virtual pixel (1/sigma voxel) on every side.
    const double m = 1.0 / s.lattice.sigma;
    const glm::dvec3 lo(-m), hi = glm::dvec3(s.lattice.dims) + m;
    std::array<glm::dvec4, 8> out;
    for (int k = 0; k < 8; ++k) {
        const glm::dvec3 p{(k & 1) ? hi.x : lo.x, (k & 2) ? hi.y : lo.y, (k & 4) ? hi.z : lo.z};
        out[std::size_t(k)] = clipFromCameraRelative(cam, s.pose.relativeWorld(p, cam.eye));
    }
    return out;
}

int proxyHullClipCorners(const CameraFrame& cam, const SpriteSetup& s,
                         std::span<glm::dvec4, kMaxHullCorners> out) {
    const SpriteLattice& L = s.lattice;
    const double k = s.pose.metresPerVoxel;
    // A pixel can be non-empty only if its sprite-plane point lies in a cell whose centre, or a
    // cardinal neighbour's centre, sends a parallel ray into the model box [0, N]^3, i.e. within
    // 1.5 cells (per axis) of the box's parallel projection H. Two pixels more (measured at the
    // centre's depth, an over-estimate of a pixel on the plane near the sprite) keep the
    // rasteriser's rounding away from every pixel that matters, as with the quad (CONTRACT.md
    // §3.10).
    const double m = 1.5 / L.sigma + 2.0 * cam.pixelScale() * s.viewDepth / k;
    std::array<glm::dvec2, 32> pts;
    for (int c = 0; c < 8; ++c) {
        const glm::dvec3 p =
            glm::dvec3((c & 1) ? L.dims.x : 0, (c & 2) ? L.dims.y : 0, (c & 4) ? L.dims.z : 0) -
            L.centre;
        const double u = glm::dot(p, L.right), v = glm::dot(p, L.up);
        for (int q = 0; q < 4; ++q)
            pts[std::size_t(4 * c + q)] = {u + ((q & 1) ? m : -m), v + ((q & 2) ? m : -m)};
    }
    // Andrew's monotone chain; collinear points dropped, counter-clockwise order.
    std::sort(pts.begin(), pts.end(),
              [](glm::dvec2 a, glm::dvec2 b) { return a.x < b.x || (a.x == b.x && a.y < b.y); });
    auto cross = [](glm::dvec2 o, glm::dvec2 a, glm::dvec2 b) {
        return (a.x - o.x) * (b.y - o.y) - (a.y - o.y) * (b.x - o.x);
    };
    std::array<glm::dvec2, 2 * 32> hull;
    std::size_t h = 0;
    for (std::size_t i = 0; i < pts.size(); ++i) {
        while (h >= 2 && cross(hull[h - 2], hull[h - 1], pts[i]) <= 0.0) --h;
        hull[h++] = pts[i];
    }
    for (std::size_t i = pts.size() - 1, lower = h + 1; i-- > 0;) {
        while (h >= lower && cross(hull[h - 2], hull[h - 1], pts[i]) <= 0.0) --h;
        hull[h++] = pts[i];
    }
    const std::size_t corners = h - 1; // the last point repeats the first
    if (corners > std::size_t(kMaxHullCorners) || corners < 3) {
        // Cannot happen for a box (hexagon + square: at most 10 corners), but never draw less
        // than the quad: its corners in fan order.
        int n = 0;
        for (int i : {0, 1, 3, 2}) out[std::size_t(n++)] = glm::dvec4(s.quad[std::size_t(i)]);
        return n;
    }
    const glm::dvec3 rW = s.pose.worldDirection(L.right), uW = s.pose.worldDirection(L.up);
    for (std::size_t i = 0; i < corners; ++i)
        out[i] = clipFromCameraRelative(cam, s.centreRel + k * (hull[i].x * rW + hull[i].y * uW));
    return int(corners);
}

} // namespace voxtier
