#pragma once
// Helpers shared by the far-tier suites (tests/far_*_test.cpp): render one scene through the
// near reference and through the far tier, and compare images with a readable first mismatch.
#include "impostor_cache/far_frame.hpp"
#include "impostor_cache/snapshot_cache.hpp"
#include "test_support.hpp"
#include "volumetric/reference_renderer.hpp"

#include <cstdio>
#include <string>
#include <vector>

namespace voxtier::test {

inline Image renderNear(const Scene& s, std::vector<SpriteSetup>* setups = nullptr) {
    const CameraFrame cam = makeCameraFrame(s.camera);
    auto sprites = setupSprites(s, cam, 0.0);
    Image img(cam.width, cam.height, s.render.background);
    renderReference(s.models, sprites, img);
    if (setups) *setups = std::move(sprites);
    return img;
}

inline Image renderFar(const Scene& s, SnapshotCache& cache, ViewSet set = ViewSet::Cube26,
                       std::vector<SpriteSetup>* setups = nullptr,
                       std::optional<int> view = std::nullopt) {
    const CameraFrame cam = makeCameraFrame(s.camera);
    auto sprites = setupSprites(s, cam, 0.0);
    Image img(cam.width, cam.height, s.render.background);
    std::vector<FarRequest> req;
    for (const auto& sp : sprites) req.push_back({&sp, view});
    drawFarSprites(s.models, req, cache, set, img);
    if (setups) *setups = std::move(sprites);
    return img;
}

/// Empty when identical, else the first differing pixel with both values.
inline std::string firstDifference(const Image& nearImg, const Image& farImg) {
    if (nearImg.width != farImg.width || nearImg.height != farImg.height)
        return "image sizes differ";
    for (int y = 0; y < nearImg.height; ++y)
        for (int x = 0; x < nearImg.width; ++x) {
            const std::size_t p = nearImg.index(x, y);
            if (nearImg.color[p] == farImg.color[p] && nearImg.depth[p] == farImg.depth[p] &&
                nearImg.id[p] == farImg.id[p])
                continue;
            std::size_t count = 0;
            for (std::size_t q = 0; q < nearImg.pixelCount(); ++q)
                count += nearImg.color[q] != farImg.color[q] ||
                         nearImg.depth[q] != farImg.depth[q] || nearImg.id[q] != farImg.id[q];
            char buf[256];
            std::snprintf(buf, sizeof buf,
                          "%zu pixels differ; first at (%d,%d): near colour %08x depth %.9g id %u, "
                          "far colour %08x depth %.9g id %u",
                          count, x, y, nearImg.color[p], double(nearImg.depth[p]), nearImg.id[p],
                          farImg.color[p], double(farImg.depth[p]), farImg.id[p]);
            return buf;
        }
    return {};
}

inline std::size_t drawnPixels(const Image& img) {
    std::size_t n = 0;
    for (auto id : img.id) n += id != kernel::VT_NO_ENTITY;
    return n;
}

} // namespace voxtier::test
