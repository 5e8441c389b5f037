#pragma once
// Numbers unique within the process, for objects that must tell their own data from another
// instance's (a SpriteStore's history, a SnapshotCache's batches): never 0, never handed out twice.
#include <atomic>
#include <cstdint>

namespace voxtier {

/// A number no earlier call in this process returned (1, 2, ...; thread-safe).
inline std::uint64_t newProcessUid() {
    static std::atomic<std::uint64_t> last{0};
    return ++last;
}

} // namespace voxtier
