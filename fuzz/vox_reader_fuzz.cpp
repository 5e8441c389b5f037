// libFuzzer target: the .vox reader on arbitrary bytes. The only acceptable outcomes are a
// parsed file or an InputError; anything else (crash, sanitizer report, other exception,
// hang) is a bug.
#include "core/error.hpp"
#include "core/vox_reader.hpp"

#include <cstddef>
#include <cstdint>
#include <span>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    try {
        // Keep a single input's memory bounded so the fuzzer explores structure, not RAM.
        voxtier::VoxReadLimits limits;
        limits.maxVoxelCells = std::size_t(1) << 24;
        const voxtier::VoxFile f =
            voxtier::parseVox(std::span<const std::uint8_t>(data, size), "fuzz.vox", limits);
        (void)f.totalVoxels();
    } catch (const voxtier::InputError&) {
    }
    return 0;
}
