#pragma once
// The directions and views the sweeps look along: the 26 canonical directions, seeded random
// ones, a model view toward a direction, and a one-entity scene at an exact magnification.
#include "core/model_view.hpp"
#include "core/scene.hpp"
#include "core/sprite.hpp"
#include "core/voxel_model.hpp"

#include <glm/glm.hpp>

#include <algorithm>
#include <cmath>
#include <memory>
#include <random>
#include <vector>

namespace voxtier::test {

/// The 26 canonical directions (voxel space, from the model centre towards the viewer).
inline std::vector<glm::ivec3> canonicalDirections() {
    std::vector<glm::ivec3> out;
    for (int z = -1; z <= 1; ++z)
        for (int y = -1; y <= 1; ++y)
            for (int x = -1; x <= 1; ++x)
                if (x || y || z) out.push_back({x, y, z});
    return out;
}

/// The identity sweeps' directions (voxel space, towards the viewer): the 26 canonical ones,
/// then 20 seeded random ones.
inline std::vector<glm::dvec3> sweepDirections() {
    std::vector<glm::dvec3> dirs;
    for (glm::ivec3 w : canonicalDirections()) dirs.push_back(glm::dvec3(w));
    std::mt19937_64 rng(20240601);
    std::normal_distribution<double> n(0.0, 1.0);
    while (dirs.size() < 26 + 20) {
        const glm::dvec3 d{n(rng), n(rng), n(rng)};
        if (glm::length(d) > 1e-3) dirs.push_back(glm::normalize(d));
    }
    return dirs;
}

/// A model view (the model fitted to a width x height image) looking along the voxel-space
/// direction `voxelDir` (towards the viewer). Canonical directions become azimuth/elevation
/// round trips with rounding zeros; the 1e-6 direction snap of core/sprite.cpp must restore them.
inline ModelView viewToward(glm::dvec3 voxelDir, double sigma, int width, int height) {
    const glm::dvec3 w = glm::normalize(worldFromVoxelSwizzle() * voxelDir);
    ModelView v;
    v.elevationDeg = glm::degrees(std::asin(std::clamp(w.y, -1.0, 1.0)));
    v.azimuthDeg = std::abs(w.y) > 0.999999 ? 0.0 : glm::degrees(std::atan2(w.x, w.z));
    v.sigma = sigma;
    v.width = width;
    v.height = height;
    return v;
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
                           int magnification, int rollQuarterTurns = 0,
                           glm::dvec3 worldOffset = glm::dvec3(0.0)) {
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
    const double extent =
        glm::length(glm::dvec3(dims)) * sigma * magnification + 8.0 * magnification;
    c.width = c.height = 2 * int(std::ceil(extent * 0.5 + 4));
    const double pixelScale = 2.0 * std::tan(glm::radians(c.fovYDeg) * 0.5) / c.height;
    v.distance = s.render.voxelSize / (sigma * pixelScale * magnification);
    c.position = e.position + wWorld * v.distance;
    c.target = e.position;
    glm::dvec3 up = std::abs(wWorld.y) > 0.99 ? glm::dvec3(0, 0, -1) : glm::dvec3(0, 1, 0);
    const glm::dvec3 fwd = -wWorld;
    for (int r = 0; r < ((rollQuarterTurns % 4) + 4) % 4; ++r)
        up = glm::cross(fwd, up); // 90° about fwd
    c.up = up;
    c.zNear = 0.01;
    return v;
}

} // namespace voxtier::test
