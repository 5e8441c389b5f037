#pragma once
// The value checks of the voxtier command line, as CLI11 validators: each one shows what it
// allows in `--help` (after the option's type, e.g. `--repeat INT:>= 1`) and rejects a bad value
// while the command line is parsed, with one line naming the option, what is allowed and what
// was given. apps/main.cpp prints those as usage errors (exit 2); errors that need an input
// file's contents (a model index past the file's models, ...) stay InputErrors (exit 1).
//
// CLI11's own CLI::Range, CLI::PositiveNumber and CLI::CheckedTransformer are not used directly:
// Range lets nan through and prints doubles as "0.000000 to 16.000000", PositiveNumber's message
// prints DBL_MAX in full, and CheckedTransformer lists an enum's integers ("{far->2,...} OR
// {2,...}"). These keep CLI11's mechanism (and its `{a,b}` / ExistingFile forms) with the
// project's one-line messages.
#include "compose/frame.hpp"
#include "core/view_set.hpp"

#include <CLI/CLI.hpp>
#include <glm/glm.hpp>

#include <initializer_list>
#include <optional>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

namespace voxtier::cli {

/// An integer in [lo, hi] ("in [1, 1000000]"); on a vector option (->delimiter(',')), each item.
CLI::Validator intIn(int lo, int hi);
/// An integer >= lo (">= 1"); `why`, if given, follows the bound in the error.
CLI::Validator atLeast(int lo, const std::string& why = "");
/// A finite number in [lo, hi] (hi = infinity: >= lo); `unit` follows in both texts
/// ("in [1, 65536] MiB").
CLI::Validator numberIn(double lo, double hi, const std::string& unit = "");
/// A finite number (rejects nan and inf, which CLI11 reads as doubles).
CLI::Validator finite();
/// Virtual pixels per voxel: (0, Limits::kMaxSigma], the bound every sigma obeys.
CLI::Validator sigmaRange();
/// "a,b,c", each an integer in [lo, hi], at least one: for list options stored as text.
CLI::Validator intList(int lo, int hi);

/// "640x480" -> {640, 480}; nullopt unless both are integers in 1..Limits::kMaxImageDim.
std::optional<glm::ivec2> readImageSize(const std::string& text);
/// An image size WxH (readImageSize).
CLI::Validator imageSize();
/// "30,20" -> {30, 20}; nullopt unless two finite numbers, the second (an elevation) in [-90, 90].
std::optional<glm::dvec2> readViewAngles(const std::string& text);
/// A view direction AZIMUTH,ELEVATION in degrees (readViewAngles).
CLI::Validator viewAngles();

/// Frames first..last (inclusive), every step-th.
struct FrameRange {
    int first = 0, last = 0, step = 1;
};
/// "A:B" or "A:B:STEP" -> {A, B, STEP}; nullopt unless 0 <= A <= B and STEP >= 1.
std::optional<FrameRange> readFrameRange(const std::string& text);
/// A frame range A:B[:STEP] (readFrameRange).
CLI::Validator frameRange();

/// The image file extensions voxtier writes (image_files/image_files.hpp): .pam with no library,
/// the others through OpenImageIO where the build has it.
inline constexpr const char* kImageExtensions[] = {".png", ".exr", ".gif", ".tif", ".jpg", ".pam"};
/// A file name ending in one of kImageExtensions (any case) that this build can write (a build
/// without OpenImageIO refuses all but .pam, with image_files' one-line reason).
CLI::Validator imageFileName();
/// The extension of the default output image: .png, or .pam in a build without OpenImageIO.
const char* defaultImageExtension();

/// One of the names of a name table (pairs of name and enum value, e.g. compose/frame.hpp's
/// kRenderModeNames): `--help` lists them as {a,b,c}, a bad value reads "unknown <what> 'x'
/// (expected: a, b, c)", and the option's enum variable gets the value (the validator hands
/// CLI11 the enum's integer). Use with ->transform.
template <class Names> CLI::Validator oneOf(const Names& names, const std::string& what) {
    std::string set, allowed;
    for (const auto& [name, value] : names) {
        set += (set.empty() ? "" : ",") + std::string(name);
        allowed += (allowed.empty() ? "" : ", ") + std::string(name);
    }
    return CLI::Validator(
        [names, what, allowed](std::string& text) {
            for (const auto& [name, value] : names)
                if (text == name) {
                    using Int = std::underlying_type_t<std::decay_t<decltype(value)>>;
                    text = std::to_string(static_cast<Int>(value));
                    return std::string();
                }
            return "unknown " + what + " '" + text + "' (expected: " + allowed + ")";
        },
        "{" + set + "}");
}

/// A name table of enum values named by their toString (found by argument-dependent lookup).
template <class E> std::vector<std::pair<std::string, E>> namesOf(std::initializer_list<E> values) {
    std::vector<std::pair<std::string, E>> names;
    for (E v : values) names.emplace_back(toString(v), v);
    return names;
}

/// The far view sets by their view counts: "26", "98", "218".
inline std::vector<std::pair<std::string, ViewSet>> viewSetNames() {
    std::vector<std::pair<std::string, ViewSet>> names;
    for (ViewSet s : {ViewSet::Cube26, ViewSet::Cube98, ViewSet::Cube218})
        names.emplace_back(std::to_string(viewCount(s)), s);
    return names;
}

/// What the shared frame flags say in one command's `--help` where they mean something of their
/// own there.
struct FrameFlagHelp {
    std::string farBackend; ///< --far-backend
    std::string costBound;  ///< --no-cost-bound
};

/// The flags `render` and `bench` share, bound straight into the FrameOptions the command draws
/// with (one place, so the two commands cannot drift apart):
/// - `--far-backend auto|vulkan|cpu` (FrameOptions::farBackend);
/// - `--near-rate auto|fragment|cell` (nearRate, compose/frame.hpp kNearRateNames);
/// - `--near-pixels auto|compute|raster` (nearPixels, kNearPixelsNames);
/// - `--near-records drawn|given` (nearRecords, kNearRecordsNames);
/// - `--far-tiles auto|coarse|fine|sprites` (farTiles, kFarTilesNames);
/// - `--far-blit simd|scalar` (farBlit.kernel, kFarBlitNames);
/// - the occlusion switches (CONTRACT.md §6, Occlusion): by default the near tier's early depth
///   test alone; `--cull` adds the CPU tiers' tiles and whole-sprite drops (occlusionCull);
///   `--no-cull` turns every kind off, the early depth test too (earlyDepthTest), for comparisons;
/// - `--no-cost-bound` (costAwareBakes off).
/// Each option's default is the value `options` holds when bound; `options` must outlive the
/// parse.
void addFrameFlags(CLI::App& cmd, FrameOptions& options, const FrameFlagHelp& help);

/// The name of `value` in a name table (for ->default_str).
template <class Names, class E> std::string nameOf(const Names& names, E value) {
    for (const auto& [name, v] : names)
        if (v == value) return name;
    return "?";
}

/// An option `name` taking one of the names of a name table (oneOf), defaulting to `value`'s.
template <class Names, class E>
CLI::Option* addChoiceOption(CLI::App& cmd, const std::string& name, E& value, const Names& names,
                             const std::string& what, const std::string& help) {
    return cmd.add_option(name, value, help)
        ->type_name("TEXT")
        ->transform(oneOf(names, what))
        ->default_str(nameOf(names, value));
}

} // namespace voxtier::cli
