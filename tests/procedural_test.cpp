// The procedural models are the fixtures of every other suite, so their layouts are checked
// against the documented formulas with independent loops, never against the generator's code.
#include "core/error.hpp"
#include "core/procedural.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <set>

namespace voxtier {
namespace {

long long countSolid(const VoxelGrid& g) {
    return static_cast<long long>(g.solidCount());
}

TEST(Procedural, BoxIsSolidWithTheRequestedIndexAndVolumeCount) {
    for (glm::ivec3 size :
         {glm::ivec3(1), glm::ivec3(8), glm::ivec3(3, 5, 8), glm::ivec3(128, 16, 1)}) {
        const auto m = makeBox(size, 7);
        ASSERT_EQ(m->frameCount(), 1);
        const VoxelGrid& g = m->frame(0);
        EXPECT_EQ(g.dims(), size);
        EXPECT_EQ(countSolid(g), 1LL * size.x * size.y * size.z);
        for (auto v : g.data()) ASSERT_EQ(v, 7);
        EXPECT_EQ(m->name(), "box");
    }
}

TEST(Procedural, ShellCountIsVolumeMinusInnerVolume) {
    struct Case {
        glm::ivec3 size;
        int t;
    };
    for (const Case& c :
         {Case{{16, 16, 16}, 1}, Case{{16, 16, 16}, 3}, Case{{3, 5, 8}, 1}, Case{{9, 9, 9}, 4},
          Case{{9, 9, 9}, 5}, Case{{2, 2, 2}, 1}, Case{{128, 16, 1}, 1}, Case{{10, 20, 30}, 2}}) {
        SCOPED_TRACE(testing::Message()
                     << c.size.x << "x" << c.size.y << "x" << c.size.z << " t=" << c.t);
        const auto model = makeShell(c.size, c.t);
        const VoxelGrid& g = model->frame(0);
        long long inner = 1;
        for (int a = 0; a < 3; ++a) inner *= std::max(0, c.size[a] - 2 * c.t);
        EXPECT_EQ(countSolid(g), 1LL * c.size.x * c.size.y * c.size.z - inner);
        // The cavity is exactly the inner box.
        for (int z = 0; z < c.size.z; ++z)
            for (int y = 0; y < c.size.y; ++y)
                for (int x = 0; x < c.size.x; ++x) {
                    const bool inside = x >= c.t && y >= c.t && z >= c.t && x < c.size.x - c.t &&
                                        y < c.size.y - c.t && z < c.size.z - c.t;
                    ASSERT_EQ(g.at({x, y, z}), inside ? 0 : 1) << x << "," << y << "," << z;
                }
    }
}

TEST(Procedural, SphereMatchesADirectCountOfVoxelCentresInsideTheRadius) {
    for (int r : {1, 2, 3, 6, 7, 16, 33}) {
        SCOPED_TRACE(r);
        const auto model = makeSphere(r);
        const VoxelGrid& g = model->frame(0);
        ASSERT_EQ(g.dims(), glm::ivec3(2 * r));
        long long expected = 0;
        for (int z = 0; z < 2 * r; ++z)
            for (int y = 0; y < 2 * r; ++y)
                for (int x = 0; x < 2 * r; ++x) {
                    // Centres are at half-integers, so these doubles are exact.
                    const double dx = x + 0.5 - r, dy = y + 0.5 - r, dz = z + 0.5 - r;
                    const bool in = dx * dx + dy * dy + dz * dz <= double(r) * r;
                    expected += in;
                    ASSERT_EQ(g.at({x, y, z}) != 0, in) << x << "," << y << "," << z;
                }
        EXPECT_EQ(countSolid(g), expected);
    }
    EXPECT_EQ(makeSphere(1)->frame(0).solidCount(), 8u); // every centre is sqrt(0.75) from (1,1,1)
}

TEST(Procedural, SphereIsSymmetricUnderAxisFlips) {
    const auto model = makeSphere(5);
    const VoxelGrid& g = model->frame(0);
    const int n = 10;
    for (int z = 0; z < n; ++z)
        for (int y = 0; y < n; ++y)
            for (int x = 0; x < n; ++x) {
                const auto v = g.at({x, y, z});
                ASSERT_EQ(v, g.at({n - 1 - x, y, z}));
                ASSERT_EQ(v, g.at({x, n - 1 - y, z}));
                ASSERT_EQ(v, g.at({x, y, n - 1 - z}));
                ASSERT_EQ(v, g.at({y, z, x}));
            }
}

/// The documented arrow, written out independently of the generator.
VoxelGrid documentedArrow(int L) {
    VoxelGrid g({L, 5, 5});
    for (int x = 0; x < L - 3; ++x) g.set({x, 2, 2}, 1);
    for (int y = 0; y < 5; ++y)
        for (int z = 0; z < 5; ++z) g.set({L - 3, y, z}, 2);
    for (int y = 1; y < 4; ++y)
        for (int z = 1; z < 4; ++z) g.set({L - 2, y, z}, 2);
    g.set({L - 1, 2, 2}, 2);
    for (int x = 0; x < 3; ++x)
        for (int z = 3; z < 5; ++z) g.set({x, 2, z}, 3);
    for (int y = 3; y < 5; ++y) g.set({L / 2, y, 2}, 4);
    return g;
}

TEST(Procedural, ArrowHasTheDocumentedLayout) {
    for (int L : {8, 9, 16, 31, 256}) {
        SCOPED_TRACE(L);
        const auto m = makeArrow(L);
        const VoxelGrid& g = m->frame(0);
        ASSERT_EQ(g.dims(), glm::ivec3(L, 5, 5));
        EXPECT_EQ(g.data(), documentedArrow(L).data());
        EXPECT_EQ(countSolid(g), L + 40);
    }
    EXPECT_EQ(makeArrow()->frame(0).solidCount(), 56u);
}

TEST(Procedural, ArrowPartsPointTheDocumentedWays) {
    const auto model = makeArrow(16);
    const VoxelGrid& g = model->frame(0);
    // Head at +X: the widest slice is near the +X end, the tip is the last voxel.
    EXPECT_EQ(g.at({15, 2, 2}), proc_index::kGreen);
    EXPECT_EQ(g.at({0, 2, 2}), proc_index::kRed);
    // Fin above the tail (+Z), nothing below the shaft except the head.
    EXPECT_EQ(g.at({0, 2, 4}), proc_index::kBlue);
    EXPECT_EQ(g.at({0, 2, 0}), 0);
    // Stub towards +Y, nothing at -Y except the head.
    EXPECT_EQ(g.at({8, 4, 2}), proc_index::kYellow);
    EXPECT_EQ(g.at({8, 0, 2}), 0);
    for (int x = 0; x < 13; ++x)
        for (int y = 0; y < 5; ++y)
            for (int z = 0; z < 5; ++z) {
                if (y < 2 || z < 2) {
                    ASSERT_EQ(g.at({x, y, z}), 0) << x << "," << y << "," << z;
                }
            }
}

TEST(Procedural, NoAxisPermutationOrFlipMapsTheArrowOntoItself) {
    // Any signed permutation that keeps the (L, 5, 5) dims: x stays x, y/z may swap, any flips.
    const auto model = makeArrow(16);
    const VoxelGrid& g = model->frame(0);
    const glm::ivec3 d = g.dims();
    for (int swapYZ = 0; swapYZ < 2; ++swapYZ)
        for (int flips = 0; flips < 8; ++flips) {
            if (!swapYZ && flips == 0) continue; // identity
            bool same = true;
            for (int z = 0; z < d.z && same; ++z)
                for (int y = 0; y < d.y && same; ++y)
                    for (int x = 0; x < d.x && same; ++x) {
                        glm::ivec3 q{x, swapYZ ? z : y, swapYZ ? y : z};
                        for (int a = 0; a < 3; ++a)
                            if (flips & (1 << a)) q[a] = d[a] - 1 - q[a];
                        same = g.at({x, y, z}) == g.at(q);
                    }
            EXPECT_FALSE(same) << "swapYZ=" << swapYZ << " flips=" << flips;
        }
}

TEST(Procedural, SingleVoxelIsOneVoxelOfTheIndex) {
    const auto m = makeSingleVoxel(255);
    EXPECT_EQ(m->frame(0).dims(), glm::ivec3(1));
    EXPECT_EQ(m->frame(0).at({0, 0, 0}), 255);
    EXPECT_EQ(makeSingleVoxel()->frame(0).at({0, 0, 0}), 1);
}

/// Entries 1..255 are opaque, not the outline's black, and pairwise distinct.
void expectOpaqueDistinctAndNeverBlack(const Palette& p) {
    std::set<Rgba8> seen;
    for (int i = 1; i < 256; ++i) {
        const Rgba8 c = p.colors[std::size_t(i)];
        EXPECT_EQ(channel(c, 3), 255u) << i;
        EXPECT_NE(c & 0xffffffu, 0u) << i;
        EXPECT_TRUE(seen.insert(c).second) << "duplicate colour at index " << i;
    }
}

TEST(Procedural, PaletteEntriesAreOpaqueDistinctAndNeverOutlineBlack) {
    const Palette& p = proceduralPalette();
    EXPECT_EQ(channel(p.colors[0], 3), 0u);
    expectOpaqueDistinctAndNeverBlack(p);
    // 1..8 are saturated: a large spread between the strongest and weakest channel.
    for (int i = 1; i <= 8; ++i) {
        const Rgba8 c = p.colors[std::size_t(i)];
        const unsigned hi = std::max({channel(c, 0), channel(c, 1), channel(c, 2)});
        const unsigned lo = std::min({channel(c, 0), channel(c, 1), channel(c, 2)});
        EXPECT_GE(hi - lo, 150u) << i;
    }
    EXPECT_EQ(p.colors[254], packRgba(254, 1, 128));
    EXPECT_EQ(p.colors[255], packRgba(255, 0, 128));
    for (const auto& m :
         {makeBox({2, 2, 2}), makeSphere(2), makeArrow(), makeShell({4, 4, 4}), makeSingleVoxel()})
        EXPECT_EQ(m->palette(), p) << m->name();
}

TEST(Procedural, OutOfRangeParametersAreInputErrors) {
    EXPECT_THROW(makeSphere(0), InputError);
    EXPECT_THROW(makeSphere(129), InputError);
    EXPECT_NO_THROW(makeSphere(128));
    EXPECT_THROW(makeArrow(7), InputError);
    EXPECT_THROW(makeArrow(257), InputError);
    EXPECT_THROW(makeShell({4, 4, 4}, 0), InputError);
    EXPECT_THROW(makeBox({0, 4, 4}), InputError);
    EXPECT_THROW(makeBox({4, 257, 4}), InputError);
}

// The tank (the bench's tank army). Its layout is drawn from a seed, so these tests pin the
// properties the bench relies on, each computed here from the voxels alone.

/// Voxel p of `g` mapped by flipping the axes whose bit is set in `flips`.
bool equalUnderFlips(const VoxelGrid& g, int flips) {
    const glm::ivec3 d = g.dims();
    for (int z = 0; z < d.z; ++z)
        for (int y = 0; y < d.y; ++y)
            for (int x = 0; x < d.x; ++x) {
                glm::ivec3 q{x, y, z};
                for (int a = 0; a < 3; ++a)
                    if (flips & (1 << a)) q[a] = d[a] - 1 - q[a];
                if (g.at({x, y, z}) != g.at(q)) return false;
            }
    return true;
}

TEST(Procedural, TankHasTheSeedsDimsFramesAndIsDeterministic) {
    const auto t = makeTank(7);
    EXPECT_EQ(t->name(), "tank");
    ASSERT_EQ(t->frameCount(), 8);
    for (int f = 0; f < 8; ++f) EXPECT_EQ(t->frame(f).dims(), glm::ivec3(32, 32, 16)) << f;
    const auto again = makeTank(7);
    for (int f = 0; f < 8; ++f) EXPECT_EQ(t->frame(f).data(), again->frame(f).data()) << f;
    EXPECT_NE(t->uid(), again->uid());
    const auto custom = makeTank(7, 3, {64, 48, 24});
    ASSERT_EQ(custom->frameCount(), 3);
    EXPECT_EQ(custom->frame(2).dims(), glm::ivec3(64, 48, 24));
    EXPECT_EQ(makeTank(7, 1)->frameCount(), 1);
}

TEST(Procedural, TankTypesDifferBySeedAndNoMirrorMapsATankOntoItself) {
    std::vector<std::vector<std::uint8_t>> types;
    for (std::uint64_t seed = 1; seed <= 10; ++seed) {
        SCOPED_TRACE(seed);
        const auto t = makeTank(seed, 2);
        const VoxelGrid& g = t->frame(0);
        for (const auto& other : types) EXPECT_NE(g.data(), other);
        types.push_back(g.data());
        // Mirror in x, in y, and the half turn about z (x and y flipped together).
        for (int flips : {1, 2, 3}) EXPECT_FALSE(equalUnderFlips(g, flips)) << "flips=" << flips;
        // The voxels reach the front, back, bottom and top of the grid.
        const Box3i b = g.contentBounds();
        EXPECT_EQ(b.min.x, 0);
        EXPECT_EQ(b.max.x, 32);
        EXPECT_EQ(b.min.z, 0);
        EXPECT_EQ(b.max.z, 16);
        // It stands on two tracks: the bottom layer is empty in the middle quarter of the width.
        for (int y = 12; y < 20; ++y)
            for (int x = 0; x < 32; ++x) ASSERT_EQ(g.at({x, y, 0}), 0) << x << "," << y;
        // Solid enough to be a vehicle, far from full.
        EXPECT_GT(g.solidCount(), 32u * 32u * 16u / 5u);
        EXPECT_LT(g.solidCount(), 32u * 32u * 16u * 3u / 4u);
    }
}

TEST(Procedural, TankFramesAllDifferAndTheTreadsRollOneVoxelPerFrame) {
    const auto t = makeTank(3, 8);
    for (int a = 0; a < 8; ++a)
        for (int b = a + 1; b < 8; ++b)
            EXPECT_NE(t->frame(a).data(), t->frame(b).data()) << a << " vs " << b;
    // The bottom row of the low-Y track (the first y with a voxel on the ground) moves by +1 in
    // x per frame, away from the rounded ends.
    int y = 0;
    while (y < 32 && t->frame(0).at({16, y, 0}) == 0) ++y;
    ASSERT_LT(y, 12);
    for (int f = 0; f + 1 < 8; ++f)
        for (int x = 3; x < 29; ++x) {
            ASSERT_NE(t->frame(f).at({x, y, 0}), 0) << f << "," << x;
            ASSERT_EQ(t->frame(f + 1).at({x, y, 0}), t->frame(f).at({x - 1, y, 0}))
                << f << "," << x;
        }
    // The treads are not uniform, so rolling is visible.
    std::set<std::uint8_t> row;
    for (int x = 3; x < 29; ++x) row.insert(t->frame(0).at({x, y, 0}));
    EXPECT_GE(row.size(), 2u);
}

TEST(Procedural, TankPaletteIsOpaqueDistinctAndNeverOutlineBlack) {
    const Palette& p = tankPalette();
    expectOpaqueDistinctAndNeverBlack(p);
    EXPECT_EQ(makeTank(1)->palette(), p);
    // Every voxel of every frame uses an entry the palette defines on purpose (32..47).
    const auto t = makeTank(5, 4);
    for (int f = 0; f < 4; ++f)
        for (auto v : t->frame(f).data()) ASSERT_TRUE(v == 0 || (v >= 32 && v <= 47)) << int(v);
}

TEST(Procedural, TankParametersOutOfRangeAreInputErrors) {
    EXPECT_THROW(makeTank(1, 0), InputError);
    EXPECT_THROW(makeTank(1, Limits::kMaxFramesPerModel + 1), InputError);
    EXPECT_THROW(makeTank(1, 1, {7, 32, 16}), InputError);
    EXPECT_THROW(makeTank(1, 1, {32, 32, 257}), InputError);
    EXPECT_NO_THROW(makeTank(1, 1, {8, 8, 8}));
}

TEST(Procedural, EveryCallReturnsAFreshModelWithItsOwnUid) {
    // Tests edit these models; two calls must never share state.
    const auto a = makeBox({2, 2, 2}), b = makeBox({2, 2, 2});
    EXPECT_NE(a->uid(), b->uid());
    a->setVoxel(0, {0, 0, 0}, 0);
    EXPECT_EQ(b->frame(0).at({0, 0, 0}), 1);
}

} // namespace
} // namespace voxtier
