// The plots of `voxtier bench` (apps/bench/plots.hpp).
#include "apps/bench/plots.hpp"

#include "apps/bench/harness.hpp"
#include "core/file_write.hpp"
#include "embedded/bench_plots_gp.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>

namespace voxtier::bench {

namespace {

namespace fs = std::filesystem;
using cli::sig;

const char* kModesGroup = "modes";

// ---------------------------------------------------------------------------------------------
// Plots: apps/bench/plots.gp reads results.csv; the bench writes it into the output folder after
// the settings it needs, with the Pareto fronts it cannot work out itself.

std::string shellQuote(const std::string& s) {
    std::string q = "'";
    for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
    return q + "'";
}

/// A gnuplot single-quoted string ('' stands for a quote).
std::string gnuplotQuote(const std::string& s) {
    std::string q = "'";
    for (char c : s) q += c == '\'' ? std::string("''") : std::string(1, c);
    return q + "'";
}
/// A gnuplot double-quoted string (backslash escapes).
std::string gnuplotDoubleQuote(const std::string& s) {
    std::string q = "\"";
    for (char c : s) q += c == '"' || c == '\\' ? "\\" + std::string(1, c) : std::string(1, c);
    return q + "\"";
}

// ---------------------------------------------------------------------------------------------
// The speed–error frontier: the error_budget sweep in motion, one curve per snapshot scale, each
// point's speed-up against the fastest exact path of its scene against its min PSNR.

/// Identical frames have an infinite PSNR; a plot draws them at 99 dB.
double plottedPsnr(double psnr) {
    return std::min(psnr, 99.0);
}

/// frontier.dat: one block per curve of "speed-up psnr budget" lines; frontier_pareto.dat: the
/// Pareto frontier's points along the speed-up.
void writeFrontierData(const std::vector<FrontierCurve>& curves, const fs::path& dir) {
    std::string data, pareto;
    const std::set<const Measurement*> front = frontierPareto(curves);
    std::vector<const Measurement*> frontPoints(front.begin(), front.end());
    std::sort(frontPoints.begin(), frontPoints.end(), [](auto* a, auto* b) {
        return a->motion.speedupVsFastestExact < b->motion.speedupVsFastestExact;
    });
    const auto line = [](const Measurement& m) {
        return sig(m.motion.speedupVsFastestExact) + " " + sig(plottedPsnr(m.motion.psnrMin));
    };
    for (const FrontierCurve& c : curves) {
        for (const Measurement* m : c.points) data += line(*m) + " " + sig(m->param) + "\n";
        data += "\n\n"; // gnuplot's `index` separator
    }
    for (const Measurement* m : frontPoints) pareto += line(*m) + "\n";
    writeFileWhole(dir / "frontier.dat", data);
    writeFileWhole(dir / "frontier_pareto.dat", pareto);
}

/// The speed/error points of the first scene: its modes and the sweep points with an error.
std::vector<const Measurement*> speedErrorPoints(const SuiteResults& r, const std::string& scene) {
    std::vector<const Measurement*> pts;
    for (const Measurement& m : r.rows)
        if (m.scene == scene && (m.group == kModesGroup || (m.group == "sweep" && m.hasError)))
            pts.push_back(&m);
    return pts;
}

/// The Pareto front of `pts` on `error`, along increasing error (decreasing time): the staircase
/// bounding what was reached, as "error frame_ms" lines.
std::string paretoData(const std::vector<const Measurement*>& pts,
                       double (*error)(const Measurement&), double errorScale) {
    auto front = paretoFront(pts, error);
    std::reverse(front.begin(), front.end());
    std::string out;
    for (std::size_t i : front)
        out += sig(errorScale * error(*pts[i])) + " " + sig(pts[i]->frameMs()) + "\n";
    return out;
}

/// The settings plots.gp starts from (its header says what each means).
std::string plotSettings(const SuiteResults& r, const std::string& scene,
                         const std::vector<std::string>& pngs) {
    std::string modes, families, variants, plots;
    for (const BenchModeInfo& mode : kBenchModes)
        modes += std::string(modes.empty() ? "" : " ") + mode.name;
    std::set<std::string> seen;
    for (const Measurement* m : speedErrorPoints(r, scene))
        if (m->group != kModesGroup && seen.insert(m->family).second)
            families += (families.empty() ? "" : " ") + gnuplotQuote(m->family);
    for (const FrontierCurve& c : frontierCurves(r, scene))
        variants += (variants.empty() ? "" : " ") + gnuplotQuote(c.variant);
    for (const std::string& png : pngs)
        plots += (plots.empty() ? "" : " ") + fs::path(png).stem().string();
    return "scene = " + gnuplotQuote(scene) + "\nmodes = " + gnuplotQuote(modes) +
           "\nfamilies = " + gnuplotDoubleQuote(families) +
           "\nvariants = " + gnuplotDoubleQuote(variants) + "\nplots = " + gnuplotQuote(plots) +
           "\n\n";
}

} // namespace

double mismatchOf(const Measurement& m) {
    return m.hasError ? m.error.mismatchMean : 0.0;
}

double displacementOf(const Measurement& m) {
    return m.hasError ? m.error.farDisplacementWorstVpx : 0.0;
}

std::vector<std::size_t> paretoFront(const std::vector<const Measurement*>& rows,
                                     double (*error)(const Measurement&)) {
    std::vector<std::size_t> front;
    for (std::size_t i = 0; i < rows.size(); ++i) {
        bool dominated = false;
        for (std::size_t j = 0; j < rows.size() && !dominated; ++j) {
            if (i == j) continue;
            const double ti = rows[i]->frameMs(), tj = rows[j]->frameMs(), ei = error(*rows[i]),
                         ej = error(*rows[j]);
            dominated = tj <= ti && ej <= ei && (tj < ti || ej < ei);
        }
        if (!dominated) front.push_back(i);
    }
    std::sort(front.begin(), front.end(), [&](std::size_t a, std::size_t b) {
        return rows[a]->frameMs() < rows[b]->frameMs();
    });
    return front;
}

std::vector<FrontierCurve> frontierCurves(const SuiteResults& r, const std::string& scene) {
    std::vector<FrontierCurve> curves;
    for (int k : r.plan.snapshotScales) {
        FrontierCurve c{scaleName(k), {}};
        for (const Measurement& m : r.rows)
            if (m.scene == scene && m.family == kBudgetFamily &&
                m.motion.speedupVsFastestExact > 0 && m.snapshotScale == k)
                c.points.push_back(&m);
        std::sort(c.points.begin(), c.points.end(),
                  [](const Measurement* a, const Measurement* b) { return a->param < b->param; });
        if (!c.points.empty()) curves.push_back(c);
    }
    return curves;
}

std::set<const Measurement*> frontierPareto(const std::vector<FrontierCurve>& curves) {
    std::vector<const Measurement*> all;
    for (const FrontierCurve& c : curves) all.insert(all.end(), c.points.begin(), c.points.end());
    std::set<const Measurement*> front;
    for (const Measurement* a : all) {
        // The fastest exact path is a point of the frontier too, at 1x with no error: nothing
        // at or below its speed can be on the frontier.
        if (!(a->motion.speedupVsFastestExact > 1.0)) continue;
        const bool dominated = std::any_of(all.begin(), all.end(), [&](const Measurement* b) {
            const double sa = a->motion.speedupVsFastestExact, sb = b->motion.speedupVsFastestExact;
            const double pa = a->motion.psnrMin, pb = b->motion.psnrMin;
            return sb >= sa && pb >= pa && (sb > sa || pb > pa);
        });
        if (!dominated) front.insert(a);
    }
    return front;
}

PlotSet drawPlots(const SuiteResults& r, const fs::path& dir) {
    PlotSet out;
    if (std::system("command -v gnuplot >/dev/null 2>&1") != 0) {
        out.note = "gnuplot was not found on PATH (install gnuplot-nox; tools/setup.sh does), so "
                   "no plots were drawn; the tables and results.csv hold every number.";
        return out;
    }
    const std::string scene = r.rows.empty() ? "" : r.rows.front().scene;
    const auto pts = speedErrorPoints(r, scene);
    if (!pts.empty()) out.pngs.push_back("speed_error.png");
    if (std::any_of(pts.begin(), pts.end(), [](const Measurement* m) { return m->motion.ms > 0; }))
        out.pngs.push_back("motion_error.png");
    const std::vector<FrontierCurve> curves = frontierCurves(r, scene);
    if (!curves.empty()) out.pngs.push_back("frontier.png");
    for (const char* group : {"scaling_entities", "scaling_size"})
        if (std::any_of(r.rows.begin(), r.rows.end(),
                        [&](const Measurement& m) { return m.group == group; }))
            out.pngs.push_back(std::string(group) + ".png");
    writeFileWhole(dir / "pareto_mismatch.dat", paretoData(pts, mismatchOf, 100.0));
    writeFileWhole(dir / "pareto_displacement.dat", paretoData(pts, displacementOf, 1.0));
    writeFrontierData(curves, dir);
    writeFileWhole(dir / "plots.gp", plotSettings(r, scene, out.pngs) + kBenchPlotsGp);
    const std::string cmd =
        "cd " + shellQuote(dir.string()) + " && gnuplot plots.gp > plots.log 2>&1";
    const int rc = std::system(cmd.c_str());
    std::vector<std::string> ok;
    for (const std::string& png : out.pngs)
        if (fs::exists(dir / png) && fs::file_size(dir / png) > 0) ok.push_back(png);
    if (rc != 0 || ok.size() != out.pngs.size())
        out.note = "gnuplot failed (exit " + std::to_string(rc) + ", see plots.log); " +
                   std::to_string(ok.size()) + " of " + std::to_string(out.pngs.size()) +
                   " plots were drawn.";
    out.pngs = ok;
    return out;
}

} // namespace voxtier::bench
