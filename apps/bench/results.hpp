#pragma once
// `voxtier bench`'s results files, written apart from its report: results.csv (one row per
// measured configuration) and results.json (the same rows, typed, with each sampled frame's
// figures and error, and the plan, the machine and the notes). Both come from one table of
// columns, whose frame figures are compose/frame_figures.hpp's kFrameFigures, so a figure added
// there is a column here without a line of bench code. Every file is written whole or not at
// all (core/file_write.hpp).
#include "apps/bench/suite.hpp"

#include <filesystem>
#include <string>
#include <vector>

namespace voxtier::bench {

/// The column names of results.csv, in order.
std::vector<std::string> resultColumns();

/// results.csv's text.
std::string resultsCsv(const SuiteResults& results);
/// results.json's text.
std::string resultsJson(const SuiteResults& results);

/// Writes results.csv and results.json into `dir` (which must exist); returns their paths.
std::vector<std::string> writeResults(const SuiteResults& results,
                                      const std::filesystem::path& dir);

} // namespace voxtier::bench
