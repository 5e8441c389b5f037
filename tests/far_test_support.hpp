#pragma once
// Helpers shared by the far-tier suites (tests/far_*_test.cpp): render one scene through the
// near reference and through the far tier, and compare images with a readable first mismatch.
#include "core/procedural.hpp"
#include "image_checks.hpp"
#include "impostor_cache/far_frame.hpp"
#include "impostor_cache/snapshot_cache.hpp"
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
    for (const auto& sp : sprites)
        req.push_back({&sp, view ? std::optional<ViewId>(viewIdOf(set, *view)) : std::nullopt});
    drawFarSprites(s.models, req, cache, set, img);
    if (setups) *setups = std::move(sprites);
    return img;
}

/// 100 entities of `model` in a 10 x 10 wall at world z = `z`, all seen along one direction
/// (parallel view mode, the camera at the origin looking exactly along world -Z = voxel -Y):
/// one snapshot serves them all.
inline Scene hundredEntityWall(std::shared_ptr<VoxelModel> model, double z) {
    Scene s;
    s.render.viewMode = ViewMode::Parallel;
    s.models = {std::move(model)};
    for (int i = 0; i < 100; ++i) {
        Entity e;
        e.position = glm::dvec3(-5.0 + (i % 10), -5.0 + (i / 10), z);
        s.entities.push_back(e);
    }
    s.camera.position = {0, 0, 0};
    s.camera.target = {0, 0, -1};
    s.camera.width = 400;
    s.camera.height = 400;
    s.camera.fovYDeg = 30.0;
    return s;
}

/// A model of two animation frames of different shapes: an arrow (frame 0), a sphere (frame 1).
inline std::shared_ptr<VoxelModel> arrowThenSphere() {
    return std::make_shared<VoxelModel>(
        "two frames", proceduralPalette(),
        std::vector<VoxelGrid>{makeArrow(16)->frame(0), makeSphere(4)->frame(0)});
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
