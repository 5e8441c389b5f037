// The tier selector's hysteresis contract (CONTRACT.md §5), on synthetic metric sequences.
#include "lod/selector.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

namespace voxtier {
namespace {

SelectorConfig distanceBand(double nearAt, double farAt) {
    SelectorConfig c;
    c.nearAt = nearAt;
    c.farAt = farAt;
    return c;
}

/// Runs one entity through a sequence of distances; returns the switch count and final tier.
struct SelectorRun {
    int switches = 0;
    Tier last = Tier::Near;
};
SelectorRun runDistances(TierSelector& sel, const std::vector<double>& distances) {
    SelectorRun r;
    for (double d : distances) {
        SelectorInput in;
        in.distance = d;
        const SelectorStats st = sel.update(std::span<const SelectorInput>(&in, 1));
        r.switches += st.switchesToFar + st.switchesToNear;
        r.last = sel.tier(0);
    }
    return r;
}

// A camera oscillating around either threshold with amplitude below (far_at - near_at)/2
// switches once (the first crossing) and never again.
TEST(Hysteresis, SmallOscillationAroundEitherThresholdSwitchesOnlyOnce) {
    const double nearAt = 30, farAt = 40, amplitude = 0.49 * (farAt - nearAt);
    for (double centre : {farAt, nearAt}) {
        TierSelector sel(distanceBand(nearAt, farAt));
        std::vector<double> d;
        // Approach from the opposite side of the band so the first crossing happens.
        d.push_back(centre == farAt ? 10.0 : 60.0);
        for (int k = 0; k < 400; ++k) d.push_back(centre + amplitude * std::sin(0.37 * k));
        const SelectorRun r = runDistances(sel, d);
        EXPECT_EQ(r.switches, 1) << "around " << centre;
    }
}

// A camera crossing the whole band back and forth switches exactly once per crossing.
TEST(Hysteresis, EachCrossingSwitchesExactlyOnce) {
    TierSelector sel(distanceBand(30, 40));
    std::vector<double> d;
    const int crossings = 6;
    for (int c = 0; c < crossings; ++c)
        for (int k = 0; k <= 50; ++k) d.push_back(c % 2 == 0 ? 10.0 + k : 60.0 - k);
    const SelectorRun r = runDistances(sel, d);
    // Every pass crosses the whole band: 10 -> 60 (to far), 60 -> 10 (to near), ...
    EXPECT_EQ(r.switches, crossings);
}

// Exactly on a threshold nothing switches; strictly past it does. Deterministic.
TEST(Hysteresis, ThresholdHitExactlyDoesNotSwitch) {
    TierSelector sel(distanceBand(30, 40));
    EXPECT_EQ(runDistances(sel, {20, 40, 40, 40}).last, Tier::Near);
    EXPECT_EQ(runDistances(sel, {std::nextafter(40.0, 100.0)}).last, Tier::Far);
    EXPECT_EQ(runDistances(sel, {30, 30}).last, Tier::Far);
    EXPECT_EQ(runDistances(sel, {std::nextafter(30.0, 0.0)}).last, Tier::Near);
}

TEST(Hysteresis, FirstFrameAssignsTiersWithoutCountingSwitches) {
    TierSelector sel(distanceBand(30, 40));
    std::vector<SelectorInput> in(3);
    in[0].distance = 5;
    in[1].distance = 35; // inside the band: starts near
    in[2].distance = 100;
    const SelectorStats st = sel.update(in);
    EXPECT_EQ(st.switchesToFar + st.switchesToNear, 0);
    EXPECT_EQ(st.nearCount, 2);
    EXPECT_EQ(st.farCount, 1);
    EXPECT_EQ(sel.tier(1), Tier::Near);
    EXPECT_EQ(sel.tier(2), Tier::Far);
}

// Projected radius shrinks with distance: the band is mirrored (near_at > far_at).
TEST(Hysteresis, PixelMetricsUseTheMirroredBand) {
    TierSelector sel(defaultSelectorFor(SelectorMetric::RadiusPx)); // near 24 px, far 16 px
    auto step = [&](double r) {
        SelectorInput in;
        in.radiusPx = r;
        sel.update(std::span<const SelectorInput>(&in, 1));
        return sel.tier(0);
    };
    EXPECT_EQ(step(50), Tier::Near);
    EXPECT_EQ(step(20), Tier::Near); // inside the band
    EXPECT_EQ(step(15.9), Tier::Far);
    EXPECT_EQ(step(23), Tier::Far); // inside the band
    EXPECT_EQ(step(24.1), Tier::Near);
}

TEST(Metric, ErrorMetricIsRadiusTimesSineOfViewAngle) {
    SelectorInput in;
    in.radiusPx = 40;
    in.viewCos = std::cos(glm::radians(30.0));
    EXPECT_NEAR(selectorMetric(SelectorMetric::ErrorPx, in), 20.0, 1e-12);
    EXPECT_EQ(selectorMetric(SelectorMetric::RadiusPx, in), 40.0);
}

// The side of a threshold, written here from the IEEE value, as the selector compared before it
// skipped std::acos and std::sin where a bound decides.
int ieeeSide(const SelectorInput& in, double threshold) {
    const double m = in.radiusPx * std::sin(std::acos(in.viewCos));
    return m > threshold ? 1 : m < threshold ? -1 : 0;
}

// error_px's comparisons are the IEEE value's, bit for bit, on thresholds anywhere and at the
// value itself, a unit in the last place or a few either side (where only the IEEE value can
// tell); and far from the threshold the bound decides without it. With no slack in the bound,
// the thresholds next to the value fail; deciding nothing fails the last count.
TEST(Metric, ErrorPxSideEqualsTheIeeeComparison) {
    std::mt19937_64 rng(35);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    int compared = 0, decidedFar = 0, farCases = 0;
    const auto check = [&](const SelectorInput& in, double t) {
        ++compared;
        ASSERT_EQ(metricSide(SelectorMetric::ErrorPx, in, t), ieeeSide(in, t))
            << "viewCos " << in.viewCos << " radiusPx " << in.radiusPx << " threshold " << t;
    };
    for (int k = 0; k < 200000; ++k) {
        SelectorInput in;
        // Cosines from -1 to 1, most between the nearest view's 0.5 and 1 and many next to 1
        // (an entity looking almost along a view).
        const double u = unit(rng);
        in.viewCos = k % 4 == 0   ? 2.0 * u - 1.0
                     : k % 4 == 1 ? 1.0 - std::ldexp(u, -int(unit(rng) * 60.0))
                                  : 0.5 + 0.5 * u;
        in.radiusPx = std::ldexp(0.5 + unit(rng), int(unit(rng) * 40.0) - 20);
        const double m = in.radiusPx * std::sin(std::acos(in.viewCos));
        double t = m;
        for (int step = 0; step < 4; ++step) { // the value and three ulps up, then down
            check(in, t);
            t = std::nextafter(t, HUGE_VAL);
        }
        t = m;
        for (int step = 0; step < 4; ++step) {
            check(in, t);
            t = std::nextafter(t, -HUGE_VAL);
        }
        for (const double rel : {1e-15, 1e-12, 1e-10, 2e-9, 1e-6, 0.01, 0.5})
            for (const double sign : {-1.0, 1.0}) check(in, m * (1.0 + sign * rel));
        if (in.viewCos >= 0.5 && m > 1e-150)
            for (const double sign : {-1.0, 1.0}) {
                ++farCases;
                decidedFar += metricSideFast(in, m * (1.0 + sign * 1e-6)) == -int(sign);
            }
        if (::testing::Test::HasFatalFailure()) return;
    }
    // What the bound must leave to the IEEE value: cosines outside [0.5, 1], radii and
    // thresholds that are not positive, finite and normal, NaNs.
    const double nan = std::nan(""), inf = HUGE_VAL;
    for (const double c : {-1.0, -0.0, 0.0, 0.25, std::nextafter(0.5, 0.0), 0.5, 1.0,
                           std::nextafter(1.0, 0.0), inf, nan})
        for (const double r : {0.0, 4.9e-324, 1e-300, 1e-200, 1.0, 40.0, 1e200, 1e300, inf, nan})
            for (const double t : {-1.0, 0.0, 4.9e-324, 1e-250, 0.5, 1.0, 1e250, inf, nan}) {
                SelectorInput in;
                in.viewCos = c, in.radiusPx = r;
                check(in, t);
                if (::testing::Test::HasFatalFailure()) return;
            }
    EXPECT_GT(compared, 3000000);
    EXPECT_EQ(decidedFar, farCases) << "a millionth from the threshold, the bound decides";
}

// The selector's tiers under error_px equal a selector written here from the IEEE metric, over
// frames whose metrics sit on, a unit in the last place beside, and far from both thresholds.
TEST(Metric, ErrorPxTiersEqualTheIeeeSelector) {
    SelectorConfig c;
    c.metric = SelectorMetric::ErrorPx;
    c.nearAt = 1.0;
    c.farAt = 0.5;
    const int n = 4096;
    TierSelector sel(c);
    std::vector<Tier> expected(std::size_t(n), Tier::Near);
    std::vector<SelectorInput> in{std::size_t(n)};
    std::mt19937_64 rng(7);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    for (int frame = 0; frame < 24; ++frame) {
        for (int i = 0; i < n; ++i) {
            SelectorInput& e = in[std::size_t(i)];
            e.viewCos = 0.5 + 0.5 * unit(rng);
            const double sine = std::sin(std::acos(e.viewCos));
            // A radius that puts the metric on a threshold (to the ulp), next to it, or anywhere.
            const double t = (i + frame) % 2 ? c.nearAt : c.farAt;
            const int kind = int(unit(rng) * 4.0);
            e.radiusPx = kind == 3 ? unit(rng) * 4.0 / sine : t / sine;
            if (kind == 1) e.radiusPx = std::nextafter(e.radiusPx, HUGE_VAL);
            if (kind == 2) e.radiusPx = std::nextafter(e.radiusPx, 0.0);
        }
        sel.update(in);
        for (int i = 0; i < n; ++i) {
            const SelectorInput& e = in[std::size_t(i)];
            const double m = e.radiusPx * std::sin(std::acos(e.viewCos));
            Tier& t = expected[std::size_t(i)];
            if (frame == 0)
                t = m < c.farAt ? Tier::Far : Tier::Near;
            else if (t == Tier::Near && m < c.farAt)
                t = Tier::Far;
            else if (t == Tier::Far && m > c.nearAt)
                t = Tier::Near;
            ASSERT_EQ(sel.tier(std::size_t(i)), t) << "entity " << i << " frame " << frame;
        }
    }
}

// View choice: without hysteresis the nearest view wins (switching exactly at the bisector);
// with delta degrees of hysteresis a direction wobbling around the bisector never flips views.
TEST(ViewHysteresis, WobbleAroundViewBoundaryDoesNotFlipWithHysteresis) {
    const std::vector<glm::dvec3> views = {{1, 0, 0}, {0, 1, 0}};
    auto dirAt = [](double deg) {
        return glm::dvec3(std::cos(glm::radians(deg)), std::sin(glm::radians(deg)), 0.0);
    };
    for (double delta : {0.0, 5.0}) {
        SelectorConfig c;
        c.viewHysteresisDeg = delta;
        TierSelector sel(c);
        SelectorInput in;
        in.distance = 100;
        sel.update(std::span<const SelectorInput>(&in, 1));
        int changes = 0;
        sel.chooseView(0, dirAt(40), views);
        for (int k = 0; k < 200; ++k) {
            sel.update(std::span<const SelectorInput>(&in, 1));
            sel.chooseView(0, dirAt(45.0 + 2.0 * std::sin(0.5 * k)), views); // wobble +-2 degrees
            changes += sel.viewChangesThisFrame();
        }
        if (delta == 0.0)
            EXPECT_GT(changes, 10);
        else
            EXPECT_EQ(changes, 0);
        // Past the bisector by more than delta it does switch.
        sel.update(std::span<const SelectorInput>(&in, 1));
        EXPECT_EQ(sel.chooseView(0, dirAt(45.0 + delta + 3.0), views), 1);
    }
}

TEST(CrossFade, FractionRisesOverTheConfiguredFramesThenStops) {
    SelectorConfig c = distanceBand(30, 40);
    c.crossfadeFrames = 3;
    TierSelector sel(c);
    runDistances(sel, {10});
    runDistances(sel, {50}); // switch to far
    std::vector<float> seen;
    for (int k = 0; k < 5; ++k) {
        float f = -1;
        Tier from = Tier::Far;
        if (sel.fading(0, &f, &from)) {
            EXPECT_EQ(from, Tier::Near);
            seen.push_back(f);
        }
        runDistances(sel, {50});
    }
    ASSERT_EQ(seen.size(), 3u);
    EXPECT_FLOAT_EQ(seen[0], 0.25f);
    EXPECT_FLOAT_EQ(seen[1], 0.5f);
    EXPECT_FLOAT_EQ(seen[2], 0.75f);
}

TEST(CrossFade, DitherIsTheStandardFourByFourBayerMatrix) {
    const int bayer[4][4] = {{0, 8, 2, 10}, {12, 4, 14, 6}, {3, 11, 1, 9}, {15, 7, 13, 5}};
    for (int y = 0; y < 8; ++y)
        for (int x = 0; x < 8; ++x)
            EXPECT_EQ(ditherThreshold(x, y), (bayer[y % 4][x % 4] + 0.5f) / 16.0f) << x << "," << y;
}

TEST(CrossFade, DitherShowsTheRequestedShareOfPixels) {
    for (float f : {0.25f, 0.5f, 0.75f}) {
        int shown = 0;
        for (int y = 0; y < 64; ++y)
            for (int x = 0; x < 64; ++x) shown += ditherThreshold(x, y) < f;
        EXPECT_EQ(shown, int(f * 64 * 64));
    }
}

} // namespace
} // namespace voxtier
