// Cache invalidation checks after voxel edits (CONTRACT.md §4, Invalidation). Every
// expectation here is computed apart from the code under test: a freshly constructed cache, a
// fresh full bake, the scalar bake (the near kernel's vtTrace, no Embree) or the CPU near
// reference render.
//  - After each kind of edit (one voxel inside, one on the surface, one emptying the model, one
//    filling it, one outside the previous content bounds) the far render equals a fresh cache's
//    render byte for byte and, at canonical directions, the near reference: no stale pixel.
//  - Incremental re-bakes equal full bakes for seeded random sequences of hundreds of edits.
//  - A single-voxel edit on a 64^3 model re-traces a small share of a full bake's rays; the
//    near tier uploads bytes in proportion to the dirty box.
//  - Edits and renders of different models on different threads are safe (run under TSan).
#include "compose/frame.hpp"
#include "core/procedural.hpp"
#include "far_test_support.hpp"
#include "image_checks.hpp"
#include "impostor_cache/snapshot_baker.hpp"
#include "impostor_cache/surface_voxels.hpp"
#include "impostor_cache/voxel_scene.hpp"
#include "view_sweeps.hpp"

#include <gtest/gtest.h>
#include <tbb/parallel_for.h>

#include <atomic>
#include <cstdio>
#include <latch>
#include <random>
#include <string>
#include <thread>
#include <vector>

namespace voxtier {
namespace {

/// A `dims` grid holding an ellipsoid inside `content` (not touching the grid's faces unless
/// `content` does), coloured by position so that recolouring a visible voxel shows.
std::shared_ptr<VoxelModel> blobModel(glm::ivec3 dims, Box3i content) {
    VoxelGrid g(dims);
    const glm::dvec3 c = glm::dvec3(content.min + content.max) * 0.5;
    const glm::dvec3 r = glm::dvec3(content.max - content.min) * 0.5;
    for (int z = content.min.z; z < content.max.z; ++z)
        for (int y = content.min.y; y < content.max.y; ++y)
            for (int x = content.min.x; x < content.max.x; ++x) {
                const glm::dvec3 q = (glm::dvec3(x, y, z) + 0.5 - c) / r;
                if (glm::dot(q, q) <= 1.0)
                    g.set({x, y, z}, std::uint8_t(1 + (x + 2 * y + 3 * z) % 8));
            }
    return std::make_shared<VoxelModel>("blob", proceduralPalette(), std::vector<VoxelGrid>{g});
}

/// The top solid voxel of column (x, y), or z = -1.
glm::ivec3 topOfColumn(const VoxelGrid& g, int x, int y) {
    for (int z = g.dims().z - 1; z >= 0; --z)
        if (g.at({x, y, z})) return {x, y, z};
    return {x, y, -1};
}

// ---------------------------------------------------------------------------------------------
// The five kinds of edit.

enum class EditKind { InsideVoxel, SurfaceVoxel, EmptiesModel, FillsModel, OutsideContentBounds };
std::string toString(EditKind k) {
    switch (k) {
    case EditKind::InsideVoxel:
        return "InsideVoxel";
    case EditKind::SurfaceVoxel:
        return "SurfaceVoxel";
    case EditKind::EmptiesModel:
        return "EmptiesModel";
    case EditKind::FillsModel:
        return "FillsModel";
    case EditKind::OutsideContentBounds:
        return "OutsideContentBounds";
    }
    return "?";
}

bool applyEdit(VoxelModel& m, EditKind kind) {
    const glm::ivec3 n = m.frame(0).dims();
    switch (kind) {
    case EditKind::InsideVoxel: // the centre voxel, recoloured: nothing visible changes
        return m.setVoxel(0, n / 2, proc_index::kViolet);
    case EditKind::SurfaceVoxel: // the top voxel of the centre column removed: visible from above
        return m.setVoxel(0, topOfColumn(m.frame(0), n.x / 2, n.y / 2), 0);
    case EditKind::EmptiesModel:
        return m.clearBox(0, {{0, 0, 0}, n});
    case EditKind::FillsModel:
        return m.fillBox(0, {{0, 0, 0}, n}, proc_index::kCyan);
    case EditKind::OutsideContentBounds: // a voxel near a grid corner, far from the content
        return m.setVoxel(0, {1, n.y - 2, 2}, proc_index::kYellow);
    }
    return false;
}

class FarAfterEdit : public ::testing::TestWithParam<EditKind> {};

// Every canonical direction at sigma 1 and 2 through one cache, before and after the edit: the
// second pass must refresh every view (each exactly once) and draw exactly what a cache built
// after the edit draws, which is exactly the near reference.
TEST_P(FarAfterEdit, FarRenderEqualsAFreshCacheAndTheNearReference) {
    const EditKind kind = GetParam();
    const auto model = blobModel({24, 24, 24}, {{5, 4, 6}, {19, 20, 18}});
    const std::vector<double> sigmas = {1.0, 2.0};
    SnapshotCache cache;
    auto renderAll = [&](SnapshotCache& c, bool checkNear) {
        std::vector<Image> out;
        for (double sigma : sigmas)
            for (glm::ivec3 w : test::canonicalDirections()) {
                const auto v = test::viewAlong(model, glm::dvec3(w), sigma, 1);
                out.push_back(test::renderFar(v.scene, c));
                if (checkNear) {
                    const std::string d =
                        test::firstDifference(test::renderNear(v.scene), out.back());
                    EXPECT_TRUE(d.empty()) << toString(kind) << " sigma " << sigma << " view ("
                                           << w.x << "," << w.y << "," << w.z << "): " << d;
                }
            }
        return out;
    };
    const std::vector<Image> before = renderAll(cache, false);
    const SnapshotCacheCounters c0 = cache.counters();
    ASSERT_EQ(c0.bakes, 52u);
    ASSERT_TRUE(applyEdit(*model, kind));

    const std::vector<Image> after = renderAll(cache, true);
    SnapshotCache fresh;
    const std::vector<Image> expected = renderAll(fresh, false);
    std::size_t changedImages = 0;
    for (std::size_t i = 0; i < after.size(); ++i) {
        EXPECT_TRUE(test::firstDifference(expected[i], after[i]).empty())
            << toString(kind) << " image " << i << ": "
            << test::firstDifference(expected[i], after[i]);
        changedImages += !diffImages(before[i], after[i]).identical();
    }
    const SnapshotCacheCounters c1 = cache.counters();
    // Every stale view was asked for once and refreshed once; its stale snapshot was dropped.
    EXPECT_EQ(c1.refreshes - c0.refreshes, 52u);
    EXPECT_EQ(c1.bakes - c0.bakes, 52u);
    EXPECT_EQ(c1.staleDropped, 52u);
    EXPECT_EQ(c1.snapshots, 52u) << "old versions must not stay in the budget";
    EXPECT_EQ(c1.incrementalRefreshes + c1.fullRefreshes, 52u);
    const bool small = kind == EditKind::InsideVoxel || kind == EditKind::SurfaceVoxel ||
                       kind == EditKind::OutsideContentBounds;
    if (small) {
        EXPECT_EQ(c1.incrementalRefreshes, 52u);
        EXPECT_LE(c1.cellsRetraced, c1.cellsRefreshed / 20) << "a single voxel: <= 5% re-traced";
        EXPECT_EQ(c1.scenesUpdated, 1u) << "the new scene is derived from the old one";
    }
    if (kind == EditKind::InsideVoxel) {
        EXPECT_EQ(changedImages, 0u);
    } else {
        EXPECT_GT(changedImages, 0u) << "the edit should be visible somewhere";
    }
    std::printf("[ edit     ] %-20s %zu of 52 images changed; refreshes: %llu incremental "
                "(%llu of %llu cells re-traced), %llu full\n",
                toString(kind).c_str(), changedImages, (unsigned long long)c1.incrementalRefreshes,
                (unsigned long long)c1.cellsRetraced, (unsigned long long)c1.cellsRefreshed,
                (unsigned long long)c1.fullRefreshes);
}

INSTANTIATE_TEST_SUITE_P(EditKinds, FarAfterEdit,
                         ::testing::Values(EditKind::InsideVoxel, EditKind::SurfaceVoxel,
                                           EditKind::EmptiesModel, EditKind::FillsModel,
                                           EditKind::OutsideContentBounds),
                         [](const auto& info) { return toString(info.param); });

// ---------------------------------------------------------------------------------------------
// Random edit sequences: incremental == full, byte for byte.

/// One random edit, near a cursor that wanders through the model (a player digging or building:
/// edits cluster) or, one time in five, anywhere: single voxels set, recoloured or removed,
/// small boxes filled or cleared, now and then a large box; some edits change nothing (no
/// version bump). Raw mt19937 words, so the sequence is the same with every standard library.
struct RandomEditor {
    std::mt19937 rng;
    glm::ivec3 cursor{0};

    void edit(VoxelModel& m) {
        const glm::ivec3 n = m.frame(0).dims();
        auto anywhere = [&] {
            return glm::ivec3(int(rng() % unsigned(n.x)), int(rng() % unsigned(n.y)),
                              int(rng() % unsigned(n.z)));
        };
        auto near = [&] {
            const glm::ivec3 d(int(rng() % 7) - 3, int(rng() % 7) - 3, int(rng() % 7) - 3);
            cursor = glm::clamp(cursor + d, glm::ivec3(0), n - 1);
            return cursor;
        };
        const glm::ivec3 p = rng() % 5 == 0 ? anywhere() : near();
        const unsigned op = rng() % 100;
        const std::uint8_t index = std::uint8_t(rng() % 9); // 0 = clear
        if (op < 55) {
            m.setVoxel(0, p, index);
        } else if (op < 80) {
            const glm::ivec3 size(1 + int(rng() % 5), 1 + int(rng() % 5), 1 + int(rng() % 5));
            m.fillBox(0, {p, p + size}, std::uint8_t(1 + rng() % 8));
        } else if (op < 96) {
            const glm::ivec3 size(1 + int(rng() % 6), 1 + int(rng() % 6), 1 + int(rng() % 6));
            m.clearBox(0, {p, p + size});
        } else {
            const glm::ivec3 b = anywhere();
            m.fillBox(0, {glm::min(p, b), glm::max(p, b) + 1}, index);
        }
    }
};

struct ViewKey {
    ViewSet set;
    int view;
    double sigma;
};

/// Face, edge and corner views of the 26, two of the 98, at an integer and a non-integer sigma
/// (non-integer sigma puts face-view rays exactly on voxel faces: the grazing case).
std::vector<ViewKey> randomSequenceViews() {
    std::vector<ViewKey> out;
    for (double sigma : {1.0, 1.5}) {
        for (int v : {0, 3, 4, 9, 14, 20, 25}) out.push_back({ViewSet::Cube26, v, sigma});
        for (int v : {31, 77}) out.push_back({ViewSet::Cube98, v, sigma});
    }
    return out;
}

// 400 seeded edits on a 28^3 model, twice; after each, three random views of a pool of 18 are
// asked for (so a view is refreshed across the union of several edits) and compared with the
// scalar bake of the current grid. A second cache with depth, bricks from the start and no
// fallback threshold (always incremental) is compared with a full Embree bake (cells and depth)
// of a fresh flat scene.
TEST(FarEditSequence, IncrementalRebakesEqualFullBakesOverHundredsOfRandomEdits) {
    for (unsigned seed : {11u, 12345u}) {
        const auto model = blobModel({28, 28, 28}, {{3, 2, 4}, {25, 26, 24}});
        RandomEditor editor{std::mt19937(seed), {14, 14, 24}};
        std::mt19937& rng = editor.rng;
        SnapshotCache plain;
        SnapshotCacheConfig cfg;
        cfg.bake.withDepth = true;
        cfg.bake.maxIncrementalShare = 1.0;
        cfg.scene.brickSize = 8;
        cfg.scene.flatUntilEdited = false;
        SnapshotCache deep(cfg);
        const std::vector<ViewKey> pool = randomSequenceViews();
        VoxelSceneOptions flat;
        flat.brickSize = 0;
        BakeOptions withDepth;
        withDepth.withDepth = true;
        for (const ViewKey& k : pool) { // warm every view at the first version
            plain.get(*model, 0, k.set, k.view, k.sigma);
            deep.get(*model, 0, k.set, k.view, k.sigma);
        }
        for (int step = 0; step < 400; ++step) {
            editor.edit(*model);
            const VoxelGrid& g = model->frame(0);
            std::unique_ptr<VoxelScene> reference; // built only when the deep cache is checked
            for (int ask = 0; ask < 3; ++ask) {
                const ViewKey k = pool[rng() % pool.size()];
                const auto a = plain.get(*model, 0, k.set, k.view, k.sigma);
                const std::string da = test::firstSnapshotDifference(
                    *a, bakeSnapshotScalar(g, k.set, k.view, k.sigma));
                ASSERT_TRUE(da.empty())
                    << "seed " << seed << " step " << step << " set " << viewCount(k.set)
                    << " view " << k.view << " sigma " << k.sigma << ": " << da;
                const auto b = deep.get(*model, 0, k.set, k.view, k.sigma);
                if (!reference) reference = std::make_unique<VoxelScene>(g, flat);
                const std::string db = test::firstSnapshotDifference(
                    *b, bakeSnapshot(*reference, k.set, k.view, k.sigma, withDepth), true);
                ASSERT_TRUE(db.empty())
                    << "seed " << seed << " step " << step << " (depth) set " << viewCount(k.set)
                    << " view " << k.view << " sigma " << k.sigma << ": " << db;
            }
        }
        const SnapshotCacheCounters c = plain.counters();
        EXPECT_GT(c.incrementalRefreshes, c.refreshes / 2) << "most should be incremental";
        EXPECT_GT(c.fullRefreshes, 0u) << "the large boxes should fall back to full bakes";
        EXPECT_LT(c.cellsRetraced, c.cellsRefreshed / 2);
        EXPECT_LE(c.snapshots, pool.size());
        const SnapshotCacheCounters d = deep.counters();
        EXPECT_EQ(d.fullRefreshes, 0u) << "no threshold and a complete log: always incremental";
        EXPECT_GT(d.bricksRebuilt, 0u);
        std::printf("[ sequence ] seed %u: %llu refreshes (%llu incremental, %llu full), %llu of "
                    "%llu cells re-traced (%.1f%%)\n",
                    seed, (unsigned long long)c.refreshes,
                    (unsigned long long)c.incrementalRefreshes, (unsigned long long)c.fullRefreshes,
                    (unsigned long long)c.cellsRetraced, (unsigned long long)c.cellsRefreshed,
                    100.0 * double(c.cellsRetraced) / double(c.cellsRefreshed));
    }
}

// ---------------------------------------------------------------------------------------------
// The rectangle: every ray that can read a voxel of the dirty box is re-traced.

/// A voxel source that is empty everywhere (so vtTrace walks the whole path) and records
/// whether the path read a voxel of `box`.
struct PathProbe {
    Box3i box;
    mutable bool touched = false;
    unsigned fetch(glm::ivec3 c) const {
        touched = touched || box.contains(c);
        return 0u;
    }
};

// Checked on the kernel's own traversal, independently of any content: for single voxels at the
// corners, edges, faces and inside of a 10x9x11 grid and a few boxes, every lattice cell whose
// ray visits the box lies in cellsReachingBox, for all 26 views and some of the 98, at integer
// and non-integer sigma (where face-view rays run exactly along voxel faces).
TEST(FarEditRectangle, EveryRayThatVisitsTheDirtyBoxIsInTheRectangle) {
    const glm::ivec3 n(10, 9, 11);
    std::vector<Box3i> boxes;
    for (glm::ivec3 p : {glm::ivec3(0, 0, 0), glm::ivec3(9, 8, 10), glm::ivec3(0, 8, 5),
                         glm::ivec3(5, 0, 10), glm::ivec3(4, 4, 5), glm::ivec3(9, 3, 0)})
        boxes.push_back({p, p + 1});
    boxes.push_back({{2, 3, 1}, {5, 4, 9}});
    boxes.push_back({{0, 0, 0}, n});
    struct ViewCase {
        ViewSet set;
        int view;
    };
    std::vector<ViewCase> views;
    for (int v = 0; v < 26; ++v) views.push_back({ViewSet::Cube26, v});
    for (int v = 0; v < 98; v += 7) views.push_back({ViewSet::Cube98, v});
    std::size_t visiting = 0, inRect = 0, total = 0;
    for (const ViewCase& vc : views)
        for (double sigma : {1.0, 1.5, 2.0, 2.5, 3.0}) {
            const SpriteLattice L =
                snapshotLattice(viewDirections(vc.set)[std::size_t(vc.view)], n, sigma);
            const kernel::SpriteGpu frame = snapshotRayFrame(L);
            for (const Box3i& box : boxes) {
                const glm::ivec4 r = cellsReachingBox(L, box);
                PathProbe probe{box};
                kernel::SpriteTracer<PathProbe> tracer{probe};
                for (int j = L.cellRange.z; j <= L.cellRange.w; ++j)
                    for (int i = L.cellRange.x; i <= L.cellRange.y; ++i) {
                        probe.touched = false;
                        kernel::uint index, face;
                        tracer.vtTrace(frame, {i, j}, index, face);
                        const bool inside = i >= r.x && i <= r.y && j >= r.z && j <= r.w;
                        ++total;
                        inRect += inside;
                        if (!probe.touched) continue;
                        ++visiting;
                        ASSERT_TRUE(inside)
                            << "set " << viewCount(vc.set) << " view " << vc.view << " sigma "
                            << sigma << " box [" << box.min.x << "," << box.min.y << ","
                            << box.min.z << ")-(" << box.max.x << "," << box.max.y << ","
                            << box.max.z << ") cell " << i << "," << j << " outside rectangle "
                            << r.x << ".." << r.y << " x " << r.z << ".." << r.w;
                    }
            }
        }
    EXPECT_GT(visiting, 0u);
    // The margin is a cell or two, not a blanket: the rectangles hold a few times the visiting
    // cells, far fewer than the lattice.
    EXPECT_LT(inRect, total / 2);
    std::printf("[ rect     ] %zu cells visit a dirty box, %zu lie in the rectangles, of %zu\n",
                visiting, inRect, total);
}

// ---------------------------------------------------------------------------------------------
// What a single-voxel edit costs.

// A 64^3 ball, every view warm at sigma 1; six single-voxel edits (surface voxels removed and
// put back, an interior recolour, a voxel added on the outside); after each, every view asked
// for again. Each refresh re-traces at most 5% of a full bake's rays, the new scene rebuilds at
// most the 8 bricks a voxel and its neighbours can reach (after the first edit, which builds
// them), and every snapshot equals the scalar bake of the edited grid.
TEST(FarEditCost, SingleVoxelEditOn64CubeRetracesAFewPercentOfAFullBake) {
    const auto model = makeSphere(32);
    SnapshotCache cache;
    auto askAll = [&] {
        std::vector<std::shared_ptr<const Snapshot>> s(26);
        tbb::parallel_for(0, 26, [&](int v) {
            s[std::size_t(v)] = cache.get(*model, 0, ViewSet::Cube26, v, 1.0);
        });
        return s;
    };
    askAll();
    std::uint64_t fullRays = 0;
    for (const auto& s : askAll()) fullRays += s->cells.size();
    const glm::ivec3 top = topOfColumn(model->frame(0), 40, 29);
    const std::vector<std::pair<glm::ivec3, std::uint8_t>> edits = {
        {top, 0},
        {top, proc_index::kRed},
        {{32, 32, 32}, proc_index::kGreen},
        {topOfColumn(model->frame(0), 10, 30), 0},
        {top + glm::ivec3(0, 0, 1), proc_index::kBlue},
        {{0, 0, 0}, proc_index::kOrange}};
    double worst = 0.0;
    for (std::size_t e = 0; e < edits.size(); ++e) {
        ASSERT_TRUE(model->setVoxel(0, edits[e].first, edits[e].second)) << e;
        const SnapshotCacheCounters c0 = cache.counters();
        const auto snaps = askAll();
        const SnapshotCacheCounters c1 = cache.counters();
        const std::uint64_t retraced = c1.cellsRetraced - c0.cellsRetraced;
        EXPECT_EQ(c1.incrementalRefreshes - c0.incrementalRefreshes, 26u) << e;
        EXPECT_EQ(c1.cellsRefreshed - c0.cellsRefreshed, fullRays) << e;
        const double share = double(retraced) / double(fullRays);
        worst = std::max(worst, share);
        EXPECT_LE(share, 0.05) << "edit " << e;
        EXPECT_GT(retraced, 0u);
        if (e > 0) {
            EXPECT_LE(c1.bricksRebuilt - c0.bricksRebuilt, 8u) << e;
        }
        for (int v = 0; v < 26; ++v) {
            const std::string d = test::firstSnapshotDifference(
                *snaps[std::size_t(v)],
                bakeSnapshotScalar(model->frame(0), ViewSet::Cube26, v, 1.0));
            ASSERT_TRUE(d.empty()) << "edit " << e << " view " << v << ": " << d;
        }
        std::printf("[ 64^3     ] edit %zu: %llu of %llu rays re-traced (%.3f%%), %llu bricks "
                    "rebuilt\n",
                    e, (unsigned long long)retraced, (unsigned long long)fullRays, 100.0 * share,
                    (unsigned long long)(c1.bricksRebuilt - c0.bricksRebuilt));
    }
    EXPECT_LE(worst, 0.05);
}

// The near half of "an edit costs in proportion to its size": through the frame, a single-voxel
// edit of a 64^3 model uploads one byte, a box edit its volume, and the frame stats and the far
// counters report the edit (Vulkan near tier, then the far tier on the same path).
TEST(FarEditCost, FrameStatsReportNearBytesAndFarRefreshesPerEdit) {
    Scene s;
    s.models = {makeSphere(32)};
    Entity e;
    e.position = {0.0, 0.0, -12.0};
    s.entities.push_back(e);
    s.camera.position = {0.0, 3.0, 0.0};
    s.camera.target = {0.0, 3.0, -12.0};
    s.camera.width = 160;
    s.camera.height = 120;
    ScriptedEdit one;
    one.atFrame = 1;
    one.op = ScriptedEdit::Op::Set;
    one.box = {{32, 32, 63}, {33, 33, 64}};
    one.index = 0;
    ScriptedEdit box = one;
    box.atFrame = 2;
    box.op = ScriptedEdit::Op::Fill;
    box.box = {{20, 20, 60}, {24, 26, 64}};
    box.index = proc_index::kBlue;
    s.edits = {one, box};
    FrameOptions o;
    o.nearBackend = NearBackend::Vulkan;
    {
        FrameRenderer r(s, o);
        std::vector<std::uint64_t> bytes;
        for (int f = 0; f < 3; ++f) {
            r.applyEditsThrough(f);
            bytes.push_back(r.render(0.0, RenderMode::Near, f).stats.vulkanNear.bytesUploaded);
        }
        EXPECT_EQ(bytes[0], 64u * 64u * 64u) << "a new model is uploaded whole";
        EXPECT_EQ(bytes[1], 1u) << "one voxel";
        EXPECT_EQ(bytes[2], 4u * 6u * 4u) << "the box's voxels";
    }
    s.models = {makeSphere(32)};
    FrameRenderer r(s, o);
    std::vector<FrameStats> st;
    for (int f = 0; f < 3; ++f) {
        r.applyEditsThrough(f);
        st.push_back(r.render(0.0, RenderMode::Far, f).stats);
    }
    EXPECT_EQ(st[0].far.bakes, 1);
    EXPECT_EQ(st[0].far.refreshes, 0);
    for (int f = 1; f < 3; ++f) {
        EXPECT_EQ(st[std::size_t(f)].far.bakes, 1) << f;
        EXPECT_EQ(st[std::size_t(f)].far.refreshes, 1) << f;
        EXPECT_EQ(st[std::size_t(f)].far.incrementalRefreshes, 1) << f;
        EXPECT_GT(st[std::size_t(f)].far.cellsRetraced, 0u) << f;
        EXPECT_EQ(st[std::size_t(f)].vulkanNear.bytesUploaded, 0u) << "far mode draws nothing near";
    }
    EXPECT_LT(st[1].far.cellsRetraced, st[2].far.cellsRetraced) << "one voxel < a 4x6x4 box";
}

// ---------------------------------------------------------------------------------------------
// Laziness, sharing, fallbacks.

// Only the views that are asked for are refreshed; the others keep their stale snapshot (the
// base of a later refresh) until asked for.
TEST(FarEditLaziness, OnlyRequestedViewsAreRefreshed) {
    const auto m = blobModel({16, 16, 16}, {{2, 2, 2}, {14, 14, 14}});
    SnapshotCache cache;
    for (int v = 0; v < 26; ++v) cache.get(*m, 0, ViewSet::Cube26, v, 1.0);
    const std::uint64_t v0 = m->version();
    ASSERT_TRUE(m->setVoxel(0, topOfColumn(m->frame(0), 8, 8), 0));
    cache.get(*m, 0, ViewSet::Cube26, 4, 1.0);
    cache.get(*m, 0, ViewSet::Cube26, 11, 1.0);
    const SnapshotCacheCounters c = cache.counters();
    EXPECT_EQ(c.refreshes, 2u);
    EXPECT_EQ(c.snapshots, 26u);
    for (int v = 0; v < 26; ++v) {
        const bool asked = v == 4 || v == 11;
        EXPECT_EQ(cache.find({m->uid(), 0, v0, viewIdOf(ViewSet::Cube26, v), 1.0}) != nullptr,
                  !asked)
            << v;
        EXPECT_EQ(cache.find({m->uid(), 0, m->version(), viewIdOf(ViewSet::Cube26, v), 1.0}) !=
                      nullptr,
                  asked)
            << v;
    }
    // A second edit, then a view that missed the first one: one refresh over both edits.
    ASSERT_TRUE(m->setVoxel(0, {8, 8, 1}, proc_index::kGreen));
    const auto s = cache.get(*m, 0, ViewSet::Cube26, 5, 1.0);
    EXPECT_EQ(cache.counters().incrementalRefreshes, 3u);
    EXPECT_TRUE(
        test::firstSnapshotDifference(*s, bakeSnapshotScalar(m->frame(0), ViewSet::Cube26, 5, 1.0))
            .empty());
}

// A model shared by 100 entities: one edit refreshes its one snapshot once, for all of them.
TEST(FarEditLaziness, ModelSharedByHundredEntitiesIsRefreshedOncePerView) {
    const Scene s =
        test::hundredEntityWall(blobModel({16, 16, 16}, {{2, 2, 2}, {14, 14, 14}}), -40.0);
    SnapshotCache cache;
    test::renderFar(s, cache);
    ASSERT_EQ(cache.counters().bakes, 1u);
    // The voxel facing the camera (voxel -Y faces world +Z): the front of the centre row.
    const VoxelGrid& g = s.models[0]->frame(0);
    int y = 0;
    while (!g.at({8, y, 8})) ++y;
    ASSERT_TRUE(s.models[0]->setVoxel(0, {8, y, 8}, 0));
    std::vector<SpriteSetup> sprites;
    const Image after = test::renderFar(s, cache, ViewSet::Cube26, &sprites);
    const SnapshotCacheCounters c = cache.counters();
    EXPECT_EQ(c.bakes, 2u);
    EXPECT_EQ(c.refreshes, 1u);
    EXPECT_EQ(c.incrementalRefreshes, 1u);
    SnapshotCache fresh;
    EXPECT_TRUE(test::firstDifference(test::renderFar(s, fresh), after).empty());
    EXPECT_TRUE(test::firstDifference(test::renderNear(s), after).empty());
}

// Edits in another animation frame bump the version but change nothing this frame shows: the
// refresh reuses the snapshot and its scene as they are.
TEST(FarEditLaziness, EditInAnotherAnimationFrameReusesTheSnapshot) {
    const auto m = test::arrowThenSphere();
    SnapshotCache cache;
    const auto before = cache.get(*m, 0, ViewSet::Cube26, 2, 1.0);
    ASSERT_TRUE(m->setVoxel(1, {4, 4, 4}, 0));
    const auto after = cache.get(*m, 0, ViewSet::Cube26, 2, 1.0);
    EXPECT_EQ(before, after) << "the same bytes: shared, not copied";
    const SnapshotCacheCounters c = cache.counters();
    EXPECT_EQ(c.incrementalRefreshes, 1u);
    EXPECT_EQ(c.cellsRetraced, 0u);
    EXPECT_EQ(c.scenesBuilt, 1u);
    EXPECT_EQ(c.snapshots, 1u);
    EXPECT_EQ(c.bytes, after->bytes());
}

// When the model's edit log no longer reaches the stale version (more than its 4096 entries
// since), the refresh bakes the view whole, and still exactly.
TEST(FarEditFallback, EditLogOverflowBakesTheViewWhole) {
    const auto m = blobModel({20, 20, 20}, {{2, 2, 2}, {18, 18, 18}});
    SnapshotCache cache;
    cache.get(*m, 0, ViewSet::Cube26, 20, 1.5);
    const std::uint64_t v0 = m->version();
    for (int i = 0; i < 5000; ++i)
        m->setVoxel(0, {i % 20, (i / 20) % 20, 19}, std::uint8_t(1 + i % 7));
    ASSERT_FALSE(m->dirtySince(v0, 0).has_value());
    const auto s = cache.get(*m, 0, ViewSet::Cube26, 20, 1.5);
    const SnapshotCacheCounters c = cache.counters();
    EXPECT_EQ(c.refreshes, 1u);
    EXPECT_EQ(c.fullRefreshes, 1u);
    EXPECT_EQ(c.incrementalRefreshes, 0u);
    EXPECT_EQ(c.scenesUpdated, 0u) << "the scene cannot be derived either";
    EXPECT_EQ(c.snapshots, 1u);
    EXPECT_TRUE(
        test::firstSnapshotDifference(*s, bakeSnapshotScalar(m->frame(0), ViewSet::Cube26, 20, 1.5))
            .empty());
}

// An edit covering most of the snapshot is baked whole (re-tracing nearly everything on top of a
// copy would cost more); a stale snapshot that was evicted leaves nothing to refresh.
TEST(FarEditFallback, LargeEditsAndEvictedSnapshotsBakeWhole) {
    const auto m = blobModel({20, 20, 20}, {{2, 2, 2}, {18, 18, 18}});
    // A corner view: the whole model's projection covers most of its lattice.
    const auto& dirs = viewDirections(ViewSet::Cube26);
    int corner = 0;
    while (dirs[std::size_t(corner)].x == 0.0 || dirs[std::size_t(corner)].y == 0.0 ||
           dirs[std::size_t(corner)].z == 0.0)
        ++corner;
    SnapshotCache cache;
    cache.get(*m, 0, ViewSet::Cube26, corner, 1.0);
    ASSERT_TRUE(m->fillBox(0, {{0, 0, 0}, {20, 20, 20}}, proc_index::kMagenta));
    const auto s = cache.get(*m, 0, ViewSet::Cube26, corner, 1.0);
    EXPECT_EQ(cache.counters().fullRefreshes, 1u);
    EXPECT_TRUE(test::firstSnapshotDifference(
                    *s, bakeSnapshotScalar(m->frame(0), ViewSet::Cube26, corner, 1.0))
                    .empty());
    cache.setBudget(0); // evict everything
    ASSERT_TRUE(m->setVoxel(0, {0, 0, 0}, proc_index::kRed));
    const auto t = cache.get(*m, 0, ViewSet::Cube26, corner, 1.0);
    EXPECT_EQ(cache.counters().refreshes, 1u) << "nothing stale was left: a plain bake";
    EXPECT_TRUE(test::firstSnapshotDifference(
                    *t, bakeSnapshotScalar(m->frame(0), ViewSet::Cube26, corner, 1.0))
                    .empty());
}

// rebakeSnapshot on its own: an empty dirty box copies, and a snapshot of another size, or one
// without the depth that is asked for, is baked whole.
TEST(FarEditFallback, RebakeOfAnUnfitSnapshotBakesWhole) {
    const auto m = makeSphere(6);
    const VoxelScene scene(m->frame(0), {});
    const Snapshot s = bakeSnapshot(scene, ViewSet::Cube26, 7, 2.0);
    BakeStats st;
    const Snapshot same = rebakeSnapshot(scene, s, Box3i{}, {}, &st);
    EXPECT_EQ(st.incremental, 1u);
    EXPECT_EQ(st.rays, 0u);
    EXPECT_EQ(same.cells, s.cells);
    BakeOptions depth;
    depth.withDepth = true;
    BakeStats sd;
    const Snapshot withDepth = rebakeSnapshot(scene, s, {{1, 1, 1}, {2, 2, 2}}, depth, &sd);
    EXPECT_EQ(sd.incremental, 0u);
    EXPECT_EQ(withDepth.depth, bakeSnapshot(scene, ViewSet::Cube26, 7, 2.0, depth).depth);
    const VoxelScene other(makeSphere(5)->frame(0), {});
    BakeStats so;
    const Snapshot resized = rebakeSnapshot(other, s, {{1, 1, 1}, {2, 2, 2}}, {}, &so);
    EXPECT_EQ(so.incremental, 0u);
    EXPECT_EQ(resized.cells, bakeSnapshotScalar(other.grid(), ViewSet::Cube26, 7, 2.0).cells);
}

// ---------------------------------------------------------------------------------------------
// The Embree scene after an edit.

// A single-voxel edit rebuilds at most the 8 bricks its 3x3x3 neighbourhood can reach and shares
// the others; a chain of derived scenes bakes what a fresh scene bakes. The first scene derived
// from a flat one builds every brick; with bricks off, the scene is rebuilt whole.
TEST(FarEditScene, DerivedScenesRebuildOnlyTheBricksTheEditReaches) {
    const auto m = blobModel({40, 36, 44}, {{2, 2, 2}, {38, 34, 42}});
    VoxelSceneOptions o;
    o.brickSize = 16;
    const VoxelScene flat(m->frame(0), o);
    EXPECT_FALSE(flat.bricked());
    std::uint64_t before = m->version();
    ASSERT_TRUE(m->setVoxel(0, {20, 20, 2}, 0));
    auto first = std::make_unique<VoxelScene>(flat, m->frame(0), *m->dirtySince(before, 0));
    EXPECT_TRUE(first->bricked());
    EXPECT_EQ(first->buildStats().bricksReused, 0u);
    EXPECT_EQ(first->buildStats().bricksBuilt, 3u * 3u * 3u);
    std::unique_ptr<VoxelScene> current = std::move(first);
    std::mt19937 rng(99);
    for (int e = 0; e < 30; ++e) {
        before = m->version();
        const glm::ivec3 p(int(rng() % 40), int(rng() % 36), int(rng() % 44));
        if (!m->setVoxel(0, p, std::uint8_t(rng() % 4))) continue;
        auto next = std::make_unique<VoxelScene>(*current, m->frame(0), *m->dirtySince(before, 0));
        const SceneBuildStats& b = next->buildStats();
        EXPECT_LE(b.bricksBuilt, 8u) << p.x << "," << p.y << "," << p.z;
        EXPECT_GT(b.bricksReused, 0u);
        current = std::move(next);
    }
    const VoxelScene fresh(m->frame(0), o);
    for (int v = 0; v < 26; ++v) {
        const Snapshot a = bakeSnapshot(*current, ViewSet::Cube26, v, 1.0);
        EXPECT_TRUE(
            test::firstSnapshotDifference(a, bakeSnapshot(fresh, ViewSet::Cube26, v, 1.0)).empty());
        EXPECT_TRUE(test::firstSnapshotDifference(
                        a, bakeSnapshotScalar(m->frame(0), ViewSet::Cube26, v, 1.0))
                        .empty());
    }
    EXPECT_EQ(current->primitiveCount(), VoxelScene(m->frame(0),
                                                    [] {
                                                        VoxelSceneOptions b;
                                                        b.flatUntilEdited = false;
                                                        return b;
                                                    }())
                                             .primitiveCount())
        << "same bricks, same primitives as a fresh bricked scene";
    VoxelSceneOptions off;
    off.brickSize = 0;
    const VoxelScene flatOnly(m->frame(0), off);
    const VoxelScene rebuilt(flatOnly, m->frame(0), {{1, 1, 1}, {2, 2, 2}});
    EXPECT_FALSE(rebuilt.bricked());
    EXPECT_EQ(rebuilt.buildStats().bricksBuilt, 1u);
}

// Both geometries: the quads of a derived bricked scene give the same snapshots.
TEST(FarEditScene, QuadScenesUpdateToo) {
    const auto m = blobModel({24, 24, 24}, {{2, 2, 2}, {22, 22, 22}});
    VoxelSceneOptions o;
    o.geometry = BakeGeometry::Quads;
    o.brickSize = 8;
    o.flatUntilEdited = false;
    const VoxelScene scene(m->frame(0), o);
    const std::uint64_t before = m->version();
    ASSERT_TRUE(m->clearBox(0, {{10, 10, 18}, {14, 13, 24}}));
    const VoxelScene derived(scene, m->frame(0), *m->dirtySince(before, 0));
    EXPECT_LT(derived.buildStats().bricksBuilt, derived.brickCount());
    for (int v = 0; v < 26; ++v)
        EXPECT_TRUE(
            test::firstSnapshotDifference(bakeSnapshot(derived, ViewSet::Cube26, v, 1.5),
                                          bakeSnapshotScalar(m->frame(0), ViewSet::Cube26, v, 1.5))
                .empty())
            << v;
}

// ---------------------------------------------------------------------------------------------
// Concurrency. TSan cannot see the synchronisation inside the system's (uninstrumented) libtbb:
// even a race-free parallel_for is reported, and so is a thread that helps another thread's
// bake through collaborative_call_once. So this test keeps every thread on keys of its own (no
// bake is joined across threads) and is meant to run on one CPU, where TBB starts no workers
// and every report is about the threads below:
//   taskset -c 0 build-tsan/tests/far_edit_test --gtest_filter='FarEditConcurrency*'

// One thread edits model A and refreshes its views (in parallel, as a frame does) and checks
// one against the scalar bake after each edit, while two others render model B through the same
// cache from every canonical direction, one at sigma 1 and one at sigma 2 (52 snapshots, more
// than the budget holds, so evictions of either model interleave with the refreshes), read the
// counters and look keys up. Afterwards every snapshot of both models equals the scalar bake.
TEST(FarEditConcurrency, EditsAndRendersOnDifferentModelsAreSafe) {
    const auto a = blobModel({20, 20, 20}, {{2, 2, 2}, {18, 18, 18}});
    const auto b = blobModel({18, 22, 16}, {{1, 1, 1}, {17, 21, 15}});
    SnapshotCache probe;
    SnapshotCacheConfig cfg;
    cfg.budgetBytes = 40 * probe.get(*a, 0, ViewSet::Cube26, 0, 1.0)->bytes();
    cfg.maxScenes = 3;
    SnapshotCache cache(cfg);
    cache.scene(*b, 0); // built before the renderers start, so neither joins the other's build
    std::atomic<bool> done{false};
    std::atomic<int> failures{0};
    // The renderers start once the editor has baked its six views and refreshed them once, so
    // at least one refresh finds its stale snapshot resident: how many later ones do depends on
    // how fast the renderers evict, which is the machine's business, not the test's.
    std::latch refreshedOnce(1);
    std::thread editor([&] {
        RandomEditor edits{std::mt19937(7), {10, 10, 10}};
        for (int step = 0; step < 40; ++step) {
            if (step == 2) refreshedOnce.count_down();
            edits.edit(*a);
            std::vector<std::shared_ptr<const Snapshot>> got(6);
            tbb::parallel_for(0, 6, [&](int k) {
                const int view = 5 * k; // the same six views every step: refreshed each time
                got[std::size_t(k)] = cache.get(*a, 0, ViewSet::Cube26, view, 1.0 + 0.5 * (k % 2));
            });
            const int k = step % 6;
            const Snapshot want =
                bakeSnapshotScalar(a->frame(0), ViewSet::Cube26, 5 * k, 1.0 + 0.5 * (k % 2));
            if (!test::firstSnapshotDifference(*got[std::size_t(k)], want).empty()) ++failures;
        }
        done = true;
    });
    auto renderer = [&](double sigma) {
        refreshedOnce.wait();
        for (int i = 0; !done || i < 26; ++i) {
            const glm::ivec3 w = test::canonicalDirections()[std::size_t(i % 26)];
            const auto v = test::viewAlong(b, glm::dvec3(w), sigma, 1);
            const Image img = test::renderFar(v.scene, cache);
            if (test::drawnPixels(img) == 0) ++failures;
            if (cache.counters().bytes > cfg.budgetBytes) ++failures;
            cache.find(
                {b->uid(), 0, b->version(), viewIdOf(ViewSet::Cube26, (i * 7) % 26), 3.0 - sigma});
        }
    };
    std::thread r1(renderer, 1.0), r2(renderer, 2.0);
    editor.join();
    r1.join();
    r2.join();
    EXPECT_EQ(failures.load(), 0);
    for (const auto& m : {a, b})
        for (int v : {0, 5, 13, 25}) {
            const auto s = cache.get(*m, 0, ViewSet::Cube26, v, 1.0);
            EXPECT_TRUE(test::firstSnapshotDifference(
                            *s, bakeSnapshotScalar(m->frame(0), ViewSet::Cube26, v, 1.0))
                            .empty())
                << m->name() << " view " << v;
        }
    EXPECT_GT(cache.counters().refreshes, 0u);
    EXPECT_GT(cache.counters().evictions, 0u);
}

} // namespace
} // namespace voxtier
