#pragma once
// The one harness of every `voxtier bench ...` command and `bake --bench` (apps/bench/): what
// they need to time things honestly on a shared machine (wall ms, timed repeats after warm-ups,
// medians and quantiles over them, the load average printed next to them), one parser for
// comma-separated number lists given on the command line, and one CSV writer driven by a column
// table, writing its file whole (each column's name and how a row gives its value, so the header
// and the rows cannot drift apart; the frame figures' table, compose/frame_figures.hpp, is the same
// idea).
#include "core/error.hpp"
#include "core/file_write.hpp"
#include "core/stopwatch.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <functional>
#include <ostream>
#include <sstream>
#include <string>
#include <type_traits>
#include <utility>
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

/// Wall ms of one call of `once`.
template <class F> double timedMs(F&& once) {
    const auto t0 = BenchClock::now();
    once();
    return msSince(t0);
}

/// Wall ms of each of `repeats` calls of `once`, after `warmup` untimed calls.
template <class F> std::vector<double> timedRepeats(int warmup, int repeats, F&& once) {
    for (int w = 0; w < warmup; ++w) once();
    std::vector<double> ms;
    for (int r = 0; r < repeats; ++r) ms.push_back(timedMs(once));
    return ms;
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

/// A number to six significant digits, as the bench's CSV and data files write it ("inf" for
/// an infinite one).
inline std::string sig(double v) {
    if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.6g", v);
    return buf;
}

/// One column of a CSV: its name in the header and how a row gives its value, written with the
/// stream's default formatting (6 significant digits for a double).
template <class Row> struct CsvColumn {
    const char* name;
    std::function<void(std::ostream&, const Row&)> write;

    template <class Get>
    CsvColumn(const char* columnName, Get get)
        : name(columnName), write([get](std::ostream& o, const Row& r) { o << get(r); }) {}
};

/// A CSV file whose header and rows both come from one column table, kept in memory and written
/// whole by save() (core/file_write.hpp). Rows written before open() are dropped, so a command
/// writes its rows whether or not the user asked for the file.
template <class Row> class CsvWriter {
  public:
    explicit CsvWriter(std::vector<CsvColumn<Row>> columns) : columns_(std::move(columns)) {}

    /// The header line, without the newline.
    std::string header() const {
        std::string h;
        for (const CsvColumn<Row>& c : columns_) h += (h.empty() ? "" : ",") + std::string(c.name);
        return h;
    }
    /// The file save() writes, its folders created then.
    void open(const std::string& path) {
        path_ = path;
        text_ = header() + '\n';
    }
    explicit operator bool() const { return !path_.empty(); }
    void write(const Row& row) {
        if (path_.empty()) return;
        std::ostringstream line;
        for (std::size_t i = 0; i < columns_.size(); ++i) {
            if (i > 0) line << ',';
            columns_[i].write(line, row);
        }
        text_ += line.str() + '\n';
    }
    /// Writes the file, whole or not at all (InputError naming it, with the OS reason).
    void save() const {
        if (!path_.empty()) writeFileWhole(path_, text_);
    }

  private:
    std::vector<CsvColumn<Row>> columns_;
    std::string path_, text_;
};

} // namespace voxtier::cli
