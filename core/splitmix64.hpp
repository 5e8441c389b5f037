#pragma once
// Deterministic PRNG: splitmix64 (Steele, Lea, Flood 2014). Its output is fully specified, so a
// seeded crowd or a seeded procedural model is the same on every platform and standard library
// (std::*_distribution is not).
#include <cstdint>

namespace voxtier {

/// splitmix64's finaliser (its output function): every input bit reaches every output bit. Also
/// what the snapshot files' digest mixes with (impostor_cache/snapshot_format.cpp).
constexpr std::uint64_t splitmix64Mix(std::uint64_t z) {
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
}

struct SplitMix64 {
    std::uint64_t state;
    std::uint64_t next() { return splitmix64Mix(state += 0x9e3779b97f4a7c15ull); }
    /// Uniform in [0, 1) with 53 random bits.
    double unit() { return double(next() >> 11) * 0x1.0p-53; }
    /// Uniform in [lo, hi).
    double uniform(double lo, double hi) { return lo + (hi - lo) * unit(); }
    /// Uniform in [0, n) (modulo bias < n / 2^64, irrelevant for picks among a few items).
    std::uint64_t below(std::uint64_t n) { return next() % n; }
};

} // namespace voxtier
