#pragma once
// Shared helpers for the test suites: small scenes built in code and an independent,
// closed-form model of what a sprite must look like (double precision, no kernel code).
#include "core/image.hpp"
#include "core/scene.hpp"
#include "core/sprite.hpp"

#include <glm/glm.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <memory>
#include <vector>

namespace voxtier::test {

inline std::shared_ptr<VoxelModel> solidBox(glm::ivec3 dims, std::uint8_t index = 1) {
    VoxelGrid g(dims);
    for (auto& v : g.data()) v = index;
    Palette p;
    for (int i = 1; i < 256; ++i) p.colors[std::size_t(i)] = packRgba(unsigned(i * 37 % 256), unsigned(i * 91 % 256), unsigned(i * 53 % 256));
    p.colors[1] = packRgba(200, 120, 40);
    return std::make_shared<VoxelModel>("box", p, std::vector<VoxelGrid>{g});
}

/// The 26 canonical directions (voxel space, from the model centre towards the viewer).
inline std::vector<glm::ivec3> canonicalDirections() {
    std::vector<glm::ivec3> out;
    for (int z = -1; z <= 1; ++z)
        for (int y = -1; y <= 1; ++y)
            for (int x = -1; x <= 1; ++x)
                if (x || y || z) out.push_back({x, y, z});
    return out;
}

/// A one-entity scene looking at the model centre from voxel-space direction `towardViewer`,
/// at the distance where one virtual pixel is exactly `magnification` screen pixels (the
/// sprite plane is then parallel to the image plane and the screen mapping is affine).
/// `rollQuarterTurns` rotates the camera about its forward axis by multiples of 90 degrees.
struct ViewSetup {
    Scene scene;
    double distance = 0.0;
};
inline ViewSetup viewAlong(std::shared_ptr<VoxelModel> model, glm::dvec3 towardViewer, double sigma,
                           int magnification, int rollQuarterTurns = 0, glm::dvec3 worldOffset = glm::dvec3(0.0)) {
    ViewSetup v;
    Scene& s = v.scene;
    s.render.sigma = sigma;
    s.render.voxelSize = 0.1;
    const glm::ivec3 dims = model->frame(0).dims();
    s.models.push_back(model);
    Entity e;
    e.model = 0;
    e.anchor = glm::dvec3(dims) * 0.5; // anchor at the centre: entity position = model centre
    e.position = worldOffset + glm::dvec3(0.25, 1.5, -2.0);
    s.entities.push_back(e);
    const glm::dvec3 wWorld = glm::normalize(worldFromVoxelSwizzle() * towardViewer);
    Camera& c = s.camera;
    c.fovYDeg = 40.0;
    // Image large enough for the sprite at this magnification (plus margin), even sizes.
    const double extent = glm::length(glm::dvec3(dims)) * sigma * magnification + 8.0 * magnification;
    c.width = c.height = 2 * int(std::ceil(extent * 0.5 + 4));
    const double pixelScale = 2.0 * std::tan(glm::radians(c.fovYDeg) * 0.5) / c.height;
    v.distance = s.render.voxelSize / (sigma * pixelScale * magnification);
    c.position = e.position + wWorld * v.distance;
    c.target = e.position;
    glm::dvec3 up = std::abs(wWorld.y) > 0.99 ? glm::dvec3(0, 0, -1) : glm::dvec3(0, 1, 0);
    const glm::dvec3 fwd = -wWorld;
    for (int r = 0; r < ((rollQuarterTurns % 4) + 4) % 4; ++r) up = glm::cross(fwd, up); // 90° about fwd
    c.up = up;
    c.zNear = 0.01;
    return v;
}

/// Independent closed-form silhouette of a solid box: for each lattice cell (§3.5, computed
/// here from the definition), does the parallel ray through its centre cross the box, and
/// through which face does it enter (axis priority x < y < z on ties)?
struct ExpectedCells {
    glm::ivec4 range;
    std::vector<int> kind;  // 0 empty, 1 solid, 2 outline
    std::vector<int> face;  // entered-face code for solid cells
    int w() const { return range.y - range.x + 1; }
    int h() const { return range.w - range.z + 1; }
    std::size_t at(int i, int j) const { return std::size_t(j - range.z) * std::size_t(w()) + std::size_t(i - range.x); }
    int count(int k) const {
        int n = 0;
        for (int v : kind) n += v == k;
        return n;
    }
};

inline ExpectedCells expectedBoxCells(glm::ivec3 dims, glm::dvec3 dir, glm::dvec3 up, double sigma) {
    dir = glm::normalize(dir);
    up = glm::normalize(up - glm::dot(up, dir) * dir);
    const glm::dvec3 right = glm::cross(dir, up);
    const glm::dvec3 c = glm::dvec3(dims) * 0.5;
    const glm::dvec3 g = glm::floor(c) - c;
    const double gu = glm::dot(g, right), gv = glm::dot(g, up);
    const double eu = glm::dot(glm::abs(right), c), ev = glm::dot(glm::abs(up), c);
    ExpectedCells e;
    e.range = {int(std::floor(sigma * (-eu - gu))) - 3, int(std::floor(sigma * (eu - gu))) + 3,
               int(std::floor(sigma * (-ev - gv))) - 3, int(std::floor(sigma * (ev - gv))) + 3};
    e.kind.assign(std::size_t(e.w() * e.h()), 0);
    e.face.assign(e.kind.size(), -1);
    for (int j = e.range.z; j <= e.range.w; ++j)
        for (int i = e.range.x; i <= e.range.y; ++i) {
            const glm::dvec3 p = c + (gu + (i + 0.5) / sigma) * right + (gv + (j + 0.5) / sigma) * up;
            double tIn = -1e300, tOut = 1e300;
            int axis = -1;
            bool miss = false;
            for (int k = 0; k < 3; ++k) {
                if (std::abs(dir[k]) < 1e-12) {
                    if (p[k] < 0.0 || p[k] >= dims[k]) miss = true;
                    continue;
                }
                const double t0 = (0.0 - p[k]) / dir[k], t1 = (dims[k] - p[k]) / dir[k];
                if (std::min(t0, t1) > tIn) {
                    tIn = std::min(t0, t1);
                    axis = k;
                }
                tOut = std::min(tOut, std::max(t0, t1));
            }
            if (!miss && tIn < tOut) {
                e.kind[e.at(i, j)] = 1;
                e.face[e.at(i, j)] = 2 * axis + (dir[axis] > 0 ? 0 : 1);
            }
        }
    // Cardinal dilation of the coverage: the outline.
    std::vector<int> k2 = e.kind;
    for (int j = e.range.z; j <= e.range.w; ++j)
        for (int i = e.range.x; i <= e.range.y; ++i) {
            if (e.kind[e.at(i, j)] == 1) continue;
            auto solid = [&](int a, int b) {
                return a >= e.range.x && a <= e.range.y && b >= e.range.z && b <= e.range.w && e.kind[e.at(a, b)] == 1;
            };
            if (solid(i - 1, j) || solid(i + 1, j) || solid(i, j - 1) || solid(i, j + 1)) k2[e.at(i, j)] = 2;
        }
    e.kind = k2;
    return e;
}

/// The lighting formula of §3.7, written independently: channel * factor, rounded.
inline Rgba8 expectedLit(Rgba8 base, const Light& light, glm::dvec3 normalVoxel, glm::dvec3 lightVoxel) {
    const double k = std::clamp(light.ambient + light.diffuse * std::max(0.0, glm::dot(normalVoxel, lightVoxel)), 0.0, 4.0);
    const long long f = std::llround(k * 65536.0);
    unsigned ch[3];
    for (int i = 0; i < 3; ++i) ch[i] = unsigned(std::min<long long>(255, (channel(base, i) * f + 32768) >> 16));
    return packRgba(ch[0], ch[1], ch[2], 255);
}

} // namespace voxtier::test
