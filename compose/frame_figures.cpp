// The table of frame figures (compose/frame_figures.hpp) and what iterates it.
#include "compose/frame_figures.hpp"

#include <algorithm>
#include <cstdio>
#include <type_traits>

namespace voxtier {

namespace {

// Every FrameStats field has exactly one line in the table, or the build stops here: T{a, b, ...}
// compiles for as many initializers as the aggregate T has fields, and no more.
struct AnyField {
    template <class T> constexpr operator T() const { return T{}; }
};
template <class T, class... Fields> constexpr std::size_t fieldCount() {
    if constexpr (requires { T{Fields{}..., AnyField{}}; })
        return fieldCount<T, Fields..., AnyField>();
    else
        return sizeof...(Fields);
}
constexpr bool membersDistinct() {
    for (std::size_t i = 0; i < kFrameFigureCount; ++i)
        for (std::size_t j = i + 1; j < kFrameFigureCount; ++j)
            if (kFrameFigures[i].member == kFrameFigures[j].member) return false;
    return true;
}
static_assert(fieldCount<FrameStats>() == kFrameFigureCount && membersDistinct(),
              "every FrameStats field needs exactly one line in kFrameFigures");

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

std::string FrameFigure::text(const FrameStats& s) const {
    return std::visit(
        [&](auto m) {
            if constexpr (std::is_floating_point_v<std::remove_reference_t<decltype(s.*m)>>) {
                char buf[32];
                std::snprintf(buf, sizeof buf, "%.3f", s.*m);
                return std::string(buf);
            } else {
                return std::to_string(s.*m);
            }
        },
        member);
}

std::string FrameFigure::words() const {
    std::string w = name;
    if (unit == FigureUnit::Ms && w.ends_with("_ms")) w.resize(w.size() - 3);
    std::replace(w.begin(), w.end(), '_', ' ');
    return w;
}

FrameStats medianOf(const std::vector<FrameStats>& repeats) {
    FrameStats m;
    std::vector<double> values;
    for (const FrameFigure& f : kFrameFigures) {
        values.clear();
        for (const FrameStats& s : repeats) values.push_back(f.of(s));
        f.set(m, median(values));
    }
    return m;
}

double PathFigures::of(FrameMember member) const {
    return values[frameFigureIndex(member)];
}

PathFigures acrossFrames(const std::vector<FrameStats>& frames) {
    PathFigures out;
    for (std::size_t i = 0; i < kFrameFigureCount; ++i) {
        const FrameFigure& f = kFrameFigures[i];
        double& v = out.values[i];
        for (const FrameStats& s : frames)
            v = f.acrossFrames == AcrossFrames::Worst ? std::max(v, f.of(s)) : v + f.of(s);
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

std::string figureCsvRow(const FrameStats& s) {
    std::string out;
    for (const FrameFigure& f : kFrameFigures) out += (out.empty() ? "" : ",") + f.text(s);
    return out;
}

} // namespace voxtier
