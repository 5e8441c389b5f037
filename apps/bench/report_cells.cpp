// The bench report's cells (apps/bench/report_cells.hpp).
#include "apps/bench/report_cells.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace voxtier::bench::cells {

std::string num(double v, int decimals) {
    if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
    if (std::isnan(v)) return "nan";
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
    return buf;
}
std::string pct(double fraction, int decimals) {
    return num(100.0 * fraction, decimals) + " %";
}
std::string mega(double v) {
    return num(v / 1e6, 1);
}

std::string count(double v) {
    return num(v, v == std::floor(v) ? 0 : v < 1 ? 2 : 1);
}

std::string psnrText(double db) {
    return std::isinf(db) ? "∞ dB (equal frames)" : num(db, 1) + " dB";
}

const Measurement* find(const SuiteResults& r, const std::string& group, const std::string& scene,
                        BenchMode mode) {
    for (const Measurement& m : r.rows)
        if (m.group == group && m.scene == scene && m.mode == mode) return &m;
    return nullptr;
}

std::vector<std::string> sceneNames(const SuiteResults& r) {
    std::vector<std::string> out;
    for (const Measurement& m : r.rows)
        if (m.group == kModesGroup && std::find(out.begin(), out.end(), m.scene) == out.end())
            out.push_back(m.scene);
    return out;
}

double perFrame(const Measurement& m, FigureId figure) {
    return m.figures[figure];
}

} // namespace voxtier::bench::cells
