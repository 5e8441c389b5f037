// The tier selector's hysteresis contract (CONTRACT.md §5), on synthetic metric sequences.
#include "lod/selector.hpp"

#include <gtest/gtest.h>

#include <cmath>
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
    in.viewAngleRad = glm::radians(30.0);
    EXPECT_NEAR(selectorMetric(SelectorMetric::ErrorPx, in), 20.0, 1e-12);
    EXPECT_EQ(selectorMetric(SelectorMetric::RadiusPx, in), 40.0);
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
