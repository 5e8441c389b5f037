#pragma once
// The hard cases' scenes, built in code: a world far from the origin, a top-down camera, equal
// depths, an entity behind the camera or under a pixel, an eye inside a proxy box; and where
// the top-down marked bar's marker lands in an image.
#include "closed_form.hpp"
#include "core/image.hpp"
#include "core/scene.hpp"
#include "core/sprite.hpp"
#include "core/sprite_kernel.h"
#include "test_models.hpp"

#include <glm/glm.hpp>
#include <glm/gtc/quaternion.hpp>

#include <cstddef>
#include <vector>

namespace voxtier::test {

/// Four rotated entities of three models in front of a camera, the whole thing moved by
/// `offset`. Positions are dyadic so that, with a power-of-two offset, every camera-relative
/// double is bit-identical to the unshifted world (the far-from-origin hard case).
inline Scene hardCaseWorld(glm::dvec3 offset) {
    Scene s;
    s.render.sigma = 2.0;
    s.models = {solidBox({8, 6, 5}), solidBox({3, 3, 9}, 7), markedBar()};
    const glm::dvec3 spots[] = {
        {0.25, 0.0, -3.5}, {1.5, 0.5, -6.0}, {-2.0, 0.25, -9.5}, {0.75, -0.5, -4.25}};
    for (int i = 0; i < 4; ++i) {
        Entity e;
        e.model = i % 3;
        e.position = offset + spots[i];
        e.rotation = glm::angleAxis(0.3 * i + 0.1, glm::normalize(glm::dvec3(0.2, 1.0, 0.1 * i)));
        s.entities.push_back(e);
    }
    s.camera.position = offset + glm::dvec3(0.5, 1.25, 2.0);
    s.camera.target = offset + glm::dvec3(0.0, 0.0, -5.0);
    s.camera.width = 320;
    s.camera.height = 200;
    return s;
}

/// The RTS camera hard case: the marked bar seen straight down (up = world -Z), slightly
/// off-centre so the view direction is not exactly the camera forward.
inline Scene topDownMarkedBar() {
    Scene s;
    s.models = {markedBar()};
    s.render.sigma = 2.0;
    s.entities.push_back(Entity{});
    s.camera.position = {0.3, 6.0, 0.0};
    s.camera.target = {0.3, 0.0, 0.0};
    s.camera.up = {0.0, 0.0, -1.0};
    s.camera.width = s.camera.height = 200;
    return s;
}

/// Mean pixel positions of topDownMarkedBar's marker voxel (its lit top face, from the closed
/// form) and of the rest of the bar, outline excluded. Counts are 0 where nothing was seen.
struct MarkerAndBar {
    double markerX = 0, markerY = 0, barX = 0, barY = 0;
    int markerPixels = 0, barPixels = 0;
};
inline MarkerAndBar markerAndBarCentres(const Scene& s, const Image& img) {
    const Rgba8 marker =
        expectedLit(packRgba(20, 220, 60), s.light, {0, 0, 1},
                    glm::transpose(worldFromVoxelSwizzle()) * glm::normalize(s.light.direction));
    MarkerAndBar r;
    for (int y = 0; y < img.height; ++y)
        for (int x = 0; x < img.width; ++x) {
            const std::size_t p = img.index(x, y);
            if (img.id[p] != 0u || img.color[p] == kernel::VT_OUTLINE_RGBA) continue;
            if (img.color[p] == marker)
                r.markerX += x, r.markerY += y, ++r.markerPixels;
            else
                r.barX += x, r.barY += y, ++r.barPixels;
        }
    if (r.markerPixels) r.markerX /= r.markerPixels, r.markerY /= r.markerPixels;
    if (r.barPixels) r.barX /= r.barPixels, r.barY /= r.barPixels;
    return r;
}

/// Two overlapping boxes (palette indices 1 and 7) at exactly the same depth, parallel view
/// mode: the equal-depth hard case, where the lower entity id must own every shared pixel.
inline Scene equalDepthPair() {
    Scene s;
    s.models = {solidBox({6, 6, 6}, 1), solidBox({6, 6, 6}, 7)};
    for (int i = 0; i < 2; ++i) {
        Entity e;
        e.model = i;
        e.position = {0.25 * i, 0.0, -4.0}; // same depth along the camera forward (-Z)
        s.entities.push_back(e);
    }
    s.render.viewMode = ViewMode::Parallel;
    s.camera.position = {0.0, 0.3, 0.0};
    s.camera.target = {0.0, 0.3, -1.0};
    s.camera.width = s.camera.height = 160;
    return s;
}

/// hardCaseWorld's first entity alone, 3 m behind the camera (which looks along -Z).
inline Scene entityBehindCamera() {
    Scene s = hardCaseWorld(glm::dvec3(0.0));
    s.entities.resize(1);
    s.entities[0].position = s.camera.position + glm::dvec3(0.0, 0.0, 3.0);
    return s;
}

/// hardCaseWorld's first entity alone, 5 km ahead of the camera: under half a pixel.
inline Scene subPixelEntity() {
    Scene s = hardCaseWorld(glm::dvec3(0.0));
    s.entities.resize(1);
    s.entities[0].position = s.camera.position + glm::dvec3(0.0, 0.0, -5000.0);
    s.camera.target = s.entities[0].position;
    return s;
}

/// hardCaseWorld with the eye at entity 0's model centre, then exactly on its proxy box face
/// (voxel z = 5 + 1/sigma), looking the same way: entity 0 must be culled, the others drawn.
inline std::vector<Scene> eyeInsideAndOnProxyBox() {
    const Scene s = hardCaseWorld(glm::dvec3(0.0));
    const EntityPose pose =
        makeEntityPose(s.entities[0], s.models[0]->frame(0).dims(), s.render.voxelSize);
    std::vector<Scene> out;
    for (glm::dvec3 eyeVoxel :
         {glm::dvec3(4.0, 3.0, 2.5), glm::dvec3(4.0, 3.0, 5.0 + 1.0 / s.render.sigma)}) {
        Scene t = s;
        t.camera.position = pose.relativeWorld(eyeVoxel, glm::dvec3(0.0));
        t.camera.target = t.camera.position + (s.camera.target - s.camera.position);
        out.push_back(t);
    }
    return out;
}

} // namespace voxtier::test
