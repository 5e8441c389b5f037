#pragma once
// The snapshot cache's two file formats (impostor_cache/snapshot_store.hpp keeps them on disk):
// a snapshot file (one view of a model frame: its key, cells, depth and a checksum of its own)
// and a pack (every view of one model frame: a header, an index sorted by view with a checksum,
// then the views' snapshot files). Both are untrusted input: every size field is bounded before
// anything is allocated from it, and a checksum is checked before what it covers is used; what
// fails throws SnapshotFileError naming the reason (one line).
//
// The digest that names the files and checksums them is not cryptographic: it tells different
// content apart (a damaged or foreign file), it does not resist someone forging one.
#include "core/view_set.hpp"
#include "core/voxel_model.hpp"
#include "impostor_cache/snapshot.hpp"

#include <array>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

namespace voxtier {

/// Bumped whenever the snapshot file layout (also a pack's entry) changes.
inline constexpr std::uint32_t kSnapshotFileVersion = 1;
/// Bumped whenever the pack layout changes.
inline constexpr std::uint32_t kSnapshotPackVersion = 1;
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
/// digestBytes of bytes given in pieces: the same digest as of their concatenation, however
/// they are cut (a pack's snapshots are checked in pieces, never read whole).
class DigestStream {
  public:
    explicit DigestStream(std::uint64_t seed = 0);
    void add(std::span<const std::uint8_t> bytes);
    Digest128 finish() const;

  private:
    void block(const std::uint8_t* p);
    std::uint64_t a_, b_, n_ = 0;
    std::array<std::uint8_t, 16> tail_{};
};
/// The voxels and dimensions of a grid.
Digest128 digestGrid(const VoxelGrid& grid);

/// What determines a snapshot's bytes (with the format version and lattice rule constants).
struct SnapshotFileKey {
    Digest128 grid;         ///< digestGrid of the model frame
    glm::ivec3 dims{0};     ///< the grid's dimensions
    ViewId view;            ///< the direction baked
    double sigma = 1.0;     ///< virtual pixels per voxel
    bool withDepth = false; ///< Snapshot::depth stored
    int outlineStride = 1;  ///< Snapshot::outlineStride
    bool operator==(const SnapshotFileKey&) const = default;
};
/// The key's file, relative to the cache directory: "ab/<32 hex digits>.snap", the first two
/// digits as a subdirectory so that no directory holds more than 1/256 of a large library.
std::filesystem::path snapshotFileName(const SnapshotFileKey& key);

/// The pack holding every view of the key's model frame (the key's view is not in its name),
/// relative to the cache directory: "ab/<32 hex digits>.pack".
std::filesystem::path snapshotPackName(const SnapshotFileKey& key);

/// Why a file cannot be used (one line; what the warning says).
class SnapshotFileError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

/// The bytes of the file a snapshot without depth takes, for a model frame of `dims` seen along
/// `view` at `sigma`: the snapshot lattice fixes the cell count before anything is traced, so
/// `bake` can say what it will write before it writes it.
std::uint64_t snapshotFileBytes(glm::ivec3 dims, ViewId view, double sigma);
/// The exact bytes of the snapshot file of `key`; SnapshotFileError when a key field is out of
/// bounds (a key read from a file).
std::uint64_t snapshotFileBytes(const SnapshotFileKey& key);

/// The bytes a pack of `views` snapshots takes beyond their snapshot files (header, index,
/// checksum): a pack's size is this plus the snapshotFileBytes of each view.
std::uint64_t snapshotPackOverhead(std::size_t views);

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

/// One view of a pack: the snapshot file's bytes (encodeSnapshotFile) for it.
struct SnapshotPackEntry {
    ViewId view;
    std::vector<std::uint8_t> file;
};
/// A pack of the model frame of `frame` (its view ignored): `entries` in any order, one per view.
/// The bytes depend only on the set of entries.
std::vector<std::uint8_t> encodeSnapshotPack(const SnapshotFileKey& frame,
                                             std::vector<SnapshotPackEntry> entries);
struct DecodedSnapshotPack {
    SnapshotFileKey frame; ///< view: the first entry's (or the default)
    std::vector<SnapshotPackEntry> entries;
};
/// Parses an untrusted pack: the header and the index are checked (sizes before allocation,
/// the checksum before use); the entries' snapshot files are not (decodeSnapshotFile does that
/// where one is used). Throws SnapshotFileError naming what is wrong.
DecodedSnapshotPack decodeSnapshotPack(std::span<const std::uint8_t> bytes);

// ---- packs on a descriptor: read in pieces, each bounded before anything is allocated -------

/// The most views a pack may index: above the 98,306 of the largest view set (`--level 64`), so
/// a pack's parsed index takes at most a few MB whatever its header claims.
inline constexpr std::size_t kMaxPackViews = std::size_t(1) << 17;

/// Where one view's snapshot file lies in a pack.
struct PackIndexEntry {
    ViewId view;
    std::uint64_t offset = 0, bytes = 0;
};
/// A pack's parsed index: the model frame (view: the default) and its views, ascending.
struct PackIndex {
    SnapshotFileKey frame;
    std::vector<PackIndexEntry> entries;
    /// The entry of `view`, or null.
    const PackIndexEntry* find(ViewId view) const;
};
/// The bytes of a pack's header and index checksum (what identifies its index).
inline constexpr std::size_t kPackHeadBytes = 68 + 16;
/// A pack's fixed-size opening, checked: its header's fields, bounded against the file's size.
struct PackHead {
    std::array<std::uint8_t, kPackHeadBytes> bytes{}; ///< the header, then the index checksum
    SnapshotFileKey frame;
    std::size_t count = 0;  ///< index entries (at most kMaxPackViews)
    std::uint64_t size = 0; ///< the pack's bytes (the file's, as the header says too)
};
/// Reads and checks the head of the pack open at `fd`, a regular file of `size` bytes (its
/// fstat): nothing is read beyond what the header allows. Throws SnapshotFileError.
PackHead readPackHead(int fd, std::uint64_t size);
/// Reads exactly the index `head` implies and checks it (checksum, views primitive and
/// ascending, entries contiguous to the end of the pack).
PackIndex readPackIndex(int fd, const PackHead& head);
/// The snapshot of `entry` in the pack open at `fd`, checked as the snapshot of `key` (its size
/// against the one the key implies before it is read, then decodeSnapshotFile, then its key).
DecodedSnapshotFile readPackEntry(int fd, const PackIndexEntry& entry, const SnapshotFileKey& key);
/// Checks the snapshot of `entry` as decodeSnapshotFile would, for `key`, reading it in pieces
/// of at most a MiB: what a writer keeps of the pack it replaces. Throws SnapshotFileError.
void checkPackEntry(int fd, const PackIndexEntry& entry, const SnapshotFileKey& key);
/// Reads exactly `n` bytes at `offset`, or throws SnapshotFileError (with the OS reason).
void preadExact(int fd, std::uint8_t* dst, std::size_t n, std::uint64_t offset);
/// Reads the snapshot file open at `fd` (the former one-file-per-snapshot layout), checked as
/// the file of `key`: the header first (key and size), then exactly the size it implies.
std::vector<std::uint8_t> readSnapshotFile(int fd, const SnapshotFileKey& key);

/// One view written into a pack: its snapshot file in memory, or `size` bytes at `offset` of
/// the pack open at `fd` (an entry checkPackEntry passed), copied in pieces.
struct PackSource {
    ViewId view;
    std::span<const std::uint8_t> bytes;
    int fd = -1;
    std::uint64_t offset = 0, size = 0;
};
/// Writes the pack of `frame` holding `sources` (one per view, any order) to `out` from its
/// current position, the same bytes as encodeSnapshotPack of them, without holding more than
/// the index and a MiB of them at once. Returns the bytes written. Throws std::system_error
/// with the OS reason where a write fails, SnapshotFileError where a source cannot be read.
std::uint64_t writePackTo(int out, const SnapshotFileKey& frame, std::vector<PackSource> sources);

/// Whether two keys name the same model frame (all but the view).
bool sameFrame(const SnapshotFileKey& a, const SnapshotFileKey& b);
/// A view as the index orders it (x, then y, then z).
std::array<int, 3> viewOrder(ViewId v);

} // namespace voxtier
