// The refinement ladder of view sets (CONTRACT.md §4): nesting, sizes, and the O(1) nearest-view
// lookup against a brute-force scan of the whole level, on random directions and on the hard
// cases: the lattice points themselves, the midpoints of lattice edges and the centres of lattice
// squares (where two or four views tie).
#include "core/splitmix64.hpp"
#include "core/view_set.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <map>

namespace voxtier {
namespace {

/// Every surface point of {-n..n}^3 in lexicographic order with its direction.
struct Level {
    std::vector<glm::ivec3> points;
    std::vector<glm::dvec3> dirs;
    explicit Level(int n) {
        for (int x = -n; x <= n; ++x)
            for (int y = -n; y <= n; ++y)
                for (int z = -n; z <= n; ++z)
                    if (std::max({std::abs(x), std::abs(y), std::abs(z)}) == n) {
                        points.push_back({x, y, z});
                        dirs.push_back(viewDirection(viewIdOf(points.back())));
                    }
    }
    /// The first point in lexicographic order with the largest dot product.
    glm::ivec3 bruteForce(glm::dvec3 towardViewer) const {
        std::size_t best = 0;
        double bestDot = -2.0;
        for (std::size_t i = 0; i < dirs.size(); ++i) {
            const double d = glm::dot(dirs[i], towardViewer);
            if (d > bestDot) bestDot = d, best = i;
        }
        return points[best];
    }
};

/// Lattice points, edge midpoints (between 4-neighbours on the surface) and square centres: the
/// points where views tie, as doubles on the cube surface.
std::vector<glm::dvec3> hardPoints(const Level& level) {
    std::vector<glm::dvec3> out;
    for (glm::ivec3 p : level.points) {
        out.push_back(glm::dvec3(p));
        for (int a = 0; a < 3; ++a) {
            glm::dvec3 e = glm::dvec3(p);
            e[a] += 0.5;
            out.push_back(e);
            for (int b = a + 1; b < 3; ++b) {
                glm::dvec3 c = e;
                c[b] += 0.5;
                out.push_back(c);
            }
        }
    }
    return out;
}

TEST(ViewLadder, LevelsHaveTheStatedSizesAndEachHoldsTheCoarserDirections) {
    EXPECT_EQ(cubeSurfaceCount(1), 26);
    EXPECT_EQ(cubeSurfaceCount(2), 98);
    EXPECT_EQ(cubeSurfaceCount(64), 98306);
    for (int n : {1, 2, 4, 8}) {
        const Level level(n);
        EXPECT_EQ(static_cast<long long>(level.points.size()), cubeSurfaceCount(n));
        for (glm::ivec3 p : level.points) // scaled into the next level: the same ViewId
            EXPECT_EQ(viewIdOf(p), viewIdOf(p * 2));
    }
}

TEST(ViewLadder, NearestViewEqualsBruteForceOnRandomDirections) {
    // 1e5 seeded directions on levels up to 16; 2,000 on 32 and 64 (the scan of 98,306 views is
    // what would make more slow, not the lookup).
    for (int n : kViewLadder) {
        const Level level(n);
        SplitMix64 rng(0x13'0000u + std::uint64_t(n));
        const int count = n <= 16 ? 100'000 : 2'000;
        for (int k = 0; k < count; ++k) {
            const glm::dvec3 d(rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0),
                               rng.uniform(-1.0, 1.0));
            if (glm::length(d) < 1e-3) continue;
            ASSERT_EQ(nearestLatticePoint(n, d), level.bruteForce(d))
                << "n " << n << " d " << d.x << " " << d.y << " " << d.z;
        }
    }
}

TEST(ViewLadder, NearestViewEqualsBruteForceAtLatticePointsEdgeMidpointsAndSquareCentres) {
    // Every such point of levels up to 16 against the full scan; on 32 and 64 every lattice point
    // must find itself, and a seeded sample of 3,000 hard points is checked against the scan.
    for (int n : kViewLadder) {
        const Level level(n);
        const std::vector<glm::dvec3> hard = hardPoints(level);
        if (n <= 16) {
            for (glm::dvec3 d : hard)
                ASSERT_EQ(nearestLatticePoint(n, d), level.bruteForce(d))
                    << "n " << n << " at " << d.x << " " << d.y << " " << d.z;
        } else {
            for (glm::ivec3 p : level.points) ASSERT_EQ(nearestLatticePoint(n, glm::dvec3(p)), p);
            SplitMix64 rng(0x1300u + std::uint64_t(n));
            for (int k = 0; k < 3'000; ++k) {
                const glm::dvec3 d = hard[rng.next() % hard.size()];
                ASSERT_EQ(nearestLatticePoint(n, d), level.bruteForce(d)) << "n " << n;
            }
        }
    }
}

// The search looks within a grid of half-step cells on each face (core/view_set.cpp,
// NearestCandidates): directions whose projection lies on a cell's border or a few ulps to either
// side, where rounding picks the cell, and directions of every length the planner and the tests
// use, against the full scan.
TEST(ViewLadder, NearestViewEqualsBruteForceAcrossTheSearchsCellBorders) {
    SplitMix64 rng(0x6a11u);
    for (int n : {1, 2, 4, 8, 16}) {
        const Level level(n);
        for (int k = 0; k < 20'000; ++k) {
            const int axis = int(rng.next() % 3), b = (axis + 1) % 3, c = (axis + 2) % 3;
            glm::dvec3 t;
            t[axis] = rng.next() % 2 ? 1.0 : -1.0;
            // A border in one coordinate (a multiple of half a step, the face's edges included),
            // anywhere in the other; nudged by up to 4 ulps.
            const double border = double(int(rng.next() % std::uint64_t(4 * n + 1)) - 2 * n) / 2;
            double onB = border / n;
            for (int u = int(rng.next() % 9) - 4; u != 0; u += u > 0 ? -1 : 1)
                onB = std::nextafter(onB, u > 0 ? 2.0 : -2.0);
            t[b] = std::clamp(onB, -1.0, 1.0);
            t[c] = rng.uniform(-1.0, 1.0);
            if (rng.next() % 2) std::swap(t[b], t[c]);
            t *= std::exp2(double(int(rng.next() % 41) - 20)); // lengths 2^-20 .. 2^20
            ASSERT_EQ(nearestLatticePoint(n, t), level.bruteForce(t))
                << "n " << n << " t " << t.x << " " << t.y << " " << t.z;
        }
    }
}

// What the error budget's level scan calls per level: the nearest view with its direction read
// from the search's table (and, past the tabled levels, computed), and the prediction with what
// the sprite fixes hoisted out, are bit for bit the functions they stand for; the prediction is
// checked against CONTRACT.md section 5's formula written out here, as it read before the split.
TEST(ViewLadder, DirectedViewsAndTheHoistedPredictionAreTheFunctionsTheyStandFor) {
    SplitMix64 rng(0x5656u);
    int infinite = 0;
    for (int n : {1, 2, 4, 8, 16, 32, 64, 100}) {
        for (int k = 0; k < 20'000; ++k) {
            const glm::dvec3 t(rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0),
                               rng.uniform(-1.0, 1.0));
            if (glm::length(t) < 1e-3) continue;
            const DirectedView v = nearestDirectedLadderView(n, t);
            ASSERT_EQ(v.id, nearestLadderView(n, t)) << "n " << n;
            const glm::dvec3 w = viewDirection(v.id);
            ASSERT_TRUE(v.direction.x == w.x && v.direction.y == w.y && v.direction.z == w.z)
                << "n " << n;
            // A sprite's box, sigma and line of sight against this view and a random other.
            const glm::dvec3 half(rng.uniform(0.5, 64.0), rng.uniform(0.5, 64.0),
                                  rng.uniform(0.5, 32.0));
            const double sigma = rng.uniform(0.25, 4.0);
            const DisplacementPredictor predictor(half, sigma, t);
            const ViewId other =
                viewIdOf(glm::ivec3(int(rng.next() % 9) - 4, int(rng.next() % 9) - 4, n));
            for (const ViewId view : {v.id, other}) {
                const glm::dvec3 d = -glm::normalize(t);
                const glm::dvec3 u = glm::normalize(glm::dvec3(view.lattice));
                const double cosTheta = std::clamp(-glm::dot(u, d), -1.0, 1.0);
                const double expected = cosTheta <= 0.0
                                            ? std::numeric_limits<double>::infinity()
                                            : sigma * glm::dot(half, glm::abs(d)) *
                                                  glm::length(glm::cross(u, d)) / cosTheta;
                infinite += std::isinf(expected);
                ASSERT_EQ(predictor.vpx(viewDirection(view)), expected) << "n " << n;
                ASSERT_EQ(predictedDisplacementVpx(half, sigma, t, view), expected) << "n " << n;
            }
        }
    }
    EXPECT_GT(infinite, 1000); // views past 90 degrees were met too
}

TEST(ViewLadder, LookupAgreesWithTheClassicSetsAndGapsShrinkWithTheLevel) {
    // n = 1 and 2 are the 26 and 98 sets: the same direction wins (index order and lexicographic
    // order differ only on exact ties, which a Fibonacci sphere does not hit).
    // The largest gaps (degrees) CONTRACT.md §5 quotes, measured by a finer search: 20,000 sphere
    // points come within 0.3 degree of them and never exceed them.
    const std::map<int, double> quotedWorst{
        {1, 27.55}, {2, 17.64}, {4, 9.72}, {8, 5.00}, {16, 2.51}};
    double previousWorst = 90.0;
    for (int n : {1, 2, 4, 8, 16}) {
        double worst = 0.0;
        const int count = 20000;
        for (int k = 0; k < count; ++k) {
            const double z = 1.0 - (2.0 * k + 1.0) / count, r = std::sqrt(1.0 - z * z);
            const double phi = k * 2.399963229728653;
            const glm::dvec3 d(r * std::cos(phi), r * std::sin(phi), z);
            const glm::dvec3 w = viewDirection(nearestLadderView(n, d));
            if (n <= 2) {
                const ViewSet set = n == 1 ? ViewSet::Cube26 : ViewSet::Cube98;
                EXPECT_EQ(w, viewDirections(set)[std::size_t(nearestView(set, d))]);
            }
            worst = std::max(worst, glm::degrees(std::acos(std::clamp(glm::dot(w, d), -1.0, 1.0))));
        }
        EXPECT_LT(worst, previousWorst) << n;
        EXPECT_LE(worst, quotedWorst.at(n) + 0.01) << n;
        EXPECT_GT(worst, quotedWorst.at(n) - 0.3) << n;
        previousWorst = worst;
    }
}

} // namespace
} // namespace voxtier
