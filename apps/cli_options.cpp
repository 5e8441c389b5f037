#include "apps/cli_options.hpp"

#include "core/error.hpp"
#include "image_files/image_files.hpp"

#include <cerrno>
#include <climits>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <sstream>

namespace voxtier::cli {

namespace {

std::string shown(double v) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%g", v);
    return buf;
}

/// The whole of `text` as a number (strtod's forms: "1e3", "0x10", "nan", "inf"), else nullopt.
std::optional<double> readNumber(const std::string& text) {
    if (text.empty()) return std::nullopt;
    char* end = nullptr;
    const double v = std::strtod(text.c_str(), &end);
    if (end != text.c_str() + text.size()) return std::nullopt;
    return v;
}

/// The whole of `text` as a decimal integer of int's range, else nullopt. No leading zeros:
/// CLI11 converts "010" as octal and "0x10" as hex, so the value checked is the value stored.
std::optional<int> readInt(const std::string& text) {
    const std::size_t digits = text.find_first_not_of("+-") == 1 ? 1 : 0;
    if (text.size() <= digits ||
        text.find_first_not_of("0123456789", digits) != std::string::npos ||
        (text[digits] == '0' && text.size() > digits + 1))
        return std::nullopt;
    errno = 0;
    const long long v = std::strtoll(text.c_str(), nullptr, 10);
    if (errno == ERANGE || v < INT_MIN || v > INT_MAX) return std::nullopt;
    return int(v);
}

/// "a,b" -> {a, b}, each the whole of its part as a number.
std::optional<glm::dvec2> readNumberPair(const std::string& text) {
    const auto at = text.find(',');
    if (at == std::string::npos) return std::nullopt;
    const auto a = readNumber(text.substr(0, at)), b = readNumber(text.substr(at + 1));
    if (!a || !b) return std::nullopt;
    return glm::dvec2(*a, *b);
}

std::string got(const std::string& text) {
    return ", got '" + text + "'";
}

} // namespace

CLI::Validator intIn(int lo, int hi) {
    const std::string range = "[" + std::to_string(lo) + ", " + std::to_string(hi) + "]";
    return CLI::Validator(
        [lo, hi, range](std::string& text) {
            const std::optional<int> v = readInt(text);
            return v && *v >= lo && *v <= hi ? std::string()
                                             : "expected an integer in " + range + got(text);
        },
        "in " + range);
}

CLI::Validator atLeast(int lo, const std::string& why) {
    const std::string bound = ">= " + std::to_string(lo);
    const std::string expected =
        "expected an integer " + bound + (why.empty() ? "" : " (" + why + ")");
    return CLI::Validator(
        [lo, expected](std::string& text) {
            const std::optional<int> v = readInt(text);
            return v && *v >= lo ? std::string() : expected + got(text);
        },
        bound);
}

CLI::Validator numberIn(double lo, double hi, const std::string& unit) {
    const std::string range =
        (std::isinf(hi) ? ">= " + shown(lo) : "in [" + shown(lo) + ", " + shown(hi) + "]") +
        (unit.empty() ? "" : " " + unit);
    return CLI::Validator(
        [lo, hi, range](std::string& text) {
            const std::optional<double> v = readNumber(text);
            return v && std::isfinite(*v) && *v >= lo && *v <= hi
                       ? std::string()
                       : "expected a finite number " + range + got(text);
        },
        range);
}

CLI::Validator finite() {
    return CLI::Validator(
        [](std::string& text) {
            const std::optional<double> v = readNumber(text);
            return v && std::isfinite(*v) ? std::string() : "expected a finite number" + got(text);
        },
        "");
}

CLI::Validator sigmaRange() {
    const std::string range = "(0, " + shown(Limits::kMaxSigma) + "]";
    return CLI::Validator(
        [range](std::string& text) {
            const std::optional<double> v = readNumber(text);
            return v && *v > 0.0 && *v <= Limits::kMaxSigma
                       ? std::string()
                       : "expected virtual pixels per voxel in " + range + got(text);
        },
        "in " + range);
}

CLI::Validator intList(int lo, int hi) {
    const std::string range = "[" + std::to_string(lo) + ", " + std::to_string(hi) + "]";
    return CLI::Validator(
        [lo, hi, range](std::string& text) {
            std::stringstream items(text);
            std::string item;
            int count = 0;
            bool ok = true;
            while (ok && std::getline(items, item, ',')) {
                const std::optional<int> v = readInt(item);
                ok = v && *v >= lo && *v <= hi;
                ++count;
            }
            return ok && count > 0
                       ? std::string()
                       : "expected a comma-separated list of integers in " + range + got(text);
        },
        "a,b,... each in " + range);
}

std::optional<glm::ivec2> readImageSize(const std::string& text) {
    const auto at = text.find('x');
    if (at == std::string::npos) return std::nullopt;
    const std::optional<int> w = readInt(text.substr(0, at)), h = readInt(text.substr(at + 1));
    if (!w || !h || *w < 1 || *h < 1 || *w > Limits::kMaxImageDim || *h > Limits::kMaxImageDim)
        return std::nullopt;
    return glm::ivec2(*w, *h);
}

CLI::Validator imageSize() {
    const std::string range = "[1, " + std::to_string(Limits::kMaxImageDim) + "]";
    return CLI::Validator(
        [range](std::string& text) {
            return readImageSize(text) ? std::string()
                                       : "expected WxH with integers in " + range + got(text);
        },
        "W, H in " + range);
}

std::optional<glm::dvec2> readViewAngles(const std::string& text) {
    const std::optional<glm::dvec2> v = readNumberPair(text);
    if (!v || !std::isfinite(v->x) || !(v->y >= -90.0 && v->y <= 90.0)) return std::nullopt;
    return v;
}

CLI::Validator viewAngles() {
    return CLI::Validator(
        [](std::string& text) {
            return readViewAngles(text) ? std::string()
                                        : "expected AZIMUTH,ELEVATION in degrees "
                                          "(elevation in [-90, 90])" +
                                              got(text);
        },
        "ELEVATION in [-90, 90]");
}

std::optional<FrameRange> readFrameRange(const std::string& text) {
    std::vector<std::optional<int>> parts;
    std::stringstream items(text);
    std::string item;
    while (std::getline(items, item, ':')) parts.push_back(readInt(item));
    if (parts.size() < 2 || parts.size() > 3 || text.back() == ':') return std::nullopt;
    for (const auto& p : parts)
        if (!p) return std::nullopt;
    const FrameRange r{*parts[0], *parts[1], parts.size() == 3 ? *parts[2] : 1};
    if (r.first < 0 || r.last < r.first || r.step < 1) return std::nullopt;
    return r;
}

CLI::Validator frameRange() {
    return CLI::Validator(
        [](std::string& text) {
            return readFrameRange(text) ? std::string()
                                        : "expected FIRST:LAST[:STEP] with 0 <= FIRST <= LAST "
                                          "and STEP >= 1" +
                                              got(text);
        },
        "FIRST <= LAST");
}

CLI::Validator imageFileName() {
    std::string list;
    for (const char* e : kImageExtensions) list += (list.empty() ? "" : ", ") + std::string(e);
    return CLI::Validator(
        [list](std::string& text) {
            const std::string ext = lowerExtension(text);
            for (const char* e : kImageExtensions)
                if (ext == e) return imageFormatRefusal(text);
            return "expected an image file name ending in one of " + list + got(text);
        },
        "");
}

const char* defaultImageExtension() {
    return imageLibraryAvailable() ? ".png" : ".pam";
}

void addFrameFlags(CLI::App& cmd, FrameOptions& options, const FrameFlagHelp& help) {
    addChoiceOption(cmd, "--far-backend", options.farBackend, kFarBackendNames, "far backend",
                    help.farBackend);
    addChoiceOption(
        cmd, "--near-rate", options.nearRate, kNearRateNames, "near rate",
        "Near sprites traced per pixel (fragment), once per lattice cell and looked up per pixel "
        "(cell), or cell-rate where it is cheaper (auto); same image");
    addChoiceOption(cmd, "--near-pixels", options.nearPixels, kNearPixelsNames, "near pixels",
                    "How the Vulkan near tier traces its per-pixel sprites: compute (every pixel "
                    "of their rectangles in a compute pass), raster (their proxies rasterised, "
                    "the kernel in the fragment shader) or auto (default: compute on a GPU, "
                    "raster on a CPU device such as lavapipe); same image");
    addChoiceOption(cmd, "--near-records", options.nearRecords, kNearRecordsNames, "near records",
                    "Where the Vulkan near tier lays its sprite records: drawn (default: in the "
                    "draw order, gathered by the host) or given (in entity order, read by the "
                    "host in sequence, found by the device through each draw place); same image");
    addChoiceOption(cmd, "--far-tiles", options.farTiles, kFarTilesNames, "far tiles",
                    "How the Vulkan far pass is cut into workgroups: coarse (a 32x32-pixel tile "
                    "a workgroup, its far sprites passed over its pixels one after another), "
                    "fine (8x8 tiles: 16 times as many workgroups), sprites (a far sprite a "
                    "workgroup, each pixel's winner by an atomic minimum, then resolved) or "
                    "auto (default: sprites); same image");
    addChoiceOption(cmd, "--far-blit", options.farBlit.kernel, kFarBlitNames, "far blit",
                    "The far blit's kernel: simd (spans of pixels on the widest SIMD unit "
                    "of this CPU) or scalar (one pixel at a time, the reference); same "
                    "image");
    auto* on = cmd.add_flag_callback(
        "--cull", [&options] { options.occlusionCull = true; },
        "Exact occlusion culling in the CPU tiers as well: sprites drawn front to back, skipping "
        "the tiles and whole sprites nearer ones already hide (pays where large sprites hide "
        "whole others); same image");
    auto* off = cmd.add_flag_callback(
        "--no-cull",
        [&options] {
            options.occlusionCull = false;
            options.earlyDepthTest = false;
        },
        "No occlusion culling at all, not even the near tier's early depth test (on by "
        "default: the CPU reference and Vulkan skip pixels a nearer sprite already holds); same "
        "image, for comparisons");
    on->excludes(off);
    cmd.add_flag("--near-skip-empty", options.nearSkipEmpty,
                 "The Vulkan near tier marches over empty space too, as the CPU reference does "
                 "(off by default: on llvmpipe it costs more than it saves); same image");
    cmd.add_flag("!--no-cost-bound", options.costAwareBakes, help.costBound);
}

} // namespace voxtier::cli
