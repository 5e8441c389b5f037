#pragma once
// `--cache-dir DIR [--cache-dir-mb MB]`: the on-disk snapshot cache of render, bench and bake
// (impostor_cache/snapshot_store.hpp), the same two options and one summary line everywhere.
#include "impostor_cache/snapshot_store.hpp"

#include <CLI/CLI.hpp>

#include <cstdint>
#include <optional>
#include <string>

namespace voxtier::cli {

struct CacheDirArgs {
    std::string dir;               ///< "" = no on-disk cache
    std::optional<double> limitMb; ///< size limit of the directory (none = unlimited)
    std::uint64_t limitBytes() const {
        return limitMb ? std::uint64_t(*limitMb * double(1 << 20)) : 0;
    }
};

/// Adds --cache-dir (and --cache-dir-mb, which needs it) to `cmd`; `what` says what reads it.
void addCacheDirOptions(CLI::App& cmd, CacheDirArgs& args, const std::string& what);
/// "24.64 MiB": bytes in binary megabytes, the one unit every size the CLI prints is in.
std::string mebibytes(double bytes);
/// "cache dir DIR: 98 snapshots read (0.09 MiB, 12.3 ms), 0 written (0.00 MiB, 0.0 ms), 0 missing,
/// 0 rejected, 0 evicted (0.00 MiB)", then the dead writers' temporaries removed, if any, and,
/// with a size limit, what it counted at its last scan and how much of that was temporaries.
std::string cacheDirSummary(const SnapshotStoreOptions& options,
                            const SnapshotStoreCounters& counters);
/// "warning: cache dir DIR: 126 snapshots could not be written (No space left on device)"
/// when counters.writeFailures > 0: the one line a run prints about failed writes.
std::string cacheDirWriteWarning(const SnapshotStoreOptions& options,
                                 const SnapshotStoreCounters& counters);

} // namespace voxtier::cli
