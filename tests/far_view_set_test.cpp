// The far tier's view sets (CONTRACT.md §4): sizes, the documented order, unit directions on the
// cube lattice, the nearest-view choice and the angular gaps CONTRACT.md §4 quotes.
#include "core/view_set.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
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
