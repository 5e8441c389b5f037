// HARD_CASES 22, the far tier's cross-check: when an entity's per-entity view direction is
// exactly a snapshot direction, the far blit draws the near reference image pixel for pixel
// (colour, depth, id). Every model of every file in scenes/vox (via readVoxFile), sigma 1 and 2,
// all 26 views, upright and rolled cameras, and the camera straight down over rotated entities.
// The two 256^3 models of tree.vox run at sigma 1 only, upright for all 26 views and rolled 90
// degrees for the 8 corner views (time budget: the near reference traces ~200k pixels per
// 256^3 image, ~0.5 s each on the 2 shared cores).
//
// Known contract problem (reported, core/sprite_kernel.h is not this module's to change): the
// kernel forms a ray origin as (rayBase + (i+1/2) cellRight) + (j+1/2) cellUp. A 90 or 270 degree
// roll swaps the roles of cellRight and cellUp, so the same geometric cell gets its float origin
// summed in the other order and can differ by one ulp; at corner views (the only ones with two
// non-zero terms per component) a 256^3 model has rays close enough to a voxel edge for that ulp
// to change the hit. The near tier itself is then not roll-invariant, and no single snapshot can
// match both. The tree's rolled corner views therefore assert "identical except at pixels whose
// kernel rays have different float origins in the two lattices" and print how many there are.
// Grouping the offsets, rayBase + ((i+1/2) cellRight + (j+1/2) cellUp), makes the origins
// bit-identical under every quarter-turn roll (commutative sum of the same products).
#include "core/procedural.hpp"
#include "core/vox_reader.hpp"
#include "far_test_support.hpp"
#include "impostor_cache/kernel_order_dda.hpp"

#include <glm/gtc/quaternion.hpp>
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <memory>

namespace voxtier {
namespace {

enum class Views { All, Corners };
struct VoxCase {
    std::string file; // relative to scenes/vox
    std::vector<double> sigmas;
    std::vector<int> rolls;
    int model = -1; // -1: every model of the file
    Views views = Views::All;
    bool allowOriginUlps = false; // see the file comment
    std::string label;
};
void PrintTo(const VoxCase& c, std::ostream* os) {
    *os << c.file << " " << c.label;
}

const std::vector<int> kAllRolls = {0, 1, 2, 3};

std::vector<std::shared_ptr<VoxelModel>> modelsOf(const std::string& file) {
    const VoxFile vox =
        readVoxFile(std::filesystem::path(VOXTIER_SOURCE_DIR) / "scenes" / "vox" / file);
    std::vector<std::shared_ptr<VoxelModel>> out;
    for (std::size_t i = 0; i < vox.models.size(); ++i)
        out.push_back(std::make_shared<VoxelModel>(file + "#" + std::to_string(i), vox.palette,
                                                   std::vector<VoxelGrid>{vox.models[i]}));
    return out;
}

int canonicalIndex(glm::ivec3 w) {
    const auto& pts = viewLatticePoints(ViewSet::Cube26);
    for (std::size_t i = 0; i < pts.size(); ++i)
        if (pts[i] == w) return int(i);
    return -1;
}

/// Differing pixels whose near cell (or a cardinal neighbour, for outline pixels) has a ray
/// origin that is not bit-identical to the origin of the snapshot cell it maps to: the
/// differences the kernel's summation order explains. Returns (explained, unexplained).
std::pair<std::size_t, std::size_t> classifyDifferences(const Image& a, const Image& b,
                                                        const SpriteSetup& sp,
                                                        const VoxelModel& model, glm::ivec3 w) {
    const SpriteLattice snapLattice =
        snapshotLattice(glm::dvec3(w), model.frame(0).dims(), sp.lattice.sigma);
    const kernel::SpriteGpu snapFrame = snapshotRayFrame(snapLattice);
    const SpriteLattice& L = sp.lattice;
    std::size_t explained = 0, unexplained = 0;
    for (int y = 0; y < a.height; ++y)
        for (int x = 0; x < a.width; ++x) {
            const std::size_t p = a.index(x, y);
            if (a.color[p] == b.color[p] && a.depth[p] == b.depth[p] && a.id[p] == b.id[p])
                continue;
            glm::ivec2 cell;
            bool originDiffers = false;
            if (kernel::vtPixelCell(sp.gpu, glm::vec2(x + 0.5f, y + 0.5f), cell))
                for (glm::ivec2 d : {glm::ivec2(0, 0), glm::ivec2(1, 0), glm::ivec2(-1, 0),
                                     glm::ivec2(0, 1), glm::ivec2(0, -1)}) {
                    const glm::ivec2 c = cell + d;
                    const glm::dvec3 q = (L.gU + (c.x + 0.5) / L.sigma) * L.right +
                                         (L.gV + (c.y + 0.5) / L.sigma) * L.up;
                    originDiffers |= kernelRayOrigin(sp.gpu, c) !=
                                     kernelRayOrigin(snapFrame, snapLattice.cellAt(q));
                }
            (originDiffers ? explained : unexplained)++;
        }
    return {explained, unexplained};
}

/// Renders `model` along every canonical direction at (sigma, roll) through both tiers and
/// records failures; the cache is shared across views and rolls (one bake per view).
void expectFarEqualsNear(const std::shared_ptr<VoxelModel>& model, double sigma,
                         const std::vector<int>& rolls, SnapshotCache& cache,
                         Views views = Views::All, bool allowOriginUlps = false) {
    std::size_t explainedTotal = 0, pixelsTotal = 0;
    for (glm::ivec3 w : test::canonicalDirections())
        for (int roll : rolls) {
            if (views == Views::Corners && (w.x == 0 || w.y == 0 || w.z == 0)) continue;
            const auto v = test::viewAlong(model, glm::dvec3(w), sigma, 1, roll);
            std::vector<SpriteSetup> sprites;
            const Image nearImg = test::renderNear(v.scene);
            const Image farImg = test::renderFar(v.scene, cache, ViewSet::Cube26, &sprites);
            ASSERT_TRUE(sprites[0].visible());
            ASSERT_GT(test::drawnPixels(nearImg), 0u); // a blank comparison would prove nothing
            // The far tier must have picked exactly this direction.
            EXPECT_EQ(chooseFarView(sprites[0], ViewSet::Cube26), canonicalIndex(w));
            const std::string diff = test::firstDifference(nearImg, farImg);
            pixelsTotal += nearImg.pixelCount();
            if (!diff.empty() && allowOriginUlps) {
                const auto [explained, unexplained] =
                    classifyDifferences(nearImg, farImg, sprites[0], *model, w);
                explainedTotal += explained;
                EXPECT_EQ(unexplained, 0u)
                    << model->name() << " sigma " << sigma << " view (" << w.x << "," << w.y << ","
                    << w.z << ") roll " << roll * 90 << ": " << diff;
                if (unexplained == 0) {
                    std::printf("[ known    ] %s view (%d,%d,%d) roll %d: %s -- all from one-ulp "
                                "ray-origin differences "
                                "(kernel summation order)\n",
                                model->name().c_str(), w.x, w.y, w.z, roll * 90, diff.c_str());
                    continue;
                }
            }
            EXPECT_TRUE(diff.empty())
                << model->name() << " sigma " << sigma << " view (" << w.x << "," << w.y << ","
                << w.z << ") roll " << roll * 90 << ": " << diff;
            if (!diff.empty()) return; // one report per model and sigma is enough to debug
        }
    // Rare by construction: at most one pixel in 100 000.
    EXPECT_LE(explainedTotal * 100000, pixelsTotal)
        << explainedTotal << " explained differences in " << pixelsTotal;
}

class FarEqualsNearOnVoxFiles : public ::testing::TestWithParam<VoxCase> {};

TEST_P(FarEqualsNearOnVoxFiles, EveryModelEveryCanonicalViewUprightAndRolled) {
    const VoxCase c = GetParam();
    const auto models = modelsOf(c.file);
    ASSERT_FALSE(models.empty());
    SnapshotCache cache;
    for (std::size_t i = 0; i < models.size(); ++i) {
        if (c.model >= 0 && int(i) != c.model) continue;
        for (double sigma : c.sigmas)
            expectFarEqualsNear(models[i], sigma, c.rolls, cache, c.views, c.allowOriginUlps);
    }
    EXPECT_GT(cache.counters().bakes, 0u);
}

INSTANTIATE_TEST_SUITE_P(
    ScenesVox, FarEqualsNearOnVoxFiles,
    ::testing::Values(
        VoxCase{"mmmm/obj_splatter1.vox", {1.0, 2.0}, kAllRolls},
        VoxCase{"mmmm/chr_cop1.vox", {1.0, 2.0}, kAllRolls},
        VoxCase{"mmmm/obj_house7.vox", {1.0, 2.0}, kAllRolls},
        VoxCase{"mmmm/veh_fire.vox", {1.0, 2.0}, kAllRolls},
        VoxCase{"mmmm/scene_house2.vox", {1.0, 2.0}, kAllRolls},
        VoxCase{"dot_vox/axes.vox", {1.0, 2.0}, kAllRolls},
        VoxCase{"dot_vox/single-voxel-with-material.vox", {1.0, 2.0}, kAllRolls},
        VoxCase{"opengametools/test_multiple_model_scene.vox", {1.0, 2.0}, kAllRolls},
        VoxCase{"opengametools/test_meta_chunk.vox", {1.0, 2.0}, kAllRolls},
        VoxCase{"bevy_vox_scene/test.vox", {1.0, 2.0}, kAllRolls},
        VoxCase{"blender_magicavoxel/hierarchy.vox", {1.0, 2.0}, kAllRolls},
        VoxCase{"vox-reader.js/tree.vox", {1.0}, {0}, 0, Views::All, false, "_model0_upright"},
        VoxCase{"vox-reader.js/tree.vox", {1.0}, {0}, 1, Views::All, false, "_model1_upright"},
        VoxCase{"vox-reader.js/tree.vox", {1.0}, {1}, -1, Views::Corners, true, "_rolled_corners"}),
    [](const auto& info) {
        std::string n = info.param.file + info.param.label;
        for (char& ch : n)
            if (!std::isalnum(static_cast<unsigned char>(ch))) ch = '_';
        return n;
    });

// Procedural models with known asymmetry and thin parts, non-cubic sizes, and sigma 3.
TEST(FarEqualsNear, ProceduralModelsAtSigmaOneTwoThree) {
    SnapshotCache cache;
    for (const auto& m : {makeArrow(16), makeShell({9, 7, 12}, 1), makeSphere(5),
                          makeBox({3, 5, 8}), makeSingleVoxel()})
        for (double sigma : {1.0, 2.0, 3.0}) expectFarEqualsNear(m, sigma, kAllRolls, cache);
}

// The RTS camera: straight down at entities yawed by quarter turns (the snapshot's up is +X
// for the ±Z views, the near lattice follows the camera: the blit's roll correction).
TEST(FarEqualsNear, CameraStraightDownOverQuarterTurnYawedEntities) {
    SnapshotCache cache;
    for (const auto& m : {makeArrow(16), makeBox({4, 6, 3})})
        for (double sigma : {1.0, 2.0})
            for (int yaw = 0; yaw < 4; ++yaw)
                for (int roll : kAllRolls) {
                    auto v = test::viewAlong(m, glm::dvec3(0, 0, 1), sigma, 2, roll);
                    v.scene.entities[0].rotation =
                        glm::angleAxis(glm::radians(90.0 * yaw), glm::dvec3(0, 1, 0));
                    std::vector<SpriteSetup> sprites;
                    const Image nearImg = test::renderNear(v.scene);
                    const Image farImg = test::renderFar(v.scene, cache, ViewSet::Cube26, &sprites);
                    EXPECT_EQ(chooseFarView(sprites[0], ViewSet::Cube26), 4); // +Z
                    EXPECT_GT(test::drawnPixels(nearImg), 0u);
                    const std::string diff = test::firstDifference(nearImg, farImg);
                    EXPECT_TRUE(diff.empty()) << m->name() << " sigma " << sigma << " yaw "
                                              << 90 * yaw << " roll " << 90 * roll << ": " << diff;
                }
}

// Far from the origin: camera-relative set-up keeps both tiers identical at 2^20 m.
TEST(FarEqualsNear, OneMillionMetresFromTheOrigin) {
    SnapshotCache cache;
    const auto m = makeArrow(16);
    for (glm::ivec3 w : {glm::ivec3(1, 0, 0), glm::ivec3(1, -1, 0), glm::ivec3(-1, 1, 1)}) {
        const auto v =
            test::viewAlong(m, glm::dvec3(w), 2.0, 2, 1, glm::dvec3(1048576.0, 0.0, -1048576.0));
        const std::string diff =
            test::firstDifference(test::renderNear(v.scene), test::renderFar(v.scene, cache));
        EXPECT_TRUE(diff.empty()) << diff;
    }
}

} // namespace
} // namespace voxtier
