#pragma once
// What every `voxtier bench ...` and `bake --bench` command needs to time things honestly on a
// shared machine: wall ms, medians over repeats, the load average printed next to them, and
// one parser for comma-separated number lists given on the command line.
#include "core/error.hpp"
#include "core/stopwatch.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>
#include <type_traits>
#include <vector>

namespace voxtier::cli {

using BenchClock = std::chrono::steady_clock;

using voxtier::msSince;

/// Median of the samples (mean of the middle two for an even count); 0 for none.
inline double median(std::vector<double> v) {
    if (v.empty()) return 0.0;
    std::sort(v.begin(), v.end());
    const std::size_t m = v.size() / 2;
    return v.size() % 2 ? v[m] : 0.5 * (v[m - 1] + v[m]);
}

/// The q-quantile of the samples (0 <= q <= 1), nearest rank: the least sample at or above a
/// share q of them; 0 for none.
inline double quantile(std::vector<double> v, double q) {
    if (v.empty()) return 0.0;
    std::sort(v.begin(), v.end());
    const auto rank = std::size_t(std::ceil(q * double(v.size())));
    return v[std::min(v.size() - 1, rank > 0 ? rank - 1 : 0)];
}

/// The 1-minute load average ("?" when unknown): printed beside timings taken on a shared machine.
inline std::string loadAverage() {
    std::ifstream in("/proc/loadavg");
    std::string a;
    in >> a;
    return a.empty() ? "?" : a;
}

/// "10,100,1000" -> {10, 100, 1000}: every item a number in [lo, hi] (an integer when T is), at
/// least one item; otherwise InputError naming `flag`.
template <class T>
std::vector<T> parseList(const std::string& text, const char* flag, double lo, double hi) {
    auto shown = [](double v) {
        char buf[32];
        std::snprintf(buf, sizeof buf, "%g", v);
        return std::string(buf);
    };
    std::vector<T> out;
    std::stringstream ss(text);
    std::string item;
    while (std::getline(ss, item, ',')) {
        try {
            std::size_t used = 0;
            const double v = std::stod(item, &used);
            if (used != item.size() || !(v >= lo && v <= hi)) throw std::invalid_argument("");
            if (std::is_integral_v<T> && v != std::floor(v)) throw std::invalid_argument("");
            out.push_back(T(v));
        } catch (const std::exception&) {
            throw InputError("", flag,
                             "expected a comma-separated list of numbers in [" + shown(lo) + ", " +
                                 shown(hi) + "], got '" + text + "'");
        }
    }
    if (out.empty()) throw InputError("", flag, "expected at least one value");
    return out;
}

} // namespace voxtier::cli
