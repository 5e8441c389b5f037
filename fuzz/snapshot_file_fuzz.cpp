// libFuzzer target: the on-disk snapshot file and pack readers (impostor_cache/snapshot_store.hpp)
// on arbitrary bytes. The only acceptable outcomes are a decoded snapshot (or pack) that encodes
// back to the very same bytes, or a SnapshotFileError; anything else (crash, sanitizer report,
// allocation beyond the input's size, other exception, hang) is a bug.
#include "impostor_cache/snapshot_store.hpp"

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <span>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    try {
        const voxtier::DecodedSnapshotFile f =
            voxtier::decodeSnapshotFile(std::span<const std::uint8_t>(data, size));
        const std::vector<std::uint8_t> again = voxtier::encodeSnapshotFile(f.key, f.snapshot);
        if (again.size() != size || std::memcmp(again.data(), data, size) != 0) std::abort();
    } catch (const voxtier::SnapshotFileError&) {
    }
    try {
        const auto bytes = std::span<const std::uint8_t>(data, size);
        voxtier::DecodedSnapshotPack p = voxtier::decodeSnapshotPack(bytes);
        const std::vector<std::uint8_t> again =
            voxtier::encodeSnapshotPack(p.frame, std::move(p.entries));
        if (again.size() != size || std::memcmp(again.data(), data, size) != 0) std::abort();
    } catch (const voxtier::SnapshotFileError&) {
    }
    return 0;
}
