// The far blit (CONTRACT.md §4): upright, unmirrored snapshots read through the near tier's
// virtual-pixel grid; nothing drawn for culled, empty, sub-pixel or behind-camera entities;
// lighting applied at blit time; the frame's Far mode.
#include "compose/frame.hpp"
#include "core/procedural.hpp"
#include "far_test_support.hpp"
#include "image_checks.hpp"
#include "view_sweeps.hpp"

#include <glm/gtc/quaternion.hpp>
#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include <cmath>
#include <optional>
#include <span>

namespace voxtier {
namespace {

/// Unlit light: every pixel is its palette colour, so a pixel names its palette index.
Light unlit() {
    Light l;
    l.ambient = 1.0;
    l.diffuse = 0.0;
    return l;
}

/// Mean pixel position of the pixels of one palette colour, if any.
std::optional<glm::dvec2> centroid(const Image& img, Rgba8 color) {
    glm::dvec2 sum(0.0);
    std::size_t n = 0;
    for (int y = 0; y < img.height; ++y)
        for (int x = 0; x < img.width; ++x)
            if (img.color[img.index(x, y)] == color) sum += glm::dvec2(x + 0.5, y + 0.5), ++n;
    if (n == 0) return std::nullopt;
    return sum / double(n);
}

/// A one-arrow scene seen from voxel-space direction `towardViewer` (any direction), camera up
/// = world up, unlit.
Scene arrowScene(glm::dvec3 towardViewer, double sigma = 2.0) {
    const auto arrow = makeArrow(24);
    auto v = test::viewAlong(arrow, towardViewer, sigma, 3);
    v.scene.light = unlit();
    return std::move(v.scene);
}

// HARD_CASES 12/18: the arrow's head (green, +X), fin (blue, +Z) and stub (yellow, +Y) land on
// the same sides of the shaft in both tiers, at canonical views and at directions up to ~25
// degrees away from any snapshot, so no tier flips or mirrors anything.
TEST(FarBlit, ArrowHeadFinAndStubPointTheSameWayAsInTheNearTier) {
    const Palette& pal = proceduralPalette();
    const std::vector<glm::dvec3> dirs = {{0, -1, 0},          {0, 1, 0},
                                          {0, -1, 1},          {1, -1, 1}, // canonical
                                          {0.2, -1.0, 0.35},   {-0.3, -1.0, 0.15},
                                          {0.25, 0.9, 0.4},    {0.1, -0.6, 0.8}, // off-canonical
                                          {-0.45, -0.8, -0.3}, {0.5, -0.55, 0.65},
                                          {-0.2, 0.35, 0.95},  {0.05, -0.98, -0.12}};
    for (glm::dvec3 w : dirs) {
        const Scene s = arrowScene(glm::normalize(w));
        SnapshotCache cache;
        const Image nearImg = test::renderNear(s), farImg = test::renderFar(s, cache);
        const auto hn = centroid(nearImg, pal.colors[proc_index::kGreen]),
                   hf = centroid(farImg, pal.colors[proc_index::kGreen]);
        const auto tn = centroid(nearImg, pal.colors[proc_index::kRed]),
                   tf = centroid(farImg, pal.colors[proc_index::kRed]);
        ASSERT_TRUE(hn && hf && tn && tf) << "w " << w.x << "," << w.y << "," << w.z;
        // Shaft -> head: same direction on screen (within the view quantisation, <~28 degrees,
        // which foreshortening can widen a little on screen), similar position.
        const glm::dvec2 an = *hn - *tn, af = *hf - *tf;
        const double cosAngle = glm::dot(an, af) / (glm::length(an) * glm::length(af));
        EXPECT_GT(cosAngle, std::cos(glm::radians(45.0)))
            << "w " << w.x << "," << w.y << "," << w.z;
        EXPECT_LT(glm::length(*hn - *hf), 0.5 * glm::length(an))
            << "w " << w.x << "," << w.y << "," << w.z;
        // The fin (+Z, blue) sits above the shaft whenever it is visible in both (camera up = +Z).
        const auto fn = centroid(nearImg, pal.colors[proc_index::kBlue]),
                   ff = centroid(farImg, pal.colors[proc_index::kBlue]);
        if (fn && ff && std::abs(w.z) < 0.9) {
            EXPECT_LT(fn->y, tn->y + 1.0) << "near fin below shaft";
            EXPECT_LT(ff->y, tf->y + 1.0) << "far fin below shaft";
        }
    }
}

TEST(FarBlit, CulledSpritesDrawNothingAndBakeNothing) {
    const auto m = makeArrow(16);
    SnapshotCache cache;
    // Behind the camera.
    {
        auto v = test::viewAlong(m, glm::dvec3(0, -1, 0), 1.0, 2);
        // Look away from the entity.
        v.scene.camera.target = v.scene.camera.position * 2.0 - v.scene.entities[0].position;
        std::vector<SpriteSetup> sp;
        const Image img = test::renderFar(v.scene, cache, ViewSet::Cube26, &sp);
        EXPECT_EQ(sp[0].cull, CullReason::BehindCamera);
        EXPECT_EQ(test::drawnPixels(img), 0u);
    }
    // Sub-pixel: a tiny entity very far away.
    {
        auto v = test::viewAlong(m, glm::dvec3(0, -1, 0), 1.0, 2);
        v.scene.entities[0].scale = 1e-3;
        std::vector<SpriteSetup> sp;
        const Image img = test::renderFar(v.scene, cache, ViewSet::Cube26, &sp);
        EXPECT_EQ(sp[0].cull, CullReason::SubPixel);
        EXPECT_EQ(test::drawnPixels(img), 0u);
    }
    // Camera inside the proxy box.
    {
        auto v = test::viewAlong(m, glm::dvec3(0, -1, 0), 1.0, 2);
        v.scene.camera.position = v.scene.entities[0].position + glm::dvec3(0.01, 0.02, 0.0);
        std::vector<SpriteSetup> sp;
        const Image img = test::renderFar(v.scene, cache, ViewSet::Cube26, &sp);
        EXPECT_EQ(sp[0].cull, CullReason::CameraInside);
        EXPECT_EQ(test::drawnPixels(img), 0u);
    }
    EXPECT_EQ(cache.counters().bakes, 0u); // culled sprites never ask for a snapshot
}

TEST(FarBlit, EmptyModelDrawsNothing) {
    const auto m = std::make_shared<VoxelModel>("empty", proceduralPalette(),
                                                std::vector<VoxelGrid>{VoxelGrid({6, 6, 6})});
    SnapshotCache cache;
    for (glm::ivec3 w : test::canonicalDirections()) {
        const auto v = test::viewAlong(m, glm::dvec3(w), 2.0, 2);
        std::vector<SpriteSetup> sp;
        const Image img = test::renderFar(v.scene, cache, ViewSet::Cube26, &sp);
        EXPECT_TRUE(sp[0].visible());
        EXPECT_EQ(test::drawnPixels(img), 0u);
    }
    EXPECT_EQ(cache.counters().bakes, 26u);
}

// The light is applied at blit time: a new light needs no re-bake and still equals the near tier.
TEST(FarBlit, RelightingNeedsNoRebakeAndMatchesTheNearTier) {
    const auto m = makeSphere(6);
    SnapshotCache cache;
    auto v = test::viewAlong(m, glm::dvec3(1, -1, 1), 2.0, 2);
    const Image first = test::renderFar(v.scene, cache);
    const auto bakes = cache.counters().bakes;
    v.scene.light.direction = glm::dvec3(0.9, -0.2, 0.1);
    v.scene.light.diffuse = 0.9;
    const Image relit = test::renderFar(v.scene, cache);
    EXPECT_EQ(cache.counters().bakes, bakes);
    EXPECT_FALSE(diffImages(first, relit).identical());
    EXPECT_TRUE(test::firstDifference(test::renderNear(v.scene), relit).empty());
}

// An externally chosen view (a selector with angular hysteresis) is used as given.
TEST(FarBlit, ExplicitViewOverridesTheNearestView) {
    const auto m = makeArrow(16);
    SnapshotCache cache;
    const auto v = test::viewAlong(m, glm::dvec3(0, -1, 0), 2.0, 2); // nearest: view 3 (-Y)
    const Image nearest = test::renderFar(v.scene, cache);
    const Image forced = test::renderFar(v.scene, cache, ViewSet::Cube26, nullptr, 16); // (0,-1,+1)
    EXPECT_FALSE(diffImages(nearest, forced).identical());
    const std::uint64_t uid = m->uid(), version = m->version();
    EXPECT_NE(cache.find({uid, 0, version, viewIdOf(ViewSet::Cube26, 3), 2.0}), nullptr);
    EXPECT_NE(cache.find({uid, 0, version, viewIdOf(ViewSet::Cube26, 16), 2.0}), nullptr);
}

TEST(FarBlit, ImageIndependentOfThreadCount) {
    Scene s = arrowScene(glm::normalize(glm::dvec3(0.3, -1.0, 0.4)));
    s.models.push_back(makeSphere(5));
    Entity e = s.entities[0];
    e.model = 1;
    e.position += glm::dvec3(0.3, 0.1, 0.2);
    s.entities.push_back(e);
    SnapshotCache a, b;
    const Image all = test::renderFar(s, a);
    Image one;
    tbb::task_arena single(1);
    single.execute([&] { one = test::renderFar(s, b); });
    EXPECT_TRUE(diffImages(all, one).identical());
    EXPECT_GT(test::drawnPixels(all), 100u);
}

// `voxtier render --mode far`: every entity through the renderer's cache, which persists.
/// The blit rule of CONTRACT.md §4 written out per pixel over each sprite's whole rectangle, with
/// no shortcut: the near cell of the pixel, its centre, the snapshot cell under it, lit at blit
/// time. (snapshotCellMap is that read point in closed form; the cell-centre form is checked
/// against it below.)
Image perPixelBlit(std::span<const FarSprite> sprites, Image target) {
    for (const FarSprite& f : sprites) {
        const SpriteSetup& sp = *f.sprite;
        if (!sp.visible()) continue;
        const SnapshotCellMap map = snapshotCellMap(sp.lattice, f.snapshot->lattice);
        for (int y = sp.screenRect.y; y < sp.screenRect.w; ++y)
            for (int x = sp.screenRect.x; x < sp.screenRect.z; ++x) {
                glm::ivec2 cell;
                if (!kernel::vtPixelCell(sp.gpu, glm::vec2(float(x) + 0.5f, float(y) + 0.5f), cell))
                    continue;
                const glm::ivec2 sc = map(cell);
                const SnapshotCell c = f.snapshot->at(sc.x, sc.y);
                if (c.code == snapshot_code::kEmpty) continue;
                const Rgba8 color =
                    snapshot_code::isSolid(c.code)
                        ? kernel::vtLit(f.palette->colors[c.index],
                                        kernel::vtFaceLight(sp.gpu, snapshot_code::face(c.code)))
                        : kernel::VT_OUTLINE_RGBA;
                target.writeIfNearer(target.index(x, y), color, sp.gpu.depth, sp.entityId);
            }
    }
    return target;
}

// The blit skips the columns of each row where no cell can be (and reuses a cell's outcome along
// a row): the image must be exactly the per-pixel rule's, for close, oblique, rolled, partly
// off-screen sprites at non-integer sigma, with cross-fade dithering.
TEST(FarBlit, ShortcutsDrawExactlyThePerPixelRule) {
    for (int variant = 0; variant < 6; ++variant) {
        SCOPED_TRACE(variant);
        Scene s;
        s.render.sigma = variant % 3 == 0 ? 1.0 : variant % 3 == 1 ? 2.0 : 1.37;
        s.models = {makeTank(std::uint64_t(variant + 1), 1), makeArrow(24), makeSphere(6, 3)};
        std::uint64_t state = 1234567ull * std::uint64_t(variant + 1);
        auto unit = [&] {
            state = state * 6364136223846793005ull + 1442695040888963407ull;
            return double(state >> 11) * 0x1.0p-53;
        };
        for (int k = 0; k < 40; ++k) {
            Entity e;
            e.model = k % 3;
            e.position = {-6.0 + 12.0 * unit(), -0.5 + 2.0 * unit(), -1.5 - 14.0 * unit()};
            e.rotation = glm::angleAxis(
                6.283 * unit(), glm::normalize(glm::dvec3(unit() - 0.5, 1.0, unit() - 0.5)));
            s.entities.push_back(e);
        }
        s.camera.position = {0.3 * variant, 1.2, 2.0};
        s.camera.target = {0.0, 0.0, -6.0};
        s.camera.up = glm::normalize(
            glm::dvec3(std::sin(0.4 * variant), std::cos(0.4 * variant), 0.0)); // rolled
        s.camera.width = 320;
        s.camera.height = 200;
        const CameraFrame cam = makeCameraFrame(s.camera);
        std::vector<SpriteSetup> sprites = setupSprites(s, cam, 0.0);
        for (std::size_t i = 0; i < sprites.size(); i += 4)
            sprites[i].gpu.fade = 0.4f, sprites[i].gpu.fadeSide = i % 8 ? 1.0f : -1.0f;
        SnapshotCache cache;
        std::vector<FarSprite> far;
        int visible = 0;
        for (const SpriteSetup& sp : sprites) {
            if (!sp.visible()) continue;
            ++visible;
            const auto& m = *s.models[std::size_t(sp.model)];
            far.push_back({&sp,
                           cache
                               .get(m, sp.frame, ViewSet::Cube26,
                                    chooseFarView(sp, ViewSet::Cube26), sp.lattice.sigma)
                               .get(),
                           &m.palette()});
        }
        ASSERT_GT(visible, 20);
        Image fast(cam.width, cam.height, s.render.background);
        FarBlitStats st;
        blitFar(far, fast, &st);
        const Image slow = perPixelBlit(far, Image(cam.width, cam.height, s.render.background));
        EXPECT_EQ(test::firstDifference(slow, fast), "");
        EXPECT_GT(st.pixelsWritten, 1000u);
        // The closed form reads the cell under the near cell's centre, as CONTRACT.md §4 words it,
        // except where that centre lies within rounding of a snapshot cell boundary.
        int boundary = 0, cells = 0;
        for (const FarSprite& f : far) {
            const SpriteLattice& L = f.sprite->lattice;
            const SnapshotCellMap map = snapshotCellMap(L, f.snapshot->lattice);
            for (int j = L.cellRange.z; j <= L.cellRange.w; ++j)
                for (int i = L.cellRange.x; i <= L.cellRange.y; ++i) {
                    const glm::dvec3 q = (L.gU + (i + 0.5) / L.sigma) * L.right +
                                         (L.gV + (j + 0.5) / L.sigma) * L.up;
                    const glm::ivec2 a = f.snapshot->lattice.cellAt(q), b = map({i, j});
                    ++cells;
                    if (a != b) {
                        ++boundary;
                        const SpriteLattice& S = f.snapshot->lattice;
                        const double u = S.sigma * (glm::dot(q, S.right) - S.gU),
                                     v = S.sigma * (glm::dot(q, S.up) - S.gV);
                        EXPECT_LT(
                            std::min(std::abs(u - std::round(u)), std::abs(v - std::round(v))),
                            1e-9);
                    }
                }
        }
        EXPECT_LT(boundary * 1000, cells);
    }
}

TEST(FarMode, FrameRendererDrawsEveryEntityThroughItsCache) {
    Scene s;
    s.render.sigma = 1.0;
    s.models = {makeArrow(16), makeSphere(4)};
    for (int i = 0; i < 12; ++i) {
        Entity e;
        e.model = i % 2;
        e.position = glm::dvec3(-3.0 + 0.6 * i, 0.0, -6.0 - 0.4 * i);
        e.rotation = glm::angleAxis(0.5 * i, glm::dvec3(0, 1, 0));
        s.entities.push_back(e);
    }
    s.camera.position = {0, 1.5, 2};
    s.camera.target = {0, 0, -8};
    s.camera.width = 320;
    s.camera.height = 200;
    FrameRenderer r(s);
    EXPECT_EQ(parseRenderMode("far"), RenderMode::Far);
    const FrameResult first = r.render(0.0, RenderMode::Far);
    EXPECT_EQ(first.stats.farDrawn, first.stats.entities - first.stats.culled);
    EXPECT_GT(first.stats.far.bakes, 0);
    EXPECT_GT(test::drawnPixels(first.image), 500u);
    const FrameResult second = r.render(0.0, RenderMode::Far);
    EXPECT_EQ(second.stats.far.bakes, 0); // cached
    // One Embree scene per model (one animation frame each), built by the first frame only.
    EXPECT_EQ(first.stats.far.scenesBuilt, 2);
    EXPECT_EQ(second.stats.far.scenesBuilt, 0);
    EXPECT_TRUE(diffImages(first.image, second.image).identical());
    for (std::size_t i = 0; i < s.entities.size(); ++i)
        EXPECT_GT(first.image.countEntity(std::uint32_t(i)), 0u) << i;
}

} // namespace
} // namespace voxtier
