// The far tier's view sets (CONTRACT.md §4): sizes, the documented order, unit directions on the
// cube lattice, the nearest-view choice and the angular gaps CONTRACT.md §4 quotes.
#include "core/view_set.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <set>

namespace voxtier {
namespace {

TEST(ViewSets, SizesAre26_98_218AndEveryPointIsOnTheCubeSurface) {
    for (auto [set, n] :
         {std::pair{ViewSet::Cube26, 1}, {ViewSet::Cube98, 2}, {ViewSet::Cube218, 3}}) {
        const auto& pts = viewLatticePoints(set);
        const auto& dirs = viewDirections(set);
        EXPECT_EQ(int(pts.size()), viewCount(set));
        EXPECT_EQ(dirs.size(), pts.size());
        std::set<std::tuple<int, int, int>> seen;
        for (std::size_t i = 0; i < pts.size(); ++i) {
            const glm::ivec3 p = pts[i];
            EXPECT_EQ(std::max({std::abs(p.x), std::abs(p.y), std::abs(p.z)}), n);
            EXPECT_TRUE(seen.insert({p.x, p.y, p.z}).second) << "duplicate";
            EXPECT_NEAR(glm::length(dirs[i]), 1.0, 1e-15);
            EXPECT_NEAR(glm::length(glm::cross(dirs[i], glm::dvec3(p))), 0.0, 1e-12);
        }
    }
    EXPECT_EQ(viewSetFromSize(98), ViewSet::Cube98);
    EXPECT_THROW(viewSetFromSize(27), std::exception);
}

TEST(ViewSets, CanonicalOrderFacesThenEdgesThenCornersAndAPrefixOfEverySet) {
    const auto& c = viewLatticePoints(ViewSet::Cube26);
    const std::vector<glm::ivec3> faces = {{1, 0, 0},  {-1, 0, 0}, {0, 1, 0},
                                           {0, -1, 0}, {0, 0, 1},  {0, 0, -1}};
    for (int i = 0; i < 6; ++i) EXPECT_EQ(c[std::size_t(i)], faces[std::size_t(i)]);
    auto nonZero = [](glm::ivec3 p) { return (p.x != 0) + (p.y != 0) + (p.z != 0); };
    for (int i = 6; i < 18; ++i) EXPECT_EQ(nonZero(c[std::size_t(i)]), 2) << i;
    for (int i = 18; i < 26; ++i) EXPECT_EQ(nonZero(c[std::size_t(i)]), 3) << i;
    EXPECT_EQ(c[6], glm::ivec3(1, 1, 0));
    EXPECT_EQ(c[18], glm::ivec3(1, 1, 1));
    EXPECT_EQ(c[25], glm::ivec3(-1, -1, -1));
    // Face views are exact axis vectors.
    EXPECT_EQ(viewDirections(ViewSet::Cube26)[3], glm::dvec3(0, -1, 0));
    for (ViewSet set : {ViewSet::Cube98, ViewSet::Cube218})
        for (int i = 0; i < 26; ++i)
            EXPECT_EQ(viewDirections(set)[std::size_t(i)],
                      viewDirections(ViewSet::Cube26)[std::size_t(i)]);
}

TEST(ViewSets, NearestViewOfAViewIsItselfAndOfANeighbourhoodToo) {
    for (ViewSet set : {ViewSet::Cube26, ViewSet::Cube98, ViewSet::Cube218}) {
        const auto& dirs = viewDirections(set);
        for (int i = 0; i < viewCount(set); ++i) {
            EXPECT_EQ(nearestView(set, dirs[std::size_t(i)]), i);
            const glm::dvec3 nudged =
                glm::normalize(dirs[std::size_t(i)] + glm::dvec3(0.01, -0.02, 0.015));
            EXPECT_EQ(nearestView(set, nudged), i);
        }
    }
}

// nearestView compares only the views in the direction's octant where it can (core/view_set.cpp):
// the same index as comparing every view, the first of equal dots included, over random
// directions of any length, directions with components exactly 0, tiny, subnormal or of either
// zero's sign, ties between views (the diagonals, the edges), every view and its neighbours,
// and the zero, infinite and NaN vectors.
TEST(ViewSets, NearestViewEqualsComparingEveryView) {
    const auto everyView = [](ViewSet set, glm::dvec3 t) {
        const auto& dirs = viewDirections(set);
        int best = 0;
        double bestDot = glm::dot(dirs[0], t);
        for (int i = 1; i < int(dirs.size()); ++i) {
            const double d = glm::dot(dirs[std::size_t(i)], t);
            if (d > bestDot) bestDot = d, best = i;
        }
        return best;
    };
    std::vector<glm::dvec3> ts;
    std::uint64_t state = 12345;
    const auto uniform = [&] { // xorshift64*, in [-1, 1)
        state ^= state >> 12, state ^= state << 25, state ^= state >> 27;
        return double((state * 2685821657736338717ull) >> 11) * 0x1p-52 - 1.0;
    };
    for (int k = 0; k < 200000; ++k) {
        const glm::dvec3 r{uniform(), uniform(), uniform()};
        ts.push_back(r);
        ts.push_back(r * 1e-150);
        ts.push_back(r * 1e150);
    }
    const double specials[] = {0.0,   -0.0,  1e-300, -1e-300, 4.9e-324, 1e-17, -1e-12,
                               1e-10, -1e-9, 1e-8,   0.5,     -1.0,     1.0};
    for (double a : specials)
        for (double b : specials)
            for (double c : {0.0, -0.0, 1.0, -1.0, 1e-9, 0.7071067811865476})
                ts.push_back({a, b, c}), ts.push_back({c, a, b}), ts.push_back({b, c, a});
    for (ViewSet set : {ViewSet::Cube26, ViewSet::Cube98, ViewSet::Cube218})
        for (const glm::dvec3 w : viewDirections(set))
            for (double e : {0.0, 1e-15, 1e-9, 1e-3})
                for (const glm::dvec3 n : {glm::dvec3(e, -e, e), glm::dvec3(-e, 2 * e, e)})
                    ts.push_back(w + n), ts.push_back((w + n) * 3.0);
    const double inf = std::numeric_limits<double>::infinity();
    ts.push_back({inf, 1.0, 0.5}), ts.push_back({-inf, inf, 1.0});
    ts.push_back({std::nan(""), 1.0, 1.0}), ts.push_back({0.0, 0.0, 0.0});
    for (ViewSet set : {ViewSet::Cube26, ViewSet::Cube98, ViewSet::Cube218})
        for (const glm::dvec3 t : ts)
            ASSERT_EQ(nearestView(set, t), everyView(set, t))
                << viewCount(set) << " views, t = (" << t.x << ", " << t.y << ", " << t.z << ")";
}

// CONTRACT.md §4: worst gap to the nearest of the 26 is about 27.5 degrees, mean about 15.5; the
// denser sets shrink it.
TEST(ViewSets, AngularGapToTheNearestViewMatchesTheDesignFigures) {
    auto gaps = [](ViewSet set) {
        double worst = 0.0, sum = 0.0;
        const int n = 20000;
        for (int k = 0; k < n; ++k) { // Fibonacci sphere
            const double z = 1.0 - (2.0 * k + 1.0) / n, r = std::sqrt(1.0 - z * z);
            const double phi = k * 2.399963229728653;
            const glm::dvec3 d(r * std::cos(phi), r * std::sin(phi), z);
            const glm::dvec3 w = viewDirections(set)[std::size_t(nearestView(set, d))];
            const double a = glm::degrees(std::acos(std::clamp(glm::dot(w, d), -1.0, 1.0)));
            worst = std::max(worst, a);
            sum += a;
        }
        return std::pair{worst, sum / n};
    };
    const auto [w26, m26] = gaps(ViewSet::Cube26);
    EXPECT_NEAR(w26, 27.5, 0.6);
    EXPECT_NEAR(m26, 15.5, 0.6);
    EXPECT_LT(gaps(ViewSet::Cube98).first, w26);
    EXPECT_LT(gaps(ViewSet::Cube218).first, gaps(ViewSet::Cube98).first);
}

} // namespace
} // namespace voxtier
