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
    std::snprintf(
        buf, sizeof buf,
        "cache dir %s: %llu snapshots read (%s, %.1f ms), %llu written (%s, %.1f ms), "
        "%llu missing, %llu rejected, %llu evicted",
        o.dir.string().c_str(), static_cast<unsigned long long>(c.reads),
        mebibytes(double(c.bytesRead)).c_str(), c.readMs, static_cast<unsigned long long>(c.writes),
        mebibytes(double(c.bytesWritten)).c_str(), c.writeMs,
        static_cast<unsigned long long>(c.misses), static_cast<unsigned long long>(c.rejected),
        static_cast<unsigned long long>(c.evicted));
    return buf;
}

std::string cacheDirWriteWarning(const SnapshotStoreOptions& o, const SnapshotStoreCounters& c) {
    return "warning: cache dir " + o.dir.string() + ": " + std::to_string(c.writeFailures) +
           " snapshot" + (c.writeFailures == 1 ? "" : "s") + " could not be written (" +
           (c.writeFailureReason.empty() ? "unknown reason" : c.writeFailureReason) +
           "); they are baked again when next needed";
}

} // namespace voxtier::cli
