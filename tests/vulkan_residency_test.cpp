// Voxel residency of the near tier: the atlas packer's placement, upload-once sharing, and partial
// re-upload after edits (only the dirty box goes to the GPU, and the image is exact afterwards).
#include "core/procedural.hpp"
#include "image_checks.hpp"
#include "test_models.hpp"
#include "view_sweeps.hpp"
#include "volumetric/atlas_packer.hpp"
#include "volumetric/voxel_residency.hpp"
#include "vulkan_test_env.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <set>
#include <stdexcept>
#include <string>

namespace voxtier {
namespace {

const auto* const kEnv = ::testing::AddGlobalTestEnvironment(new test::NearRendererEnvironment);

using test::VulkanTest;
class NearResidency : public VulkanTest {};

// ---------------------------------------------------------------------------------------------
// Packer (no GPU)

TEST(AtlasPacker, BlocksStayInsideAndNeverOverlap) {
    AtlasPacker packer(128, 96, 4096);
    std::mt19937 rng(7);
    std::uniform_int_distribution<int> side(1, 40);
    std::vector<Box3i> placed;
    for (int n = 0; n < 300; ++n) {
        const glm::ivec3 size{side(rng), side(rng), side(rng)};
        const glm::ivec3 at = packer.allocate(size);
        const Box3i b{at, at + size};
        EXPECT_GE(glm::min(b.min.x, glm::min(b.min.y, b.min.z)), 0);
        EXPECT_LE(b.max.x, 128);
        EXPECT_LE(b.max.y, 96);
        EXPECT_LE(b.max.z, packer.usedDepth());
        for (const Box3i& o : placed)
            ASSERT_TRUE(b.intersected(o).empty()) << "block " << n << " overlaps";
        placed.push_back(b);
    }
}

TEST(AtlasPacker, SmallBlocksShareOneSlab) {
    AtlasPacker packer(512, 512, 4096);
    for (int n = 0; n < 64 * 64; ++n) packer.allocate({8, 8, 8}); // exactly one 512x512x8 slab
    EXPECT_EQ(packer.usedDepth(), 8);
    packer.allocate({1, 1, 1});
    EXPECT_EQ(packer.usedDepth(), 9);
}

TEST(AtlasPacker, FullAtlasThrowsLengthError) {
    AtlasPacker packer(16, 16, 20);
    packer.allocate({16, 16, 12});
    EXPECT_THROW(packer.allocate({16, 16, 9}), std::length_error);
    EXPECT_EQ(packer.usedDepth(), 12) << "a failed allocation changes nothing";
    EXPECT_NO_THROW(packer.allocate({16, 16, 8}));
    EXPECT_THROW(packer.allocate({17, 1, 1}), std::length_error);
}

// ---------------------------------------------------------------------------------------------
// Residency through the renderer

struct Frame {
    Image near, reference;
    NearStats stats;
};
Frame renderFrame(NearRenderer& nr, const Scene& s) {
    const auto r = test::renderBoth(nr, s);
    return {r.near, r.reference, r.nearStats};
}

// An 8^3 box seen along +X (its +X face fills the sprite), with a private model instance so the
// residency has never seen it.
test::ViewSetup freshBoxView() {
    return test::viewAlong(test::solidBox({8, 8, 8}), glm::dvec3(1, 0, 0), 2.0, 2);
}

TEST_F(NearResidency, NewModelUploadsWholeFrameOnceAndNothingWhenUnchanged) {
    auto v = freshBoxView();
    const Frame first = renderFrame(nearRenderer(), v.scene);
    EXPECT_EQ(first.stats.bytesUploaded, 512u);
    EXPECT_EQ(first.stats.uploadRegions, 1u);
    const Frame second = renderFrame(nearRenderer(), v.scene);
    EXPECT_EQ(second.stats.bytesUploaded, 0u);
    EXPECT_EQ(test::describeDifference(second.near, second.reference), "");
}

TEST_F(NearResidency, EntitiesSharingAModelShareItsAtlasBlock) {
    auto v = freshBoxView();
    for (int i = 1; i < 5; ++i) {
        Entity e = v.scene.entities[0];
        e.position += glm::dvec3(-0.7 * i, 0.1 * i, 0.1 * i); // behind the first, peeking out
        v.scene.entities.push_back(e);
    }
    const Frame f = renderFrame(nearRenderer(), v.scene);
    EXPECT_EQ(f.stats.sprites, 5u);
    EXPECT_EQ(f.stats.bytesUploaded, 512u) << "one block for five entities";
    EXPECT_EQ(test::describeDifference(f.near, f.reference), "");
}

TEST_F(NearResidency, SingleVoxelEditUploadsOneVoxelAndImageMatchesReference) {
    auto v = freshBoxView();
    VoxelModel& model = *v.scene.models[0];
    const Frame before = renderFrame(nearRenderer(), v.scene);
    ASSERT_EQ(test::describeDifference(before.near, before.reference), "");
    ASSERT_TRUE(model.setVoxel(0, {7, 3, 4}, 2)); // on the +X face, which faces the camera
    const Frame after = renderFrame(nearRenderer(), v.scene);
    EXPECT_EQ(after.stats.bytesUploaded, 1u);
    EXPECT_EQ(after.stats.uploadRegions, 1u);
    EXPECT_EQ(test::describeDifference(after.near, after.reference), "");
    const ImageDiff changed = diffImages(before.near, after.near);
    EXPECT_EQ(changed.colorDiffs, 4u * 4u) << "one voxel = a 2x2-cell block at 2 pixels per cell";
    // Removing a voxel from the face shows the one behind it (index 1, same face): colour back.
    ASSERT_TRUE(model.setVoxel(0, {7, 3, 4}, 0));
    const Frame removed = renderFrame(nearRenderer(), v.scene);
    EXPECT_EQ(removed.stats.bytesUploaded, 1u);
    EXPECT_EQ(test::describeDifference(removed.near, removed.reference), "");
    EXPECT_EQ(test::describeDifference(removed.near, before.near), "");
}

TEST_F(NearResidency, BoxEditsUploadTheUnionOfTheirDirtyBoxes) {
    auto v = freshBoxView();
    VoxelModel& model = *v.scene.models[0];
    renderFrame(nearRenderer(), v.scene);
    ASSERT_TRUE(model.fillBox(0, {{6, 1, 1}, {8, 3, 4}}, 3)); // 2x2x3
    ASSERT_TRUE(model.clearBox(0, {{7, 5, 5}, {8, 7, 7}}));   // 1x2x2
    const Frame f = renderFrame(nearRenderer(), v.scene);
    EXPECT_EQ(f.stats.bytesUploaded, 2u * 6u * 6u) << "union box [6,8)x[1,7)x[1,7)";
    EXPECT_EQ(test::describeDifference(f.near, f.reference), "");
}

TEST_F(NearResidency, EditLogOverflowReuploadsTheWholeFrame) {
    auto v = freshBoxView();
    VoxelModel& model = *v.scene.models[0];
    renderFrame(nearRenderer(), v.scene);
    for (int k = 0; k < 5000; ++k)
        ASSERT_TRUE(model.setVoxel(0, {7, 2, 2}, std::uint8_t(2 + k % 2)));
    ASSERT_FALSE(model.dirtySince(1, 0).has_value()) << "the log should no longer reach version 1";
    const Frame f = renderFrame(nearRenderer(), v.scene);
    EXPECT_EQ(f.stats.bytesUploaded, 512u);
    EXPECT_EQ(test::describeDifference(f.near, f.reference), "");
}

/// A model of two animation frames the residency has never seen: a solid 4x4x4 block of index 1
/// (64 voxels), then a solid 3x5x2 block of index 2 (30 voxels).
std::shared_ptr<VoxelModel> twoFrameModel(const std::string& name) {
    VoxelGrid a({4, 4, 4}), b({3, 5, 2});
    for (auto& x : a.data()) x = 1;
    for (auto& x : b.data()) x = 2;
    return std::make_shared<VoxelModel>(name, proceduralPalette(), std::vector<VoxelGrid>{a, b});
}

// Animation frames are separate blocks; each is uploaded the first time a sprite shows it.
TEST_F(NearResidency, AnimationFramesBecomeResidentOnFirstUse) {
    auto model = twoFrameModel("anim");
    auto v = test::viewAlong(model, glm::dvec3(1, 2, 3), 2.0, 3);
    const Frame f0 = renderFrame(nearRenderer(), v.scene);
    EXPECT_EQ(f0.stats.bytesUploaded, 64u);
    v.scene.entities[0].frame = 1;
    const Frame f1 = renderFrame(nearRenderer(), v.scene);
    EXPECT_EQ(f1.stats.bytesUploaded, 30u);
    EXPECT_EQ(test::describeDifference(f1.near, f1.reference), "");
    v.scene.entities[0].frame = 0;
    const Frame again = renderFrame(nearRenderer(), v.scene);
    EXPECT_EQ(again.stats.bytesUploaded, 0u);
    EXPECT_EQ(test::describeDifference(again.near, again.reference), "");
}

// The first showings of a drawn order, found from the sprites in another order and their places
// in the drawn one (what a moving camera's frame does), are those of a walk along the drawn order:
// the first place of each model, of each of its frames and of the first sprite whose model or
// frame is out of range; culled sprites and sprites not drawn show nothing.
TEST(FirstShowings, FromPlacesEqualAWalkOfTheDrawnOrder) {
    const std::vector<std::shared_ptr<VoxelModel>> models{
        twoFrameModel("a"), test::solidBox({2, 2, 2}), nullptr, twoFrameModel("c")};
    std::mt19937 rng(7);
    for (const std::size_t n : {0u, 1u, 2u, 7u, 300u, 5000u}) {
        std::vector<SpriteSetup> store(n);
        for (SpriteSetup& s : store) {
            s.model = int(rng() % 5);     // 2: no model, 4: past the list
            s.frame = int(rng() % 4) - 1; // -1 and 2: past every model's frames
            if (rng() % 10 == 0) s.cull = CullReason::OffScreen;
        }
        std::vector<const SpriteSetup*> sprites;
        for (const SpriteSetup& s : store) sprites.push_back(&s);
        std::vector<std::uint32_t> drawn;
        for (std::uint32_t k = 0; k < n; ++k)
            if (rng() % 5 != 0) drawn.push_back(k);
        std::shuffle(drawn.begin(), drawn.end(), rng);
        std::vector<std::uint32_t> places(n, VoxelResidency::kNotShown);
        for (std::size_t p = 0; p < drawn.size(); ++p) places[drawn[p]] = std::uint32_t(p);

        std::vector<std::uint32_t> expected;
        std::set<int> modelsSeen;
        std::set<std::pair<int, int>> framesSeen;
        bool outOfRangeSeen = false;
        for (std::size_t p = 0; p < drawn.size(); ++p) {
            const SpriteSetup& s = *sprites[drawn[p]];
            if (!s.visible()) continue;
            const bool known = s.model < int(models.size()) && models[std::size_t(s.model)] &&
                               s.frame >= 0 && s.frame < models[std::size_t(s.model)]->frameCount();
            if (!known) {
                if (!outOfRangeSeen) expected.push_back(std::uint32_t(p));
                outOfRangeSeen = true;
                continue;
            }
            const bool first = modelsSeen.insert(s.model).second;
            if (framesSeen.insert({s.model, s.frame}).second || first)
                expected.push_back(std::uint32_t(p));
        }
        EXPECT_EQ(VoxelResidency::firstShowingsAt(models, sprites, places), expected) << n;
    }
    const SpriteSetup one;
    const std::vector<const SpriteSetup*> sprites{&one};
    EXPECT_THROW(VoxelResidency::firstShowingsAt(models, sprites, {}), std::invalid_argument);
}

// The per-frame table of placements the near tier reads for every sprite gives what entry() and
// brickBase() give for each resident (model, frame), in the scene's model order, and refuses a
// frame no sprite has shown yet.
TEST_F(NearResidency, PlacementsTableAgreesWithTheLookupsOfEachResidentFrame) {
    auto animated = twoFrameModel("anim2");
    auto v = test::viewAlong(animated, glm::dvec3(1, 2, 3), 2.0, 3);
    auto box = test::solidBox({5, 6, 7});
    v.scene.models.insert(v.scene.models.begin(), box); // the animated model is index 1 now
    v.scene.entities[0].model = 1;
    Entity second = v.scene.entities[0];
    second.model = 0;
    second.position += glm::dvec3(0.0, 0.0, -1.0);
    v.scene.entities.push_back(second);
    renderFrame(nearRenderer(), v.scene);
    const VoxelResidency& residency = nearRenderer().passes().residency();
    VoxelResidency::Placements table;
    residency.placements(v.scene.models, table);
    const auto agrees = [&](std::size_t m, int f) {
        const VoxelResidency::Placements::Frame& p = table.at(m, f);
        EXPECT_EQ(p.atlas, residency.entry(*v.scene.models[m], f))
            << "model " << m << " frame " << f;
        EXPECT_EQ(p.brickBase, residency.brickBase(*v.scene.models[m], f))
            << "model " << m << " frame " << f;
    };
    agrees(0, 0);
    agrees(1, 0);
    EXPECT_NE(table.at(0, 0).atlas, table.at(1, 0).atlas) << "two models, two blocks";
    EXPECT_THROW(table.at(1, 1), std::logic_error) << "frame 1 is not shown yet";
    EXPECT_THROW(table.at(1, 2), std::logic_error) << "no such frame";
    EXPECT_THROW(table.at(2, 0), std::logic_error) << "no such model";
    v.scene.entities[0].frame = 1;
    renderFrame(nearRenderer(), v.scene);
    residency.placements(v.scene.models, table);
    agrees(1, 1);
    agrees(1, 0);
    agrees(0, 0);
}

// A block deeper than what is left makes the atlas grow: the new image is a GPU copy of the old
// one plus the new block, so earlier models keep rendering exactly without a re-upload. Uses a
// renderer of its own so the atlas starts empty whatever ran before in this process.
TEST(VulkanResidency, AtlasGrowthKeepsResidentBlocksWithoutReupload) {
    Scene s;
    s.render.sigma = 1.0;
    s.models = {makeShell({24, 20, 60}, 2, proc_index::kViolet), makeSphere(40, proc_index::kCyan)};
    for (int i = 0; i < 2; ++i) {
        Entity e;
        e.model = i;
        e.position = {-4.0 + 8.0 * i, 0.0, -20.0};
        e.rotation = glm::angleAxis(0.4 + i, glm::dvec3(0.0, 1.0, 0.0));
        s.entities.push_back(e);
    }
    s.camera.position = {0.0, 6.0, 8.0};
    s.camera.target = {0.0, 0.0, -20.0};
    s.camera.width = 240;
    s.camera.height = 160;
    Scene onlyFirst = s;
    onlyFirst.entities.resize(1);
    VulkanDeviceOptions options;
    options.validation = true;
    options.echoMessages = false;
    auto log = std::make_shared<VulkanMessageLog>();
    auto renderer = std::make_unique<NearRenderer>(options, log);
    NearRenderer& nr = *renderer;
    std::uint64_t growths = 0;
    const Frame a = renderFrame(nr, onlyFirst);
    growths += a.stats.atlasGrowths;
    EXPECT_EQ(test::describeDifference(a.near, a.reference), "");
    const Frame b = renderFrame(nr, s);
    growths += b.stats.atlasGrowths;
    EXPECT_EQ(b.stats.bytesUploaded, 80u * 80u * 80u) << "only the new sphere is uploaded";
    EXPECT_GE(growths, 1u) << "a 60- then an 80-deep block cannot share the first 64 slices";
    EXPECT_GT(b.near.countEntity(0), 100u);
    EXPECT_GT(b.near.countEntity(1), 100u);
    EXPECT_EQ(test::describeDifference(b.near, b.reference), "");
    renderer.reset();
    EXPECT_EQ(log->count(), 0u) << log->joined();
}

} // namespace
} // namespace voxtier
