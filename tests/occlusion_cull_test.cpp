// Exact occlusion culling (issue 25, core/occlusion.hpp): the CPU tiers skip what nearer sprites
// already hide, and the image must not change by a single bit of colour, depth or id. Every
// frame here is drawn twice, with and without culling, in every mode whose tiers cull (the CPU
// reference near tier, the far blit, the hybrid of both with cross-fades), and compared whole.
#include "cli_support.hpp"
#include "compose/frame.hpp"
#include "core/occlusion.hpp"
#include "core/procedural.hpp"
#include "core/scene_loader.hpp"
#include "crowd_scenes.hpp"
#include "frame_test_support.hpp"
#include "hard_case_scenes.hpp"
#include "image_checks.hpp"
#include "image_files/image_files.hpp"
#include "source_tree.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <limits>
#include <vector>

namespace voxtier {
namespace {

Image filled(int w, int h, float depth) {
    Image img(w, h, 0);
    for (std::size_t p = 0; p < img.pixelCount(); ++p) {
        img.depth[p] = depth;
        img.id[p] = 7;
    }
    return img;
}

TEST(OcclusionTiles, AFullTileHidesOnlyWhatIsStrictlyFartherThanAllOfIt) {
    Image img = filled(40, 20, 0.5f);
    img.depth[img.index(3, 4)] = 0.25f; // the tile's farthest pixel
    OcclusionTiles t(img);
    EXPECT_TRUE(t.hides({0, 0, 16, 16}, 0.2f));
    EXPECT_FALSE(t.hides({0, 0, 16, 16}, 0.25f)) << "an equal depth is the id rule's to decide";
    EXPECT_FALSE(t.hides({0, 0, 16, 16}, 0.3f));
    EXPECT_TRUE(t.hides({16, 0, 32, 16}, 0.3f));
    // The partial tiles at the image's right and bottom edges count only their own pixels.
    EXPECT_TRUE(t.hides({32, 16, 40, 20}, 0.3f));
}

TEST(OcclusionTiles, OneEmptyPixelKeepsTheTileOpen) {
    Image img = filled(32, 16, 0.9f);
    img.depth[img.index(20, 15)] = 0.0f;
    img.id[img.index(20, 15)] = kernel::VT_NO_ENTITY;
    OcclusionTiles t(img);
    EXPECT_TRUE(t.hides({0, 0, 16, 16}, 0.1f));
    EXPECT_FALSE(t.hides({16, 0, 32, 16}, 0.1f));
    EXPECT_FALSE(t.hides({10, 0, 20, 4}, 0.1f)) << "the rectangle reaches the open tile";
    // Trimmed at the ends only where a tile hides: [10, 30) keeps the open tile's columns.
    EXPECT_EQ(t.visibleColumns(0, 10, 30, 0.1f), std::make_pair(16, 30));
    const auto [x0, x1] = t.visibleColumns(0, 0, 14, 0.1f);
    EXPECT_GE(x0, x1) << "no open column left";
}

TEST(OcclusionTiles, ATileIsReadAgainOnceEnoughHasBeenDrawnOverIt) {
    Image img(16, 16, 0);
    OcclusionTiles t(img);
    EXPECT_FALSE(t.hides({0, 0, 16, 16}, 0.1f)); // read: all empty
    for (std::size_t p = 0; p < img.pixelCount(); ++p) img.depth[p] = 0.5f;
    t.drawn(0, 0, 8, 16); // half the tile's pixels: it cannot have filled yet
    EXPECT_FALSE(t.hides({0, 0, 16, 16}, 0.1f));
    t.drawn(0, 8, 16, 16);
    EXPECT_TRUE(t.hides({0, 0, 16, 16}, 0.1f));
}

TEST(OcclusionTiles, FrontToBackOrdersByDepthThenId) {
    std::vector<SpriteSetup> s(4);
    const float depths[] = {0.2f, 0.8f, 0.2f, 0.5f};
    const std::uint32_t ids[] = {9, 1, 3, 4};
    for (int i = 0; i < 4; ++i)
        s[std::size_t(i)].gpu.depth = depths[i], s[std::size_t(i)].entityId = ids[i];
    s[3].cull = CullReason::OffScreen;
    std::vector<const SpriteSetup*> p = {&s[0], &s[1], &s[2], &s[3]};
    EXPECT_EQ(frontToBack(p), (std::vector<std::uint32_t>{1, 2, 0}));
}

/// A seeded generator for the many-sprite orders (the same numbers on every platform).
struct Lcg {
    std::uint64_t state;
    std::uint64_t operator()() {
        return (state = state * 6364136223846793005ull + 1442695040888963407ull) >> 33;
    }
};

/// The order frontToBack must give: the visible sprites of `p` by a plain stable sort, nearer
/// first, then the lower id (then the lower index).
std::vector<std::uint32_t> plainOrder(std::span<const SpriteSetup* const> p) {
    std::vector<std::uint32_t> expected;
    for (std::uint32_t i = 0; i < p.size(); ++i)
        if (p[i] && p[i]->visible()) expected.push_back(i);
    std::stable_sort(expected.begin(), expected.end(), [&](std::uint32_t a, std::uint32_t b) {
        if (p[a]->gpu.depth != p[b]->gpu.depth) return p[a]->gpu.depth > p[b]->gpu.depth;
        return p[a]->entityId < p[b]->entityId;
    });
    return expected;
}

// Many sprites (so that the keys are read and sorted in parallel): the order is the one a plain
// sort of the visible sprites by (nearer first, lower id, lower index) gives, with hidden and
// absent sprites left out, ties of depth and id broken by index, and a visible sprite at depth 0
// with the greatest id (its key equals the hidden sprites' marker) kept in its place.
TEST(OcclusionTiles, FrontToBackOfManySpritesIsTheSortOfTheVisibleOnes) {
    const std::size_t n = 50000;
    std::vector<SpriteSetup> s(n);
    std::vector<const SpriteSetup*> p(n);
    Lcg next{12345};
    for (std::size_t i = 0; i < n; ++i) {
        s[i].gpu.depth = float(next() % 500) / 500.0f; // many equal depths, some 0
        s[i].entityId = std::uint32_t(next() % 40000); // some equal ids
        if (next() % 7 == 0) s[i].cull = CullReason::OffScreen;
        p[i] = next() % 50 == 0 ? nullptr : &s[i];
    }
    for (std::size_t i : {std::size_t(17), std::size_t(n - 3)}) {
        s[i] = SpriteSetup{};
        s[i].gpu.depth = 0.0f;
        s[i].entityId = std::numeric_limits<std::uint32_t>::max();
        p[i] = &s[i];
    }
    const std::vector<std::uint32_t> expected = plainOrder(p);
    const std::vector<std::uint32_t> order = frontToBack(p);
    ASSERT_EQ(order.size(), expected.size());
    EXPECT_TRUE(order == expected);
    EXPECT_EQ(order[order.size() - 2], 17u);
    EXPECT_EQ(order.back(), std::uint32_t(n - 3));
}

// The usual frame: sprites in entity order (ids ascending with the index, where the sort spares
// the id's digits), many at equal depths, some hidden or absent; then the same with one visible
// sprite in four at depth 0 (whose keys reach the hidden marker's depth half: the full sort) and
// with ids out of order. Each order is the plain sort's.
TEST(OcclusionTiles, FrontToBackOfSpritesInEntityOrderIsTheSortOfTheVisibleOnes) {
    const std::size_t n = 60000;
    std::vector<SpriteSetup> s(n);
    std::vector<const SpriteSetup*> p(n);
    Lcg next{777};
    std::uint32_t id = 0;
    for (std::size_t i = 0; i < n; ++i) {
        s[i].gpu.depth = float(1 + next() % 300) / 300.0f;
        s[i].entityId = id += 1 + std::uint32_t(next() % 2);
        if (next() % 9 == 0) s[i].cull = CullReason::OffScreen;
        p[i] = next() % 60 == 0 ? nullptr : &s[i];
    }
    const auto expectPlainSort = [&](const char* what) {
        EXPECT_TRUE(frontToBack(p) == plainOrder(p)) << what;
    };
    expectPlainSort("ids ascending");
    std::vector<float> depths(n);
    for (std::size_t i = 0; i < n; ++i) depths[i] = s[i].gpu.depth;
    for (std::size_t i = 0; i < n; i += 4) s[i].gpu.depth = 0.0f;
    expectPlainSort("visible sprites at depth 0");
    for (std::size_t i = 0; i < n; ++i) s[i].gpu.depth = depths[i];
    std::swap(s[100].entityId, s[50000].entityId);
    s[100].cull = s[50000].cull = CullReason::None, p[100] = &s[100], p[50000] = &s[50000];
    s[100].gpu.depth = s[50000].gpu.depth = 0.25f;
    expectPlainSort("two ids out of order");
    // Each half ascending, the second below the first: out of order only where the halves meet
    // (where TBB's first split falls), which the halves' join must see.
    for (std::size_t i = 0; i < n; ++i)
        s[i].entityId = std::uint32_t(i < n / 2 ? n + i : i - n / 2);
    expectPlainSort("halves out of order");
}

/// Renders the frames of `scene` in `mode` with and without culling (two renderers, the same
/// frames in order, so the selector and the caches go through the same states) and expects the
/// images equal in colour, depth and id. Returns the sprites culling dropped whole, all frames.
int expectCullingChangesNothing(Scene scene, RenderMode mode, const std::vector<int>& frames,
                                const std::string& what) {
    FrameOptions on = test::cpuNear(), off = test::cpuNear();
    on.occlusionCull = true;
    off.occlusionCull = false;
    Scene copy = scene;
    FrameRenderer culled(scene, on), whole(copy, off);
    int dropped = 0;
    for (int f : frames) {
        const double t = scene.path ? scene.timeOfFrame(f) : 0.0;
        const FrameResult a = culled.render(t, mode, f);
        const FrameResult b = whole.render(t, mode, f);
        EXPECT_EQ(b.stats.reference.culled + b.stats.far.culled, 0) << what;
        const ImageDiff d = diffImages(a.image, b.image);
        EXPECT_TRUE(d.identical()) << what << " " << toString(mode) << " frame " << f << ": "
                                   << test::describeDifference(a.image, b.image, "culled", "whole");
        dropped += a.stats.reference.culled + a.stats.far.culled;
    }
    return dropped;
}

std::vector<int> someFrames(const Scene& s, int count) {
    const int n = s.path ? s.path->frameCount() : 1;
    std::vector<int> f;
    for (int k = 0; k < count; ++k) f.push_back(k * std::max(1, n - 1) / std::max(1, count - 1));
    return f;
}

class CullingOnSceneFiles : public ::testing::TestWithParam<const char*> {};

TEST_P(CullingOnSceneFiles, SameImageInEveryCpuMode) {
    Scene s = loadScene(test::sourcePath(GetParam()));
    // Smaller images keep the bench scenes fast; the sprites shrink, the overdraw stays.
    if (s.camera.width > 480) s.camera.width /= 2, s.camera.height /= 2;
    for (RenderMode m : {RenderMode::Reference, RenderMode::Far, RenderMode::Hybrid})
        expectCullingChangesNothing(s, m, someFrames(s, 3), GetParam());
}

INSTANTIATE_TEST_SUITE_P(
    Scenes, CullingOnSceneFiles,
    ::testing::Values("scenes/default.json", "scenes/golden/arrows.json",
                      "scenes/golden/crowd.json", "scenes/golden/equal_depth.json",
                      "scenes/golden/far_origin.json", "scenes/golden/topdown.json",
                      "scenes/bench/tank_army.json", "scenes/bench/rts_pan.json",
                      "scenes/bench/street.json", "scenes/bench/vox_crowd.json"));

// The CPU reference's early depth test: a pixel already holding what the depth/id rule keeps
// against a sprite is neither traced nor looked up. The images with and without it must be equal
// in colour, depth and id, in both draw orders (as given, and front to back) and at both rates,
// and on crowds it must skip real work.
TEST(EarlyDepthTest, SameImageAndFewerTraces) {
    for (const char* file : {"scenes/golden/crowd.json", "scenes/golden/equal_depth.json",
                             "scenes/golden/far_origin.json", "scenes/bench/tank_army.json",
                             "scenes/bench/street.json"}) {
        Scene s = loadScene(test::sourcePath(file));
        if (s.camera.width > 480) s.camera.width /= 2, s.camera.height /= 2;
        const CameraFrame cam = makeCameraFrame(s.cameraAt(0.0));
        const std::vector<SpriteSetup> sprites = setupSprites(s, cam, 0.0);
        for (bool cull : {false, true})
            for (NearRate rate : {NearRate::Fragment, NearRate::Cell}) {
                ReferenceOptions early, every;
                early.occlusionCull = every.occlusionCull = cull;
                early.rate = every.rate = rate;
                every.earlyDepthTest = false;
                Image a(cam.width, cam.height, s.render.background), b = a;
                ReferenceStats sa, sb;
                renderReference(s.models, sprites, a, &sa, early);
                renderReference(s.models, sprites, b, &sb, every);
                const std::string what =
                    std::string(file) + (cull ? " cull " : " no-cull ") + toString(rate);
                EXPECT_EQ(test::describeDifference(a, b, "early-z", "every pixel"), "") << what;
                EXPECT_EQ(sb.pixelsHidden, 0u) << what;
                EXPECT_EQ(sa.pixelsTested, sb.pixelsTested) << what;
                EXPECT_EQ(sa.pixelsInSprite + sa.pixelsHidden >= sb.pixelsInSprite, true) << what;
                if (std::string(file).find("crowd") != std::string::npos ||
                    std::string(file).find("tank_army") != std::string::npos) {
                    EXPECT_GT(sa.pixelsHidden, 0u) << what;
                    EXPECT_LT(sa.pixelsTraced + sa.pixelsLookedUp,
                              sb.pixelsTraced + sb.pixelsLookedUp)
                        << what;
                }
            }
    }
}

// Cross-fades: both tiers draw a fading entity with complementary dither halves at one depth;
// culling must leave both halves' pixels. A corridor walked through with 6-frame fades, and the
// error budget's view switches, which fade too.
TEST(Culling, CrossFadingEntitiesKeepEveryPixel) {
    Scene s = test::crossFadeCorridor();
    std::vector<int> all;
    for (int f = 0; f < s.path->frameCount(); ++f) all.push_back(f);
    FrameRenderer probe(s, test::cpuNear());
    int fading = 0;
    for (int f : all)
        fading += probe.render(s.timeOfFrame(f), RenderMode::Hybrid, f).stats.plan.fading;
    ASSERT_GT(fading, 0) << "the path must cross-fade somewhere";
    EXPECT_GT(expectCullingChangesNothing(s, RenderMode::Hybrid, all, "corridor"), 0);
    s.selector.metric = SelectorMetric::ErrorBudget;
    s.selector.budgetVpx = 1.0;
    expectCullingChangesNothing(s, RenderMode::Hybrid, all, "corridor, error budget");
}

// Equal depths everywhere: stacks of entities at one position (identical sprites, the id rule
// alone decides every pixel) and rows at one view depth, some of them crossing the near plane.
TEST(Culling, EqualDepthStacksAndSpritesThroughTheNearPlane) {
    const Scene s = test::equalDepthStacks();
    for (RenderMode m : {RenderMode::Reference, RenderMode::Far, RenderMode::Hybrid})
        expectCullingChangesNothing(s, m, {0}, "equal-depth stacks");
}

// A wall in front of a crowd: every entity behind it is dropped whole, so the far tier bakes no
// snapshot of the model only they show, and the CPU reference traces none of their cells.
TEST(Culling, EntitiesBehindAWallAreDroppedBeforeAnyBake) {
    Scene s;
    s.render.voxelSize = 0.1;
    s.models = {makeBox({40, 40, 40}), makeSphere(4)};
    Entity wall;
    wall.model = 0;
    wall.position = {0, -2, -3}; // the anchor is the bottom centre: the wall spans y -2..2
    s.entities.push_back(wall);
    for (int i = 0; i < 30; ++i) {
        Entity e;
        e.model = 1;
        e.position = {-0.6 + 0.3 * (i % 5), -0.5 + 0.2 * (i / 5), -12.0 - 0.5 * i};
        s.entities.push_back(e);
    }
    s.camera.width = 200;
    s.camera.height = 120;
    s.camera.position = {0, 0, 2};
    s.camera.target = {0, 0, -10};
    FrameOptions on = test::cpuNear(), off = test::cpuNear();
    // Per pixel: cell-rate cells are traced on first use, and two bands needing one cell at once
    // both trace it, so a cell-rate sprite's read count varies by a few from run to run.
    on.nearRate = off.nearRate = NearRate::Fragment;
    on.occlusionCull = true;
    off.occlusionCull = false;
    Scene copy = s;
    FrameRenderer culled(s, on), whole(copy, off);
    const FrameResult a = culled.render(0.0, RenderMode::Far, 0);
    const FrameResult b = whole.render(0.0, RenderMode::Far, 0);
    EXPECT_TRUE(diffImages(a.image, b.image).identical());
    EXPECT_EQ(a.stats.far.culled, 30);
    EXPECT_EQ(a.stats.far.bakes, 1) << "the wall's one view, nothing of the hidden spheres";
    EXPECT_GT(b.stats.far.bakes, 1);
    for (std::uint32_t e = 1; e <= 30; ++e) ASSERT_EQ(b.image.countEntity(e), 0u);
    const FrameResult c = culled.render(0.0, RenderMode::Reference, 0);
    EXPECT_EQ(c.stats.reference.culled, 30);
    // Not one voxel read for the hidden spheres, with culling (dropped whole) and without it
    // (the wall, entity 0, is drawn first, and the early depth test rejects every pixel behind
    // it): both read exactly what the wall alone reads.
    Scene wallOnly = s;
    wallOnly.entities.resize(1);
    FrameRenderer alone(wallOnly, off);
    const std::uint64_t wallReads =
        alone.render(0.0, RenderMode::Reference, 0).stats.reference.voxelFetches;
    EXPECT_GT(wallReads, 0u);
    EXPECT_EQ(c.stats.reference.voxelFetches, wallReads);
    EXPECT_EQ(whole.render(0.0, RenderMode::Reference, 0).stats.reference.voxelFetches, wallReads);
}

// The CPU reference counts its sprite rows for a progress line (issue 27): every row it adds to
// the total is counted done by the end of the frame, with culling (runs, sprites skipped whole)
// or without, and counting changes no pixel.
TEST(Culling, ReferenceRowProgressEndsAtItsTotalAndChangesNothing) {
    for (const bool cull : {false, true}) {
        Scene scene = test::hardCaseWorld(glm::dvec3(0.0));
        Scene copy = scene;
        FrameOptions counted = test::cpuNear(), plain = test::cpuNear();
        counted.occlusionCull = plain.occlusionCull = cull;
        WorkProgress rows;
        counted.nearProgress = &rows;
        FrameRenderer a(copy, counted);
        FrameRenderer b(scene, plain);
        const FrameResult ra = a.render(0.0, RenderMode::Reference);
        const FrameResult rb = b.render(0.0, RenderMode::Reference);
        // Four sprites of the hard-case world, each some tens of rows tall on its 200 rows.
        EXPECT_GT(rows.total.load(), 40u) << cull;
        EXPECT_EQ(rows.done.load(), rows.total.load()) << cull;
        EXPECT_TRUE(diffImages(ra.image, rb.image).identical())
            << test::describeDifference(ra.image, rb.image, "counted", "plain");
        // A second frame counts anew from a reset.
        const std::uint64_t first = rows.total.load();
        rows.reset();
        a.render(0.0, RenderMode::Reference);
        EXPECT_EQ(rows.total.load(), first);
        EXPECT_EQ(rows.done.load(), first);
    }
}

// The command line's switches: render --cull, the default (the near tier's early depth test) and
// --no-cull write the same colours in every mode, near on Vulkan included (the library-level
// cases compare depth and id too); --cull and --no-cull together are refused.
TEST(Culling, RenderCullAndNoCullWriteTheSameImage) {
    const auto dir = test::scratchDir("cull_cli", true);
    for (const char* mode : {"reference", "far", "hybrid", "near"}) {
        const std::string base = "render " + test::sourcePath("scenes/bench/street.json") +
                                 " --near-backend reference --size 320x180 --mode " + mode;
        const std::string whole = (dir / (std::string(mode) + "_whole.exr")).string();
        const auto rw = test::runCli(base + " --no-cull -o " + whole);
        ASSERT_EQ(rw.status, 0) << rw.err;
        for (const char* flag : {"--cull", ""}) {
            const std::string out = (dir / (std::string(mode) + flag + "_out.exr")).string();
            const auto r = test::runCli(base + " " + flag + " -o " + out);
            ASSERT_EQ(r.status, 0) << r.err;
            EXPECT_TRUE(diffImages(readColorImage(out), readColorImage(whole)).identical())
                << mode << " " << flag;
        }
    }
    const auto both = test::runCli("render " + test::sourcePath("scenes/golden/crowd.json") +
                                   " --cull --no-cull -o " + (dir / "x.png").string());
    EXPECT_NE(both.status, 0);
    EXPECT_NE(both.err.find("--no-cull"), std::string::npos) << both.err;
}

// The crowd the issue is about: the tank army at 100,000 entities, where culling drops most
// sprites whole (small image, so the run without culling stays a few seconds).
TEST(Culling, OneHundredThousandTanks) {
    const Scene s = test::tankArmy(100000, 320, 180);
    ASSERT_EQ(s.entities.size(), 100000u);
    // Seen from above the crowd, nearly every tank shows its top over the ones in front, so few
    // are dropped whole; what culling saves here is the hidden rows and tiles of each.
    for (RenderMode m : {RenderMode::Reference, RenderMode::Far})
        expectCullingChangesNothing(s, m, {0}, "100,000 tanks");
}

} // namespace
} // namespace voxtier
