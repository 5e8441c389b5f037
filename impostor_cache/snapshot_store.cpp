#include "impostor_cache/snapshot_store.hpp"

#include "core/error.hpp"
#include "core/stopwatch.hpp"

#include <sys/file.h>
#include <sys/stat.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fcntl.h>
#include <system_error>
#include <unistd.h>

namespace voxtier {

namespace {

// ---- digest -------------------------------------------------------------------------------

std::uint64_t rotl(std::uint64_t x, int r) {
    return (x << r) | (x >> (64 - r));
}
/// splitmix64's finaliser: every input bit reaches every output bit.
std::uint64_t finalMix(std::uint64_t z) {
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
}
std::uint64_t loadWord(const std::uint8_t* p) {
    std::uint64_t w = 0;
    for (int i = 0; i < 8; ++i) w |= std::uint64_t(p[i]) << (8 * i); // little-endian everywhere
    return w;
}

// ---- file layout ----------------------------------------------------------------------------
// Little-endian, fixed offsets:
//   magic[8] "VXSNAP\r\n" | u32 format version | u32 lattice rule | u64 grid digest lo, hi |
//   i32 dims[3] | i32 view[3] | f64 sigma | u32 flags (bit 0: depth) | i32 cellRange[4] |
//   u64 cell count | u64 depth count | cells (index, code) x cell count | f32 depth x depth count |
//   u64 checksum lo, hi (digestBytes of everything before it)
constexpr char kMagic[8] = {'V', 'X', 'S', 'N', 'A', 'P', '\r', '\n'};
constexpr std::size_t kHeaderBytes = 8 + 4 + 4 + 16 + 12 + 12 + 8 + 4 + 16 + 8 + 8;
constexpr std::size_t kChecksumBytes = 16;
constexpr std::uint32_t kFlagDepth = 1;
/// Bits 8-15 of the flags: the outline stride less one (0 in files of stride 1, so files written
/// before the stride existed read as stride 1).
constexpr int kStrideShift = 8;
constexpr std::uint32_t kStrideMask = 0xFFu << kStrideShift;
std::uint32_t flagsOf(const SnapshotFileKey& k) {
    return (k.withDepth ? kFlagDepth : 0u) | (std::uint32_t(k.outlineStride - 1) << kStrideShift);
}
/// The key's flag fields from a file's flags word, checked.
void readFlags(std::uint32_t flags, SnapshotFileKey& k) {
    if (flags & ~(kFlagDepth | kStrideMask)) throw SnapshotFileError("unknown flags");
    k.withDepth = flags & kFlagDepth;
    k.outlineStride = int((flags & kStrideMask) >> kStrideShift) + 1;
    if (k.outlineStride > kMaxSnapshotScale) throw SnapshotFileError("outline stride out of range");
}
/// View lattice components a file may name: far beyond any view set (n = 3 uses 3), small enough
/// that the normalisation is exact.
constexpr int kMaxViewComponent = 1 << 12;

class Writer {
  public:
    explicit Writer(std::vector<std::uint8_t>& out) : out_(out) {}
    void bytes(const void* p, std::size_t n) {
        const auto* b = static_cast<const std::uint8_t*>(p);
        for (std::size_t i = 0; i < n; ++i)
            out_.push_back(b[i]); // (insert: a GCC 12 false warning)
    }
    void u32(std::uint32_t v) {
        for (int i = 0; i < 4; ++i) out_.push_back(std::uint8_t(v >> (8 * i)));
    }
    void u64(std::uint64_t v) {
        for (int i = 0; i < 8; ++i) out_.push_back(std::uint8_t(v >> (8 * i)));
    }
    void i32(int v) { u32(std::uint32_t(v)); }
    void f64(double v) {
        std::uint64_t bits;
        std::memcpy(&bits, &v, 8);
        u64(bits);
    }

  private:
    std::vector<std::uint8_t>& out_;
};

/// Reads the fixed-size header; the caller has checked that it is all there.
class Reader {
  public:
    explicit Reader(const std::uint8_t* p) : p_(p) {}
    std::uint32_t u32() {
        std::uint32_t v = 0;
        for (int i = 0; i < 4; ++i) v |= std::uint32_t(p_[i]) << (8 * i);
        p_ += 4;
        return v;
    }
    std::uint64_t u64() {
        const std::uint64_t v = loadWord(p_);
        p_ += 8;
        return v;
    }
    int i32() { return int(u32()); }
    double f64() {
        const std::uint64_t bits = u64();
        double v;
        std::memcpy(&v, &bits, 8);
        return v;
    }

  private:
    const std::uint8_t* p_;
};

std::string hex(std::uint64_t v) {
    char buf[17];
    std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(v));
    return buf;
}

/// The lattice of a key, or SnapshotFileError when the key fields are out of bounds (a file's
/// key fields are checked here before anything is sized from them).
SpriteLattice latticeOf(const SnapshotFileKey& k) {
    for (int c = 0; c < 3; ++c)
        if (k.dims[c] < 1 || k.dims[c] > Limits::kMaxModelDim)
            throw SnapshotFileError("dims out of range");
    for (int c = 0; c < 3; ++c)
        if (k.view.lattice[c] < -kMaxViewComponent || k.view.lattice[c] > kMaxViewComponent)
            throw SnapshotFileError("view out of range");
    if (k.view.lattice == glm::ivec3(0) || !(viewIdOf(k.view.lattice) == k.view))
        throw SnapshotFileError("view is not a primitive lattice vector");
    if (!(k.sigma > 0.0 && k.sigma <= Limits::kMaxSigma)) // also rejects nan
        throw SnapshotFileError("sigma out of range");
    return snapshotLattice(viewDirection(k.view), k.dims, k.sigma, k.outlineStride);
}

std::size_t cellCount(const SpriteLattice& L) {
    return std::size_t(L.width()) * std::size_t(L.height());
}

std::size_t fileSize(std::size_t cells, std::size_t depths) {
    return kHeaderBytes + cells * sizeof(SnapshotCell) + depths * sizeof(float) + kChecksumBytes;
}

} // namespace

std::uint64_t snapshotFileBytes(glm::ivec3 dims, ViewId view, double sigma) {
    return fileSize(cellCount(snapshotLattice(viewDirection(view), dims, sigma)), 0);
}

Digest128 digestBytes(std::span<const std::uint8_t> bytes, std::uint64_t seed) {
    // Two independent multiply-rotate lanes over 16-byte blocks (a grid of 256^3 digests in a
    // few ms), the length and a finaliser at the end.
    constexpr std::uint64_t P1 = 0x9e3779b185ebca87ull, P2 = 0xc2b2ae3d27d4eb4full;
    std::uint64_t a = seed ^ 0x243f6a8885a308d3ull, b = ~seed ^ 0x13198a2e03707344ull;
    const std::uint8_t* p = bytes.data();
    const std::size_t n = bytes.size();
    std::size_t i = 0;
    for (; i + 16 <= n; i += 16) {
        a = rotl(a ^ (loadWord(p + i) * P2), 31) * P1;
        b = rotl(b ^ (loadWord(p + i + 8) * P1), 29) * P2;
    }
    std::uint8_t tail[16] = {};
    std::memcpy(tail, p + i, n - i);
    a = rotl(a ^ (loadWord(tail) * P2), 31) * P1;
    b = rotl(b ^ (loadWord(tail + 8) * P1), 29) * P2;
    a = finalMix(a ^ n);
    b = finalMix(b ^ rotl(n, 32) ^ a);
    return {finalMix(a ^ b), b};
}

Digest128 digestGrid(const VoxelGrid& grid) {
    const glm::ivec3 d = grid.dims();
    const std::uint64_t seed =
        finalMix(std::uint64_t(std::uint32_t(d.x)) | std::uint64_t(std::uint32_t(d.y)) << 21 |
                 std::uint64_t(std::uint32_t(d.z)) << 42);
    return digestBytes(grid.data(), seed);
}

namespace {

/// What determines a snapshot's bytes, in file order: both the file name (its digest) and the
/// header (checked on read) are made of it.
void writeKey(Writer& w, const SnapshotFileKey& k) {
    w.u32(kSnapshotFileVersion);
    w.u32(kSnapshotLatticeRule);
    w.u64(k.grid.lo);
    w.u64(k.grid.hi);
    for (int c = 0; c < 3; ++c) w.i32(k.dims[c]);
    for (int c = 0; c < 3; ++c) w.i32(k.view.lattice[c]);
    w.f64(k.sigma);
    w.u32(flagsOf(k));
}

} // namespace

std::filesystem::path snapshotFileName(const SnapshotFileKey& k) {
    std::vector<std::uint8_t> bytes;
    Writer w(bytes);
    writeKey(w, k);
    const Digest128 d = digestBytes(bytes);
    const std::string name = hex(d.lo) + hex(d.hi);
    return std::filesystem::path(name.substr(0, 2)) / (name + ".snap");
}

std::vector<std::uint8_t> encodeSnapshotFile(const SnapshotFileKey& k, const Snapshot& s) {
    std::vector<std::uint8_t> out;
    out.reserve(fileSize(s.cells.size(), s.depth.size()));
    Writer w(out);
    w.bytes(kMagic, sizeof kMagic);
    writeKey(w, k);
    for (int c = 0; c < 4; ++c) w.i32(s.lattice.cellRange[c]);
    w.u64(s.cells.size());
    w.u64(s.depth.size());
    for (const SnapshotCell& c : s.cells) {
        out.push_back(c.index);
        out.push_back(c.code);
    }
    for (float f : s.depth) {
        std::uint32_t bits;
        std::memcpy(&bits, &f, 4);
        w.u32(bits);
    }
    const Digest128 sum = digestBytes(out);
    w.u64(sum.lo);
    w.u64(sum.hi);
    return out;
}

namespace {

/// The header's fields, every one bounded: what the rest of the file must be.
struct SnapshotFileHeader {
    SnapshotFileKey key;
    SpriteLattice lattice;
    std::size_t cells = 0, depths = 0;
    std::size_t fileBytes = 0; ///< the exact size of the whole file
};

/// The opening every snapshot file and pack shares: its magic (`what` names the kind in the
/// error), its format version, and the lattice rule. Returns a reader past them.
Reader openHeader(const std::uint8_t* header, const char (&magic)[8], const char* what,
                  std::uint32_t expectedVersion) {
    if (std::memcmp(header, magic, sizeof magic) != 0)
        throw SnapshotFileError(std::string("not a voxtier snapshot ") + what + " (magic)");
    Reader r(header + sizeof magic);
    const std::uint32_t version = r.u32(), rule = r.u32();
    if (version != expectedVersion)
        throw SnapshotFileError("stale format version " + std::to_string(version) + " (expected " +
                                std::to_string(expectedVersion) + ")");
    if (rule != kSnapshotLatticeRule)
        throw SnapshotFileError("stale lattice rule " + std::to_string(rule) + " (expected " +
                                std::to_string(kSnapshotLatticeRule) + ")");
    return r;
}

/// Parses the first kHeaderBytes of a file (the caller checked there are that many). Every size
/// is checked against the lattice that the key fields (bounded first) imply, so nothing is
/// sized from an unchecked field.
SnapshotFileHeader decodeHeader(const std::uint8_t* header) {
    Reader r = openHeader(header, kMagic, "file", kSnapshotFileVersion);
    SnapshotFileHeader h;
    SnapshotFileKey& k = h.key;
    k.grid.lo = r.u64();
    k.grid.hi = r.u64();
    for (int c = 0; c < 3; ++c) k.dims[c] = r.i32();
    for (int c = 0; c < 3; ++c) k.view.lattice[c] = r.i32();
    k.sigma = r.f64();
    readFlags(r.u32(), k);
    glm::ivec4 range;
    for (int c = 0; c < 4; ++c) range[c] = r.i32();
    const std::uint64_t cells = r.u64(), depths = r.u64();
    h.lattice = latticeOf(k);
    if (range != h.lattice.cellRange) throw SnapshotFileError("cell range does not match the key");
    h.cells = cellCount(h.lattice);
    h.depths = k.withDepth ? h.cells : 0;
    if (cells != h.cells || depths != h.depths)
        throw SnapshotFileError("cell count does not match the key");
    h.fileBytes = fileSize(h.cells, h.depths);
    return h;
}

void checkSize(std::uint64_t actual, std::uint64_t expected) {
    if (actual != expected)
        throw SnapshotFileError(std::string(actual < expected ? "truncated" : "wrong size") + " (" +
                                std::to_string(actual) + " bytes, expected " +
                                std::to_string(expected) + ")");
}

/// Reads a whole file: the header first, then exactly the size it implies (a file is never read
/// or allocated for by a size it claims before that size has been checked).
std::vector<std::uint8_t> readFile(int fd) {
    struct stat st {};
    if (fstat(fd, &st) != 0) throw SnapshotFileError("cannot stat");
    const std::uint64_t size = std::uint64_t(st.st_size);
    auto readInto = [fd](std::uint8_t* dst, std::size_t n) {
        for (std::size_t done = 0; done < n;) {
            const ssize_t got = ::read(fd, dst + done, n - done);
            if (got < 0 && errno == EINTR) continue;
            if (got <= 0) throw SnapshotFileError("truncated while reading");
            done += std::size_t(got);
        }
    };
    if (size < kHeaderBytes + kChecksumBytes)
        throw SnapshotFileError("truncated (" + std::to_string(size) +
                                " bytes, shorter than the header)");
    std::vector<std::uint8_t> bytes(kHeaderBytes);
    readInto(bytes.data(), kHeaderBytes);
    const SnapshotFileHeader h = decodeHeader(bytes.data());
    checkSize(size, h.fileBytes);
    bytes.resize(h.fileBytes);
    readInto(bytes.data() + kHeaderBytes, h.fileBytes - kHeaderBytes);
    return bytes;
}

} // namespace

DecodedSnapshotFile decodeSnapshotFile(std::span<const std::uint8_t> bytes) {
    if (bytes.size() < kHeaderBytes + kChecksumBytes)
        throw SnapshotFileError("truncated (" + std::to_string(bytes.size()) +
                                " bytes, shorter than the header)");
    const SnapshotFileHeader h = decodeHeader(bytes.data());
    checkSize(bytes.size(), h.fileBytes);
    const std::size_t summed = h.fileBytes - kChecksumBytes;
    const Digest128 sum = digestBytes(bytes.first(summed));
    Reader tail(bytes.data() + summed);
    if (tail.u64() != sum.lo || tail.u64() != sum.hi)
        throw SnapshotFileError("checksum mismatch (corrupted)");

    DecodedSnapshotFile out{h.key, {}};
    Snapshot& s = out.snapshot;
    s.view = h.key.view;
    s.w = viewDirection(h.key.view);
    s.lattice = h.lattice;
    s.outlineStride = h.key.outlineStride;
    s.cells.resize(h.cells);
    const std::uint8_t* p = bytes.data() + kHeaderBytes;
    for (SnapshotCell& c : s.cells) {
        c = {p[0], p[1]};
        p += 2;
        if (c.code > snapshot_code::kOutline) throw SnapshotFileError("bad cell code");
    }
    s.depth.resize(h.depths);
    for (float& f : s.depth) {
        std::uint32_t bits = 0;
        for (int i = 0; i < 4; ++i) bits |= std::uint32_t(p[i]) << (8 * i);
        std::memcpy(&f, &bits, 4);
        p += 4;
    }
    return out;
}

namespace {

// ---- pack layout ----------------------------------------------------------------------------
// Little-endian, fixed offsets:
//   magic[8] "VXPACK\r\n" | u32 pack version | u32 lattice rule | u64 grid digest lo, hi |
//   i32 dims[3] | f64 sigma | u32 flags (bit 0: depth) | u32 entry count | u64 pack bytes |
//   index: (i32 view[3] | u64 offset | u64 bytes) x entry count, views ascending (x, y, z) |
//   u64 checksum lo, hi (digestBytes of the header and the index) |
//   the entries' snapshot files, contiguous, in index order
constexpr char kPackMagic[8] = {'V', 'X', 'P', 'A', 'C', 'K', '\r', '\n'};
constexpr std::size_t kPackHeaderBytes = 8 + 4 + 4 + 16 + 12 + 8 + 4 + 4 + 8;
constexpr std::size_t kPackIndexEntryBytes = 12 + 8 + 8;

/// The model frame part of a key, as a pack's header and name hold it.
void writeFrameKey(Writer& w, const SnapshotFileKey& k) {
    w.u32(kSnapshotPackVersion);
    w.u32(kSnapshotLatticeRule);
    w.u64(k.grid.lo);
    w.u64(k.grid.hi);
    for (int c = 0; c < 3; ++c) w.i32(k.dims[c]);
    w.f64(k.sigma);
    w.u32(flagsOf(k));
}

bool sameFrame(const SnapshotFileKey& a, const SnapshotFileKey& b) {
    return a.grid == b.grid && a.dims == b.dims && a.sigma == b.sigma &&
           a.withDepth == b.withDepth && a.outlineStride == b.outlineStride;
}

std::array<int, 3> viewOrder(ViewId v) {
    return {v.lattice.x, v.lattice.y, v.lattice.z};
}

struct PackIndexEntry {
    ViewId view;
    std::uint64_t offset = 0, bytes = 0;
};
struct PackIndex {
    SnapshotFileKey frame;
    std::vector<PackIndexEntry> entries;
    std::uint64_t indexEnd = 0; ///< where the first entry starts
};

/// Parses the header (the caller has kPackHeaderBytes of it) of a pack of `actualBytes`: every
/// field bounded, the entry count against the bytes there are. Returns the count.
std::size_t decodePackHeader(const std::uint8_t* header, std::uint64_t actualBytes,
                             SnapshotFileKey& frame) {
    Reader r = openHeader(header, kPackMagic, "pack", kSnapshotPackVersion);
    frame.grid.lo = r.u64();
    frame.grid.hi = r.u64();
    for (int c = 0; c < 3; ++c) frame.dims[c] = r.i32();
    frame.sigma = r.f64();
    readFlags(r.u32(), frame);
    const std::uint32_t count = r.u32();
    const std::uint64_t total = r.u64();
    for (int c = 0; c < 3; ++c)
        if (frame.dims[c] < 1 || frame.dims[c] > Limits::kMaxModelDim)
            throw SnapshotFileError("dims out of range");
    if (!(frame.sigma > 0.0 && frame.sigma <= Limits::kMaxSigma))
        throw SnapshotFileError("sigma out of range");
    checkSize(actualBytes, total);
    const std::uint64_t minEntry = kPackIndexEntryBytes + kHeaderBytes + kChecksumBytes;
    if (count > (total - kPackHeaderBytes - kChecksumBytes) / minEntry)
        throw SnapshotFileError("entry count does not fit the pack");
    return count;
}

/// Parses the index (`bytes`: the header's count of entries, then the checksum) and checks it
/// against `header` and the pack's size: views primitive and ascending, entries contiguous to
/// the end.
PackIndex decodePackIndex(const std::uint8_t* header, std::span<const std::uint8_t> index,
                          std::size_t count, const SnapshotFileKey& frame, std::uint64_t total) {
    std::vector<std::uint8_t> summed(header, header + kPackHeaderBytes);
    summed.insert(summed.end(), index.begin(), index.end() - kChecksumBytes);
    const Digest128 sum = digestBytes(summed);
    Reader tail(index.data() + index.size() - kChecksumBytes);
    if (tail.u64() != sum.lo || tail.u64() != sum.hi)
        throw SnapshotFileError("index checksum mismatch (corrupted)");
    PackIndex out{frame, {}, kPackHeaderBytes + count * kPackIndexEntryBytes + kChecksumBytes};
    out.entries.resize(count);
    Reader r(index.data());
    std::uint64_t at = out.indexEnd;
    for (std::size_t i = 0; i < count; ++i) {
        PackIndexEntry& e = out.entries[i];
        for (int c = 0; c < 3; ++c) e.view.lattice[c] = r.i32();
        e.offset = r.u64();
        e.bytes = r.u64();
        for (int c = 0; c < 3; ++c)
            if (e.view.lattice[c] < -kMaxViewComponent || e.view.lattice[c] > kMaxViewComponent)
                throw SnapshotFileError("index: view out of range");
        if (e.view.lattice == glm::ivec3(0) || !(viewIdOf(e.view.lattice) == e.view))
            throw SnapshotFileError("index: view is not a primitive lattice vector");
        if (i > 0 && !(viewOrder(out.entries[i - 1].view) < viewOrder(e.view)))
            throw SnapshotFileError("index: views not ascending");
        if (e.offset != at || e.bytes < kHeaderBytes + kChecksumBytes || e.bytes > total - at)
            throw SnapshotFileError("index: entry outside the pack");
        at += e.bytes;
    }
    if (at != total) throw SnapshotFileError("index: entries do not end the pack");
    return out;
}

/// Reads exactly `n` bytes at `offset`, or throws SnapshotFileError.
void preadExact(int fd, std::uint8_t* dst, std::size_t n, std::uint64_t offset) {
    for (std::size_t done = 0; done < n;) {
        const ssize_t got = ::pread(fd, dst + done, n - done, off_t(offset + done));
        if (got < 0 && errno == EINTR) continue;
        if (got <= 0) throw SnapshotFileError("truncated while reading");
        done += std::size_t(got);
    }
}

const PackIndexEntry* findView(const PackIndex& index, ViewId view) {
    const auto it = std::lower_bound(
        index.entries.begin(), index.entries.end(), viewOrder(view),
        [](const PackIndexEntry& e, const std::array<int, 3>& v) { return viewOrder(e.view) < v; });
    return it != index.entries.end() && it->view == view ? &*it : nullptr;
}

} // namespace

/// A parsed index and what identifies the pack it came from: a pack is never changed in place
/// (a writer renames a new file over it), so the same file, size, header and index checksum is
/// the same index. (Were it damaged in place meanwhile, each snapshot still has its own key and
/// checksum: a wrong offset is a rejected snapshot, never a wrong one.)
struct SnapshotStore::CachedIndex {
    dev_t dev = 0;
    ino_t ino = 0;
    std::uint64_t size = 0;
    std::array<std::uint8_t, kPackHeaderBytes + kChecksumBytes> headerAndSum{};
    PackIndex index;
};

/// The index of an open pack: the header, the index checksum, then (unless this store parsed
/// that very index already) exactly the index they imply.
std::shared_ptr<const SnapshotStore::CachedIndex>
SnapshotStore::readPackIndex(int fd, const std::string& rel) const {
    struct stat st {};
    if (fstat(fd, &st) != 0) throw SnapshotFileError("cannot stat");
    const std::uint64_t size = std::uint64_t(st.st_size);
    if (size < kPackHeaderBytes + kChecksumBytes)
        throw SnapshotFileError("truncated (" + std::to_string(size) +
                                " bytes, shorter than the header)");
    auto fresh = std::make_shared<CachedIndex>();
    fresh->dev = st.st_dev;
    fresh->ino = st.st_ino;
    fresh->size = size;
    std::uint8_t* header = fresh->headerAndSum.data();
    preadExact(fd, header, kPackHeaderBytes, 0);
    SnapshotFileKey frame;
    const std::size_t count = decodePackHeader(header, size, frame);
    const std::uint64_t indexBytes = count * kPackIndexEntryBytes;
    preadExact(fd, header + kPackHeaderBytes, kChecksumBytes, kPackHeaderBytes + indexBytes);
    {
        std::lock_guard lock(mutex_);
        const auto known = indexes_.find(rel);
        if (known != indexes_.end() && known->second->dev == fresh->dev &&
            known->second->ino == fresh->ino && known->second->size == size &&
            known->second->headerAndSum == fresh->headerAndSum)
            return known->second;
    }
    std::vector<std::uint8_t> index(indexBytes + kChecksumBytes);
    preadExact(fd, index.data(), index.size(), kPackHeaderBytes);
    fresh->index = decodePackIndex(header, index, count, frame, size);
    std::lock_guard lock(mutex_);
    if (indexes_.size() >= kMaxCachedIndexes) indexes_.clear();
    indexes_[rel] = fresh;
    return fresh;
}

std::filesystem::path snapshotPackName(const SnapshotFileKey& k) {
    std::vector<std::uint8_t> bytes;
    Writer w(bytes);
    writeFrameKey(w, k);
    const Digest128 d = digestBytes(bytes);
    const std::string name = hex(d.lo) + hex(d.hi);
    return std::filesystem::path(name.substr(0, 2)) / (name + ".pack");
}

std::uint64_t snapshotPackOverhead(std::size_t views) {
    return kPackHeaderBytes + views * kPackIndexEntryBytes + kChecksumBytes;
}

std::vector<std::uint8_t> encodeSnapshotPack(const SnapshotFileKey& frame,
                                             std::vector<SnapshotPackEntry> entries) {
    std::sort(entries.begin(), entries.end(),
              [](const SnapshotPackEntry& a, const SnapshotPackEntry& b) {
                  return viewOrder(a.view) < viewOrder(b.view);
              });
    std::uint64_t total = snapshotPackOverhead(entries.size());
    for (const SnapshotPackEntry& e : entries) total += e.file.size();
    std::vector<std::uint8_t> out;
    out.reserve(total);
    Writer w(out);
    w.bytes(kPackMagic, sizeof kPackMagic);
    writeFrameKey(w, frame);
    w.u32(std::uint32_t(entries.size()));
    w.u64(total);
    std::uint64_t at = snapshotPackOverhead(entries.size());
    for (const SnapshotPackEntry& e : entries) {
        for (int c = 0; c < 3; ++c) w.i32(e.view.lattice[c]);
        w.u64(at);
        w.u64(e.file.size());
        at += e.file.size();
    }
    const Digest128 sum = digestBytes(out);
    w.u64(sum.lo);
    w.u64(sum.hi);
    for (const SnapshotPackEntry& e : entries) out.insert(out.end(), e.file.begin(), e.file.end());
    return out;
}

DecodedSnapshotPack decodeSnapshotPack(std::span<const std::uint8_t> bytes) {
    if (bytes.size() < kPackHeaderBytes + kChecksumBytes)
        throw SnapshotFileError("truncated (" + std::to_string(bytes.size()) +
                                " bytes, shorter than the header)");
    DecodedSnapshotPack out;
    const std::size_t count = decodePackHeader(bytes.data(), bytes.size(), out.frame);
    const PackIndex index = decodePackIndex(
        bytes.data(),
        bytes.subspan(kPackHeaderBytes, count * kPackIndexEntryBytes + kChecksumBytes), count,
        out.frame, bytes.size());
    for (const PackIndexEntry& e : index.entries) {
        const auto file = bytes.subspan(std::size_t(e.offset), std::size_t(e.bytes));
        out.entries.push_back({e.view, {file.begin(), file.end()}});
    }
    if (!out.entries.empty()) out.frame.view = out.entries.front().view;
    return out;
}

// ---- the store ------------------------------------------------------------------------------

SnapshotStore::SnapshotStore(SnapshotStoreOptions options) : options_(std::move(options)) {
    std::error_code ec;
    std::filesystem::create_directories(options_.dir, ec);
    if (ec || !std::filesystem::is_directory(options_.dir))
        throw InputError(options_.dir.string(), "--cache-dir",
                         "cannot create the directory" + (ec ? ": " + ec.message() : ""));
    if (!options_.warn)
        options_.warn = [](const std::string& line) { std::fprintf(stderr, "%s\n", line.c_str()); };
    removeStaleTemporaries();
}

SnapshotStore::~SnapshotStore() {
    flush();
}

std::filesystem::path SnapshotStore::pathOf(const SnapshotFileKey& key) const {
    return options_.dir / snapshotPackName(key);
}

void SnapshotStore::warn(const std::filesystem::path& file, const std::string& reason) {
    options_.warn("warning: " + file.string() + ": " + reason + "; baking it again");
}

namespace {
std::string viewText(ViewId v) {
    return "view (" + std::to_string(v.lattice.x) + " " + std::to_string(v.lattice.y) + " " +
           std::to_string(v.lattice.z) + ")";
}
int openRead(const std::filesystem::path& p) {
    return ::open(p.c_str(), O_RDONLY | O_CLOEXEC);
}
void lockShared(int fd) {
    while (::flock(fd, LOCK_SH) != 0 && errno == EINTR) {
    }
}
} // namespace

bool SnapshotStore::contains(const SnapshotFileKey& key) const {
    const std::string rel = snapshotPackName(key).string();
    {
        std::lock_guard lock(mutex_);
        const auto p = pending_.find(rel);
        if (p != pending_.end() && p->second.files.count(viewOrder(key.view))) return true;
    }
    const int fd = openRead(options_.dir / rel);
    if (fd >= 0) {
        bool found = false;
        try {
            const auto cached = readPackIndex(fd, rel);
            found =
                sameFrame(cached->index.frame, key) && findView(cached->index, key.view) != nullptr;
        } catch (const SnapshotFileError&) {
            // load() says what is wrong with it
        }
        ::close(fd);
        if (found) return true;
    }
    std::error_code ec;
    return std::filesystem::is_regular_file(options_.dir / snapshotFileName(key), ec);
}

std::optional<Snapshot> SnapshotStore::load(const SnapshotFileKey& key) {
    const auto t0 = std::chrono::steady_clock::now();
    const std::filesystem::path rel = snapshotPackName(key);
    std::vector<std::uint8_t> file;
    {
        // Buffered by this process and not written yet.
        std::lock_guard lock(mutex_);
        const auto p = pending_.find(rel.string());
        if (p != pending_.end()) {
            const auto f = p->second.files.find(viewOrder(key.view));
            if (f != p->second.files.end()) file = f->second;
        }
    }
    const std::filesystem::path path = options_.dir / rel;
    if (file.empty()) {
        const int fd = openRead(path);
        if (fd < 0) return loadFormerFile(key, t0);
        // Shared lock while reading: the evictor skips packs it cannot lock exclusively.
        lockShared(fd);
        try {
            const auto cached = readPackIndex(fd, rel.string());
            if (!sameFrame(cached->index.frame, key))
                throw SnapshotFileError("written for another key");
            const PackIndexEntry* e = findView(cached->index, key.view);
            if (e) {
                file.resize(std::size_t(e->bytes));
                preadExact(fd, file.data(), file.size(), e->offset);
                ::futimens(fd, nullptr); // now: most recently used (atime is unreliable)
            }
        } catch (const SnapshotFileError& e) {
            // The pack as a whole: one line per pack, however many of its views are asked for.
            ::close(fd);
            bool first = false;
            {
                std::lock_guard lock(mutex_);
                ++counters_.rejected;
                first = warnedPacks_.insert(rel.string()).second;
            }
            if (first) warn(path, e.what());
            return std::nullopt;
        }
        ::close(fd);
        if (file.empty()) return loadFormerFile(key, t0);
    }
    std::optional<Snapshot> snap;
    try {
        DecodedSnapshotFile f = decodeSnapshotFile(file);
        if (!(f.key == key)) throw SnapshotFileError("written for another key");
        snap = std::move(f.snapshot);
    } catch (const SnapshotFileError& e) {
        warn(path, viewText(key.view) + ": " + e.what());
        std::lock_guard lock(mutex_);
        ++counters_.rejected;
        return std::nullopt;
    }
    std::lock_guard lock(mutex_);
    ++counters_.reads;
    counters_.bytesRead += file.size();
    counters_.readMs += msSince(t0);
    return snap;
}

std::optional<Snapshot> SnapshotStore::loadFormerFile(const SnapshotFileKey& key,
                                                      std::chrono::steady_clock::time_point t0) {
    const std::filesystem::path path = options_.dir / snapshotFileName(key);
    const int fd = openRead(path);
    if (fd < 0) {
        std::lock_guard lock(mutex_);
        ++counters_.misses;
        return std::nullopt;
    }
    lockShared(fd);
    std::optional<Snapshot> snap;
    std::size_t bytes = 0;
    try {
        const std::vector<std::uint8_t> data = readFile(fd);
        bytes = data.size();
        DecodedSnapshotFile f = decodeSnapshotFile(data);
        if (!(f.key == key)) throw SnapshotFileError("written for another key");
        snap = std::move(f.snapshot);
        ::futimens(fd, nullptr);
    } catch (const SnapshotFileError& e) {
        ::close(fd);
        warn(path, e.what());
        std::lock_guard lock(mutex_);
        ++counters_.rejected;
        return std::nullopt;
    }
    ::close(fd);
    std::lock_guard lock(mutex_);
    ++counters_.reads;
    counters_.bytesRead += bytes;
    counters_.readMs += msSince(t0);
    return snap;
}

bool SnapshotStore::save(const SnapshotFileKey& key, const Snapshot& snap) {
    std::vector<std::uint8_t> file = encodeSnapshotFile(key, snap);
    const std::string rel = snapshotPackName(key).string();
    const auto now = std::chrono::steady_clock::now();
    bool due = false;
    {
        std::lock_guard lock(mutex_);
        if (pending_.empty()) pendingSince_ = now;
        Pending& p = pending_[rel];
        p.frame = key;
        pendingBytes_ += file.size();
        auto [it, added] = p.files.try_emplace(viewOrder(key.view), std::move(file));
        if (!added) pendingBytes_ -= it->second.size(); // the same bytes again
        due = pendingBytes_ >= options_.flushBytes || now - pendingSince_ >= options_.flushAfter;
    }
    // A flush already running in another thread writes what was there before; the rest waits
    // for the next one rather than this thread waiting for it.
    if (!due || !flushMutex_.try_lock()) return true;
    std::lock_guard flushing(flushMutex_, std::adopt_lock);
    return flushLocked();
}

bool SnapshotStore::flush() {
    std::lock_guard flushing(flushMutex_);
    return flushLocked();
}

bool SnapshotStore::flushLocked() {
    std::map<std::string, Pending> work;
    {
        std::lock_guard lock(mutex_);
        work = pending_; // copied: load() keeps finding these until they are in their pack
    }
    bool ok = true;
    for (const auto& [rel, p] : work) {
        const auto t0 = std::chrono::steady_clock::now();
        const PackWrite w = writePack(options_.dir / rel, p);
        {
            std::lock_guard lock(mutex_);
            if (w.error == 0) {
                counters_.writes += p.files.size();
                ++counters_.packWrites;
                counters_.bytesWritten += w.bytes;
                counters_.writeMs += msSince(t0);
                warnedPacks_.erase(rel);
            } else if ((counters_.writeFailures += p.files.size()) == p.files.size()) {
                counters_.writeFailureReason = std::generic_category().message(w.error);
            }
            // Written or failed, they leave the buffer: a failed one is baked again when next
            // needed, as a snapshot that was never saved.
            Pending& left = pending_[rel];
            for (const auto& [view, file] : p.files)
                if (left.files.erase(view)) pendingBytes_ -= file.size();
            if (left.files.empty()) pending_.erase(rel);
            if (pending_.empty()) pendingBytes_ = 0;
        }
        if (w.error == 0 && w.bytes > w.replacedBytes)
            keepLimitAfterWrite(w.bytes - w.replacedBytes);
        ok = ok && w.error == 0;
    }
    return ok;
}

SnapshotStore::PackWrite SnapshotStore::writePack(const std::filesystem::path& path,
                                                  const Pending& pending) {
    PackWrite out;
    std::error_code ec;
    std::filesystem::create_directories(path.parent_path(), ec);
    // Writers of packs of this subdirectory take turns from reading the pack to renaming its
    // replacement, so that none drops another's new views. Without the lock (a filesystem that
    // has none) it goes on: at worst a view is baked again later.
    const std::filesystem::path lockPath = path.parent_path() / ".lock";
    const int lockFd = ::open(lockPath.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0666);
    if (lockFd >= 0)
        while (::flock(lockFd, LOCK_EX) != 0 && errno == EINTR) {
        }
    // The pack's valid snapshots; a pack or a snapshot that fails its checks is left out.
    std::map<std::array<int, 3>, std::vector<std::uint8_t>> merged;
    const int fd = openRead(path);
    if (fd >= 0) {
        lockShared(fd); // not removed by the evictor while it is read
        struct stat st {};
        if (fstat(fd, &st) == 0) {
            out.replacedBytes = std::uint64_t(st.st_size);
            std::vector<std::uint8_t> bytes(out.replacedBytes);
            try {
                preadExact(fd, bytes.data(), bytes.size(), 0);
                const DecodedSnapshotPack pack = decodeSnapshotPack(bytes);
                if (sameFrame(pack.frame, pending.frame))
                    for (const SnapshotPackEntry& e : pack.entries) {
                        SnapshotFileKey key = pending.frame;
                        key.view = e.view;
                        try {
                            if (decodeSnapshotFile(e.file).key == key)
                                merged[viewOrder(e.view)] = e.file;
                        } catch (const SnapshotFileError&) {
                        }
                    }
            } catch (const SnapshotFileError&) {
            }
        }
        ::close(fd);
    }
    for (const auto& [view, file] : pending.files) merged[view] = file;
    std::vector<SnapshotPackEntry> entries;
    entries.reserve(merged.size());
    for (auto& [view, file] : merged)
        entries.push_back({ViewId{glm::ivec3(view[0], view[1], view[2])}, std::move(file)});
    const std::vector<std::uint8_t> bytes = encodeSnapshotPack(pending.frame, std::move(entries));
    out.bytes = bytes.size();

    // A name no other writer uses (pid + a process-wide counter).
    static std::atomic<std::uint64_t> serial{0};
    std::filesystem::path tmp = path;
    tmp += ".tmp" + std::to_string(::getpid()) + "-" + std::to_string(serial++);
    int& err = out.error;
    const int tfd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
    if (tfd < 0) {
        err = errno;
    } else {
        // Held until the rename: the stale-temporary sweep never removes a live writer's file.
        ::flock(tfd, LOCK_EX | LOCK_NB);
        for (std::size_t done = 0; done < bytes.size() && !err;) {
            const ssize_t n = ::write(tfd, bytes.data() + done, bytes.size() - done);
            if (n < 0 && errno == EINTR) continue;
            if (n < 0) err = errno;
            if (n == 0) err = ENOSPC; // 0 for a non-empty buffer: nothing more fits
            if (n > 0) done += std::size_t(n);
        }
        // No fsync: a pack lost in a power cut is a checksum mismatch, re-baked on read.
        // close(2) is where NFS reports a failed flush: checked before the file gets its name.
        if (::close(tfd) != 0 && !err && errno != EINTR) err = errno;
        if (!err && ::rename(tmp.c_str(), path.c_str()) != 0) err = errno;
        if (err) ::unlink(tmp.c_str());
    }
    if (lockFd >= 0) ::close(lockFd);
    return out;
}

namespace {
/// A writer's temporary: "<digest>.pack.tmp<pid>-<serial>" (or the former "*.snap.tmp*").
bool isTemporary(const std::filesystem::path& p) {
    const std::string name = p.filename().string();
    return name.find(".pack.tmp") != std::string::npos ||
           name.find(".snap.tmp") != std::string::npos;
}
} // namespace

std::size_t SnapshotStore::removeStaleTemporaries() {
    const auto now = std::filesystem::file_time_type::clock::now();
    std::size_t removed = 0;
    std::error_code ec;
    for (auto it = std::filesystem::recursive_directory_iterator(options_.dir, ec);
         !ec && it != std::filesystem::recursive_directory_iterator(); it.increment(ec)) {
        if (it.depth() > 1 || !isTemporary(it->path())) continue;
        std::error_code fec;
        const auto time = it->last_write_time(fec);
        if (fec || now - time < options_.staleTempAge) continue;
        const int fd = ::open(it->path().c_str(), O_RDONLY | O_CLOEXEC);
        if (fd < 0) continue; // renamed or removed meanwhile
        // Not waiting: a temporary someone holds is a live writer's, whatever its age.
        struct stat held {
        }, named{};
        if (::flock(fd, LOCK_EX | LOCK_NB) == 0 && fstat(fd, &held) == 0 &&
            ::stat(it->path().c_str(), &named) == 0 && held.st_ino == named.st_ino &&
            held.st_dev == named.st_dev && ::unlink(it->path().c_str()) == 0)
            ++removed;
        ::close(fd);
    }
    if (removed > 0) {
        std::lock_guard lock(mutex_);
        counters_.staleTempsRemoved += removed;
    }
    return removed;
}

void SnapshotStore::keepLimitAfterWrite(std::uint64_t fileBytes) {
    if (options_.limitBytes == 0) return;
    // One thread at a time: a write renamed before a scan is seen by it, one renamed after is
    // added after the scan's total is stored, so no file of this process goes uncounted.
    std::lock_guard limitLock(limitMutex_);
    if (approxBytes_) {
        *approxBytes_ += fileBytes;
        if (*approxBytes_ <= options_.limitBytes) return;
    }
    // Over (or not known yet): scan and, if over, go down to 90% of the limit so that the next
    // writes do not each rescan the directory.
    std::uint64_t total = 0;
    for (const SnapshotStoreFile& f : list()) total += f.bytes;
    if (total > options_.limitBytes) total = evictDownTo(options_.limitBytes / 10 * 9);
    approxBytes_ = total;
}

std::vector<SnapshotStoreFile> SnapshotStore::list() const {
    std::vector<SnapshotStoreFile> files;
    std::error_code ec;
    for (auto it = std::filesystem::recursive_directory_iterator(options_.dir, ec);
         !ec && it != std::filesystem::recursive_directory_iterator(); it.increment(ec)) {
        if (it.depth() > 1) continue;
        std::error_code fec;
        if (!it->is_regular_file(fec) ||
            (it->path().extension() != ".pack" && it->path().extension() != ".snap"))
            continue;
        const std::uint64_t size = it->file_size(fec);
        const auto time = it->last_write_time(fec);
        if (!fec) files.push_back({it->path(), size, time});
    }
    std::sort(files.begin(), files.end(),
              [](const SnapshotStoreFile& a, const SnapshotStoreFile& b) {
                  return a.lastUse < b.lastUse || (a.lastUse == b.lastUse && a.path < b.path);
              });
    return files;
}

std::uint64_t SnapshotStore::evictDownTo(std::uint64_t targetBytes) {
    removeStaleTemporaries(); // they take space too, and nothing else removes them
    const std::vector<SnapshotStoreFile> files = list();
    std::uint64_t total = 0;
    for (const SnapshotStoreFile& f : files) total += f.bytes;
    for (const SnapshotStoreFile& f : files) {
        if (total <= targetBytes) break;
        const int fd = ::open(f.path.c_str(), O_RDONLY | O_CLOEXEC);
        if (fd < 0) {
            total -= f.bytes; // removed by someone else meanwhile
            continue;
        }
        // Not waiting: a file someone is reading stays; the next oldest goes instead.
        bool removed = false;
        if (::flock(fd, LOCK_EX | LOCK_NB) == 0) {
            struct stat held {
            }, named{};
            // Still the same file under that name (not replaced by a fresh write meanwhile)?
            if (fstat(fd, &held) == 0 && ::stat(f.path.c_str(), &named) == 0 &&
                held.st_ino == named.st_ino && held.st_dev == named.st_dev)
                removed = ::unlink(f.path.c_str()) == 0;
        }
        ::close(fd);
        if (removed) {
            total -= f.bytes;
            std::lock_guard lock(mutex_);
            ++counters_.evicted;
            counters_.bytesEvicted += f.bytes;
        }
    }
    return total;
}

SnapshotStoreCounters SnapshotStore::counters() const {
    std::lock_guard lock(mutex_);
    return counters_;
}

} // namespace voxtier
