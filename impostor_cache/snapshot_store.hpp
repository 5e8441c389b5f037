#pragma once
// The on-disk snapshot cache (DESIGN.md §4 "Persistence"): baked snapshots outlive the process,
// so a render, a bench or a shipped game reads them instead of baking, and a model library can
// be pre-baked (`voxtier bake --cache-dir`), on a cluster too (`bake --shard I/N`).
//
// One file per snapshot, named by a digest of everything that determines its bytes: the model
// frame's voxels and dimensions, sigma, the view direction (ViewId), whether depth is stored, the
// lattice rule and the file format version. The palette is not in the key: a snapshot holds
// palette indices. Files are written to a temporary name and renamed, so a reader never sees half
// a file and two processes baking the same key both succeed (the last rename wins; both files
// are the same bytes). A file is untrusted input: every field is bounded before any allocation,
// and a file that is truncated, corrupted (checksum), foreign (magic), of another format version
// or lattice rule, or written for another key is never used: one warning line naming the file and
// the reason, and the caller re-bakes and replaces it.
//
// Size limit: readers hold a shared flock while they read and then touch the file's mtime (the
// least-recently-used order); the evictor removes the oldest files first and only those it can
// lock exclusively without waiting, so a file another process is reading is never removed.
//
// Write failures (a full disk, a read-only directory) are counted with the first one's OS reason,
// not warned per file: the caller says so once (render: one warning line; bake: a failed run).
//
// Temporaries of writers that died (a killed bake) are removed when a store is opened and by the
// size limit's sweep: a "*.snap.tmp*" file whose mtime is older than staleTempAge (an hour) and
// that no process holds (a writer keeps an exclusive flock on its temporary until it is renamed;
// the sweeper removes only what it can lock without waiting). Why that is safe with concurrent
// writers on shared storage: a write takes milliseconds, so an hour-old temporary is a dead
// writer's; where flock does not reach across machines, the age alone decides, and even removing
// a live (hour-stalled) writer's temporary only makes its rename fail, which is a counted write
// failure, never a partial file under a final name.
#include "core/voxel_model.hpp"
#include "impostor_cache/snapshot.hpp"
#include "impostor_cache/view_set.hpp"

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <mutex>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

namespace voxtier {

/// Bumped whenever the file layout changes.
inline constexpr std::uint32_t kSnapshotFileVersion = 1;
/// Bumped whenever snapshotLattice, snapshotRayFrame or the bake's cell rule change what a
/// snapshot holds for the same voxels: files baked by the old rule are then never found.
inline constexpr std::uint32_t kSnapshotLatticeRule = 1;

/// A 128-bit digest (two 64-bit lanes); not cryptographic, it tells different content apart.
struct Digest128 {
    std::uint64_t lo = 0, hi = 0;
    bool operator==(const Digest128&) const = default;
    /// For VersionedLru, which memoises the digest of each model frame version.
    std::size_t bytes() const { return sizeof(Digest128); }
};
Digest128 digestBytes(std::span<const std::uint8_t> bytes, std::uint64_t seed = 0);
/// The voxels and dimensions of a grid.
Digest128 digestGrid(const VoxelGrid& grid);

/// What determines a snapshot's bytes (with the format version and lattice rule constants).
struct SnapshotFileKey {
    Digest128 grid;         ///< digestGrid of the model frame
    glm::ivec3 dims{0};     ///< the grid's dimensions
    ViewId view;            ///< the direction baked
    double sigma = 1.0;     ///< virtual pixels per voxel
    bool withDepth = false; ///< Snapshot::depth stored
    bool operator==(const SnapshotFileKey&) const = default;
};
/// The key's file, relative to the cache directory: "ab/<32 hex digits>.snap", the first two
/// digits as a subdirectory so that no directory holds more than 1/256 of a large library.
std::filesystem::path snapshotFileName(const SnapshotFileKey& key);

/// Why a file cannot be used (one line; what the warning says).
class SnapshotFileError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

/// The bytes of the file a snapshot without depth takes, for a model frame of `dims` seen along
/// `view` at `sigma`: the snapshot lattice fixes the cell count before anything is traced, so
/// `bake` can say what it will write before it writes it.
std::uint64_t snapshotFileBytes(glm::ivec3 dims, ViewId view, double sigma);

/// The file bytes of a snapshot baked for `key`.
std::vector<std::uint8_t> encodeSnapshotFile(const SnapshotFileKey& key, const Snapshot& snap);
struct DecodedSnapshotFile {
    SnapshotFileKey key;
    Snapshot snapshot;
};
/// Parses untrusted bytes; throws SnapshotFileError naming what is wrong. Every size field is
/// checked against the lattice its key fields imply (which are bounded first) before any
/// allocation, and the checksum before the payload is used.
DecodedSnapshotFile decodeSnapshotFile(std::span<const std::uint8_t> bytes);

struct SnapshotStoreOptions {
    std::filesystem::path dir;
    /// Bytes of snapshot files kept in the directory (0: no limit); least recently used beyond.
    std::uint64_t limitBytes = 0;
    /// Where warnings go (one line each, no newline); default: stderr.
    std::function<void(const std::string&)> warn;
    /// A temporary file older than this that no process holds is a dead writer's (see above).
    std::chrono::seconds staleTempAge{3600};
};

struct SnapshotStoreCounters {
    std::uint64_t reads = 0;  ///< snapshots read from valid files
    std::uint64_t misses = 0; ///< keys with no file
    std::uint64_t rejected =
        0;                    ///< files not used (truncated, corrupted, foreign, stale, wrong key)
    std::uint64_t writes = 0; ///< files written
    std::uint64_t bytesRead = 0, bytesWritten = 0;
    std::uint64_t evicted = 0, bytesEvicted = 0; ///< files removed for the size limit
    std::uint64_t writeFailures = 0;             ///< files that could not be written
    std::string writeFailureReason;              ///< the first failure's OS reason
    std::uint64_t staleTempsRemoved = 0;         ///< dead writers' temporaries removed
    double readMs = 0.0, writeMs = 0.0;
};

/// One file in the directory, as the evictor sees it.
struct SnapshotStoreFile {
    std::filesystem::path path;
    std::uint64_t bytes = 0;
    std::filesystem::file_time_type lastUse;
};

class SnapshotStore {
  public:
    /// Creates the directory if needed; throws InputError(dir, "--cache-dir") if it cannot.
    explicit SnapshotStore(SnapshotStoreOptions options);

    /// The snapshot stored for `key`, or nullopt when there is no file or it is not usable (then
    /// one warning line; the caller bakes and save() replaces the file). Marks the file used.
    std::optional<Snapshot> load(const SnapshotFileKey& key);
    /// Whether a file for `key` exists (not read, not validated, not marked used): enough for
    /// planning what a frame can have without baking, since load() still checks the file and
    /// the caller re-bakes a bad one.
    bool contains(const SnapshotFileKey& key) const;
    /// Writes the file (temporary name, then rename), then keeps the size limit. Returns false
    /// when it could not be written (counted, with the reason; no warning, no file left): the
    /// cache is an optimisation, the caller decides whether that fails its run.
    bool save(const SnapshotFileKey& key, const Snapshot& snap);
    /// Removes the temporaries of writers that died (the rule above). Returns how many.
    std::size_t removeStaleTemporaries();
    /// Removes least recently used files until the directory is at most `targetBytes`, skipping
    /// files another process is reading. Returns the bytes left.
    std::uint64_t evictDownTo(std::uint64_t targetBytes);
    /// Every snapshot file of the directory, oldest use first.
    std::vector<SnapshotStoreFile> list() const;

    std::filesystem::path pathOf(const SnapshotFileKey& key) const;
    const SnapshotStoreOptions& options() const { return options_; }
    SnapshotStoreCounters counters() const;

  private:
    void warn(const std::filesystem::path& file, const std::string& reason);
    void keepLimitAfterWrite(std::uint64_t fileBytes);

    SnapshotStoreOptions options_;
    mutable std::mutex mutex_;
    SnapshotStoreCounters counters_;
    std::mutex limitMutex_; ///< for approxBytes_ (and one scan at a time)
    /// The directory's bytes as this process last scanned them plus what it wrote since (other
    /// processes write too: a scan corrects it before anything is removed).
    std::optional<std::uint64_t> approxBytes_;
};

} // namespace voxtier
