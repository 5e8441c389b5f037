// The procedural models are the fixtures of every other suite, so their layouts are checked
// against the documented formulas with independent loops, never against the generator's code.
#include "core/error.hpp"
#include "core/procedural.hpp"

#include <algorithm>
#include <array>
#include <gtest/gtest.h>
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

TEST(Procedural, PaletteEntriesAreOpaqueDistinctAndNeverOutlineBlack) {
    const Palette& p = proceduralPalette();
    EXPECT_EQ(channel(p.colors[0], 3), 0u);
    std::set<Rgba8> seen;
    for (int i = 1; i < 256; ++i) {
        const Rgba8 c = p.colors[std::size_t(i)];
        EXPECT_EQ(channel(c, 3), 255u) << i;
        EXPECT_NE(c & 0xffffffu, 0u) << i;
        EXPECT_TRUE(seen.insert(c).second) << "duplicate colour at index " << i;
    }
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

TEST(Procedural, EveryCallReturnsAFreshModelWithItsOwnUid) {
    // Tests edit these models; two calls must never share state.
    const auto a = makeBox({2, 2, 2}), b = makeBox({2, 2, 2});
    EXPECT_NE(a->uid(), b->uid());
    a->setVoxel(0, {0, 0, 0}, 0);
    EXPECT_EQ(b->frame(0).at({0, 0, 0}), 1);
}

} // namespace
} // namespace voxtier
