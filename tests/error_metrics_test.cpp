// The error metrics of CONTRACT.md §8 on images whose answer is known by construction.
#include "compose/error_metrics.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace voxtier {
namespace {

TEST(DistanceTransform, EqualsBruteForceOnRandomMasks) {
    std::mt19937 rng(7);
    for (int trial = 0; trial < 20; ++trial) {
        const int w = 5 + int(rng() % 40), h = 5 + int(rng() % 40);
        std::vector<std::uint8_t> m(std::size_t(w * h));
        for (auto& v : m) v = (rng() % 23) == 0;
        const auto d = squaredDistanceTransform(m, w, h);
        for (int y = 0; y < h; ++y)
            for (int x = 0; x < w; ++x) {
                double best = std::numeric_limits<double>::infinity();
                for (int yy = 0; yy < h; ++yy)
                    for (int xx = 0; xx < w; ++xx)
                        if (m[std::size_t(yy * w + xx)])
                            best =
                                std::min(best, double((x - xx) * (x - xx) + (y - yy) * (y - yy)));
                ASSERT_EQ(d[std::size_t(y * w + x)], best)
                    << "trial " << trial << " at " << x << "," << y;
            }
    }
}

Image withSquare(int x0, int y0, int size, std::uint32_t id, Rgba8 c) {
    Image img(64, 64, packRgba(0, 0, 0));
    for (int y = y0; y < y0 + size; ++y)
        for (int x = x0; x < x0 + size; ++x) {
            img.color[img.index(x, y)] = c;
            img.id[img.index(x, y)] = id;
            img.depth[img.index(x, y)] = 0.5f;
        }
    return img;
}

TEST(EntityError, ShiftedSquareReportsShiftAsDisplacement) {
    const Image truth = withSquare(10, 10, 8, 3, packRgba(200, 0, 0));
    const Image shifted = withSquare(13, 10, 8, 3, packRgba(200, 0, 0));
    const EntityError e = entityError(truth, shifted, 3);
    EXPECT_EQ(e.footprintTruth, 64u);
    EXPECT_EQ(e.footprintTest, 64u);
    EXPECT_EQ(e.unionPixels, 88u);        // 8 rows x 11 columns
    EXPECT_EQ(e.mismatched, 48u);         // 3 columns on each side
    EXPECT_EQ(e.coverageMismatched, 48u); // same colour: every mismatch is coverage
    EXPECT_DOUBLE_EQ(e.silhouetteDisplacementPx, 3.0);
}

TEST(EntityError, IdenticalFootprintWithOtherColourHasNoDisplacement) {
    const Image a = withSquare(5, 5, 6, 1, packRgba(10, 20, 30));
    const Image b = withSquare(5, 5, 6, 1, packRgba(10, 20, 31));
    const EntityError e = entityError(a, b, 1);
    EXPECT_EQ(e.mismatchFraction(), 1.0);
    EXPECT_EQ(e.coverageMismatchFraction(), 0.0);
    EXPECT_EQ(e.silhouetteDisplacementPx, 0.0);
}

TEST(EntityError, MissingEntityIsInfinitelyDisplaced) {
    const Image a = withSquare(5, 5, 6, 1, packRgba(10, 20, 30));
    const Image b(64, 64, packRgba(0, 0, 0));
    EXPECT_TRUE(std::isinf(entityError(a, b, 1).silhouetteDisplacementPx));
}

TEST(FrameError, SummaryOfIdenticalImagesIsZeroWithInfinitePsnr) {
    const Image a = withSquare(5, 5, 6, 1, packRgba(10, 20, 30));
    const auto per = entityErrors(a, a, {1});
    const FrameError f = summarize(per, a, a);
    EXPECT_EQ(f.worstMismatch, 0.0);
    EXPECT_EQ(f.rmse, 0.0);
    EXPECT_EQ(f.changedPixels, 0u);
}

} // namespace
} // namespace voxtier
