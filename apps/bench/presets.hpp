#pragma once
// The bench's presets as data: one row per preset (how many repeats, path frames, sweep points
// and scaling points a run measures), and one row per command-line override of a preset's
// figure (its flag, its bound, the field it sets). makePlan applies the overrides to the named
// preset; `voxtier bench`'s options are declared from the same rows, so a flag, its check, its
// help and makePlan cannot drift apart.
#include "apps/bench/suite.hpp"

#include <optional>
#include <span>
#include <string>
#include <vector>

namespace voxtier::bench {

/// Every preset, in the order --help lists them: "full" (the default), "quick" (--quick: under
/// two minutes on a two-core machine), "smoke" (--smoke, test-only: tiny scenes, one repeat, one
/// sweep point).
std::span<const Preset> presets();
/// The preset of that name; std::logic_error for a name not in the table.
const Preset& presetNamed(const std::string& name);

/// An integer figure of the preset that a flag overrides.
struct CountOverride {
    const char* flag;
    std::optional<int> SuiteOptions::*given;
    int Preset::*field;
    int least;       ///< the least value allowed
    const char* why; ///< why that bound ("" if it needs no reason)
    const char* help;
};
std::span<const CountOverride> countOverrides();

/// A list of integers of the preset that a flag overrides ("a,b,c"; a value named twice is
/// measured once).
struct ListOverride {
    const char* flag;
    std::string SuiteOptions::*given;
    std::vector<int> Preset::*field;
    int lo, hi; ///< each value in [lo, hi]
    const char* help;
};
std::span<const ListOverride> listOverrides();

/// "(full 7, quick 3)": a figure's value in each preset a user can name, for --help.
std::string presetDefaults(int Preset::*field);
std::string presetDefaults(std::vector<int> Preset::*field);

/// The named preset with the overrides of `options` applied; InputError naming the flag for a
/// value out of its bounds (the command line checks them too, while parsing).
Plan makePlan(const SuiteOptions& options);

} // namespace voxtier::bench
