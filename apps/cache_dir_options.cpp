#include "apps/cache_dir_options.hpp"

#include "apps/cli_options.hpp"

#include <cstdio>

namespace voxtier::cli {

void addCacheDirOptions(CLI::App& cmd, CacheDirArgs& args, const std::string& what) {
    CLI::Option* dir = cmd.add_option("--cache-dir", args.dir,
                                      "On-disk snapshot cache: " + what +
                                          " (created if missing; files are checked, bad ones "
                                          "re-baked)");
    // Beyond a petabyte is a typo, not a budget.
    cmd.add_option("--cache-dir-mb", args.limitMb,
                   "Size limit of the --cache-dir directory in MiB (the least recently used "
                   "model frames' packs are removed first; default: no limit)")
        ->check(numberIn(1, 1e9, "MiB"))
        ->needs(dir);
}

std::string mebibytes(double bytes) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.2f MiB", bytes / double(1 << 20));
    return buf;
}

std::string cacheDirSummary(const SnapshotStoreOptions& o, const SnapshotStoreCounters& c) {
    char buf[512];
    std::snprintf(buf, sizeof buf,
                  "cache dir %s: %llu snapshots read (%.2f MiB, %.1f ms), %llu written (%.2f MiB, "
                  "%.1f ms), %llu missing, %llu rejected, %llu evicted (%.2f MiB)",
                  o.dir.string().c_str(), static_cast<unsigned long long>(c.reads),
                  c.bytesRead / 1048576.0, c.readMs, static_cast<unsigned long long>(c.writes),
                  c.bytesWritten / 1048576.0, c.writeMs, static_cast<unsigned long long>(c.misses),
                  static_cast<unsigned long long>(c.rejected),
                  static_cast<unsigned long long>(c.evicted), c.bytesEvicted / 1048576.0);
    std::string line = buf;
    if (c.staleTempsRemoved > 0) {
        std::snprintf(buf, sizeof buf, ", %llu dead writers' temporar%s removed (%.2f MiB)",
                      static_cast<unsigned long long>(c.staleTempsRemoved),
                      c.staleTempsRemoved == 1 ? "y" : "ies", c.staleTempBytes / 1048576.0);
        line += buf;
    }
    if (c.lockWaitMs >= 1.0) {
        std::snprintf(buf, sizeof buf, ", %.0f ms waiting for other processes' locks",
                      c.lockWaitMs);
        line += buf;
    }
    // What the size limit counted, temporaries included: why a directory of small packs can
    // still be over its limit (other writers' temporaries, removed only once stale).
    if (o.limitBytes > 0 && c.limitScans > 0) {
        std::snprintf(buf, sizeof buf, "; limit %.2f MiB: %.2f MiB counted", o.limitBytes / 1048576.0,
                      c.countedBytes / 1048576.0);
        line += buf;
        if (c.countedTemps > 0) {
            std::snprintf(buf, sizeof buf, ", %.2f MiB of it in %llu temporar%s",
                          c.countedTempBytes / 1048576.0,
                          static_cast<unsigned long long>(c.countedTemps),
                          c.countedTemps == 1 ? "y" : "ies");
            line += buf;
        }
    }
    return line;
}

std::string cacheDirWriteWarning(const SnapshotStoreOptions& o, const SnapshotStoreCounters& c) {
    return "warning: cache dir " + o.dir.string() + ": " + std::to_string(c.writeFailures) +
           " snapshot" + (c.writeFailures == 1 ? "" : "s") + " could not be written (" +
           (c.writeFailureReason.empty() ? "unknown reason" : c.writeFailureReason) +
           "); they are baked again when next needed";
}

} // namespace voxtier::cli
