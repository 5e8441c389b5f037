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

TEST(FrameFigures, NamesAreUniqueAndTheScriptsNamesKeepTheirMeaning) {
    std::set<std::string> names;
    for (const FrameFigure& f : kFrameFigures) EXPECT_TRUE(names.insert(f.name).second) << f.name;
    // The results.csv names a script reads keep their meaning: each reads the field it names.
    FrameStats s;
    s.totalMs = 7.5;
    s.far.ensureMs = 2.25;
    s.reference.pixelsTested = 11;
    s.cacheBytes = 4096;
    const Figures f = figuresOf(s);
    EXPECT_EQ(f["frame_ms"], 7.5);
    EXPECT_EQ(f["far_lookup_bake_ms"], 2.25);
    EXPECT_EQ(f["near_fragments"], 11.0);
    EXPECT_EQ(f["cache_bytes"], 4096.0);
    EXPECT_EQ(FigureId("cache_bytes").figure().acrossFrames, AcrossFrames::Worst);
    EXPECT_EQ(FigureId("far_predicted_worst_vpx").figure().unit, FigureUnit::Vpx);
}

// A frame's near sprites are drawn by one near backend and its far sprites by one far backend:
// a column both backends fill reads whichever drew, and each backend's own figure stays apart.
TEST(FrameFigures, AColumnOfBothNearBackendsReadsTheOneThatDrew) {
    FrameStats cpu, vulkan;
    cpu.reference.pixelsTested = 100, cpu.reference.voxelFetches = 900;
    cpu.reference.cellsTraced = 5;
    vulkan.vulkanNear.fragmentInvocations = 200, vulkan.vulkanNear.voxelFetches = 1800;
    vulkan.vulkanNear.cellsTraced = 7;
    const Figures a = figuresOf(cpu), b = figuresOf(vulkan);
    EXPECT_EQ(a["near_fragments"], 100.0);
    EXPECT_EQ(b["near_fragments"], 200.0);
    EXPECT_EQ(a["voxel_steps"], 900.0);
    EXPECT_EQ(b["voxel_steps"], 1800.0);
    EXPECT_EQ(a["near_cells_traced"], 5.0);
    EXPECT_EQ(b["near_cells_traced"], 7.0);
}

TEST(FrameFigures, TheFarBlitColumnIsTheCpuBlitOrTheFarPassesShare) {
    FrameStats cpu, vulkan;
    cpu.far.blit.milliseconds = 1.5;
    cpu.far.blit.pixelsTested = 640;
    vulkan.vulkan.farPassMs = 0.25;
    EXPECT_EQ(figuresOf(cpu)["far_blit_ms"], 1.5);
    EXPECT_EQ(figuresOf(cpu)["blit_pixels"], 640.0);
    EXPECT_EQ(figuresOf(vulkan)["far_blit_ms"], 0.25);
}

TEST(FrameFigures, WordsDropTheMillisecondUnitOnly) {
    EXPECT_EQ(FigureId("host_readback_ms").figure().words(), "host readback");
    EXPECT_EQ(FigureId("far_lookup_bake_ms").figure().words(), "far lookup bake");
    EXPECT_EQ(FigureId("cache_bytes").figure().words(), "cache bytes");
}

TEST(FrameFigures, MedianOfRepeatsIsTakenFigureByFigure) {
    std::vector<FrameStats> repeats(3);
    repeats[0].totalMs = 5.0, repeats[1].totalMs = 1.0, repeats[2].totalMs = 3.0;
    repeats[0].nearDrawn = 7, repeats[1].nearDrawn = 9, repeats[2].nearDrawn = 8;
    repeats[0].reference.voxelFetches = 100, repeats[1].reference.voxelFetches = 300;
    repeats[2].reference.voxelFetches = 200;
    repeats[0].cacheBytes = 4, repeats[1].cacheBytes = 4, repeats[2].cacheBytes = 4;
    const Figures m = medianOf(repeats);
    EXPECT_EQ(m["frame_ms"], 3.0);
    EXPECT_EQ(m["near_entities"], 8.0);
    EXPECT_EQ(m["voxel_steps"], 200.0);
    EXPECT_EQ(m["cache_bytes"], 4.0);
    EXPECT_EQ(m["far_entities"], 0.0);
}

TEST(FrameFigures, AnEvenMedianTakesTheMiddleTwoAndTruncatesWholeNumbersOnly) {
    std::vector<FrameStats> repeats(2);
    repeats[0].totalMs = 5.0, repeats[1].totalMs = 2.0;
    repeats[0].nearDrawn = 7, repeats[1].nearDrawn = 8;
    repeats[0].plan.worstVpx = 1.0, repeats[1].plan.worstVpx = 2.0;
    const Figures m = medianOf(repeats);
    EXPECT_EQ(m["frame_ms"], 3.5);
    EXPECT_EQ(m["near_entities"], 7.0); // 7.5 -> 7: a count stays whole
    EXPECT_EQ(m["far_predicted_worst_vpx"], 1.5);
}

TEST(FrameFigures, PathFiguresAverageTimesAndCountsAndKeepTheWorstMemory) {
    std::vector<Figures> frames(4);
    for (int i = 0; i < 4; ++i) {
        FrameStats s;
        s.totalMs = 10.0 * (i + 1);     // 10, 20, 30, 40
        s.far.bakes = std::uint64_t(i); // 0, 1, 2, 3
        s.cacheBytes = std::uint64_t(i == 2 ? 900 : 100);
        frames[std::size_t(i)] = figuresOf(s);
    }
    const Figures p = acrossFrames(frames);
    EXPECT_DOUBLE_EQ(p["frame_ms"], 25.0);
    EXPECT_DOUBLE_EQ(p["far_bakes"], 1.5);
    EXPECT_DOUBLE_EQ(p["cache_bytes"], 900.0);
    EXPECT_DOUBLE_EQ(p["entities"], 0.0);
    EXPECT_EQ(acrossFrames({})["frame_ms"], 0.0);
}

TEST(FrameFigures, CsvRowHasOneFieldPerHeaderNameWithIntegersExact) {
    FrameStats s;
    s.entities = 12;
    s.hostSetupMs = 1.23456;
    s.far.cellsRetraced = 123456789012ull;
    s.plan.worstVpx = 2.0;
    const std::string header = figureCsvHeader(), row = figureCsvRow(figuresOf(s));
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
    EXPECT_EQ(fields[FigureId("entities").index], "12");
    EXPECT_EQ(fields[FigureId("host_setup_ms").index], "1.235");
    EXPECT_EQ(fields[FigureId("far_cells_retraced").index], "123456789012");
    EXPECT_EQ(fields[FigureId("far_predicted_worst_vpx").index], "2.000");
}

} // namespace
} // namespace voxtier
