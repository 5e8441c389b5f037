#include "core/detail/json_fields.hpp"

#include "core/error.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

namespace voxtier::detail {

[[noreturn]] void fail(const Ctx& c, const std::string& path, const std::string& reason) {
    throw InputError(c.file, path, reason);
}

std::string child(const std::string& parent, std::string_view key) {
    return parent.empty() ? std::string(key) : parent + "." + std::string(key);
}
std::string element(const std::string& parent, std::size_t i) {
    return parent + "[" + std::to_string(i) + "]";
}

std::string fmt(double v) {
    std::ostringstream s;
    s.precision(17);
    s << v;
    return s.str();
}

namespace {

/// Levenshtein distance, for "did you mean" hints on typos.
std::size_t editDistance(std::string_view a, std::string_view b) {
    std::vector<std::size_t> row(b.size() + 1);
    for (std::size_t j = 0; j <= b.size(); ++j) row[j] = j;
    for (std::size_t i = 1; i <= a.size(); ++i) {
        std::size_t diag = row[0];
        row[0] = i;
        for (std::size_t j = 1; j <= b.size(); ++j) {
            const std::size_t up = row[j];
            row[j] = std::min({row[j] + 1, row[j - 1] + 1, diag + (a[i - 1] == b[j - 1] ? 0 : 1)});
            diag = up;
        }
    }
    return row[b.size()];
}

} // namespace

/// " (did you mean 'x'?)" for a close candidate, else " (expected one of: a, b, c)".
std::string suggestion(std::string_view got, const std::vector<std::string>& candidates) {
    std::string best;
    std::size_t bestD = std::numeric_limits<std::size_t>::max();
    for (const auto& c : candidates) {
        const std::size_t d = editDistance(got, c);
        if (d < bestD) bestD = d, best = c;
    }
    if (!best.empty() && bestD <= std::max<std::size_t>(1, best.size() / 3))
        return " (did you mean '" + best + "'?)";
    if (candidates.empty() || candidates.size() > 12) return "";
    std::string s = " (expected one of: ";
    for (std::size_t i = 0; i < candidates.size(); ++i) s += (i ? ", " : "") + candidates[i];
    return s + ")";
}

const char* typeName(const json& v) {
    switch (v.type()) {
    case json::value_t::null:
        return "null";
    case json::value_t::object:
        return "an object";
    case json::value_t::array:
        return "an array";
    case json::value_t::string:
        return "a string";
    case json::value_t::boolean:
        return "a boolean";
    case json::value_t::binary:
        return "binary data";
    case json::value_t::discarded:
        return "nothing";
    default:
        return "a number";
    }
}

// ---------------------------------------------------------------------------------------------
// Typed accessors. Each names the JSON path and the expected shape in its error.

double number(const Ctx& c, const json& v, const std::string& path) {
    if (!v.is_number()) fail(c, path, std::string("expected a finite number, got ") + typeName(v));
    const double d = v.get<double>();
    if (!std::isfinite(d)) fail(c, path, "expected a finite number");
    return d;
}

double positive(const Ctx& c, const json& v, const std::string& path) {
    const double d = number(c, v, path);
    if (!(d > 0.0)) fail(c, path, "expected a positive number, got " + fmt(d));
    return d;
}

double nonNegative(const Ctx& c, const json& v, const std::string& path) {
    const double d = number(c, v, path);
    if (!(d >= 0.0)) fail(c, path, "expected a number >= 0, got " + fmt(d));
    return d;
}

long long integer(const Ctx& c, const json& v, const std::string& path, long long lo,
                  long long hi) {
    const std::string expected =
        "expected an integer in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]";
    long long r = 0;
    if (v.is_number_unsigned()) {
        const auto u = v.get<std::uint64_t>();
        if (u > std::uint64_t(std::numeric_limits<long long>::max())) fail(c, path, expected);
        r = static_cast<long long>(u);
    } else if (v.is_number_integer()) {
        r = v.get<long long>();
    } else if (v.is_number_float()) {
        // 3.0 is accepted as 3 (some tools write every number as a float); 3.5 is not.
        const double d = v.get<double>();
        if (!std::isfinite(d) || d != std::floor(d) || d < double(lo) || d > double(hi))
            fail(c, path, expected + ", got " + fmt(d));
        r = static_cast<long long>(d);
    } else {
        fail(c, path, expected + ", got " + typeName(v));
    }
    if (r < lo || r > hi) fail(c, path, expected + ", got " + std::to_string(r));
    return r;
}

int intIn(const Ctx& c, const json& v, const std::string& path, int lo, int hi) {
    return static_cast<int>(integer(c, v, path, lo, hi));
}

std::uint64_t seedValue(const Ctx& c, const json& v, const std::string& path) {
    if (v.is_number_unsigned()) return v.get<std::uint64_t>();
    if (v.is_number_integer() && v.get<long long>() >= 0) return std::uint64_t(v.get<long long>());
    fail(c, path, "expected an unsigned integer seed");
}

bool boolean(const Ctx& c, const json& v, const std::string& path) {
    if (!v.is_boolean()) fail(c, path, std::string("expected true or false, got ") + typeName(v));
    return v.get<bool>();
}

std::string string(const Ctx& c, const json& v, const std::string& path) {
    if (!v.is_string()) fail(c, path, std::string("expected a string, got ") + typeName(v));
    return v.get<std::string>();
}

std::string nonEmptyString(const Ctx& c, const json& v, const std::string& path) {
    std::string s = string(c, v, path);
    if (s.empty()) fail(c, path, "expected a non-empty string");
    return s;
}

/// A string that must be one of `options`; returns its position in the list.
int choice(const Ctx& c, const json& v, const std::string& path,
           const std::vector<std::string>& options) {
    const std::string s = string(c, v, path);
    for (std::size_t i = 0; i < options.size(); ++i)
        if (s == options[i]) return int(i);
    fail(c, path, "unknown value '" + s + "'" + suggestion(s, options));
}

const json& arrayOf(const Ctx& c, const json& v, const std::string& path, std::size_t n,
                    const char* what) {
    if (!v.is_array() || v.size() != n)
        fail(c, path, "expected an array of " + std::to_string(n) + " " + what);
    return v;
}

glm::dvec3 vec3(const Ctx& c, const json& v, const std::string& path) {
    const char* what = "finite numbers";
    arrayOf(c, v, path, 3, what);
    glm::dvec3 r;
    for (int i = 0; i < 3; ++i) {
        if (!v[std::size_t(i)].is_number()) fail(c, path, "expected an array of 3 finite numbers");
        r[i] = v[std::size_t(i)].get<double>();
        if (!std::isfinite(r[i])) fail(c, path, "expected an array of 3 finite numbers");
    }
    return r;
}

glm::dvec2 vec2(const Ctx& c, const json& v, const std::string& path) {
    arrayOf(c, v, path, 2, "finite numbers");
    glm::dvec2 r;
    for (int i = 0; i < 2; ++i) {
        if (!v[std::size_t(i)].is_number()) fail(c, path, "expected an array of 2 finite numbers");
        r[i] = v[std::size_t(i)].get<double>();
        if (!std::isfinite(r[i])) fail(c, path, "expected an array of 2 finite numbers");
    }
    return r;
}

glm::ivec3 ivec3(const Ctx& c, const json& v, const std::string& path, int lo, int hi) {
    const std::string what = "integers in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]";
    arrayOf(c, v, path, 3, what.c_str());
    glm::ivec3 r;
    for (int i = 0; i < 3; ++i)
        r[i] = intIn(c, v[std::size_t(i)], element(path, std::size_t(i)), lo, hi);
    return r;
}

Rgba8 color(const Ctx& c, const json& v, const std::string& path) {
    arrayOf(c, v, path, 3, "integers in [0, 255] (r, g, b)");
    glm::ivec3 r;
    for (int i = 0; i < 3; ++i)
        r[i] = intIn(c, v[std::size_t(i)], element(path, std::size_t(i)), 0, 255);
    return packRgba(unsigned(r.x), unsigned(r.y), unsigned(r.z));
}

Obj::Obj(const Ctx& c, const json& v, std::string path) : c_(c), v_(v), path_(std::move(path)) {
    if (!v.is_object()) fail(c, path_, std::string("expected an object, got ") + typeName(v));
}

void Obj::allow(const std::vector<std::string_view>& keys) const {
    std::vector<std::string> allowed(keys.begin(), keys.end());
    for (const auto& [k, val] : v_.items()) {
        if (k == "comment") {
            string(c_, val, at(k));
            continue;
        }
        if (std::find(allowed.begin(), allowed.end(), k) == allowed.end())
            fail(c_, at(k), "unknown key '" + k + "'" + suggestion(k, allowed));
    }
}

const json& Obj::require(std::string_view key) const {
    const json* v = get(key);
    if (!v) fail(c_, path_, "missing required key '" + std::string(key) + "'");
    return *v;
}

const json& array(const Ctx& c, const json& v, const std::string& path) {
    if (!v.is_array()) fail(c, path, std::string("expected an array, got ") + typeName(v));
    return v;
}

} // namespace voxtier::detail
