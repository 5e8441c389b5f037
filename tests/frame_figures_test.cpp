// The table of frame figures (compose/frame_figures.hpp): the medians, the path aggregates and
// the CSV text it drives, checked against values worked out here field by field.
#include "compose/frame_figures.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <set>
#include <string>
#include <string_view>
#include <vector>

namespace voxtier {
namespace {

TEST(FrameFigures, NamesAreUniqueAndLookUpByMember) {
    std::set<std::string> names;
    for (const FrameFigure& f : kFrameFigures) EXPECT_TRUE(names.insert(f.name).second) << f.name;
    // The results.csv names a script reads keep their meaning.
    static_assert(std::string_view(kFrameFigures[frameFigureIndex(&FrameStats::totalMs)].name) ==
                  "frame_ms");
    EXPECT_STREQ(kFrameFigures[frameFigureIndex(&FrameStats::bakeMs)].name, "far_lookup_bake_ms");
    EXPECT_STREQ(kFrameFigures[frameFigureIndex(&FrameStats::nearPixelsTested)].name,
                 "near_fragments");
    EXPECT_EQ(kFrameFigures[frameFigureIndex(&FrameStats::cacheBytes)].acrossFrames,
              AcrossFrames::Worst);
}

TEST(FrameFigures, WordsDropTheMillisecondUnitOnly) {
    EXPECT_EQ(kFrameFigures[frameFigureIndex(&FrameStats::hostReadbackMs)].words(),
              "host readback");
    EXPECT_EQ(kFrameFigures[frameFigureIndex(&FrameStats::bakeMs)].words(), "far lookup bake");
    EXPECT_EQ(kFrameFigures[frameFigureIndex(&FrameStats::cacheBytes)].words(), "cache bytes");
}

TEST(FrameFigures, MedianOfRepeatsIsTakenFigureByFigure) {
    std::vector<FrameStats> repeats(3);
    repeats[0].totalMs = 5.0, repeats[1].totalMs = 1.0, repeats[2].totalMs = 3.0;
    repeats[0].nearDrawn = 7, repeats[1].nearDrawn = 9, repeats[2].nearDrawn = 8;
    repeats[0].voxelFetches = 100, repeats[1].voxelFetches = 300, repeats[2].voxelFetches = 200;
    repeats[0].cacheBytes = 4, repeats[1].cacheBytes = 4, repeats[2].cacheBytes = 4;
    const FrameStats m = medianOf(repeats);
    EXPECT_EQ(m.totalMs, 3.0);
    EXPECT_EQ(m.nearDrawn, 8);
    EXPECT_EQ(m.voxelFetches, 200u);
    EXPECT_EQ(m.cacheBytes, 4u);
    EXPECT_EQ(m.farDrawn, 0);
    // An even count takes the mean of the middle two; a count is truncated as before (int()).
    repeats.pop_back();
    const FrameStats even = medianOf(repeats);
    EXPECT_EQ(even.totalMs, 3.0);
    EXPECT_EQ(even.nearDrawn, 8); // (7 + 9) / 2
    repeats[1].nearDrawn = 8;
    EXPECT_EQ(medianOf(repeats).nearDrawn, 7); // 7.5 -> 7
}

TEST(FrameFigures, PathFiguresAverageTimesAndCountsAndKeepTheWorstMemory) {
    std::vector<FrameStats> frames(4);
    for (int i = 0; i < 4; ++i) {
        frames[std::size_t(i)].totalMs = 10.0 * (i + 1); // 10, 20, 30, 40
        frames[std::size_t(i)].farBakes = i;             // 0, 1, 2, 3
        frames[std::size_t(i)].cacheBytes = std::uint64_t(i == 2 ? 900 : 100);
    }
    const PathFigures p = acrossFrames(frames);
    EXPECT_DOUBLE_EQ(p.of(&FrameStats::totalMs), 25.0);
    EXPECT_DOUBLE_EQ(p.of(&FrameStats::farBakes), 1.5);
    EXPECT_DOUBLE_EQ(p.of(&FrameStats::cacheBytes), 900.0);
    EXPECT_DOUBLE_EQ(p.of(&FrameStats::entities), 0.0);
    EXPECT_EQ(acrossFrames({}).of(&FrameStats::totalMs), 0.0);
}

TEST(FrameFigures, CsvRowHasOneFieldPerHeaderNameWithIntegersExact) {
    FrameStats s;
    s.entities = 12;
    s.hostSetupMs = 1.23456;
    s.farCellsRetraced = 123456789012ull;
    const std::string header = figureCsvHeader(), row = figureCsvRow(s);
    EXPECT_EQ(std::count(header.begin(), header.end(), ','), std::ptrdiff_t(kFrameFigureCount) - 1);
    EXPECT_EQ(std::count(row.begin(), row.end(), ','), std::ptrdiff_t(kFrameFigureCount) - 1);
    EXPECT_EQ(header.substr(0, header.find(',')), kFrameFigures[0].name);
    // Field i of the row is figure i's text.
    std::vector<std::string> fields(1);
    for (char c : row) {
        if (c == ',')
            fields.emplace_back();
        else
            fields.back().push_back(c);
    }
    EXPECT_EQ(fields[frameFigureIndex(&FrameStats::entities)], "12");
    EXPECT_EQ(fields[frameFigureIndex(&FrameStats::hostSetupMs)], "1.235");
    EXPECT_EQ(fields[frameFigureIndex(&FrameStats::farCellsRetraced)], "123456789012");
}

} // namespace
} // namespace voxtier
