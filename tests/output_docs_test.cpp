// docs/outputs.md documents the columns of `voxtier render --csv` and `--pops` in one table each;
// these tests keep the tables in step with the code that writes the columns (kFrameFigures,
// kPopColumns) and with the header lines the CLI writes.
#include "cli_support.hpp"
#include "compose/frame_figures.hpp"
#include "compose/pop_measure.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace voxtier {
namespace {

namespace fs = std::filesystem;

struct Row {
    std::string name, unit, meaning;
};

std::string trim(const std::string& s) {
    const auto b = s.find_first_not_of(' '), e = s.find_last_not_of(' ');
    return b == std::string::npos ? "" : s.substr(b, e - b + 1);
}

/// The rows of the first table after the heading `heading` in docs/outputs.md: its cells, the
/// first without its backticks.
std::vector<Row> tableAfter(const std::string& heading) {
    std::ifstream in(fs::path(VOXTIER_SOURCE_DIR) / "docs" / "outputs.md");
    EXPECT_TRUE(in) << "docs/outputs.md";
    std::vector<Row> rows;
    std::string line;
    bool under = false, inTable = false;
    while (std::getline(in, line)) {
        if (line.rfind("#", 0) == 0) {
            if (inTable) break;
            under = line == heading;
            continue;
        }
        if (!under) continue;
        if (line.rfind("|", 0) != 0) {
            if (inTable) break;
            continue;
        }
        std::vector<std::string> cells;
        std::stringstream ss(line.substr(1));
        std::string cell;
        while (std::getline(ss, cell, '|')) cells.push_back(trim(cell));
        if (!inTable) { // the header and the separator line
            inTable = true;
            std::getline(in, line);
            continue;
        }
        EXPECT_GE(cells.size(), 3u) << line;
        if (cells.size() < 3) continue;
        std::string name = cells[0];
        if (name.size() >= 2 && name.front() == '`' && name.back() == '`')
            name = name.substr(1, name.size() - 2);
        rows.push_back({name, cells[1], cells[2]});
    }
    EXPECT_FALSE(rows.empty()) << "no table under " << heading;
    return rows;
}

TEST(OutputDocs, CsvTableListsEveryFrameFigureInOrderWithItsUnit) {
    const std::vector<Row> rows = tableAfter("## `--csv` columns");
    ASSERT_EQ(rows.size(), 2 + kFrameFigureCount);
    EXPECT_EQ(rows[0].name, "frame");
    EXPECT_EQ(rows[1].name, "time");
    for (std::size_t i = 0; i < kFrameFigureCount; ++i) {
        EXPECT_EQ(rows[2 + i].name, kFrameFigures[i].name) << "row " << 2 + i;
        EXPECT_EQ(rows[2 + i].unit, toString(kFrameFigures[i].unit)) << kFrameFigures[i].name;
        EXPECT_FALSE(rows[2 + i].meaning.empty()) << kFrameFigures[i].name;
    }
}

TEST(OutputDocs, PopsTableListsEveryColumnInOrderWithItsUnit) {
    const std::vector<Row> rows = tableAfter("## `--pops` columns");
    ASSERT_EQ(rows.size(), kPopColumns.size());
    for (std::size_t i = 0; i < rows.size(); ++i) {
        EXPECT_EQ(rows[i].name, kPopColumns[i].name) << "row " << i;
        const std::string unit = *kPopColumns[i].unit ? kPopColumns[i].unit : "—";
        EXPECT_EQ(rows[i].unit, unit) << kPopColumns[i].name;
        EXPECT_FALSE(rows[i].meaning.empty()) << kPopColumns[i].name;
    }
}

/// The first line of `file`.
std::string headerOf(const fs::path& file) {
    std::ifstream in(file);
    std::string line;
    std::getline(in, line);
    return line;
}

std::string names(const std::vector<Row>& rows) {
    std::string s;
    for (const Row& r : rows) s += (s.empty() ? "" : ",") + r.name;
    return s;
}

// The files the CLI writes have exactly the documented columns, in the documented order.
TEST(OutputDocs, TheCliWritesTheDocumentedColumns) {
    const fs::path d = test::scratchDir("voxtier_output_docs", true);
    const std::string scene = test::writeText(d, "s.json", R"({
        "camera": {"size": [64, 48]},
        "camera_path": {"fps": 10, "keys": [
            {"time": 0, "position": [0, 1, 4], "target": [0, 0.5, 0]},
            {"time": 0.3, "position": [0, 1, 30], "target": [0, 0.5, 0]}]},
        "selector": {"near_at": 8, "far_at": 10},
        "models": [{"name": "a", "generator": "arrow"}],
        "entities": [{"model": "a", "rotation_deg": [0, 40, 0]}]})");
    const test::CliRun r =
        test::runCli("render " + scene + " --path -o " + (d / "f.pam").string() + " --csv " +
                     (d / "frames.csv").string() + " --pops " + (d / "pops.csv").string());
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_EQ(headerOf(d / "frames.csv"), names(tableAfter("## `--csv` columns")));
    EXPECT_EQ(headerOf(d / "pops.csv"), names(tableAfter("## `--pops` columns")));
}

} // namespace
} // namespace voxtier
