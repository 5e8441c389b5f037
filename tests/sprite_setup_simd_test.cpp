// The SIMD sprite set-up (core/sprite_setup_simd.cpp) against the scalar setupSpriteInto, every
// field bit for bit, and the selection inputs it derives on its lanes against selectionInputs: the
// bench's tank army along its camera path, and entities placed for each branch of the set-up (every
// cull reason, snapped and unsnapped view directions, quads that cross the near plane), at three
// sigmas, in both view modes, in batches of every length around the SIMD width. (The lattice's
// fallback up vector is not among them: a visible sprite's view direction is never within 1e-6 of
// the camera's up, as that puts it at view depth ~0, behind the near plane.)
#include "core/scene_loader.hpp"
#include "core/sprite.hpp"
#include "source_tree.hpp"
#include "sprite_compare.hpp"
#include "test_models.hpp"

#include <glm/gtc/quaternion.hpp>
#include <gtest/gtest.h>

#include <bit>
#include <map>
#include <random>

namespace voxtier {
namespace {

using test::sameSelection;
using test::sameSprite;

/// Sets every (entity, constants) pair up both ways and compares; counts each cull reason.
void expectSameSetUps(const std::vector<SpriteConstants>& constants, const CameraFrame& cam,
                      const RenderParams& params, std::map<CullReason, int>* reasons = nullptr) {
    std::vector<SpriteSetup> scalar(constants.size()), simd(constants.size());
    std::vector<SpriteSelectionInputs> selection(constants.size());
    // Filled with what no set-up writes, so that a job that leaves them shows.
    std::vector<std::uint8_t> visible(constants.size(), 7);
    std::vector<float> depth(constants.size(), -1.0f);
    std::vector<SpriteSetupJob> jobs;
    for (std::size_t i = 0; i < constants.size(); ++i) {
        setupSpriteInto(scalar[i], cam, constants[i], std::uint32_t(i), params);
        jobs.push_back(
            {&simd[i], &constants[i], std::uint32_t(i), &selection[i], &visible[i], &depth[i]});
    }
    setupSpritesInto(jobs, cam, params);
    for (std::size_t i = 0; i < constants.size(); ++i) {
        ASSERT_TRUE(sameSprite(simd[i], scalar[i]))
            << " (SIMD target " << spriteSetupSimdTarget() << ", sigma " << params.sigma << ")";
        // The selection inputs the lanes derive beside the sprite.
        ASSERT_TRUE(sameSelection(selection[i], selectionInputs(scalar[i])))
            << " (entity " << i << ", SIMD target " << spriteSetupSimdTarget() << ")";
        // The visibility and depth the jobs write beside it (a store's per-entity copies).
        ASSERT_EQ(visible[i], scalar[i].visible() ? 1 : 0) << " (entity " << i << ")";
        ASSERT_EQ(std::bit_cast<std::uint32_t>(depth[i]),
                  std::bit_cast<std::uint32_t>(scalar[i].gpu.depth))
            << " (entity " << i << ")";
        if (reasons) ++(*reasons)[scalar[i].cull];
    }
}

TEST(SpriteSetupSimd, TheTankArmyAlongItsPathEqualsTheScalarSetUp) {
    const Scene s = loadScene(test::sourcePath("scenes/bench/tank_army.json"));
    for (const double t : {0.0, 1.3, 2.7, 4.0}) {
        std::vector<SpriteConstants> constants;
        for (const Entity& e : s.entities) {
            const VoxelModel& m = *s.models.at(std::size_t(e.model));
            constants.push_back(spriteConstants(e, m, e.frameAt(m, t), s.render, s.light));
        }
        expectSameSetUps(constants, makeCameraFrame(s.cameraAt(t)), s.render);
    }
}

TEST(SpriteSetupSimd, EveryBranchOfTheSetUpEqualsTheScalarSetUp) {
    std::mt19937_64 rng(45);
    std::uniform_real_distribution<double> unit(-1.0, 1.0);
    const std::vector<std::shared_ptr<VoxelModel>> models = {
        test::solidBox({1, 1, 1}), test::solidBox({16, 16, 16}), test::solidBox({7, 3, 200}),
        test::solidBox({32, 32, 16})};
    Camera camera;
    camera.position = {0.3, 1.7, 4.0};
    camera.target = {-0.2, 0.4, -3.0};
    camera.width = 320;
    camera.height = 200;
    const CameraFrame cam = makeCameraFrame(camera);
    const Light light;

    // Rotations: none, quarter turns (axis-aligned views whose components snap to 0) and random.
    const auto rotation = [&](int kind) {
        if (kind == 0) return glm::dquat(1.0, 0.0, 0.0, 0.0);
        if (kind == 1)
            return glm::angleAxis(glm::radians(90.0 * double(rng() % 4)), glm::dvec3(0, 1, 0)) *
                   glm::angleAxis(glm::radians(90.0 * double(rng() % 4)), glm::dvec3(1, 0, 0));
        return glm::normalize(glm::dquat(unit(rng), unit(rng), unit(rng), unit(rng)));
    };
    const auto placed = [&](int k) {
        Entity e;
        e.model = int(rng() % models.size());
        e.rotation = rotation(k % 3);
        e.scale = 0.2 + 3.0 * std::abs(unit(rng));
        const glm::dvec3 ahead = cam.eye + cam.forward * (8.0 * std::abs(unit(rng)));
        switch (k % 7) {
        case 0: // in front, anywhere on screen or beside it
            e.position = ahead + 6.0 * glm::dvec3(unit(rng), unit(rng), unit(rng));
            break;
        case 1: // behind the eye
            e.position = cam.eye - cam.forward * (1.0 + 5.0 * std::abs(unit(rng)));
            break;
        case 2: // around the eye: inside the proxy box, or a quad crossing the near plane
            e.position = cam.eye + 0.3 * glm::dvec3(unit(rng), unit(rng), unit(rng));
            e.scale = 10.0;
            break;
        case 3: // far enough to be below half a pixel
            e.position = cam.eye + cam.forward * 5000.0;
            break;
        case 4: // off screen to the side
            e.position = ahead + cam.right * 40.0;
            break;
        case 5: // on the view axis, seen straight along the camera's up or down
            e.position = cam.eye + cam.forward * 2.0 + cam.up * (unit(rng) > 0 ? 3.0 : -3.0);
            e.rotation = glm::dquat(1.0, 0.0, 0.0, 0.0);
            break;
        default: // an explicit anchor
            e.position = ahead;
            e.anchor = glm::dvec3(unit(rng), unit(rng), unit(rng)) * 20.0;
            break;
        }
        return e;
    };
    std::map<CullReason, int> reasons;
    for (const double sigma : {0.5, 1.0, 3.0})
        for (const ViewMode mode : {ViewMode::PerEntity, ViewMode::Parallel}) {
            RenderParams params;
            params.sigma = sigma;
            params.viewMode = mode;
            // Batches of 1 to 19 sprites: shorter than, equal to and past every SIMD width.
            for (int count = 1; count < 20; ++count) {
                std::vector<SpriteConstants> constants;
                for (int k = 0; k < count * 7; ++k) {
                    const Entity e = placed(k);
                    const VoxelModel& m = *models[std::size_t(e.model)];
                    constants.push_back(spriteConstants(e, m, 0, params, light));
                }
                expectSameSetUps(constants, cam, params, &reasons);
            }
        }
    // The test reached every branch it names.
    for (const CullReason r : {CullReason::None, CullReason::BehindCamera, CullReason::CameraInside,
                               CullReason::SubPixel, CullReason::OffScreen})
        EXPECT_GT(reasons[r], 0) << toString(r);
}

} // namespace
} // namespace voxtier
