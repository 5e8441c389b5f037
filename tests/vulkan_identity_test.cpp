// The Vulkan near tier equals the CPU reference pixel for pixel (colour, depth bits, entity id):
// on the golden scenes, the default scene, and every model shipped in scenes/vox/ seen from the
// 26 canonical directions and 20 seeded random ones at sigma 1 and 2. Both sides run the same
// kernel file (core/sprite_kernel.h) on the same per-entity floats, so any difference is a bug in
// one of them, never a tolerance question.
#include "core/model_view.hpp"
#include "core/scene_loader.hpp"
#include "core/vox_reader.hpp"
#include "image_checks.hpp"
#include "source_tree.hpp"
#include "view_sweeps.hpp"
#include "vulkan_test_env.hpp"

#include <gtest/gtest.h>

#include <cctype>
#include <filesystem>
#include <random>
#include <set>
#include <tuple>

namespace voxtier {
namespace {

const auto* const kEnv = ::testing::AddGlobalTestEnvironment(new test::NearRendererEnvironment);

using test::sourcePath;

std::string str(glm::dvec3 v) {
    char buf[96];
    std::snprintf(buf, sizeof buf, "(%.6f, %.6f, %.6f)", v.x, v.y, v.z);
    return buf;
}

/// Every .vox under scenes/vox/ except the deliberately broken dot_vox/not_a.vox
/// (VoxModelSweepCoverage checks that the list stays complete).
const std::vector<std::string> kVoxFiles = {
    "mmmm/obj_splatter1.vox",
    "mmmm/chr_cop1.vox",
    "mmmm/obj_house7.vox",
    "mmmm/veh_fire.vox",
    "mmmm/scene_house2.vox",
    "dot_vox/axes.vox",
    "dot_vox/single-voxel-with-material.vox",
    "opengametools/test_multiple_model_scene.vox",
    "opengametools/test_meta_chunk.vox",
    "bevy_vox_scene/test.vox",
    "vox-reader.js/tree.vox",
    "blender_magicavoxel/hierarchy.vox",
};

class SceneIdentity : public test::VulkanTest,
                      public ::testing::WithParamInterface<std::tuple<std::string, test::NearWay>> {
};

// Every golden scene and the default scene (its path frames too: the camera flies in from
// above), traced in compute, and rasterised with the hull proxy and with the quad.
TEST_P(SceneIdentity, VulkanImageEqualsReferenceImage) {
    const auto [file, way] = GetParam();
    Scene scene = loadScene(sourcePath(file));
    std::vector<double> times = {0.0};
    if (scene.path) times = {0.0, scene.timeOfFrame(scene.path->frameCount() / 2)};
    const NearOptions options = way.options();
    for (double t : times) {
        const auto r = test::renderBoth(nearRenderer(), scene, t, options);
        EXPECT_EQ(test::describeDifference(r.near, r.reference), "") << file << " at t=" << t;
        EXPECT_GT(test::drawnPixels(r.reference), 100u) << "the scene should draw something";
        EXPECT_EQ(r.nearStats.sprites, r.referenceStats.sprites);
    }
}

INSTANTIATE_TEST_SUITE_P(
    GoldenAndDefault, SceneIdentity,
    ::testing::Combine(::testing::Values("scenes/golden/arrows.json", "scenes/golden/crowd.json",
                                         "scenes/golden/equal_depth.json",
                                         "scenes/golden/far_origin.json",
                                         "scenes/golden/topdown.json", "scenes/default.json"),
                       ::testing::ValuesIn(test::kNearWays)),
    [](const auto& info) {
        return std::filesystem::path(std::get<0>(info.param)).stem().string() + "_" +
               std::get<1>(info.param).name;
    });

class VoxModelSweep : public test::VulkanTest, public ::testing::WithParamInterface<std::string> {};

// Each model of the file, 46 directions x sigma {1, 2}: the near tier equals the reference.
TEST_P(VoxModelSweep, EveryModelEveryDirectionMatchesReference) {
    const VoxFile vox = readVoxFile(sourcePath("scenes/vox/" + GetParam()));
    ASSERT_FALSE(vox.models.empty());
    const auto dirs = test::sweepDirections();
    int frames = 0, drawnFrames = 0;
    for (std::size_t m = 0; m < vox.models.size(); ++m) {
        auto model = std::make_shared<VoxelModel>(GetParam() + "#" + std::to_string(m), vox.palette,
                                                  std::vector<VoxelGrid>{vox.models[m]});
        if (model->frame(0).solidCount() == 0) continue;
        for (double sigma : {1.0, 2.0})
            for (std::size_t k = 0; k < dirs.size(); ++k) {
                // Moderate images: lavapipe is a CPU rasterizer and the suite must stay fast. The
                // model is fitted to the view, so large models get sub-pixel cells (a hard case).
                const Scene scene = sceneForModel(model, test::viewToward(dirs[k], sigma, 112, 84));
                const auto r = test::renderBoth(nearRenderer(), scene);
                ++frames;
                if (k <
                    26) { // canonical: the azimuth/elevation round trip must still give exact zeros
                    int zeros = 0, want = 0;
                    for (int a = 0; a < 3; ++a) {
                        zeros += r.sprites[0].gpu.dir[a] == 0.0f;
                        want += dirs[k][a] == 0.0;
                    }
                    ASSERT_EQ(zeros, want)
                        << "direction #" << k << " " << str(dirs[k]) << " not snapped";
                }
                drawnFrames += test::drawnPixels(r.reference) > 0;
                const std::string diff = test::describeDifference(r.near, r.reference);
                ASSERT_EQ(diff, "")
                    << "model " << m << " (" << str(glm::dvec3(vox.models[m].dims())) << ") sigma "
                    << sigma << " direction #" << k << " " << str(dirs[k]);
            }
    }
    EXPECT_EQ(drawnFrames, frames) << "every view of a non-empty model draws something";
}

INSTANTIATE_TEST_SUITE_P(ScenesVox, VoxModelSweep, ::testing::ValuesIn(kVoxFiles),
                         [](const auto& info) {
                             std::string name = std::filesystem::path(info.param).stem().string();
                             for (char& c : name)
                                 if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
                             return name;
                         });

// A model added to scenes/vox/ without a sweep here fails this test.
TEST(VoxModelSweepCoverage, ListsEveryVoxFileInScenesVox) {
    const std::set<std::string> listed(kVoxFiles.begin(), kVoxFiles.end());
    const std::filesystem::path root = sourcePath("scenes/vox");
    for (const auto& e : std::filesystem::recursive_directory_iterator(root)) {
        if (e.path().extension() != ".vox") continue;
        const std::string rel = std::filesystem::relative(e.path(), root).generic_string();
        if (rel == "dot_vox/not_a.vox") continue;
        EXPECT_TRUE(listed.count(rel)) << rel << " is not in the Vulkan sweep";
    }
}

} // namespace
} // namespace voxtier
