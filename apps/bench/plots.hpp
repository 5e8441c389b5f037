#pragma once
// `voxtier bench`'s plots: PNGs drawn by gnuplot (apps/bench/plots.gp, embedded in the binary)
// from the output folder's results.csv, with the Pareto fronts and the speed–error frontier it
// cannot work out itself written beside it as .dat files. report.md embeds them.
#include "apps/bench/suite.hpp"

#include <cstddef>
#include <filesystem>
#include <set>
#include <string>
#include <vector>

namespace voxtier::bench {

/// A row's mean footprint mismatch, and its worst far displacement in virtual pixels (0 for the
/// truth): the error axes of the speed–error plots.
double mismatchOf(const Measurement& m);
double displacementOf(const Measurement& m);

/// Indices of the rows (into `rows`) that no other row beats on both frame time and `error`
/// (lower is better on both), in order of increasing frame time.
std::vector<std::size_t> paretoFront(const std::vector<const Measurement*>& rows,
                                     double (*error)(const Measurement&));

/// One curve of the speed–error frontier: the error_budget sweep in motion at one snapshot
/// scale, each point's speed-up against the fastest exact path of its scene against its min
/// PSNR.
struct FrontierCurve {
    std::string variant;                    ///< "x3": the snapshot scale
    std::vector<const Measurement*> points; ///< by budget
};
/// The curves of `scene`, one per snapshot scale of the plan (in its order).
std::vector<FrontierCurve> frontierCurves(const SuiteResults& r, const std::string& scene);
/// The points of `curves` faster than the fastest exact path that no other point beats on both
/// speed-up and min PSNR (higher is better on both).
std::set<const Measurement*> frontierPareto(const std::vector<FrontierCurve>& curves);

struct PlotSet {
    std::vector<std::string> pngs; ///< file names in the output folder
    std::string note;              ///< why plots are missing, if they are
};

/// Draws the plots into `dir`, which holds results.csv already. Plots are skipped, with the
/// reason in the note, when gnuplot is missing or fails.
PlotSet drawPlots(const SuiteResults& r, const std::filesystem::path& dir);

} // namespace voxtier::bench
