#pragma once
// Internal to core's scene loader (not installed): typed reads of JSON values, each naming the
// JSON path and the expected shape in its error (InputError(file, path, reason), one line), and
// Obj, a JSON object whose keys are checked against the ones its section accepts.
#include "core/voxel_model.hpp"

#include <glm/glm.hpp>
#include <nlohmann/json.hpp>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <initializer_list>
#include <string>
#include <string_view>
#include <vector>

namespace voxtier::detail {

using json = nlohmann::json;

/// The document being read: the name its errors start with, and the directory its relative
/// paths resolve against.
struct Ctx {
    std::string file;
    std::filesystem::path baseDir;
};

[[noreturn]] void fail(const Ctx& c, const std::string& path, const std::string& reason);

// JSON paths and the words of messages.
std::string child(const std::string& parent, std::string_view key); ///< "a.b"
std::string element(const std::string& parent, std::size_t i);      ///< "a[3]"
std::string fmt(double v);                                          ///< round-trip precision
/// " (did you mean 'x'?)" for a close candidate, else " (expected one of: a, b, c)".
std::string suggestion(std::string_view got, const std::vector<std::string>& candidates);
/// "an object", "a string", ... for "expected X, got Y" messages.
const char* typeName(const json& v);

// Typed accessors: the value at `path`, or InputError naming it and the expected shape.
double number(const Ctx& c, const json& v, const std::string& path);
double positive(const Ctx& c, const json& v, const std::string& path);
double nonNegative(const Ctx& c, const json& v, const std::string& path);
/// An integer in [lo, hi]; 3.0 is accepted as 3, 3.5 is not.
long long integer(const Ctx& c, const json& v, const std::string& path, long long lo, long long hi);
int intIn(const Ctx& c, const json& v, const std::string& path, int lo, int hi);
std::uint64_t seedValue(const Ctx& c, const json& v, const std::string& path);
bool boolean(const Ctx& c, const json& v, const std::string& path);
std::string string(const Ctx& c, const json& v, const std::string& path);
std::string nonEmptyString(const Ctx& c, const json& v, const std::string& path);
/// A string that must be one of `options`; returns its position in the list.
int choice(const Ctx& c, const json& v, const std::string& path,
           const std::vector<std::string>& options);
/// `v` itself when it is an array of `n` elements ("expected an array of n <what>" if not).
const json& arrayOf(const Ctx& c, const json& v, const std::string& path, std::size_t n,
                    const char* what);
const json& array(const Ctx& c, const json& v, const std::string& path);
glm::dvec3 vec3(const Ctx& c, const json& v, const std::string& path);
glm::dvec2 vec2(const Ctx& c, const json& v, const std::string& path);
glm::ivec3 ivec3(const Ctx& c, const json& v, const std::string& path, int lo, int hi);
Rgba8 color(const Ctx& c, const json& v, const std::string& path);

/// A JSON object with its path. Keys are looked up by name; `allow` rejects every key not in
/// the list (plus "comment"), so a typo is an error instead of a silently ignored setting.
class Obj {
  public:
    Obj(const Ctx& c, const json& v, std::string path);

    /// `keys`: a list of core/scene_keys.hpp (sceneKeysOf), or a union of such lists.
    void allow(const std::vector<std::string_view>& keys) const;

    const json* get(std::string_view key) const {
        const auto it = v_.find(std::string(key));
        return it == v_.end() ? nullptr : &*it;
    }
    const json& require(std::string_view key) const;
    std::string at(std::string_view key) const { return child(path_, key); }
    const std::string& path() const { return path_; }

    // Optional typed fields: leave `out` untouched when the key is absent.
    void num(std::string_view k, double& out) const {
        if (auto v = get(k)) out = number(c_, *v, at(k));
    }
    void pos(std::string_view k, double& out) const {
        if (auto v = get(k)) out = positive(c_, *v, at(k));
    }
    void nonNeg(std::string_view k, double& out) const {
        if (auto v = get(k)) out = nonNegative(c_, *v, at(k));
    }
    void v3(std::string_view k, glm::dvec3& out) const {
        if (auto v = get(k)) out = vec3(c_, *v, at(k));
    }
    void flag(std::string_view k, bool& out) const {
        if (auto v = get(k)) out = boolean(c_, *v, at(k));
    }
    void str(std::string_view k, std::string& out) const {
        if (auto v = get(k)) out = string(c_, *v, at(k));
    }
    void i(std::string_view k, int& out, int lo, int hi) const {
        if (auto v = get(k)) out = intIn(c_, *v, at(k), lo, hi);
    }

  private:
    const Ctx& c_;
    const json& v_;
    std::string path_;
};

} // namespace voxtier::detail
