#pragma once
// The on-disk snapshot cache (docs/baking.md): baked snapshots outlive the process, so a render,
// a bench or a shipped game reads them instead of baking, and a model library can be pre-baked
// (`voxtier bake --cache-dir`), on a cluster too (`bake --shard I/N`). The file formats are
// impostor_cache/snapshot_format.hpp; this is the directory: where files go, who may write
// them when, and how big it may grow.
//
// Snapshots are kept in packs: one file per model frame (its voxels and dimensions, sigma,
// whether depth is stored, the lattice rule and the pack format version, digested into the
// name "ab/<32 hex digits>.pack") holding every view of it baked so far.
//
// A pack is never changed in place. A writer merges the pack's valid snapshots with its new
// ones, writes the whole to a temporary name and renames it over the pack, holding an exclusive
// flock on the subdirectory's ".lock" file from the read to the rename, so that writers in
// other processes (or on other machines, where flock reaches) add their views instead of losing
// them; a reader sees the old pack or the new one, never half of one, and a failed write leaves
// the old one. The pack's bytes depend only on the set of snapshots (index sorted by view), so
// the shards of a bake, in any order, give the unsharded bake's files. Where flock does not reach
// across machines, two writers of one pack at the same moment may drop one's new views (the last
// rename wins): those are baked again when next needed, never read wrong.
//
// Nothing waits for ever. A reader never waits for a writer (writers never lock a pack
// exclusively; a pack the evictor is removing is a miss). A writer waits for a subdirectory's
// lock at most lockWait per flush, in total over all its subdirectories; past it, that
// subdirectory's packs are not written (a write failure whose reason names the folder), and a
// later flush tries it once without waiting. Every descriptor and lock is held by a guard, so no
// failure (an exception included) leaves one held; the destructor flushes under the same rules.
//
// Writes are buffered per pack (save()) and written by flush(): when the buffer holds
// flushBytes, when its oldest snapshot waited flushAfter (both checked at the next save), on
// flush() (bake: after each model frame; render: before its summary) and in the destructor.
// Rewriting a pack per snapshot would copy it once per view; with writeOnlyOnFlush (bake) a
// pack is written once per flush() however big it is, so the bytes written are the packs'.
//
// A file is untrusted input. A path is opened without following a symbolic link and without
// blocking (a FIFO), and is used only if fstat says it is a regular file; a pack's fields are
// bounded before anything is allocated or read from them, and its snapshots are read one at a
// time (a writer checks and copies the old pack's in pieces). A pack that is not a regular file,
// truncated, corrupted (checksum), foreign (magic), of another format version or lattice rule,
// or written for another model frame is never used, and a snapshot in it that fails its own
// checks is re-baked alone: one warning line per pack naming the file and the first reason,
// however many of its views are asked for; the pack is replaced by the next write (a directory
// in its place removed). Files of the former layout (one "ab/<hex>.snap" file per snapshot) are
// still read, checked the same way, and evicted by the size limit; new snapshots go to packs.
//
// Size limit: readers hold a shared flock on a pack while they read it and then touch its mtime
// (the least-recently-used order); the evictor removes the least recently used packs first
// (a model frame's views together) and only those it can lock exclusively without waiting, so a
// pack another process is reading is never removed. The limit counts writers' temporaries too
// (they take the disk's space), though only stale ones can be removed.
//
// Write failures (a full disk, a read-only directory, a stuck lock) are counted per snapshot
// with the first one's reason (the errno of the step that failed first), not warned per file:
// the caller says so once (render: one warning line; bake: a failed run).
//
// Temporaries of writers that died (a killed bake) are removed when a store is opened and by the
// size limit's sweep: a "*.pack.tmp*" (or former "*.snap.tmp*") file whose mtime is older than
// staleTempAge (an hour) and that no process holds (a writer keeps an exclusive flock on its
// temporary until it is renamed; the sweeper removes only what it can lock without waiting). Why
// that is safe with concurrent writers on shared storage: a write takes milliseconds, so an
// hour-old temporary is a dead writer's; where flock does not reach across machines, the age
// alone decides, and even removing a live (hour-stalled) writer's temporary only makes its rename
// fail, which is a counted write failure, never a partial file under a final name.
#include "impostor_cache/snapshot_format.hpp"

#include <array>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <vector>

namespace voxtier {

struct SnapshotStoreOptions {
    std::filesystem::path dir;
    /// Bytes of snapshot files kept in the directory (0: no limit); least recently used beyond.
    std::uint64_t limitBytes = 0;
    /// Where warnings go (one line each, no newline); default: stderr.
    std::function<void(const std::string&)> warn;
    /// A temporary file older than this that no process holds is a dead writer's (see above).
    std::chrono::seconds staleTempAge{3600};
    /// Buffered snapshots are written when they reach this many bytes, or when the oldest has
    /// waited flushAfter (checked at the next save), besides flush() and the destructor.
    std::uint64_t flushBytes = std::uint64_t(32) << 20;
    std::chrono::milliseconds flushAfter{5000};
    /// Only flush() and the destructor write (bake): each pack once per flush, its views held
    /// in memory until then, instead of rewriting a big pack each time the buffer fills.
    bool writeOnlyOnFlush = false;
    /// The longest one flush waits for subdirectory locks other processes hold, in total.
    std::chrono::milliseconds lockWait{2000};
    /// Called with the name of each step of a pack write ("folder", "locked": the folder's lock
    /// held, "read", "write", "rename") before it is taken: for tests, which throw from it or
    /// stop the process there. When not set, the environment variable VOXTIER_STORE_FAULT
    /// ("alloc@STEP": throw std::bad_alloc; "stop@STEP": SIGSTOP the process) sets it, so a
    /// fault test can inject into the command-line tool.
    std::function<void(std::string_view step)> beforeStep;
};

struct SnapshotStoreCounters {
    std::uint64_t reads = 0;  ///< snapshots read from valid files
    std::uint64_t misses = 0; ///< keys with no snapshot in the directory
    /// Snapshots not used (their pack or file not a regular file, truncated, corrupted, foreign,
    /// stale, wrong key).
    std::uint64_t rejected = 0;
    std::uint64_t writes = 0;       ///< snapshots written (into packs)
    std::uint64_t packWrites = 0;   ///< packs written (each a whole file)
    std::uint64_t bytesRead = 0;    ///< snapshot file bytes read (a pack's index not counted)
    std::uint64_t bytesWritten = 0; ///< bytes of the packs written
    std::uint64_t evicted = 0, bytesEvicted = 0; ///< files (packs) removed for the size limit
    std::uint64_t writeFailures = 0;             ///< snapshots that could not be written
    std::string writeFailureReason;              ///< the first failure's reason
    std::uint64_t staleTempsRemoved = 0;         ///< dead writers' temporaries removed
    std::uint64_t staleTempBytes = 0;            ///< their bytes
    /// What the size limit counted at its last scan (limitScans > 0: there is a limit and it
    /// scanned): the directory's bytes after its evictions, of which `countedTemps` writers'
    /// temporaries took countedTempBytes.
    std::uint64_t limitScans = 0, countedBytes = 0, countedTempBytes = 0, countedTemps = 0;
    double readMs = 0.0, writeMs = 0.0;
    double lockWaitMs = 0.0; ///< flushes' time waiting for folder locks other processes held
};

/// One file (a pack, or a former single snapshot file) in the directory, as the evictor sees it.
struct SnapshotStoreFile {
    std::filesystem::path path;
    std::uint64_t bytes = 0;
    std::filesystem::file_time_type lastUse;
};

class SnapshotStore {
  public:
    /// Creates the directory if needed; throws InputError(dir, "--cache-dir") if it cannot.
    explicit SnapshotStore(SnapshotStoreOptions options);
    /// Writes what is still buffered (flush(); its lock waits bounded like any flush's).
    ~SnapshotStore();
    SnapshotStore(const SnapshotStore&) = delete;
    SnapshotStore& operator=(const SnapshotStore&) = delete;

    /// The snapshot stored for `key` (buffered, in its pack, or in a former single file), or
    /// nullopt when there is none or it is not usable (then one warning line, once per pack; the
    /// caller bakes and save() replaces it). Marks the pack used. Never waits for a lock.
    std::optional<Snapshot> load(const SnapshotFileKey& key);
    /// Whether the directory has `key` (its pack's index is read, the snapshot is not validated,
    /// nothing is marked used): enough for planning what a frame can have without baking, since
    /// load() still checks the snapshot and the caller re-bakes a bad one.
    bool contains(const SnapshotFileKey& key) const;
    /// Buffers the snapshot for its pack; writes the buffer when it is due (see above). Returns
    /// false when a write it did failed (counted, with the reason; no warning, no file left):
    /// the cache is an optimisation, the caller decides whether that fails its run.
    bool save(const SnapshotFileKey& key, const Snapshot& snap);
    /// Writes every buffered snapshot into its pack (merged with the pack's valid snapshots,
    /// temporary name, then rename), then keeps the size limit. Returns false when any could
    /// not be written (counted per snapshot, as above).
    bool flush();
    /// Removes the temporaries of writers that died (the rule above). Returns how many.
    std::size_t removeStaleTemporaries();
    /// Removes least recently used files until the directory (temporaries counted) is at most
    /// `targetBytes`, skipping files another process is reading. Returns the bytes left.
    std::uint64_t evictDownTo(std::uint64_t targetBytes);
    /// Every pack (and former single snapshot file) of the directory, oldest use first.
    std::vector<SnapshotStoreFile> list() const;

    /// The pack of `key`.
    std::filesystem::path pathOf(const SnapshotFileKey& key) const;
    const SnapshotStoreOptions& options() const { return options_; }
    SnapshotStoreCounters counters() const;

  private:
    using File = std::shared_ptr<const std::vector<std::uint8_t>>;
    /// What is buffered for one pack: its model frame and the snapshot files by view.
    struct Pending {
        SnapshotFileKey frame;
        std::map<std::array<int, 3>, File> files;
    };
    struct PackWrite {
        int error = 0; ///< errno of the first step that failed, 0: written
        std::uint64_t bytes = 0, replacedBytes = 0;
    };
    struct CachedIndex;
    struct Scan;
    std::shared_ptr<const CachedIndex> readPackIndex(int fd, const std::string& pack) const;
    bool flushLocked();
    PackWrite writePack(const std::filesystem::path& pack, const Pending& pending);
    std::optional<Snapshot> loadFormerFile(const SnapshotFileKey& key,
                                           std::chrono::steady_clock::time_point t0);
    /// One warning line per pack: true when this is the pack's first.
    bool warnOnce(const std::filesystem::path& file, const std::string& reason);
    void reject(const std::filesystem::path& file, const std::string& reason);
    void keepLimitAfterWrite(std::uint64_t fileBytes);
    Scan scan() const;
    void step(std::string_view name) const;

    SnapshotStoreOptions options_;
    mutable std::mutex mutex_;
    SnapshotStoreCounters counters_;
    std::mutex limitMutex_; ///< for approxBytes_ (and one scan at a time)
    /// The directory's bytes as this process last scanned them plus what it wrote since (other
    /// processes write too: a scan corrects it before anything is removed).
    std::optional<std::uint64_t> approxBytes_;
    // The write buffer, under mutex_: by pack path relative to the directory.
    std::map<std::string, Pending> pending_;
    std::uint64_t pendingBytes_ = 0;
    std::chrono::steady_clock::time_point pendingSince_;
    std::mutex flushMutex_; ///< one flush at a time
    /// Subdirectories whose lock a flush waited lockWait for in vain (under flushMutex_): later
    /// flushes try them once without waiting, so a stuck writer costs one wait in all.
    std::set<std::string> stuckFolders_;
    /// The packs' indexes parsed so far (under mutex_), reused while a pack is the same file.
    mutable std::map<std::string, std::shared_ptr<const CachedIndex>> indexes_;
    static constexpr std::size_t kMaxCachedIndexes = 4096;
    /// Packs warned about (one line each), under mutex_; forgotten when rewritten.
    std::set<std::string> warnedPacks_;
};

} // namespace voxtier
