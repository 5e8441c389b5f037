#pragma once
// `voxtier bench`'s report: report.md, which leads with each scene's hybrid against the fastest
// exact path on the machine, and the PNG plots it embeds (apps/bench/plots.hpp). It reads the
// folder's results.csv (apps/bench/results.hpp), written first.
#include "apps/bench/suite.hpp"

#include <filesystem>
#include <string>
#include <vector>

namespace voxtier::bench {

/// One line per scene: the hybrid against the fastest exact path on this machine, in motion
/// where the scene has a camera path, with the error it costs (min frame PSNR against all-near,
/// the share of pixels differing, the worst far displacement in virtual pixels). The first is
/// the report's first line, and `voxtier bench`'s; `markdown` bolds the scene and the ratio.
std::vector<std::string> leadLines(const SuiteResults& results, bool markdown);

/// Draws the plots and writes report.md into `dir`, which holds results.csv already. Plots are
/// skipped, with the reason in the report, when gnuplot is missing or fails. Returns the files
/// written.
std::vector<std::string> writeReport(const SuiteResults& results, const std::filesystem::path& dir);

} // namespace voxtier::bench
