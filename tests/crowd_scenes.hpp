#pragma once
// The scenes the occlusion suites (tests/occlusion_cull_test.cpp for the CPU tiers,
// tests/vulkan_cull_test.cpp for the Vulkan near tier) both draw with and without culling, and the
// one the suites of kept records (near_records_test, far_records_test) both draw frame by frame.
#include "core/procedural.hpp"
#include "core/scene_loader.hpp"
#include "source_tree.hpp"

#include <nlohmann/json.hpp>

#include <fstream>
#include <vector>

namespace voxtier::test {

/// A corridor of 60 entities walked through with 6-frame cross-fades (distance selector, near
/// at 3 m, far at 5 m): both tiers draw a fading entity, complementary dither halves at one depth.
inline Scene crossFadeCorridor() {
    Scene s;
    s.render.voxelSize = 0.1;
    s.models = {makeArrow(16), makeBox({6, 8, 10}), makeSphere(5)};
    for (int i = 0; i < 60; ++i) {
        Entity e;
        e.model = i % 3;
        e.position = {0.3 * (i % 5) - 0.6, 0.0, -1.2 * (i / 5)};
        e.rotation = glm::angleAxis(0.5 * i, glm::dvec3(0, 1, 0));
        s.entities.push_back(e);
    }
    s.camera.width = 200;
    s.camera.height = 120;
    CameraPath path;
    path.fps = 10;
    CameraKey a, b;
    a.time = 0, a.position = {0, 0.5, 4}, a.target = {0, 0, -20};
    b.time = 2, b.position = {0, 0.5, -4}, b.target = {0, 0, -30};
    path.keys = {a, b};
    s.path = path;
    s.selector.nearAt = 3;
    s.selector.farAt = 5;
    s.selector.crossfadeFrames = 6;
    return s;
}

/// Equal depths everywhere: stacks of three entities at one position (identical sprites, the id
/// rule alone decides every pixel) in rows at one view depth, the first row's sprites crossing
/// the near plane.
inline Scene equalDepthStacks() {
    Scene s;
    s.render.voxelSize = 0.1;
    s.models = {makeBox({8, 8, 8}), makeSphere(6)};
    for (int row = 0; row < 6; ++row)
        for (int col = -6; col <= 6; ++col)
            for (int copy = 0; copy < 3; ++copy) { // three entities in one place
                Entity e;
                e.model = (row + col + 6 + copy) % 2;
                e.position = {0.5 * col, 0.0, -0.4 - 0.8 * row};
                e.rotation = glm::angleAxis(0.3 * copy, glm::dvec3(0, 1, 0));
                s.entities.push_back(e);
            }
    s.camera.width = 160;
    s.camera.height = 100;
    s.camera.position = {0, 0.1, 0.2}; // the first row's sprites cross the near plane
    s.camera.target = {0, 0, -10};
    s.camera.zNear = 0.5;
    return s;
}

/// The bench's tank army with its crowds scaled to `entities` in all, seen at width x height.
inline Scene tankArmy(int entities, int width, int height) {
    std::ifstream in(sourcePath("scenes/bench/tank_army.json"));
    nlohmann::json doc = nlohmann::json::parse(in);
    long long crowd = 0;
    for (const auto& c : doc["crowds"]) crowd += c.value("count", 0);
    const int plain = doc.contains("entities") ? int(doc["entities"].size()) : 0;
    int left = entities - plain;
    for (std::size_t i = 0; i < doc["crowds"].size(); ++i) {
        const bool last = i + 1 == doc["crowds"].size();
        const int n =
            last ? left
                 : int(double(doc["crowds"][i].value("count", 0)) * entities / double(crowd));
        doc["crowds"][i]["count"] = n;
        left -= n;
    }
    doc["camera"]["size"] = {width, height};
    return loadSceneJson(doc, "tank_army_" + std::to_string(entities), sourcePath("scenes/bench"));
}

/// The bench's tank army, 240 tanks, half of them stepping their 8 animation frames at 8 frames a
/// second, under a still camera, a quarter of the pixels (lavapipe is the device in CI),
/// cross-fading over 3 frames between tiers by distance (near at 100 m, far beyond 110 m). Every
/// tank starts at frame 0 and every other one stays there: a step brings frames of a model that
/// no sprite showed before, first shown where no sprite of that model was first before.
inline Scene stillSteppingArmy() {
    Scene s = loadScene(sourcePath("scenes/bench/tank_army.json"));
    s.path.reset();
    s.entities.resize(240);
    for (std::size_t e = 0; e < s.entities.size(); ++e) {
        s.entities[e].frame = 0;
        if (e % 2) s.entities[e].fps = 0.0;
    }
    s.camera.width = 320;
    s.camera.height = 180;
    s.selector.metric = SelectorMetric::Distance;
    s.selector.nearAt = 100.0;
    s.selector.farAt = 110.0;
    s.selector.crossfadeFrames = 3;
    return s;
}

/// What frame k of the kept-records tests changes in a stillSteppingArmy() (28 frames: k from 18
/// on are drawn hybrid): three tanks moved at frames 5 and 13, the camera at 9, a voxel edit of
/// model 0 at 11, and every 7th tank sent past far_at at 20 and back at 24 (tier switches,
/// cross-faded by copies). The near and far records tests run the same script.
inline void changeSteppingArmy(Scene& s, int k) {
    if (k == 5 || k == 13)
        for (const std::size_t e : {3u, 50u, 120u}) s.entities[e].position.x += 0.2;
    if (k == 9) s.camera.position += glm::dvec3(0.2, 0.0, 0.1);
    if (k == 11) s.models[0]->clearBox(0, Box3i{{0, 0, 8}, {32, 32, 16}});
    if (k == 20 || k == 24)
        for (std::size_t e = 0; e < 240; e += 7) s.entities[e].position.z += k == 20 ? -60.0 : 60.0;
}

} // namespace voxtier::test
