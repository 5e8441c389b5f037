#pragma once
// The closed-form model of a sprite, written independently of the kernel in double precision:
// which lattice cells a solid box covers and outlines, through which face each is entered, how
// a face is lit, and the count of an image's pixels that differ from that answer.
#include "core/camera.hpp"
#include "core/image.hpp"
#include "core/scene.hpp"
#include "core/sprite.hpp"
#include "core/voxel_model.hpp"
#include "view_sweeps.hpp"

#include <glm/glm.hpp>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdio>
#include <string>
#include <vector>

namespace voxtier::test {

/// Independent closed-form silhouette of a solid box: for each lattice cell (§3.5, computed
/// here from the definition), does the parallel ray through its centre cross the box, and
/// through which face does it enter (axis priority x < y < z on ties)?
struct ExpectedCells {
    glm::ivec4 range;
    std::vector<int> kind; // 0 empty, 1 solid, 2 outline
    std::vector<int> face; // entered-face code for solid cells
    int w() const { return range.y - range.x + 1; }
    int h() const { return range.w - range.z + 1; }
    std::size_t at(int i, int j) const {
        return std::size_t(j - range.z) * std::size_t(w()) + std::size_t(i - range.x);
    }
    int count(int k) const {
        int n = 0;
        for (int v : kind) n += v == k;
        return n;
    }
};

inline ExpectedCells expectedBoxCells(glm::ivec3 dims, glm::dvec3 dir, glm::dvec3 up,
                                      double sigma) {
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
            const glm::dvec3 p =
                c + (gu + (i + 0.5) / sigma) * right + (gv + (j + 0.5) / sigma) * up;
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
                return a >= e.range.x && a <= e.range.y && b >= e.range.z && b <= e.range.w &&
                       e.kind[e.at(a, b)] == 1;
            };
            if (solid(i - 1, j) || solid(i + 1, j) || solid(i, j - 1) || solid(i, j + 1))
                k2[e.at(i, j)] = 2;
        }
    e.kind = k2;
    return e;
}

/// The lighting formula of §3.7, written independently: channel * factor, rounded.
inline Rgba8 expectedLit(Rgba8 base, const Light& light, glm::dvec3 normalVoxel,
                         glm::dvec3 lightVoxel) {
    const double k = std::clamp(
        light.ambient + light.diffuse * std::max(0.0, glm::dot(normalVoxel, lightVoxel)), 0.0, 4.0);
    const long long f = std::llround(k * 65536.0);
    unsigned ch[3];
    for (int i = 0; i < 3; ++i)
        ch[i] = unsigned(std::min<long long>(255, (channel(base, i) * f + 32768) >> 16));
    return packRgba(ch[0], ch[1], ch[2], 255);
}

/// The closed-form check of tests/reference_golden_test.cpp (compareWithClosedForm), shared
/// here so the Vulkan tests hold the GPU image to the same independent answer: a solid box from
/// viewAlong(towardViewer) must be exactly the double-precision silhouette, outline, lighting,
/// depth and id. Returns the number of wrong pixels and describes the first.
inline int countClosedFormMismatches(const ViewSetup& v, glm::dvec3 towardViewer, const Image& img,
                                     std::string* first = nullptr,
                                     ExpectedCells* expected = nullptr) {
    const Scene& s = v.scene;
    const CameraFrame cam = makeCameraFrame(s.camera);
    const glm::dmat3 voxelFromWorld = glm::transpose(worldFromVoxelSwizzle());
    const glm::dvec3 dir = -glm::normalize(towardViewer);
    const glm::dvec3 upVoxel = voxelFromWorld * cam.up;
    const double sigma = s.render.sigma;
    const glm::ivec3 dims = s.models[0]->frame(0).dims();
    const ExpectedCells e = expectedBoxCells(dims, dir, upVoxel, sigma);
    if (expected) *expected = e;
    const glm::dvec3 up = glm::normalize(upVoxel - glm::dot(upVoxel, dir) * dir);
    const glm::dvec3 right = glm::cross(dir, up);
    const glm::dvec3 c = glm::dvec3(dims) * 0.5;
    const glm::dvec3 g = glm::floor(c) - c;
    const double gu = glm::dot(g, right), gv = glm::dot(g, up);
    const double m =
        double(std::lround(s.render.voxelSize / (sigma * cam.pixelScale() * v.distance)));
    const glm::dvec3 lightVoxel = voxelFromWorld * glm::normalize(s.light.direction);
    const float depth = float(cam.zNear / v.distance);
    int count = 0;
    for (int y = 0; y < img.height; ++y)
        for (int x = 0; x < img.width; ++x) {
            const double su = (x + 0.5 - img.width * 0.5) / m;
            const double sv = -(y + 0.5 - img.height * 0.5) / m;
            const int i = int(std::floor(su - sigma * gu)), j = int(std::floor(sv - sigma * gv));
            int kind = 0, face = -1;
            if (i >= e.range.x && i <= e.range.y && j >= e.range.z && j <= e.range.w) {
                kind = e.kind[e.at(i, j)];
                face = e.face[e.at(i, j)];
            }
            const std::size_t p = img.index(x, y);
            Rgba8 want = s.render.background;
            if (kind == 1)
                want = expectedLit(s.models[0]->palette().colors[1], s.light,
                                   faceNormal(unsigned(face)), lightVoxel);
            if (kind == 2) want = packRgba(0, 0, 0, 255);
            const bool idOk = kind == 0 ? img.id[p] == kernel::VT_NO_ENTITY : img.id[p] == 0u;
            const bool depthOk =
                kind == 0 ? img.depth[p] == 0.0f : std::abs(img.depth[p] - depth) <= 1e-6f * depth;
            if (img.color[p] != want || !idOk || !depthOk) {
                if (count++ == 0 && first) {
                    char buf[200];
                    std::snprintf(buf, sizeof buf,
                                  "pixel (%d,%d) cell (%d,%d): expected kind %d colour %08x, got "
                                  "colour %08x id %u",
                                  x, y, i, j, kind, want, img.color[p], img.id[p]);
                    *first = buf;
                }
            }
        }
    return count;
}

} // namespace voxtier::test
