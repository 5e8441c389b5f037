#include "impostor_cache/snapshot_format.hpp"

#include "core/error.hpp"
#include "core/splitmix64.hpp"

#include <sys/stat.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <system_error>
#include <unistd.h>

namespace voxtier {

namespace {

// ---- digest -------------------------------------------------------------------------------

std::uint64_t rotl(std::uint64_t x, int r) {
    return (x << r) | (x >> (64 - r));
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

std::uint64_t snapshotFileBytes(const SnapshotFileKey& key) {
    const std::size_t cells = cellCount(latticeOf(key));
    return fileSize(cells, key.withDepth ? cells : 0);
}

// Two independent multiply-rotate lanes over 16-byte blocks (a grid of 256^3 digests in a few
// ms), then the last partial block zero-padded (a whole zero block when the length is a
// multiple of 16), the length and splitmix64's finaliser.
namespace {
constexpr std::uint64_t kP1 = 0x9e3779b185ebca87ull, kP2 = 0xc2b2ae3d27d4eb4full;
} // namespace

DigestStream::DigestStream(std::uint64_t seed)
    : a_(seed ^ 0x243f6a8885a308d3ull), b_(~seed ^ 0x13198a2e03707344ull) {}

void DigestStream::block(const std::uint8_t* p) {
    a_ = rotl(a_ ^ (loadWord(p) * kP2), 31) * kP1;
    b_ = rotl(b_ ^ (loadWord(p + 8) * kP1), 29) * kP2;
}

void DigestStream::add(std::span<const std::uint8_t> bytes) {
    const std::uint8_t* p = bytes.data();
    std::size_t n = bytes.size();
    std::size_t held = std::size_t(n_ % 16);
    n_ += n;
    if (held > 0) { // complete the block a previous piece began
        const std::size_t take = std::min(n, 16 - held);
        std::memcpy(tail_.data() + held, p, take);
        p += take;
        n -= take;
        held += take;
        if (held < 16) return;
        block(tail_.data());
    }
    for (; n >= 16; p += 16, n -= 16) block(p);
    std::memcpy(tail_.data(), p, n);
}

Digest128 DigestStream::finish() const {
    DigestStream s = *this;
    std::array<std::uint8_t, 16> last{};
    std::memcpy(last.data(), tail_.data(), std::size_t(n_ % 16));
    s.block(last.data());
    const std::uint64_t a = splitmix64Mix(s.a_ ^ n_);
    const std::uint64_t b = splitmix64Mix(s.b_ ^ rotl(n_, 32) ^ a);
    return {splitmix64Mix(a ^ b), b};
}

Digest128 digestBytes(std::span<const std::uint8_t> bytes, std::uint64_t seed) {
    DigestStream d(seed);
    d.add(bytes);
    return d.finish();
}

Digest128 digestGrid(const VoxelGrid& grid) {
    const glm::ivec3 d = grid.dims();
    const std::uint64_t seed =
        splitmix64Mix(std::uint64_t(std::uint32_t(d.x)) | std::uint64_t(std::uint32_t(d.y)) << 21 |
                      std::uint64_t(std::uint32_t(d.z)) << 42);
    return digestBytes(grid.data(), seed);
}

namespace {

/// What determines a snapshot's bytes, in file order: both the file name (its digest) and the
/// header (checked on read) are made of it. A pack's name and header hold the same but the view
/// (`withView` false), after the pack's version.
void writeKey(Writer& w, const SnapshotFileKey& k, std::uint32_t version = kSnapshotFileVersion,
              bool withView = true) {
    w.u32(version);
    w.u32(kSnapshotLatticeRule);
    w.u64(k.grid.lo);
    w.u64(k.grid.hi);
    for (int c = 0; c < 3; ++c) w.i32(k.dims[c]);
    if (withView)
        for (int c = 0; c < 3; ++c) w.i32(k.view.lattice[c]);
    w.f64(k.sigma);
    w.u32(flagsOf(k));
}

/// "ab/<32 hex digits><extension>": the digest of `key`, its first two digits a subdirectory.
std::filesystem::path digestName(std::span<const std::uint8_t> key, const char* extension) {
    const Digest128 d = digestBytes(key);
    const std::string name = hex(d.lo) + hex(d.hi);
    return std::filesystem::path(name.substr(0, 2)) / (name + extension);
}

} // namespace

std::filesystem::path snapshotFileName(const SnapshotFileKey& k) {
    std::vector<std::uint8_t> bytes;
    Writer w(bytes);
    writeKey(w, k);
    return digestName(bytes, ".snap");
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

} // namespace

/// A file is never read or allocated for by a size it claims before that size has been checked.
std::vector<std::uint8_t> readSnapshotFile(int fd, const SnapshotFileKey& key) {
    struct stat st {};
    if (fstat(fd, &st) != 0) throw SnapshotFileError("cannot stat");
    const std::uint64_t size = std::uint64_t(st.st_size);
    auto readInto = [fd](std::uint8_t* dst, std::size_t n) {
        for (std::size_t done = 0; done < n;) {
            const ssize_t got = ::read(fd, dst + done, n - done);
            if (got < 0 && errno == EINTR) continue;
            if (got < 0)
                throw SnapshotFileError(std::string("cannot read: ") + std::strerror(errno));
            if (got == 0) throw SnapshotFileError("truncated while reading");
            done += std::size_t(got);
        }
    };
    if (size < kHeaderBytes + kChecksumBytes)
        throw SnapshotFileError("truncated (" + std::to_string(size) +
                                " bytes, shorter than the header)");
    std::vector<std::uint8_t> bytes(kHeaderBytes);
    readInto(bytes.data(), kHeaderBytes);
    const SnapshotFileHeader h = decodeHeader(bytes.data());
    if (!(h.key == key)) throw SnapshotFileError("written for another key");
    checkSize(size, h.fileBytes);
    bytes.resize(h.fileBytes);
    readInto(bytes.data() + kHeaderBytes, h.fileBytes - kHeaderBytes);
    return bytes;
}

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
    writeKey(w, k, kSnapshotPackVersion, false);
}

} // namespace

bool sameFrame(const SnapshotFileKey& a, const SnapshotFileKey& b) {
    return a.grid == b.grid && a.dims == b.dims && a.sigma == b.sigma &&
           a.withDepth == b.withDepth && a.outlineStride == b.outlineStride;
}

std::array<int, 3> viewOrder(ViewId v) {
    return {v.lattice.x, v.lattice.y, v.lattice.z};
}

namespace {

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
    if (count > kMaxPackViews)
        throw SnapshotFileError("entry count " + std::to_string(count) + " over " +
                                std::to_string(kMaxPackViews));
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
    PackIndex out{frame, {}};
    out.entries.resize(count);
    Reader r(index.data());
    std::uint64_t at = kPackHeaderBytes + count * kPackIndexEntryBytes + kChecksumBytes;
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

} // namespace

void preadExact(int fd, std::uint8_t* dst, std::size_t n, std::uint64_t offset) {
    for (std::size_t done = 0; done < n;) {
        const ssize_t got = ::pread(fd, dst + done, n - done, off_t(offset + done));
        if (got < 0 && errno == EINTR) continue;
        if (got < 0) throw SnapshotFileError(std::string("cannot read: ") + std::strerror(errno));
        if (got == 0) throw SnapshotFileError("truncated while reading");
        done += std::size_t(got);
    }
}

const PackIndexEntry* PackIndex::find(ViewId view) const {
    const auto it = std::lower_bound(
        entries.begin(), entries.end(), viewOrder(view),
        [](const PackIndexEntry& e, const std::array<int, 3>& v) { return viewOrder(e.view) < v; });
    return it != entries.end() && it->view == view ? &*it : nullptr;
}

static_assert(kPackHeadBytes == kPackHeaderBytes + kChecksumBytes);

PackHead readPackHead(int fd, std::uint64_t size) {
    if (size < kPackHeaderBytes + kChecksumBytes)
        throw SnapshotFileError("truncated (" + std::to_string(size) +
                                " bytes, shorter than the header)");
    PackHead head;
    head.size = size;
    std::uint8_t* header = head.bytes.data();
    preadExact(fd, header, kPackHeaderBytes, 0);
    head.count = decodePackHeader(header, size, head.frame);
    preadExact(fd, header + kPackHeaderBytes, kChecksumBytes,
               kPackHeaderBytes + head.count * kPackIndexEntryBytes);
    return head;
}

PackIndex readPackIndex(int fd, const PackHead& head) {
    std::vector<std::uint8_t> index(head.count * kPackIndexEntryBytes + kChecksumBytes);
    preadExact(fd, index.data(), index.size(), kPackHeaderBytes);
    return decodePackIndex(head.bytes.data(), index, head.count, head.frame, head.size);
}

std::filesystem::path snapshotPackName(const SnapshotFileKey& k) {
    std::vector<std::uint8_t> bytes;
    Writer w(bytes);
    writeFrameKey(w, k);
    return digestName(bytes, ".pack");
}

std::uint64_t snapshotPackOverhead(std::size_t views) {
    return kPackHeaderBytes + views * kPackIndexEntryBytes + kChecksumBytes;
}

namespace {

/// A pack's header, index and index checksum, for views ascending with the sizes of their
/// snapshot files; `reserveAll`: room for the snapshot files too (an encoder appends them).
std::vector<std::uint8_t> packOpening(const SnapshotFileKey& frame,
                                      std::span<const std::pair<ViewId, std::uint64_t>> views,
                                      bool reserveAll) {
    std::uint64_t total = snapshotPackOverhead(views.size());
    for (const auto& [view, bytes] : views) total += bytes;
    std::vector<std::uint8_t> out;
    out.reserve(reserveAll ? total : snapshotPackOverhead(views.size()));
    Writer w(out);
    w.bytes(kPackMagic, sizeof kPackMagic);
    writeFrameKey(w, frame);
    w.u32(std::uint32_t(views.size()));
    w.u64(total);
    std::uint64_t at = snapshotPackOverhead(views.size());
    for (const auto& [view, bytes] : views) {
        for (int c = 0; c < 3; ++c) w.i32(view.lattice[c]);
        w.u64(at);
        w.u64(bytes);
        at += bytes;
    }
    const Digest128 sum = digestBytes(out);
    w.u64(sum.lo);
    w.u64(sum.hi);
    return out;
}

template <class T> void sortByView(std::vector<T>& v) {
    std::sort(v.begin(), v.end(),
              [](const T& a, const T& b) { return viewOrder(a.view) < viewOrder(b.view); });
}

} // namespace

std::vector<std::uint8_t> encodeSnapshotPack(const SnapshotFileKey& frame,
                                             std::vector<SnapshotPackEntry> entries) {
    sortByView(entries);
    std::vector<std::pair<ViewId, std::uint64_t>> views;
    for (const SnapshotPackEntry& e : entries) views.emplace_back(e.view, e.file.size());
    std::vector<std::uint8_t> out = packOpening(frame, views, true);
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

// ---- one view of a pack on a descriptor ------------------------------------------------------

namespace {

/// The pieces a pack's snapshots are checked and copied in: a snapshot of the largest model at
/// the largest sigma takes hundreds of MB, and a pack many of them.
constexpr std::size_t kPieceBytes = std::size_t(1) << 20;

std::string viewText(ViewId v) {
    return "view (" + std::to_string(v.lattice.x) + " " + std::to_string(v.lattice.y) + " " +
           std::to_string(v.lattice.z) + ")";
}

/// The snapshot file size `key` implies, checked against the entry's before anything is read.
std::uint64_t checkedEntrySize(const PackIndexEntry& entry, const SnapshotFileKey& key) {
    if (!(entry.view == key.view)) throw SnapshotFileError(viewText(entry.view) + ": wrong view");
    const std::uint64_t expected = snapshotFileBytes(key);
    if (entry.bytes != expected)
        throw SnapshotFileError(viewText(key.view) + ": wrong size (" +
                                std::to_string(entry.bytes) + " bytes, expected " +
                                std::to_string(expected) + ")");
    return expected;
}

} // namespace

DecodedSnapshotFile readPackEntry(int fd, const PackIndexEntry& entry, const SnapshotFileKey& key) {
    std::vector<std::uint8_t> file(std::size_t(checkedEntrySize(entry, key)));
    try {
        preadExact(fd, file.data(), file.size(), entry.offset);
        DecodedSnapshotFile f = decodeSnapshotFile(file);
        if (!(f.key == key)) throw SnapshotFileError("written for another key");
        return f;
    } catch (const SnapshotFileError& e) {
        throw SnapshotFileError(viewText(key.view) + ": " + e.what());
    }
}

void checkPackEntry(int fd, const PackIndexEntry& entry, const SnapshotFileKey& key) {
    const std::uint64_t size = checkedEntrySize(entry, key);
    try {
        std::vector<std::uint8_t> piece(kHeaderBytes);
        preadExact(fd, piece.data(), kHeaderBytes, entry.offset);
        const SnapshotFileHeader h = decodeHeader(piece.data());
        if (!(h.key == key)) throw SnapshotFileError("written for another key");
        checkSize(size, h.fileBytes);
        DigestStream sum;
        sum.add(piece);
        // The cells (two bytes each, codes checked), then the depths: pieces of an even size
        // from an even offset (kHeaderBytes), so no cell is cut in two.
        const std::uint64_t cellsEnd = kHeaderBytes + std::uint64_t(h.cells) * sizeof(SnapshotCell);
        const std::uint64_t summed = size - kChecksumBytes;
        for (std::uint64_t at = kHeaderBytes; at < summed;) {
            const std::uint64_t end = at < cellsEnd ? cellsEnd : summed;
            const std::size_t n = std::size_t(std::min<std::uint64_t>(kPieceBytes, end - at));
            piece.resize(n);
            preadExact(fd, piece.data(), n, entry.offset + at);
            if (at < cellsEnd)
                for (std::size_t i = 1; i < n; i += 2)
                    if (piece[i] > snapshot_code::kOutline)
                        throw SnapshotFileError("bad cell code");
            sum.add(piece);
            at += n;
        }
        std::uint8_t stored[kChecksumBytes];
        preadExact(fd, stored, kChecksumBytes, entry.offset + summed);
        const Digest128 d = sum.finish();
        Reader r(stored);
        if (r.u64() != d.lo || r.u64() != d.hi)
            throw SnapshotFileError("checksum mismatch (corrupted)");
    } catch (const SnapshotFileError& e) {
        throw SnapshotFileError(viewText(key.view) + ": " + e.what());
    }
}

namespace {
void writeAll(int fd, const std::uint8_t* p, std::size_t n) {
    while (n > 0) {
        const ssize_t w = ::write(fd, p, n);
        if (w < 0 && errno == EINTR) continue;
        if (w < 0) throw std::system_error(errno, std::generic_category(), "write");
        if (w == 0) throw std::system_error(ENOSPC, std::generic_category(), "write");
        p += w;
        n -= std::size_t(w);
    }
}
} // namespace

std::uint64_t writePackTo(int out, const SnapshotFileKey& frame, std::vector<PackSource> sources) {
    sortByView(sources);
    std::vector<std::pair<ViewId, std::uint64_t>> views;
    for (const PackSource& src : sources)
        views.emplace_back(src.view, src.fd >= 0 ? src.size : src.bytes.size());
    const std::vector<std::uint8_t> opening = packOpening(frame, views, false);
    writeAll(out, opening.data(), opening.size());
    std::uint64_t written = opening.size();
    std::vector<std::uint8_t> piece;
    for (const PackSource& src : sources) {
        if (src.fd < 0) {
            writeAll(out, src.bytes.data(), src.bytes.size());
            written += src.bytes.size();
            continue;
        }
        for (std::uint64_t done = 0; done < src.size;) {
            const std::size_t n =
                std::size_t(std::min<std::uint64_t>(kPieceBytes, src.size - done));
            piece.resize(n);
            preadExact(src.fd, piece.data(), n, src.offset + done);
            writeAll(out, piece.data(), n);
            done += n;
        }
        written += src.size;
    }
    return written;
}

} // namespace voxtier
