// The far tier on Vulkan (CONTRACT.md §6, the far pass): far sprites drawn by a compute pass in the
// near tier's frame, into the same targets, equal the CPU far blit into the near image pixel for
// pixel (colour, depth bits, id), and the validation layer (synchronization validation included)
// stays silent. Over the golden scenes (all far and hybrid, through the frame recipe), every
// bundled model at canonical and seeded random views with rolls, sigma 0.5-3 and cross-fades,
// sprites cut by the image edge, equal-depth pairs with near sprites either way round, and 10^6 m
// from the origin. Snapshots are uploaded to the device once and freed when the cache drops them.
#include "compose/frame.hpp"
#include "compose/frame_figures.hpp"
#include "compose/vulkan_frame.hpp"
#include "core/procedural.hpp"
#include "core/scene_loader.hpp"
#include "core/splitmix64.hpp"
#include "hard_case_scenes.hpp"
#include "image_checks.hpp"
#include "impostor_cache/far_frame.hpp"
#include "impostor_cache/far_residency.hpp"
#include "impostor_cache/shaders/far_shared.h"
#include "impostor_cache/snapshot_cache.hpp"
#include "source_tree.hpp"
#include "test_models.hpp"
#include "view_sweeps.hpp"
#include "vulkan_test_env.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <memory>
#include <set>
#include <string>

namespace voxtier {
namespace {

const auto* const kEnv = ::testing::AddGlobalTestEnvironment(new test::NearRendererEnvironment);

using test::describeDifference;
using test::sourcePath;

class VulkanFar : public test::VulkanTest {
  protected:
    /// The suite's far passes, one per way of cutting the pass (FarTiles), on the shared
    /// renderer's frames (their residencies persist across the suite's tests, as a renderer's
    /// does across frames).
    static FarPass& farPass(FarTiles tiles = FarTiles::Coarse) {
        std::unique_ptr<FarPass>& pass = passes_[std::size_t(tiles)];
        if (!pass) pass = std::make_unique<FarPass>(nearRenderer().frames(), tiles);
        return *pass;
    }
    static void TearDownTestSuite() {
        for (auto& pass : passes_) pass.reset();
    }
    static std::string nameOf(FarTiles tiles) {
        return tiles == FarTiles::Fine ? "fine" : tiles == FarTiles::Sprites ? "sprites" : "coarse";
    }
    /// `near` sprites and `batch` in one Vulkan frame (compose/vulkan_frame.hpp).
    static Image drawBoth(const CameraFrame& cam, const Scene& scene,
                          std::span<const SpriteSetup* const> near, const FarBatch& batch,
                          FarPassStats* stats = nullptr, Rgba8 clear = 0,
                          FarTiles tiles = FarTiles::Coarse) {
        VulkanFrameRequest request;
        request.camera = &cam;
        request.models = &scene.models;
        request.nearSprites = near;
        request.far = &batch;
        request.clear = clear;
        VulkanFrameResult r = drawVulkanFrame(nearRenderer(), &farPass(tiles), request);
        if (stats) *stats = r.far;
        return std::move(r.image);
    }
    inline static std::array<std::unique_ptr<FarPass>, 4> passes_; // by FarTiles
    static constexpr FarTiles kEveryCut[] = {FarTiles::Coarse, FarTiles::Fine, FarTiles::Sprites};

    static FrameOptions options(FarBackend far, NearBackend near = NearBackend::Vulkan,
                                FarTiles tiles = FarTiles::Coarse) {
        FrameOptions o;
        o.farTiles = tiles;
        o.sharedNear = sharedNearRenderer();
        o.nearBackend = near;
        o.nearPixels = NearPixels::Compute; // a GPU's default (Auto draws on lavapipe)
        o.farBackend = far;
        o.costAwareBakes = false; // a test must not depend on timing
        return o;
    }

    /// The hard-case world on a 160 x 100 image at sigma 1, its entities taken out into `kinds`
    /// (one of each, for the crowd tests to place copies of).
    static Scene smallImage(std::vector<Entity>& kinds) {
        Scene s = test::hardCaseWorld(glm::dvec3(0.0));
        s.render.sigma = 1.0;
        s.camera.width = 160;
        s.camera.height = 100;
        kinds = std::move(s.entities);
        s.entities.clear();
        return s;
    }
    /// `count` entities of the hard-case kinds in turn, heaped in the box [lo, hi] in front of
    /// the camera of smallImage, each turned at random about +Y (seeded).
    static Scene heapOfKinds(int count, std::uint64_t seed, glm::dvec3 lo, glm::dvec3 hi) {
        std::vector<Entity> kinds;
        Scene s = smallImage(kinds);
        SplitMix64 rng{seed};
        for (int i = 0; i < count; ++i) {
            Entity e = kinds[std::size_t(i) % kinds.size()];
            e.position = {rng.uniform(lo.x, hi.x), rng.uniform(lo.y, hi.y),
                          rng.uniform(lo.z, hi.z)};
            e.rotation = glm::angleAxis(rng.uniform(0.0, 6.28), glm::dvec3(0.0, 1.0, 0.0));
            s.entities.push_back(e);
        }
        return s;
    }
    /// Where a sprite can draw: its screen rectangle within the image (empty: nowhere).
    static glm::ivec4 rectInImage(const SpriteSetup& sp, const CameraFrame& cam) {
        if (!sp.visible()) return glm::ivec4(0);
        return glm::clamp(sp.screenRect, glm::ivec4(0),
                          glm::ivec4(cam.width, cam.height, cam.width, cam.height));
    }

    /// One frame of `scene` drawn as `plan` says, near sprites on Vulkan, far sprites once by
    /// the CPU blit and by the Vulkan far pass cut each way, through one snapshot cache: the
    /// images are identical. Returns the CPU image's far-drawn pixel count (the test must draw).
    std::size_t expectSame(const Scene& scene, const std::vector<SpriteSetup>& sprites,
                           const std::vector<EntityPlan>& plan, const std::string& what) {
        const CameraFrame cam = makeCameraFrame(scene.camera);
        std::vector<const SpriteSetup*> nearSprites;
        std::vector<SpriteSetup> faded; // reserved: pointers into it stay valid
        faded.reserve(3 * sprites.size());
        std::vector<FarRequest> requests;
        for (std::size_t i = 0; i < sprites.size(); ++i) {
            const EntityPlan& p = plan[i];
            const auto share = [&](bool keepBelow) -> const SpriteSetup* {
                if (p.fade <= 0.0f) return &sprites[i];
                SpriteSetup c = sprites[i];
                c.gpu.fade = p.fade;
                c.gpu.fadeSide = keepBelow ? 1.0f : -1.0f;
                faded.push_back(c);
                return &faded.back();
            };
            if (p.drawsNear()) nearSprites.push_back(share(p.tier == Tier::Near));
            if (p.drawsFar()) requests.push_back({share(p.tier == Tier::Far), p.view});
            if (p.fadeFromView && p.fade > 0.0f) requests.push_back({share(false), p.fadeFromView});
        }
        const ViewSet set = ViewSet::Cube26;
        Image cpu = nearRenderer().render(cam, scene.models, nearSprites, scene.render.background);
        const Image nearOnly = cpu;
        drawFarSprites(scene.models, requests, cache_, set, cpu);
        const FarBatch batch = prepareFarBatch(scene.models, requests, cache_, set);
        std::size_t farPixels = 0;
        for (std::size_t p = 0; p < cpu.pixelCount(); ++p)
            farPixels += cpu.id[p] != nearOnly.id[p] || cpu.color[p] != nearOnly.color[p];
        for (const FarTiles tiles : kEveryCut) {
            const std::string how = what + ", " + nameOf(tiles);
            FarPassStats fs;
            const Image gpu =
                drawBoth(cam, scene, nearSprites, batch, &fs, scene.render.background, tiles);
            EXPECT_EQ(describeDifference(gpu, cpu, "vulkan far", "cpu far"), "") << how;
            if (farPixels) { // the far pass really ran
                EXPECT_GT(fs.sprites, 0u) << how;
                EXPECT_EQ(fs.tiles > 0u, tiles != FarTiles::Sprites) << how;
            }
        }
        return farPixels;
    }

    /// The hard-case world with a far request (the nearest view) for each of its sprites.
    struct HardCaseRequests {
        Scene scene;
        CameraFrame cam;
        std::vector<SpriteSetup> sprites;
        std::vector<FarRequest> requests; ///< into `sprites`, whose storage a move keeps
    };
    static HardCaseRequests hardCaseRequests() {
        HardCaseRequests h;
        h.scene = test::hardCaseWorld(glm::dvec3(0.0));
        h.cam = makeCameraFrame(h.scene.camera);
        h.sprites = setupSprites(h.scene, h.cam, 0.0);
        for (const auto& sp : h.sprites) h.requests.push_back({&sp, std::nullopt});
        return h;
    }

    static std::vector<EntityPlan> allFar(std::size_t n) {
        EntityPlan p;
        p.tier = Tier::Far;
        return std::vector<EntityPlan>(n, p);
    }

    SnapshotCache cache_;
};

TEST_F(VulkanFar, GoldenScenesEqualTheCpuBlitThroughTheFrame) {
    // The frame recipe (compose/frame.cpp) with each far backend: all far, and hybrid over the
    // first frames of each scene's path (switches and cross-fades as the selector makes them).
    for (const char* file :
         {"scenes/golden/arrows.json", "scenes/golden/crowd.json", "scenes/golden/equal_depth.json",
          "scenes/golden/far_origin.json", "scenes/golden/topdown.json", "scenes/default.json"}) {
        // The fine tiles and the pass cut by sprite too, over the all-far frame and the path's
        // first frames.
        Scene a = loadScene(sourcePath(file)), b = a, c = a, d = a;
        FrameRenderer cpu(a, options(FarBackend::Cpu)), gpu(b, options(FarBackend::Vulkan)),
            fine(c, options(FarBackend::Vulkan, NearBackend::Vulkan, FarTiles::Fine)),
            bySprite(d, options(FarBackend::Vulkan, NearBackend::Vulkan, FarTiles::Sprites));
        const FrameResult fc = cpu.render(0.0, RenderMode::Far),
                          fg = gpu.render(0.0, RenderMode::Far),
                          ff = fine.render(0.0, RenderMode::Far),
                          fs = bySprite.render(0.0, RenderMode::Far);
        EXPECT_EQ(describeDifference(fg.image, fc.image, "vulkan far", "cpu far"), "")
            << file << " all far";
        EXPECT_EQ(describeDifference(ff.image, fc.image, "vulkan far, fine", "cpu far"), "")
            << file << " all far";
        EXPECT_EQ(describeDifference(fs.image, fc.image, "vulkan far, sprites", "cpu far"), "")
            << file << " all far";
        EXPECT_GT(fc.stats.farDrawn, 0) << file;
        EXPECT_EQ(fg.stats.farOnVulkan, 1) << file;
        EXPECT_EQ(ff.stats.farOnVulkan, 1) << file;
        EXPECT_EQ(fs.stats.farOnVulkan, 1) << file;
        EXPECT_EQ(fc.stats.farOnVulkan, 0) << file;
        const double fps = a.path ? a.path->fps : 30.0;
        for (int f = 0; f < 4; ++f) {
            const double t = f * 4 / fps;
            const FrameResult hc = cpu.render(t, RenderMode::Hybrid, f);
            const FrameResult hg = gpu.render(t, RenderMode::Hybrid, f);
            const FrameResult hf = fine.render(t, RenderMode::Hybrid, f);
            const FrameResult hs = bySprite.render(t, RenderMode::Hybrid, f);
            EXPECT_EQ(describeDifference(hg.image, hc.image, "vulkan far", "cpu far"), "")
                << file << " hybrid frame " << f;
            EXPECT_EQ(describeDifference(hf.image, hc.image, "vulkan far, fine", "cpu far"), "")
                << file << " hybrid frame " << f;
            EXPECT_EQ(describeDifference(hs.image, hc.image, "vulkan far, sprites", "cpu far"), "")
                << file << " hybrid frame " << f;
            EXPECT_EQ(hg.plan, hc.plan) << file << " hybrid frame " << f;
        }
    }
}

// Issue 29: snapshots 2 and 3 times finer than the sprites carry their wider outline in their
// codes, so the far pass reads them as it reads any snapshot, and draws the CPU blit's image.
TEST_F(VulkanFar, FinerSnapshotsEqualTheCpuBlit) {
    for (const char* file : {"scenes/golden/crowd.json", "scenes/golden/topdown.json"})
        for (int scale : {2, 3}) {
            Scene a = loadScene(sourcePath(file));
            a.selector.snapshotScale = scale;
            Scene b = a;
            FrameRenderer cpu(a, options(FarBackend::Cpu)), gpu(b, options(FarBackend::Vulkan));
            const FrameResult fc = cpu.render(0.0, RenderMode::Far),
                              fg = gpu.render(0.0, RenderMode::Far);
            EXPECT_EQ(describeDifference(fg.image, fc.image, "vulkan far", "cpu far"), "")
                << file << " x" << scale;
            EXPECT_GT(fc.stats.farDrawn, 0) << file;
            EXPECT_EQ(fg.stats.farOnVulkan, 1) << file;
            // The bakes' rays count whichever backend draws the far sprites.
            EXPECT_GT(fc.stats.far.raysTraced, 0u) << file;
            EXPECT_EQ(fg.stats.far.raysTraced, fc.stats.far.raysTraced) << file;
        }
}

TEST_F(VulkanFar, NearSpritesOnTheCpuReferenceComposeWithTheVulkanFarImage) {
    Scene a = loadScene(sourcePath("scenes/default.json")), b = a;
    FrameRenderer cpu(a, options(FarBackend::Cpu, NearBackend::Reference));
    FrameRenderer gpu(b, options(FarBackend::Vulkan, NearBackend::Reference));
    for (int f = 0; f < 3; ++f) {
        const FrameResult hc = cpu.render(f * 0.2, RenderMode::Hybrid, f);
        const FrameResult hg = gpu.render(f * 0.2, RenderMode::Hybrid, f);
        EXPECT_EQ(describeDifference(hg.image, hc.image, "vulkan far", "cpu far"), "") << f;
        EXPECT_EQ(hg.stats.nearOnVulkan, 0);
    }
}

// With the near tier on Vulkan and the far tier on the CPU, the far snapshots are looked up and
// baked while the device draws, then blitted on the image read back (compose/frame.cpp): the same
// image and figures as the near tier drawn by the CPU reference first (the far tier after it),
// and as occlusion culling's runs, which look up and blit a run at a time on the near image.
TEST_F(VulkanFar, SnapshotsBakedWhileTheDeviceDrawsBlitTheImageOfOneAfterTheOther) {
    for (const char* file :
         {"scenes/default.json", "scenes/golden/arrows.json", "scenes/golden/far_origin.json"}) {
        Scene a = loadScene(sourcePath(file)), b = a, c = a;
        FrameRenderer ahead(a, options(FarBackend::Cpu)),
            after(b, options(FarBackend::Cpu, NearBackend::Reference));
        FrameOptions runs = options(FarBackend::Cpu);
        runs.occlusionCull = true;
        FrameRenderer inRuns(c, runs);
        const double fps = a.path ? a.path->fps : 30.0;
        int bakedAhead = 0, frames = 0;
        for (int f = 0; f < 4; ++f) {
            const double t = f * 4 / fps;
            const FrameResult ha = ahead.render(t, RenderMode::Hybrid, f);
            const FrameResult hb = after.render(t, RenderMode::Hybrid, f);
            const FrameResult hc = inRuns.render(t, RenderMode::Hybrid, f);
            EXPECT_EQ(ha.plan, hb.plan) << file << " frame " << f;
            EXPECT_EQ(describeDifference(ha.image, hb.image, "baked ahead", "one after the other"),
                      "")
                << file << " frame " << f;
            EXPECT_EQ(describeDifference(ha.image, hc.image, "baked ahead", "culled in runs"), "")
                << file << " frame " << f;
            if (ha.stats.farDrawn == 0 || ha.stats.nearDrawn == 0) continue;
            ++frames;
            EXPECT_EQ(ha.stats.nearOnVulkan, 1) << file << " frame " << f;
            // The same far work, counted as before: sprites, snapshots, bakes.
            EXPECT_EQ(ha.stats.far.sprites, hb.stats.far.sprites) << file << " frame " << f;
            EXPECT_EQ(ha.stats.far.snapshotsUsed, hb.stats.far.snapshotsUsed) << file;
            EXPECT_EQ(ha.stats.far.bakes, hb.stats.far.bakes) << file << " frame " << f;
            EXPECT_EQ(ha.stats.far.blit.pixelsTested, hb.stats.far.blit.pixelsTested) << file;
            EXPECT_GE(ha.stats.farMs, ha.stats.far.ensureMs + ha.stats.far.blit.milliseconds);
            bakedAhead += int(ha.stats.far.bakes);
        }
        EXPECT_GT(frames, 0) << file << ": no frame drew both tiers";
        EXPECT_GT(bakedAhead, 0) << file << ": nothing was baked while the device drew";
    }
}

TEST_F(VulkanFar, AColourOnlyFrameHasTheColourOfTheFullFrame) {
    // One plane read back instead of three: the same colour, with the ground plane and with a
    // transparent background filled in where no sprite drew (found by alpha, not by id).
    for (const bool transparent : {false, true}) {
        Scene a = loadScene(sourcePath("scenes/default.json"));
        a.ground = GroundPlane{};
        if (transparent) a.render.background = packRgba(40, 44, 52, 0);
        Scene b = a;
        FrameOptions colourOnly = options(FarBackend::Vulkan);
        colourOnly.depthAndIds = false;
        FrameRenderer full(a, options(FarBackend::Vulkan)), part(b, colourOnly);
        for (int f = 0; f < 2; ++f) {
            const FrameResult rf = full.render(f * 0.25, RenderMode::Hybrid, f);
            const FrameResult rp = part.render(f * 0.25, RenderMode::Hybrid, f);
            EXPECT_TRUE(rp.image.id.empty() && rp.image.depth.empty());
            ASSERT_EQ(rp.image.color.size(), rf.image.color.size());
            std::size_t differ = 0;
            for (std::size_t p = 0; p < rf.image.color.size(); ++p)
                differ += rf.image.color[p] != rp.image.color[p];
            EXPECT_EQ(differ, 0u) << "frame " << f << (transparent ? " transparent" : " ground");
            EXPECT_GT(rf.stats.farDrawn, 0);
            EXPECT_EQ(rp.stats.farOnVulkan, 1);
        }
    }
}

TEST_F(VulkanFar, BundledModelsAtCanonicalAndRandomViewsWithRollsSigmasAndFades) {
    SplitMix64 rng{26};
    const auto canonical = test::canonicalDirections();
    int cases = 0;
    for (const test::BundledModel& m : test::bundledVoxModels()) {
        const glm::ivec3 dims = m.model->frame(0).dims();
        const bool large = std::max({dims.x, dims.y, dims.z}) > 64;
        // Large models (the 256^3 trees) at a few views: the CPU blit's half of each check is
        // what costs (its bakes are shared with the far pass through the one cache).
        const int views = large ? 2 : 5;
        for (int k = 0; k < views; ++k) {
            const bool random = k % 2 == 1;
            const glm::dvec3 dir =
                random ? glm::dvec3(rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1))
                       : glm::dvec3(canonical[rng.below(canonical.size())]);
            if (glm::length(dir) < 0.1) continue;
            const double sigmas[] = {0.5, 1.0, 1.5, 2.0, 3.0};
            const double sigma = large ? 1.0 : sigmas[rng.below(5)];
            const int roll = int(rng.below(4));
            test::ViewSetup v = test::viewAlong(m.model, dir, sigma, 1, roll);
            const CameraFrame cam = makeCameraFrame(v.scene.camera);
            const auto sprites = setupSprites(v.scene, cam, 0.0);
            const std::string what = m.file + "#" + std::to_string(m.index) + " dir " +
                                     std::to_string(dir.x) + "," + std::to_string(dir.y) + "," +
                                     std::to_string(dir.z) + " sigma " + std::to_string(sigma) +
                                     " roll " + std::to_string(roll);
            // All far; a tier cross-fade (near and far halves in one frame); a view cross-fade.
            std::vector<EntityPlan> plan = allFar(sprites.size());
            const std::size_t drawn = expectSame(v.scene, sprites, plan, what + " far");
            // A few tiny models draw nothing at sigma 0.5 in every tier (sub-pixel, or thinner
            // than the two voxels between cell rays); the count below keeps the test honest.
            cases += drawn > 0;
            plan[0].fade = float(rng.uniform(0.1, 0.9));
            plan[0].fadeFrom = Tier::Near;
            expectSame(v.scene, sprites, plan, what + " tier fade");
            plan[0].fadeFrom = Tier::Far;
            plan[0].view =
                viewIdOf(ViewSet::Cube26, nearestView(ViewSet::Cube26, -sprites[0].lattice.dir));
            plan[0].fadeFromView = viewIdOf(ViewSet::Cube26, int(rng.below(26)));
            expectSame(v.scene, sprites, plan, what + " view fade");
        }
    }
    EXPECT_GT(cases, 20);
}

TEST_F(VulkanFar, PartlyOffScreenEqualDepthPairsAndFarFromTheOrigin) {
    // Cut by the image edge, magnified.
    test::ViewSetup v = test::viewAlong(test::solidBox({12, 9, 7}), glm::dvec3(1, 1, 2), 1.0, 4);
    v.scene.camera.target += glm::dvec3(0.35, 0.2, 0.0);
    {
        const CameraFrame cam = makeCameraFrame(v.scene.camera);
        const auto sprites = setupSprites(v.scene, cam, 0.0);
        ASSERT_TRUE(sprites[0].visible());
        EXPECT_GT(expectSame(v.scene, sprites, allFar(1), "partly off-screen"), 0u);
    }
    // Equal depths: the lower entity id owns the shared pixels whichever tier draws it.
    const Scene pair = test::equalDepthPair();
    const CameraFrame cam = makeCameraFrame(pair.camera);
    const auto sprites = setupSprites(pair, cam, 0.0);
    ASSERT_EQ(sprites[0].gpu.depth, sprites[1].gpu.depth);
    for (const auto& [t0, t1] : {std::pair{Tier::Near, Tier::Far}, std::pair{Tier::Far, Tier::Near},
                                 std::pair{Tier::Far, Tier::Far}}) {
        std::vector<EntityPlan> plan(2);
        plan[0].tier = t0;
        plan[1].tier = t1;
        EXPECT_GT(expectSame(pair, sprites, plan, "equal-depth pair"), 0u);
    }
    // About 10^6 m from the origin (2^20 m, so the camera-relative doubles are exact).
    const Scene distant = test::hardCaseWorld(glm::dvec3(1 << 20));
    const CameraFrame dc = makeCameraFrame(distant.camera);
    const auto ds = setupSprites(distant, dc, 0.0);
    EXPECT_GT(expectSame(distant, ds, allFar(ds.size()), "10^6 m"), 0u);
    std::vector<EntityPlan> mixed = allFar(ds.size());
    mixed[1].tier = mixed[3].tier = Tier::Near;
    expectSame(distant, ds, mixed, "10^6 m, mixed tiers");
}

// A crowd of 300 far sprites heaped on one spot of the image: one coarse tile and one fine
// tile each list more far sprites than a workgroup reads in one batch (64), so the pass runs
// several batches per tile in both sizes, and the depth rule decides among many sprites per pixel.
TEST_F(VulkanFar, CrowdedTilesOfManySmallSpritesEqualTheCpuBlit) {
    const Scene s = heapOfKinds(300, 35, {-1.0, -0.6, -16.0}, {1.0, 0.6, -8.0});
    const CameraFrame cam = makeCameraFrame(s.camera);
    const auto sprites = setupSprites(s, cam, 0.0);
    // The most far rectangles any tile of each size holds, counted here from the sprites.
    const auto mostInOneTile = [&](int side) {
        std::vector<int> count(std::size_t((cam.width + side - 1) / side) *
                               std::size_t((cam.height + side - 1) / side));
        const int columns = (cam.width + side - 1) / side;
        for (const SpriteSetup& sp : sprites) {
            const glm::ivec4 r = rectInImage(sp, cam);
            if (r.z <= r.x || r.w <= r.y) continue;
            for (int ty = r.y / side; ty <= (r.w - 1) / side; ++ty)
                for (int tx = r.x / side; tx <= (r.z - 1) / side; ++tx)
                    ++count[std::size_t(ty * columns + tx)];
        }
        return *std::max_element(count.begin(), count.end());
    };
    ASSERT_GT(mostInOneTile(32), 128) << "a coarse tile reads three batches or more";
    ASSERT_GT(mostInOneTile(8), 64) << "a fine tile reads two batches or more";
    EXPECT_GT(expectSame(s, sprites, allFar(sprites.size()), "crowded tiles"), 500u);
    std::vector<EntityPlan> mixed = allFar(sprites.size());
    for (std::size_t i = 0; i < mixed.size(); i += 3) mixed[i].tier = Tier::Near;
    expectSame(s, sprites, mixed, "crowded tiles, every third near");
}

// More far sprites than the host bins in one run (FarPass: 4,096 entries a run at least, each
// tile's list assembled from the runs in draw order): 9,000 small sprites on a 160 x 100 image,
// so every tile of both sizes lists hundreds, read from several runs.
TEST_F(VulkanFar, ThousandsOfSpritesBinnedInRunsEqualTheCpuBlit) {
    const Scene s = heapOfKinds(9000, 4096, {-6.0, -3.5, -40.0}, {6.0, 3.5, -12.0});
    const CameraFrame cam = makeCameraFrame(s.camera);
    const auto sprites = setupSprites(s, cam, 0.0);
    std::size_t onScreen = 0;
    for (const SpriteSetup& sp : sprites) {
        const glm::ivec4 r = rectInImage(sp, cam);
        onScreen += r.z > r.x && r.w > r.y;
    }
    ASSERT_GT(onScreen, 2u * 4096u) << "at least two runs of the binning";
    EXPECT_GT(expectSame(s, sprites, allFar(sprites.size()), "9,000 far sprites"), 2000u);
}

// Every far instance reads its own model's palette, though the host finds the frame's palettes
// per chunk of 4,096 instances on every core and merges them: 10,000 far boxes of 24 models,
// each with its own colours, the first chunk showing two of them, the next one first showing two
// more, the last all 24 in turn (more than a chunk compares one by one), some instances
// off-screen (drawn nowhere): every pixel equals the CPU blit's, which reads each sprite's
// palette itself.
TEST_F(VulkanFar, PalettesFirstShownInLaterChunksEqualTheCpuBlit) {
    std::vector<Entity> kinds;
    Scene s = smallImage(kinds);
    s.models.clear();
    constexpr int kModels = 24;
    for (int k = 0; k < kModels; ++k) {
        Palette palette = makeBox({4, 4, 4})->palette();
        for (int i = 1; i < 256; ++i)
            palette.colors[std::size_t(i)] =
                packRgba(unsigned(40 + 8 * k), unsigned(i), unsigned(255 - 8 * k));
        s.models.push_back(std::make_shared<VoxelModel>(
            "box " + std::to_string(k), palette,
            std::vector<VoxelGrid>{
                makeBox({4 + k % 4, 5, 4 + k / 8}, std::uint8_t(20 + 9 * k))->frame(0)}));
    }
    SplitMix64 rng{2029};
    for (int i = 0; i < 10000; ++i) {
        Entity e;
        // Chunk 0: models 1 and 0; chunk 1 first shows 3, then 2; chunk 2 all of them.
        e.model = i < 4096 ? 1 - i % 2 : (i < 8192 ? 3 - i % 4 : i % kModels);
        e.position = {rng.uniform(-6.0, 6.0), rng.uniform(-3.5, 3.5), rng.uniform(-40.0, -12.0)};
        if (i % 7 == 3) e.position.x += 40.0; // off-screen
        e.rotation = glm::angleAxis(rng.uniform(0.0, 6.28), glm::dvec3(0.0, 1.0, 0.0));
        s.entities.push_back(e);
    }
    const CameraFrame cam = makeCameraFrame(s.camera);
    const auto sprites = setupSprites(s, cam, 0.0);
    EXPECT_GT(expectSame(s, sprites, allFar(sprites.size()), "24 palettes"), 2000u);
    Image cpu(cam.width, cam.height, s.render.background);
    std::vector<FarRequest> requests;
    for (const SpriteSetup& sp : sprites) requests.push_back({&sp, std::nullopt});
    drawFarSprites(s.models, requests, cache_, ViewSet::Cube26, cpu);
    std::set<unsigned> shown; // each model's colours have their own red channel
    for (std::size_t p = 0; p < cpu.pixelCount(); ++p)
        if (cpu.id[p] != kernel::VT_NO_ENTITY) shown.insert(channel(cpu.color[p], 0));
    EXPECT_GE(shown.size(), std::size_t(kModels) - 4) << "most models' colours are on screen";
}

// The far pass draws each tile's sprites nearest first and stops passing them over a pixel at
// the first one the pixel refuses (far_blit.comp): exact only if its order is the rule's, equal
// depths by ascending id. Groups of coincident entities (one position, so one depth: the id
// decides) of differing models and turns, heaped over a few tiles, some cross-fading between two
// views (the same entity twice, at one depth), or drawn near in the middle of a group.
TEST_F(VulkanFar, CoincidentCrowdsStopInTheRulesOrder) {
    std::vector<Entity> kinds;
    Scene s = smallImage(kinds);
    SplitMix64 rng{49};
    for (int group = 0; group < 60; ++group) {
        const glm::dvec3 at{rng.uniform(-0.8, 0.8), rng.uniform(-0.5, 0.5),
                            rng.uniform(-14.0, -8.0)};
        const glm::dquat turn = glm::angleAxis(rng.uniform(0.0, 6.28), glm::dvec3(0.0, 1.0, 0.0));
        for (int k = 0; k < 5; ++k) {
            // Two kinds in turn, one turn: entities k and k + 2 are the same sprite but for the id
            // (one depth), the other kind at a depth of its own overlapping them.
            Entity e = kinds[std::size_t(group + k % 2) % kinds.size()];
            e.position = at;
            e.rotation = k % 2 ? turn : glm::dquat(turn.w, turn.x, -turn.y, turn.z);
            s.entities.push_back(e);
        }
    }
    const CameraFrame cam = makeCameraFrame(s.camera);
    const auto sprites = setupSprites(s, cam, 0.0);
    int ties = 0;
    for (std::size_t i = 0; i + 2 < sprites.size(); ++i)
        ties += sprites[i].visible() && sprites[i].gpu.depth == sprites[i + 2].gpu.depth;
    ASSERT_GT(ties, 100) << "coincident entities share their depth";
    std::vector<EntityPlan> plan = allFar(sprites.size());
    EXPECT_GT(expectSame(s, sprites, plan, "coincident crowds"), 200u);
    for (std::size_t i = 0; i < plan.size(); i += 4) {
        if (!sprites[i].visible()) continue;
        plan[i].fade = float(rng.uniform(0.2, 0.8));
        plan[i].fadeFrom = Tier::Far;
        plan[i].view =
            viewIdOf(ViewSet::Cube26, nearestView(ViewSet::Cube26, -sprites[i].lattice.dir));
        plan[i].fadeFromView = viewIdOf(ViewSet::Cube26, int(rng.below(26)));
    }
    EXPECT_GT(expectSame(s, sprites, plan, "coincident crowds, view fades"), 200u);
    // The middle entity of each group near: a pixel the near tier drew at a far sprite's depth
    // refuses the higher ids of that depth and not the lower ones.
    plan = allFar(sprites.size());
    for (std::size_t i = 2; i < plan.size(); i += 5) plan[i].tier = Tier::Near;
    EXPECT_GT(expectSame(s, sprites, plan, "coincident crowds, middles near"), 200u);
}

// A far sprite of two million pixels: the pass cut by sprite covers its rectangle in two thousand
// chunks of FAR_SPLAT_CHUNK pixels, a workgroup each.
TEST_F(VulkanFar, ASpriteLargerThanOneWorkgroupsShareEqualsTheCpuBlit) {
    const test::ViewSetup v =
        test::viewAlong(test::solidBox({40, 40, 40}), glm::dvec3(1, 1, 2), 1.0, 20);
    const CameraFrame cam = makeCameraFrame(v.scene.camera);
    const auto sprites = setupSprites(v.scene, cam, 0.0);
    const glm::ivec4 r = rectInImage(sprites[0], cam);
    ASSERT_GT(std::int64_t(r.z - r.x) * (r.w - r.y), 1000 * std::int64_t(far_gpu::FAR_SPLAT_CHUNK))
        << "a thousand chunks";
    EXPECT_GT(expectSame(v.scene, sprites, allFar(1), "one large far sprite"), 500000u);
}

// Far sprites large on the image, overlapping one another at different depths and at equal
// depths, some with near sprites among them: the chunks of one rectangle and of the others run
// as separate workgroups in any order, and each pixel still goes to the sprite the depth-and-id
// rule picks.
TEST_F(VulkanFar, LargeRectanglesInChunksEqualTheCpuBlit) {
    Scene s = heapOfKinds(12, 4242, {-0.6, -0.4, -2.2}, {0.6, 0.4, -1.4});
    s.render.sigma = 2.0; // finer cells: more of each sprite's rectangle holds its voxels
    s.camera.width = 480; // the heap's sprites each thousands of pixels
    s.camera.height = 300;
    const std::size_t single = s.entities.size();
    for (std::size_t i = 0; i < single; i += 3) s.entities.push_back(s.entities[i]); // equal depths
    const CameraFrame cam = makeCameraFrame(s.camera);
    const auto sprites = setupSprites(s, cam, 0.0);
    int large = 0;
    for (const SpriteSetup& sp : sprites) {
        const glm::ivec4 r = rectInImage(sp, cam);
        large += std::int64_t(r.z - r.x) * (r.w - r.y) > 3 * std::int64_t(far_gpu::FAR_SPLAT_CHUNK);
    }
    std::string areas;
    for (const SpriteSetup& sp : sprites) {
        const glm::ivec4 r = rectInImage(sp, cam);
        areas += std::to_string((r.z - r.x) * (r.w - r.y)) + " ";
    }
    ASSERT_GE(large, 8) << "rectangles of several chunks: " << areas;
    std::vector<EntityPlan> plan = allFar(sprites.size());
    EXPECT_GT(expectSame(s, sprites, plan, "large far sprites"), 5000u);
    // The pass cut by sprite ran more workgroups than sprites: the chunks past the first.
    std::vector<FarRequest> requests;
    for (const SpriteSetup& sp : sprites) requests.push_back({&sp, std::nullopt});
    const FarBatch batch = prepareFarBatch(s.models, requests, cache_, ViewSet::Cube26);
    FarPassStats fs;
    drawBoth(cam, s, {}, batch, &fs, s.render.background, FarTiles::Sprites);
    EXPECT_GT(fs.splatGroups, fs.sprites + 3u * std::uint64_t(large));
    for (std::size_t i = 1; i < plan.size(); i += 4) plan[i].tier = Tier::Near;
    EXPECT_GT(expectSame(s, sprites, plan, "large far sprites, some near"), 5000u);
}

TEST_F(VulkanFar, AutoCutsThePassBySprite) {
    const FarPass automatic(nearRenderer().frames());
    EXPECT_EQ(automatic.tiles(), FarTiles::Sprites);
    for (const FarTiles tiles : kEveryCut) EXPECT_EQ(farPass(tiles).tiles(), tiles);
}

// More far sprites than a dispatch holds workgroups along x (65,535 on lavapipe, the least the
// standard allows): the pass cut by sprite runs a workgroup per sprite, so its dispatch wraps
// into rows (far_splat.comp: instance = row * row length + column). The instances go nearest
// first, so the farthest sprites are those past the first row: a heap on the left half of the
// image, and beyond all of it a few thousand on the right half that nothing hides. The heap's
// tiles list tens of thousands of sprites each, more than one walk takes on lavapipe (far_shared.h:
// its loop limit), so the tiles' pass runs in parts.
TEST_F(VulkanFar, MoreSpritesThanADispatchRowOrATileWalkHoldsEqualTheCpuBlit) {
    const std::uint32_t rowOfGroups =
        nearRenderer().frames().device().properties().limits.maxComputeWorkGroupCount[0];
    const int nearer = int(std::min<std::uint32_t>(rowOfGroups, 200000));
    Scene s = heapOfKinds(nearer, 65535, {-7.0, -3.0, -30.0}, {-1.5, 3.0, -12.0});
    const Scene beyond = heapOfKinds(3000, 65536, {4.0, -6.0, -60.0}, {16.0, 6.0, -40.0});
    s.entities.insert(s.entities.end(), beyond.entities.begin(), beyond.entities.end());
    const CameraFrame cam = makeCameraFrame(s.camera);
    const auto sprites = setupSprites(s, cam, 0.0);
    std::size_t onScreen = 0, beyondOnScreen = 0;
    int nearRight = 0, beyondLeft = cam.width; // the heaps' rectangles do not meet
    for (std::size_t i = 0; i < sprites.size(); ++i) {
        const glm::ivec4 r = rectInImage(sprites[i], cam);
        if (r.z <= r.x || r.w <= r.y) continue;
        ++onScreen;
        if (i >= std::size_t(nearer)) {
            ++beyondOnScreen;
            beyondLeft = std::min(beyondLeft, r.x);
            ASSERT_LT(sprites[i].gpu.depth, sprites[0].gpu.depth) << "behind the near heap";
        } else {
            nearRight = std::max(nearRight, r.z);
        }
    }
    ASSERT_LE(nearRight, beyondLeft) << "nothing of the near heap hides the far one";
    ASSERT_GT(onScreen, std::size_t(rowOfGroups) + 1000) << "the dispatch takes two rows";
    ASSERT_GT(beyondOnScreen, 1000u);
    EXPECT_GT(expectSame(s, sprites, allFar(sprites.size()), "more sprites than a row"), 2000u);
}

TEST_F(VulkanFar, SnapshotsAreUploadedOnceAndFreedWhenTheCacheDropsThem) {
    // The fine tiles' and the sprites' passes of earlier tests in this process hold their
    // snapshots too (a device copy is freed once nobody else holds its cells): gone, so that only
    // this test's coarse pass holds any (ctest runs each test alone; the binary run whole failed
    // here).
    passes_[std::size_t(FarTiles::Fine)].reset();
    passes_[std::size_t(FarTiles::Sprites)].reset();
    HardCaseRequests hard = hardCaseRequests();
    Scene& s = hard.scene;
    const CameraFrame& cam = hard.cam;
    const std::vector<FarRequest>& requests = hard.requests;
    SnapshotCache cache;
    FarPassStats first, second;
    std::set<const void*> firstOwners;
    {
        const FarBatch batch = prepareFarBatch(s.models, requests, cache, ViewSet::Cube26);
        (void)drawBoth(cam, s, {}, batch, &first);
        (void)drawBoth(cam, s, {}, batch, &second);
        EXPECT_EQ(first.snapshotsUploaded, batch.snapshots.size());
        EXPECT_GT(first.bytesUploaded, 0u);
        EXPECT_GT(first.snapshotUploadMs, 0.0) << "the uploads' host time";
        EXPECT_EQ(second.snapshotsUploaded, 0u); // resident since the first frame
        EXPECT_EQ(second.bytesUploaded, 0u);
        for (const FarSnapshotCells& c : batch.snapshots) firstOwners.insert(c.owner.get());
        // Earlier tests' snapshots (their caches are gone) were freed by the first update.
        EXPECT_EQ(farPass().residentSnapshots(), batch.snapshots.size());
    }
    // An edit of model 0 (a corner voxel, seen from most views): its snapshots are refreshed
    // (new ones) and only those are uploaded, each into its predecessor's range and only the rows
    // that changed; the image still equals the CPU blit's.
    {
        s.models[0]->setVoxel(0, {0, 0, 0}, 0);
        FarFrameStats fs;
        const FarBatch batch = prepareFarBatch(s.models, requests, cache, ViewSet::Cube26, &fs);
        FarPassStats edited;
        const Image gpu = drawBoth(cam, s, {}, batch, &edited);
        Image cpu(cam.width, cam.height, 0);
        drawFarSprites(s.models, requests, cache, ViewSet::Cube26, cpu);
        EXPECT_EQ(describeDifference(gpu, cpu, "vulkan far", "cpu far"), "") << "after an edit";
        EXPECT_GT(fs.refreshes, 0u);
        EXPECT_EQ(edited.snapshotsUploaded, fs.refreshes);
        EXPECT_LT(edited.snapshotsUploaded, batch.snapshots.size());
        std::uint64_t refreshedBytes = 0; // what uploading the refreshed snapshots whole costs
        for (const FarSnapshotCells& c : batch.snapshots)
            if (!firstOwners.count(c.owner.get()))
                refreshedBytes += std::uint64_t(c.width()) * std::uint64_t(c.height()) * 2;
        EXPECT_GT(edited.bytesUploaded, 0u);
        EXPECT_LT(edited.bytesUploaded, refreshedBytes);
        // The predecessors' ranges were taken over or freed: as many resident as in use.
        EXPECT_EQ(farPass().residentSnapshots(), batch.snapshots.size());
    }
    // The cache evicts everything (budget 0) and the frame's batch is gone: the next far pass
    // frees their device ranges before drawing.
    cache.setBudget(0);
    const Scene other = test::equalDepthPair();
    const CameraFrame oc = makeCameraFrame(other.camera);
    const auto os = setupSprites(other, oc, 0.0);
    std::vector<FarRequest> otherRequests{{&os[0], std::nullopt}};
    SnapshotCache otherCache;
    const FarBatch one = prepareFarBatch(other.models, otherRequests, otherCache, ViewSet::Cube26);
    (void)drawBoth(oc, other, {}, one);
    EXPECT_EQ(farPass().residentSnapshots(), one.snapshots.size());
}

// The snapshots' uploads are timed apart from the rest of the far pass (the cost bound leaves them
// out of the blit's rate): on the device a pass of their own inside the far pass's uploads, and in
// a frame's figures their host and device time, within the far pass's share.
TEST_F(VulkanFar, SnapshotUploadsAreTimedApartWithinTheFarPass) {
    HardCaseRequests hard = hardCaseRequests();
    SnapshotCache cache;
    const FarBatch batch =
        prepareFarBatch(hard.scene.models, hard.requests, cache, ViewSet::Cube26);
    VulkanFrameRequest request;
    request.camera = &hard.cam;
    request.models = &hard.scene.models;
    request.far = &batch;
    const VulkanFrameResult r = drawVulkanFrame(nearRenderer(), &farPass(), request);
    ASSERT_TRUE(r.report.ms("far_upload").has_value()) << "lavapipe has timestamps";
    ASSERT_TRUE(r.report.ms("far_snapshots").has_value());
    EXPECT_LE(*r.report.ms("far_snapshots"), *r.report.ms("far_upload"));

    Scene s = hard.scene;
    FrameRenderer renderer(s, options(FarBackend::Vulkan));
    const FrameResult first = renderer.render(0.0, RenderMode::Far, 0);
    const FrameStats& st = first.stats;
    ASSERT_GT(st.vulkanFar.bytesUploaded, 0u);
    EXPECT_GT(st.vulkanFar.snapshotUploadMs, 0.0);
    // Host and device: the device's copies of the bytes uploaded take time too (lavapipe's
    // timestamps are the host clock's nanoseconds).
    EXPECT_GT(st.vulkan.farSnapshotsMs, st.vulkanFar.snapshotUploadMs);
    EXPECT_LE(st.vulkan.farSnapshotsMs, st.vulkan.farPassMs);
    EXPECT_EQ(figuresOf(st)["far_snapshot_upload_ms"], st.vulkan.farSnapshotsMs);
    const FrameResult second = renderer.render(0.0, RenderMode::Far, 1);
    EXPECT_EQ(second.stats.vulkanFar.bytesUploaded, 0u) << "resident since the first frame";
}

// The device copies follow the snapshots' owners (FarResidency): a new version of a snapshot
// takes over its predecessor's range when the predecessor has the same cell range and nobody else
// holds it; one of another size is uploaded apart and the predecessor freed in the same update;
// a snapshot somebody still holds stays resident though no frame draws it, and goes in the first
// update after it is let go.
TEST_F(VulkanFar, ResidencyFreesWhatNobodyHoldsAndKeepsWhatSomebodyDoes) {
    FarResidency residency(nearRenderer().device());
    const auto cells = [](glm::ivec4 range, std::uint64_t lineage) {
        const auto bytes = std::make_shared<std::vector<std::uint8_t>>(
            std::size_t((range.y - range.x + 1) * (range.w - range.z + 1) * 2), 7);
        return FarSnapshotCells{bytes, lineage, bytes->data(), range};
    };
    const auto update = [&](std::vector<FarSnapshotCells> snapshots) {
        FarBatch batch;
        batch.snapshots = std::move(snapshots);
        FarResidencyStats st;
        const std::vector<std::uint32_t> offsets = residency.update(batch, &st);
        return std::pair{st, offsets};
    };
    const glm::ivec4 small{0, 3, 0, 3}, large{0, 5, 0, 7};
    {
        const auto [st, offsets] = update({cells(small, 11)});
        EXPECT_EQ(st.snapshotsUploaded, 1u);
        EXPECT_EQ(residency.residentSnapshots(), 1u);
    }
    // Lineage 11 again, larger: uploaded apart, the predecessor freed.
    FarSnapshotCells held = cells(large, 11);
    std::uint32_t largeAt = 0;
    {
        const auto [st, offsets] = update({held});
        EXPECT_EQ(st.snapshotsUploaded, 1u);
        EXPECT_EQ(st.refreshesInPlace, 0u);
        EXPECT_EQ(st.snapshotsFreed, 1u);
        EXPECT_EQ(residency.residentSnapshots(), 1u);
        largeAt = offsets.at(0);
    }
    // Lineage 11 again, the same size, its predecessor held here: not taken over, and kept
    // (another owner); lineage 12 new.
    {
        const auto [st, offsets] = update({cells(large, 11), cells(small, 12)});
        EXPECT_EQ(st.snapshotsUploaded, 2u);
        EXPECT_EQ(st.refreshesInPlace, 0u);
        EXPECT_EQ(st.snapshotsFreed, 0u);
        EXPECT_EQ(residency.residentSnapshots(), 3u);
        EXPECT_NE(offsets.at(0), largeAt);
    }
    // Let go: the next update frees it (and the two that frame drew, which nobody holds either).
    held = FarSnapshotCells{};
    {
        const FarSnapshotCells next = cells(small, 13);
        const auto [st, offsets] = update({next});
        EXPECT_EQ(st.snapshotsFreed, 3u);
        EXPECT_EQ(residency.residentSnapshots(), 1u);
        // Drawn again by the next frame: resident already, nothing uploaded, nothing freed.
        const auto [again, same] = update({next});
        EXPECT_EQ(again.snapshotsUploaded, 0u);
        EXPECT_EQ(again.snapshotsFreed, 0u);
        EXPECT_EQ(same, offsets);
    }
    // A refresh in place: lineage 13, same size, the predecessor held by nobody but the device.
    {
        const auto [st, offsets] = update({cells(small, 13)});
        EXPECT_EQ(st.refreshesInPlace, 1u);
        EXPECT_EQ(st.snapshotsFreed, 0u);
        EXPECT_EQ(residency.residentSnapshots(), 1u);
    }
}

// An animated crowd draws each animation frame's snapshots in turn while the cache holds them
// all: when nothing fits, the buffer grows (below the device's storage buffer range), and the
// snapshots held but not drawn this frame stay resident, so that a frame coming back to them
// uploads nothing. Each "animation frame" here is 64 snapshots of 64 x 64 cells (8 KiB each),
// four of them 2 MiB, eight times the buffer's first 256 KiB.
TEST_F(VulkanFar, ResidencyGrowsRatherThanDropWhatTheCacheStillHolds) {
    FarResidency residency(nearRenderer().device());
    const glm::ivec4 range{0, 63, 0, 63};
    std::vector<std::vector<FarSnapshotCells>> steps(4); // held, as a cache holds them
    std::uint64_t lineage = 100;
    for (auto& step : steps)
        for (int k = 0; k < 64; ++k) {
            const auto bytes =
                std::make_shared<std::vector<std::uint8_t>>(64 * 64 * 2, std::uint8_t(k));
            step.push_back(FarSnapshotCells{bytes, ++lineage, bytes->data(), range});
        }
    const auto draw = [&](const std::vector<FarSnapshotCells>& snapshots) {
        FarBatch batch;
        batch.snapshots = snapshots;
        FarResidencyStats st;
        const std::vector<std::uint32_t> offsets = residency.update(batch, &st);
        // Every snapshot of the batch in its own range.
        std::set<std::uint32_t> distinct(offsets.begin(), offsets.end());
        EXPECT_EQ(distinct.size(), offsets.size());
        return st;
    };
    for (const auto& step : steps) {
        const FarResidencyStats st = draw(step);
        EXPECT_EQ(st.snapshotsUploaded, 64u);
        EXPECT_EQ(st.snapshotsFreed, 0u);
    }
    EXPECT_EQ(residency.residentSnapshots(), 4u * 64u);
    EXPECT_GT(residency.totals().growths, 0u);
    // The second cycle: every snapshot resident, nothing uploaded or freed.
    for (const auto& step : steps) {
        const FarResidencyStats st = draw(step);
        EXPECT_EQ(st.snapshotsUploaded, 0u);
        EXPECT_EQ(st.bytesUploaded, 0u);
        EXPECT_EQ(st.snapshotsFreed, 0u);
    }
    // Let go of by the cache: freed at the next update.
    steps.resize(1);
    const FarResidencyStats st = draw(steps[0]);
    EXPECT_EQ(st.snapshotsFreed, 3u * 64u);
    EXPECT_EQ(residency.residentSnapshots(), 64u);
}

// A snapshot only the residency holds can appear only after the cache drops it (FarBatch's cache
// and drop count), so the residency looks for such snapshots (an owner count read per resident
// snapshot) only from a change of either until a few updates later: a snapshot let go of while
// the cache says it dropped nothing stays resident; one the cache dropped goes at the next update,
// or, held then by a frame still in flight, at an update after that frame lets go.
TEST_F(VulkanFar, ResidencySweepsAfterTheCacheDropsSnapshots) {
    FarResidency residency(nearRenderer().device());
    const auto snapshots = [](int count, std::uint64_t firstLineage) {
        std::vector<FarSnapshotCells> out;
        for (int k = 0; k < count; ++k) {
            const auto bytes = std::make_shared<std::vector<std::uint8_t>>(16 * 16 * 2, 3);
            out.push_back(FarSnapshotCells{
                bytes, firstLineage + std::uint64_t(k), bytes->data(), {0, 15, 0, 15}});
        }
        return out;
    };
    std::uint64_t drops = 0;
    const auto update = [&](const std::vector<FarSnapshotCells>& drawn) {
        FarBatch batch;
        batch.snapshots = drawn;
        batch.cacheUid = 7, batch.cacheDrops = drops;
        FarResidencyStats st;
        residency.update(batch, &st);
        return st.snapshotsFreed;
    };
    const std::vector<FarSnapshotCells> kept = snapshots(4, 100);
    std::vector<FarSnapshotCells> dropped = snapshots(4, 200), inFlight = snapshots(4, 300);
    std::vector<FarSnapshotCells> all = kept;
    all.insert(all.end(), dropped.begin(), dropped.end());
    all.insert(all.end(), inFlight.begin(), inFlight.end());
    update(all);
    for (int k = 0; k < 6; ++k) EXPECT_EQ(update(kept), 0u); // past the sweeps a change owes
    // Let go of without a drop the batches tell: no sweep looks.
    dropped.clear();
    all.clear();
    EXPECT_EQ(update(kept), 0u);
    EXPECT_EQ(residency.residentSnapshots(), 12u);
    // The cache says it dropped them: freed at once; the ones a frame in flight still holds stay.
    ++drops;
    EXPECT_EQ(update(kept), 4u);
    EXPECT_EQ(residency.residentSnapshots(), 8u);
    // That frame lets go: freed by one of the next updates, though the drops are as they were.
    inFlight.clear();
    std::uint64_t freed = 0;
    for (int k = 0; k < 2; ++k) freed += update(kept);
    EXPECT_EQ(freed, 4u);
    EXPECT_EQ(residency.residentSnapshots(), kept.size());

    // A batch from the snapshot cache says which cache, and counts what it has dropped.
    const HardCaseRequests hard = hardCaseRequests();
    const Scene& s = hard.scene;
    const std::vector<FarRequest>& requests = hard.requests;
    SnapshotCache cache;
    const FarBatch before = prepareFarBatch(s.models, requests, cache, ViewSet::Cube26);
    EXPECT_EQ(before.cacheUid, cache.uid());
    EXPECT_NE(SnapshotCache().uid(), cache.uid());
    cache.setBudget(0); // evicts every snapshot
    const FarBatch after = prepareFarBatch(s.models, requests, cache, ViewSet::Cube26);
    EXPECT_GE(after.cacheDrops, before.cacheDrops + before.snapshots.size());
}

} // namespace
} // namespace voxtier
