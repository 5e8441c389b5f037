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
    return renderReferenceImage(s, setups);
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
    return describeDifference(nearImg, farImg, "near", "far");
}

/// Empty when two snapshots hold the same cells (and, with `depth`, depths), else the first
/// differing cell with both values.
inline std::string firstSnapshotDifference(const Snapshot& a, const Snapshot& b,
                                           bool depth = false) {
    if (a.cells.size() != b.cells.size() || a.lattice.cellRange != b.lattice.cellRange)
        return "different lattices";
    for (std::size_t k = 0; k < a.cells.size(); ++k)
        if (!(a.cells[k] == b.cells[k]))
            return "cell " + std::to_string(k) + ": " + std::to_string(a.cells[k].index) + "/" +
                   std::to_string(a.cells[k].code) + " vs " + std::to_string(b.cells[k].index) +
                   "/" + std::to_string(b.cells[k].code);
    if (depth && a.depth != b.depth) return "depth differs";
    return {};
}

} // namespace voxtier::test
