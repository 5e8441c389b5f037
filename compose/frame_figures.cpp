// The table of frame figures (compose/frame_figures.hpp) and what iterates it.
#include "compose/frame_figures.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace voxtier {

namespace {

constexpr bool namesDistinct() {
    for (std::size_t i = 0; i < kFrameFigureCount; ++i)
        for (std::size_t j = i + 1; j < kFrameFigureCount; ++j)
            if (std::string_view(kFrameFigures[i].name) == kFrameFigures[j].name) return false;
    return true;
}
static_assert(namesDistinct(), "every output column of kFrameFigures needs its own name");

double median(std::vector<double> v) {
    if (v.empty()) return 0.0;
    std::sort(v.begin(), v.end());
    const std::size_t m = v.size() / 2;
    return v.size() % 2 ? v[m] : 0.5 * (v[m - 1] + v[m]);
}

} // namespace

const char* toString(FigureUnit u) {
    switch (u) {
    case FigureUnit::Count:
        return "count";
    case FigureUnit::Bytes:
        return "bytes";
    case FigureUnit::Ms:
        return "ms";
    case FigureUnit::Vpx:
        return "vpx";
    }
    return "?";
}

const char* toString(AcrossFrames a) {
    switch (a) {
    case AcrossFrames::Mean:
        return "mean";
    case AcrossFrames::Sum:
        return "sum";
    case AcrossFrames::Worst:
        return "worst";
    }
    return "?";
}

std::string FrameFigure::text(double value) const {
    char buf[32];
    if (isWhole(unit))
        std::snprintf(buf, sizeof buf, "%.0f", std::trunc(value));
    else
        std::snprintf(buf, sizeof buf, "%.3f", value);
    return buf;
}

std::string FrameFigure::words() const {
    std::string w = name;
    if (unit == FigureUnit::Ms && w.ends_with("_ms")) w.resize(w.size() - 3);
    std::replace(w.begin(), w.end(), '_', ' ');
    return w;
}

Figures figuresOf(const FrameStats& s) {
    Figures out;
    for (std::size_t i = 0; i < kFrameFigureCount; ++i) out.values[i] = kFrameFigures[i].read(s);
    return out;
}

Figures medianOf(const std::vector<FrameStats>& repeats) {
    Figures out;
    std::vector<double> values;
    for (std::size_t i = 0; i < kFrameFigureCount; ++i) {
        const FrameFigure& f = kFrameFigures[i];
        values.clear();
        for (const FrameStats& s : repeats) values.push_back(f.read(s));
        const double m = median(values);
        out.values[i] = isWhole(f.unit) ? std::trunc(m) : m;
    }
    return out;
}

Figures acrossFrames(const std::vector<Figures>& frames) {
    Figures out;
    for (std::size_t i = 0; i < kFrameFigureCount; ++i) {
        const FrameFigure& f = kFrameFigures[i];
        double& v = out.values[i];
        for (const Figures& s : frames)
            v = f.acrossFrames == AcrossFrames::Worst ? std::max(v, s.values[i]) : v + s.values[i];
        if (f.acrossFrames == AcrossFrames::Mean && !frames.empty()) v /= double(frames.size());
    }
    return out;
}

std::string figureCsvHeader() {
    std::string out;
    for (const FrameFigure& f : kFrameFigures)
        out += (out.empty() ? "" : ",") + std::string(f.name);
    return out;
}

std::string figureCsvRow(const Figures& f) {
    std::string out;
    for (std::size_t i = 0; i < kFrameFigureCount; ++i)
        out += (i ? "," : "") + kFrameFigures[i].text(f.values[i]);
    return out;
}

} // namespace voxtier
