#pragma once
// `voxtier bench` output: results.csv (one row per measured configuration), results.json (the
// same plus per-frame detail), PNG plots drawn by gnuplot, and report.md, which embeds them.
#include "apps/bench/suite.hpp"

#include <string>
#include <vector>

namespace voxtier::bench {

/// Writes everything into `dir` (which must exist). Plots are skipped, with the reason in the
/// report, when gnuplot is missing or fails. Returns the files written.
std::vector<std::string> writeReport(SuiteResults results, const std::string& dir);

/// Indices of the rows (into `rows`) that no other row beats on both frame time and `error`
/// (lower is better on both), in order of increasing frame time.
std::vector<std::size_t> paretoFront(const std::vector<const Measurement*>& rows,
                                     double (*error)(const Measurement&));

} // namespace voxtier::bench
