// Issue 13: far == near pixel for pixel (colour, depth, id) at every direction of the refinement
// ladder's levels 1, 2, 4 and 8, not only the 26 canonical ones: an entity seen exactly along a
// lattice direction is drawn by the far tier from that direction's snapshot (the O(1) lookup
// must pick it) and equals the near reference. The camera's up is the one the canonical-view
// tests use (test::viewAlong), which is the snapshot's up rule, so the two lattices coincide.
// Level 8 holds every direction of levels 1, 2 and 4 (1,538 in all); it runs for the mmmm cop,
// fire truck and house at sigma 1 (~1 ms per direction and model on the 2 shared cores).
#include "core/vox_reader.hpp"
#include "far_test_support.hpp"
#include "image_checks.hpp"
#include "view_sweeps.hpp"

#include <gtest/gtest.h>

#include <filesystem>

namespace voxtier {
namespace {

std::shared_ptr<VoxelModel> firstModelOf(const std::string& file) {
    const VoxFile vox =
        readVoxFile(std::filesystem::path(VOXTIER_SOURCE_DIR) / "scenes" / "vox" / file);
    return std::make_shared<VoxelModel>(file, vox.palette,
                                        std::vector<VoxelGrid>{vox.models.front()});
}

/// Every surface point of {-n..n}^3 whose direction is not on a coarser level of the ladder
/// already tested (primitive vectors only, so each direction is tested once).
std::vector<glm::ivec3> directionsOfLevel(int n) {
    std::vector<glm::ivec3> out;
    for (int x = -n; x <= n; ++x)
        for (int y = -n; y <= n; ++y)
            for (int z = -n; z <= n; ++z) {
                const glm::ivec3 p{x, y, z};
                if (std::max({std::abs(x), std::abs(y), std::abs(z)}) != n) continue;
                if (viewIdOf(p).lattice == p) out.push_back(p);
            }
    return out;
}

/// Draws `model` along every direction of levels 1..maxLevel through both tiers; returns the
/// number of directions compared, stopping at the first difference (reported).
int expectFarEqualsNearOnLadder(const std::shared_ptr<VoxelModel>& model, int maxLevel) {
    SnapshotCache cache;
    int compared = 0;
    for (int n = 1; n <= maxLevel; n *= 2)
        for (glm::ivec3 w : directionsOfLevel(n)) {
            const auto v = test::viewAlong(model, glm::dvec3(w), 1.0, 1);
            const CameraFrame cam = makeCameraFrame(v.scene.camera);
            const std::vector<SpriteSetup> sprites = setupSprites(v.scene, cam, 0.0);
            EXPECT_TRUE(sprites[0].visible());
            const ViewId chosen = nearestLadderView(maxLevel, -sprites[0].lattice.dir);
            EXPECT_EQ(chosen, viewIdOf(w)) << "(" << w.x << "," << w.y << "," << w.z << ")";
            const Image nearImg = test::renderNear(v.scene);
            Image farImg(cam.width, cam.height, v.scene.render.background);
            const std::vector<FarRequest> req{{&sprites[0], chosen}};
            drawFarSprites(v.scene.models, req, cache, ViewSet::Cube26, farImg);
            EXPECT_GT(test::drawnPixels(nearImg), 0u);
            const std::string diff = test::firstDifference(nearImg, farImg);
            EXPECT_TRUE(diff.empty()) << model->name() << " level " << n << " view (" << w.x << ","
                                      << w.y << "," << w.z << "): " << diff;
            if (!diff.empty()) return compared;
            ++compared;
        }
    return compared;
}

TEST(FarEqualsNearOnTheLadder, EveryDirectionOfLevels1To8ForTheCopTheFireTruckAndTheHouse) {
    for (const char* file : {"mmmm/chr_cop1.vox", "mmmm/veh_fire.vox", "mmmm/obj_house7.vox"})
        EXPECT_EQ(expectFarEqualsNearOnLadder(firstModelOf(file), 8), 1538) << file;
}

} // namespace
} // namespace voxtier
