// The far tier's baker (CONTRACT.md §4, HARD_CASES 16-21): every snapshot cell equals the near
// kernel's vtShadeCell for the same lattice cell, whatever Embree geometry, trace API, thread
// count or primitive set produced it; solid boxes match an independent closed form.
#include "closed_form.hpp"
#include "core/procedural.hpp"
#include "far_test_support.hpp"
#include "impostor_cache/detail/embree_device.hpp"
#include "impostor_cache/embree_error.hpp"
#include "impostor_cache/snapshot_baker.hpp"
#include "impostor_cache/surface_voxels.hpp"
#include "impostor_cache/voxel_scene.hpp"

#include <gtest/gtest.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <atomic>
#include <random>
#include <set>
#include <xmmintrin.h>

namespace voxtier {
namespace {

/// Adjacent voxels of different colours in a 3D checkerboard: edge and corner views have rays
/// that cross two voxel boundaries at equal parameters, so the entered face and the voxel hit
/// depend on the tie order alone (HARD_CASES 17).
std::shared_ptr<VoxelModel> checkerboard(glm::ivec3 dims) {
    VoxelGrid g(dims);
    for (int z = 0; z < dims.z; ++z)
        for (int y = 0; y < dims.y; ++y)
            for (int x = 0; x < dims.x; ++x)
                g.set({x, y, z}, std::uint8_t(1 + (x + y + z) % 2 + 2 * (z % 2)));
    return std::make_shared<VoxelModel>("checker", proceduralPalette(), std::vector<VoxelGrid>{g});
}

/// Sparse random voxels with random indices 1..255 (thin, isolated, grazing cases).
std::shared_ptr<VoxelModel> randomSparse(glm::ivec3 dims, double fill, unsigned seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    VoxelGrid g(dims);
    for (auto& v : g.data()) v = u(rng) < fill ? std::uint8_t(1 + rng() % 255) : 0;
    return std::make_shared<VoxelModel>("random", proceduralPalette(), std::vector<VoxelGrid>{g});
}

std::vector<std::shared_ptr<VoxelModel>> bakeModels() {
    return {makeArrow(16),
            makeSphere(6),
            makeShell({9, 7, 12}, 1),
            makeBox({3, 5, 8}),
            makeSingleVoxel(254),
            checkerboard({6, 5, 4}),
            randomSparse({13, 11, 9}, 0.2, 7),
            randomSparse({20, 20, 20}, 0.02, 11)};
}

// The snapshot is the near kernel's cell image: vtShadeCell (hit, entered face, cardinal
// outline) evaluated by the reference renderer's traceCells on the snapshot lattice.
TEST(EmbreeBake, EveryCellEqualsTheNearKernelsShadeCell) {
    for (const auto& m : bakeModels())
        for (double sigma : {1.0, 2.0, 1.5}) {
            const VoxelScene scene(m->frame(0), {});
            for (int v = 0; v < 26; ++v) {
                const Snapshot s = bakeSnapshot(scene, ViewSet::Cube26, v, sigma);
                const CellImage k = traceCells(snapshotRayFrame(s.lattice), m->frame(0));
                ASSERT_EQ(k.range, s.lattice.cellRange);
                for (int j = k.range.z; j <= k.range.w; ++j)
                    for (int i = k.range.x; i <= k.range.y; ++i) {
                        const std::size_t a = k.at(i, j);
                        const SnapshotCell c = s.at(i, j);
                        std::uint8_t want = snapshot_code::kEmpty;
                        if (k.kind[a] == kernel::VT_KIND_SOLID)
                            want = std::uint8_t(snapshot_code::kSolid0 + k.face[a]);
                        if (k.kind[a] == kernel::VT_KIND_OUTLINE) want = snapshot_code::kOutline;
                        ASSERT_EQ(c.code, want) << m->name() << " sigma " << sigma << " view " << v
                                                << " cell " << i << "," << j;
                        if (k.kind[a] == kernel::VT_KIND_SOLID) {
                            ASSERT_EQ(c.index, k.index[a]);
                        }
                    }
            }
        }
}

// Both geometries and all three trace APIs give the scalar kernel's snapshots, for the dense
// view sets too (every direction of 98 and 218 has components 0 or >= 1/sqrt(19)).
TEST(EmbreeBake, QuadsAndBoxesEveryApiEqualTheScalarKernelBake) {
    for (const auto& m : bakeModels())
        for (BakeGeometry geo : {BakeGeometry::Boxes, BakeGeometry::Quads}) {
            const VoxelScene scene(m->frame(0), {geo, true, true});
            for (TraceApi api : {TraceApi::Packet8, TraceApi::Packet16, TraceApi::Stream})
                for (ViewSet set : {ViewSet::Cube26, ViewSet::Cube98})
                    for (double sigma : {1.0, 2.0})
                        for (int v = 0; v < viewCount(set); ++v) {
                            const std::string d = test::firstSnapshotDifference(
                                bakeSnapshot(scene, set, v, sigma, {api, false}),
                                bakeSnapshotScalar(m->frame(0), set, v, sigma));
                            ASSERT_TRUE(d.empty())
                                << m->name() << " " << toString(geo) << " " << toString(api)
                                << " set " << viewCount(set) << " view " << v << " sigma " << sigma
                                << ": " << d;
                        }
        }
}

TEST(EmbreeBake, View218SetEqualsTheScalarKernelBake) {
    const auto m = randomSparse({12, 10, 14}, 0.25, 3);
    const VoxelScene scene(m->frame(0), {});
    for (int v = 0; v < 218; ++v)
        ASSERT_TRUE(
            test::firstSnapshotDifference(bakeSnapshot(scene, ViewSet::Cube218, v, 1.0),
                                          bakeSnapshotScalar(m->frame(0), ViewSet::Cube218, v, 1.0))
                .empty())
            << "view " << v;
}

// HARD_CASES 19: interior voxels can never be the first hit, so leaving them out changes
// nothing; merging primitives (runs, rectangles) changes nothing either.
TEST(EmbreeBake, SurfaceOnlyBakeEqualsBakeOverEveryVoxel) {
    for (const auto& m : {makeSphere(7), makeBox({6, 5, 7}), makeShell({10, 8, 6}, 2),
                          randomSparse({10, 10, 10}, 0.6, 5)})
        for (BakeGeometry geo : {BakeGeometry::Boxes, BakeGeometry::Quads}) {
            const VoxelScene surface(m->frame(0), {geo, true, true});
            const VoxelScene every(m->frame(0), {geo, false, true});
            const VoxelScene unmerged(m->frame(0), {geo, true, false});
            const VoxelScene everyUnmerged(m->frame(0), {geo, false, false});
            EXPECT_LT(unmerged.primitiveCount(), everyUnmerged.primitiveCount()) << m->name();
            EXPECT_LE(surface.primitiveCount(), unmerged.primitiveCount()) << m->name();
            for (int v = 0; v < 26; ++v)
                for (double sigma : {1.0, 2.0}) {
                    const Snapshot a = bakeSnapshot(surface, ViewSet::Cube26, v, sigma);
                    EXPECT_TRUE(test::firstSnapshotDifference(
                                    a, bakeSnapshot(every, ViewSet::Cube26, v, sigma))
                                    .empty())
                        << m->name() << " view " << v;
                    EXPECT_TRUE(test::firstSnapshotDifference(
                                    a, bakeSnapshot(unmerged, ViewSet::Cube26, v, sigma))
                                    .empty())
                        << m->name() << " view " << v;
                    EXPECT_TRUE(test::firstSnapshotDifference(
                                    a, bakeSnapshot(everyUnmerged, ViewSet::Cube26, v, sigma))
                                    .empty())
                        << m->name() << " view " << v;
                }
        }
}

TEST(SurfaceVoxels, InteriorOfASolidBlockIsExcluded) {
    const auto m = makeBox({5, 4, 3});
    const auto single = surfaceBoxes(m->frame(0), true, false);
    EXPECT_EQ(single.size(), std::size_t(5 * 4 * 3 - 3 * 2 * 1));
    EXPECT_EQ(surfaceBoxes(m->frame(0), false, false).size(), std::size_t(5 * 4 * 3));
    // Exposed faces of a box: its surface area; merged: one rectangle per side.
    EXPECT_EQ(exposedFaces(m->frame(0), true, false).size(),
              std::size_t(2 * (5 * 4 + 4 * 3 + 5 * 3)));
    EXPECT_EQ(exposedFaces(m->frame(0), true, true).size(), 6u);
}

// HARD_CASES 14/17/21: the result does not depend on how rows are split across threads.
TEST(EmbreeBake, IdenticalSnapshotsWithOneThreadAndAllThreads) {
    for (const auto& m : {checkerboard({7, 6, 5}), randomSparse({16, 16, 16}, 0.1, 9)}) {
        const VoxelScene scene(m->frame(0), {});
        std::vector<Snapshot> all, one;
        for (int v = 0; v < 26; ++v) all.push_back(bakeSnapshot(scene, ViewSet::Cube26, v, 2.0));
        tbb::task_arena single(1);
        single.execute([&] {
            for (int v = 0; v < 26; ++v)
                one.push_back(bakeSnapshot(scene, ViewSet::Cube26, v, 2.0));
        });
        for (int v = 0; v < 26; ++v)
            EXPECT_TRUE(
                test::firstSnapshotDifference(all[std::size_t(v)], one[std::size_t(v)]).empty())
                << "view " << v;
    }
}

// HARD_CASES 21: Embree runs with FTZ/DAZ in every worker, and the workers' MXCSR control bits
// are restored afterwards (the exact traversal and the rest of the program run without them).
// The low six bits are sticky exception flags, not modes, and are not compared.
TEST(EmbreeBake, EveryEmbreeCallRunsWithFlushToZeroAndTheWorkersAreRestored) {
    const auto m = randomSparse({24, 24, 24}, 0.1, 13);
    const VoxelScene scene(m->frame(0), {BakeGeometry::Boxes});
    constexpr unsigned kControl = ~0x3Fu;
    const unsigned before = _mm_getcsr() & kControl;
    std::atomic<int> changed{0};
    tbb::parallel_for(0, 26, [&](int v) {
        const unsigned mine = _mm_getcsr() & kControl;
        bakeSnapshot(scene, ViewSet::Cube26, v, 2.0);
        if ((_mm_getcsr() & kControl) != mine) ++changed;
    });
    EXPECT_EQ(embreeCallsWithoutFlushDenormals(), 0u);
    EXPECT_EQ(changed.load(), 0);
    EXPECT_EQ(_mm_getcsr() & kControl, before);
}

// HARD_CASES 17: equal-t ties between adjacent voxels of different colours resolve the same
// way on every run, thread count and API, and the way the kernel resolves them.
TEST(EmbreeBake, EqualParameterTiesAreDeterministicAndFollowTheKernel) {
    const auto m = checkerboard({6, 6, 6});
    const VoxelScene boxes(m->frame(0), {BakeGeometry::Boxes});
    const VoxelScene quads(m->frame(0), {BakeGeometry::Quads});
    for (int v = 6; v < 26; ++v) { // edge and corner views: the ones with tied crossings
        const Snapshot ref = bakeSnapshotScalar(m->frame(0), ViewSet::Cube26, v, 1.0);
        // The edge/corner views do see both colours of the checkerboard.
        std::set<int> indices;
        for (const SnapshotCell& c : ref.cells)
            if (snapshot_code::isSolid(c.code)) indices.insert(c.index);
        EXPECT_GE(indices.size(), 2u);
        for (int run = 0; run < 3; ++run)
            for (const VoxelScene* sc : {&boxes, &quads})
                for (TraceApi api : {TraceApi::Packet8, TraceApi::Stream})
                    EXPECT_TRUE(test::firstSnapshotDifference(
                                    bakeSnapshot(*sc, ViewSet::Cube26, v, 1.0, {api, false}), ref)
                                    .empty())
                        << "view " << v;
    }
}

// CONTRACT.md §7 / HARD_CASES 16, 20: views of solid boxes and slabs match the closed form: no
// holes, no extra cells, the right entered faces. At sigma 1.5 only the face views are
// compared: there some face-view rays run exactly on voxel faces (the half-open rule decides,
// in float and in double alike), while edge and corner views get rays exactly through box
// edges, where the float kernel and a double closed form may legitimately round apart (the
// kernel is what the snapshot must equal, and does: see the tests above).
TEST(EmbreeBake, SolidBoxesAndSlabsMatchTheClosedFormAtEveryView) {
    for (glm::ivec3 dims : {glm::ivec3(12, 9, 1), glm::ivec3(1, 12, 9), glm::ivec3(9, 1, 12),
                            glm::ivec3(4, 4, 4), glm::ivec3(5, 3, 8)})
        for (double sigma : {1.0, 2.0, 3.0, 1.5}) {
            const auto m = makeBox(dims);
            const VoxelScene scene(m->frame(0), {});
            for (int v = 0; v < 26; ++v) {
                if (sigma != std::floor(sigma) && v >= 6) continue;
                const Snapshot s = bakeSnapshot(scene, ViewSet::Cube26, v, sigma);
                const test::ExpectedCells e =
                    test::expectedBoxCells(dims, s.lattice.dir, s.lattice.up, sigma);
                std::size_t solid = 0;
                for (int j = e.range.z; j <= e.range.w; ++j)
                    for (int i = e.range.x; i <= e.range.y; ++i) {
                        const int kind = e.kind[e.at(i, j)];
                        const SnapshotCell c = s.at(i, j);
                        const int got = snapshot_code::isSolid(c.code)
                                            ? 1
                                            : (c.code == snapshot_code::kOutline ? 2 : 0);
                        ASSERT_EQ(got, kind)
                            << dims.x << "x" << dims.y << "x" << dims.z << " sigma " << sigma
                            << " view " << v << " cell " << i << "," << j;
                        if (kind == 1) {
                            ++solid;
                            ASSERT_EQ(int(snapshot_code::face(c.code)), e.face[e.at(i, j)]);
                        }
                    }
                EXPECT_EQ(solid, s.solidCount());
                // A face view of a slab at integer sigma is a full rectangle of sigma-cells.
                if (v < 6 && sigma == std::floor(sigma)) {
                    const int axis = v / 2;
                    const std::size_t area =
                        std::size_t(dims[(axis + 1) % 3] * dims[(axis + 2) % 3] * sigma * sigma);
                    EXPECT_EQ(s.solidCount(), area) << "holes in the face view " << v;
                }
            }
        }
}

// HARD_CASES 20: an empty model bakes empty snapshots (and an empty scene); a single voxel is
// a sigma x sigma block with a four-sided outline.
TEST(EmbreeBake, EmptyModelYieldsEmptySnapshots) {
    const auto m = std::make_shared<VoxelModel>("empty", proceduralPalette(),
                                                std::vector<VoxelGrid>{VoxelGrid({7, 5, 3})});
    for (BakeGeometry geo : {BakeGeometry::Boxes, BakeGeometry::Quads}) {
        const VoxelScene scene(m->frame(0), {geo});
        EXPECT_TRUE(scene.empty());
        for (int v = 0; v < 26; ++v) {
            const Snapshot s = bakeSnapshot(scene, ViewSet::Cube26, v, 2.0);
            for (const SnapshotCell& c : s.cells) ASSERT_EQ(c.code, snapshot_code::kEmpty);
        }
    }
}

TEST(EmbreeBake, SingleVoxelFaceViewIsSigmaBlockWithCardinalOutline) {
    const auto m = makeSingleVoxel(255);
    const VoxelScene scene(m->frame(0), {});
    for (int sigma : {1, 2, 3})
        for (int v = 0; v < 6; ++v) {
            const Snapshot s = bakeSnapshot(scene, ViewSet::Cube26, v, sigma);
            std::size_t solid = 0, outline = 0;
            for (const SnapshotCell& c : s.cells) {
                solid += snapshot_code::isSolid(c.code);
                outline += c.code == snapshot_code::kOutline;
                if (snapshot_code::isSolid(c.code)) {
                    EXPECT_EQ(c.index, 255);
                }
            }
            EXPECT_EQ(solid, std::size_t(sigma * sigma));
            EXPECT_EQ(outline, std::size_t(4 * sigma));
        }
}

// Optional depth along w: for a face view of a box, the entered face's distance from the
// sprite plane through the centre is half the box depth (in front of the plane: negative).
TEST(EmbreeBake, OptionalDepthIsTheEnteredFaceDistanceFromTheSpritePlane) {
    const auto m = makeBox({6, 4, 10});
    const VoxelScene scene(m->frame(0), {});
    BakeOptions o;
    o.withDepth = true;
    for (int v = 0; v < 6; ++v) {
        const Snapshot s = bakeSnapshot(scene, ViewSet::Cube26, v, 1.0, o);
        ASSERT_EQ(s.depth.size(), s.cells.size());
        const double half = 0.5 * glm::ivec3(6, 4, 10)[v / 2];
        for (std::size_t k = 0; k < s.cells.size(); ++k)
            if (snapshot_code::isSolid(s.cells[k].code)) {
                ASSERT_NEAR(s.depth[k], -half, 1e-3) << "view " << v;
            }
        EXPECT_TRUE(bakeSnapshot(scene, ViewSet::Cube26, v, 1.0).depth.empty());
    }
}

// Embree's failures come out as EmbreeError with a one-line message naming what failed, the
// code and Embree's own words: a device Embree refuses to create, and a call rejected by the
// device's error callback (checked once, then cleared).
TEST(EmbreeErrors, FailuresSurfaceAsEmbreeErrorWithOneLineMessage) {
    try {
        rtcReleaseDevice(detail::newEmbreeDevice("threads=abc"));
        ADD_FAILURE() << "Embree accepted threads=abc";
    } catch (const EmbreeError& e) {
        const std::string what = e.what();
        EXPECT_NE(what.find("rtcNewDevice(\"threads=abc\") failed: RTC_ERROR_"), std::string::npos)
            << what;
        EXPECT_NE(e.code(), int(RTC_ERROR_NONE));
        EXPECT_EQ(what.find('\n'), std::string::npos);
    }
    RTCScene scene = rtcNewScene(detail::embreeDevice());
    rtcSetSceneBuildQuality(scene, RTCBuildQuality(77));
    try {
        detail::throwOnEmbreeError("build quality");
        ADD_FAILURE() << "the rejected call was not reported";
    } catch (const EmbreeError& e) {
        const std::string what = e.what();
        EXPECT_EQ(what.rfind("embree: build quality failed: RTC_ERROR_", 0), 0u) << what;
        EXPECT_NE(what.find(": invalid build quality"), std::string::npos) << what;
        EXPECT_NE(e.code(), int(RTC_ERROR_NONE));
        EXPECT_EQ(what.find('\n'), std::string::npos);
    }
    EXPECT_NO_THROW(detail::throwOnEmbreeError("nothing"));
    rtcReleaseScene(scene);
}

} // namespace
} // namespace voxtier
