#pragma once
// The bench report's cells: how its numbers are written, and the rows it reads
// (apps/bench/report.cpp and apps/bench/time_split.cpp share them).
#include "apps/bench/suite.hpp"

#include <string>
#include <vector>

namespace voxtier::bench::cells {

/// The group of the per-scene mode rows (Measurement::group).
inline constexpr const char* kModesGroup = "modes";

/// `v` with `decimals` decimals ("inf", "nan" as such).
std::string num(double v, int decimals = 2);
/// A fraction as a percentage: 0.25 -> "25.00 %".
std::string pct(double fraction, int decimals = 2);
/// Millions, one decimal.
std::string mega(double v);
/// A count per frame: whole where it is whole, else to two figures ("3", "0.25", "12.5").
std::string count(double v);
/// A PSNR in dB; equal frames have an infinite one.
std::string psnrText(double db);

/// The row of `group`, `scene` and `mode`, or null.
const Measurement* find(const SuiteResults& r, const std::string& group, const std::string& scene,
                        BenchMode mode);
/// The scenes of the mode rows, in the order measured.
std::vector<std::string> sceneNames(const SuiteResults& r);
/// A figure of the path, per frame as the figure table combines it.
double perFrame(const Measurement& m, FigureId figure);

} // namespace voxtier::bench::cells
