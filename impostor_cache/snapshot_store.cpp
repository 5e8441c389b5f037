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
    return snapshotLattice(viewDirection(k.view), k.dims, k.sigma);
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
    w.u32(k.withDepth ? kFlagDepth : 0);
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

/// Parses the first kHeaderBytes of a file (the caller checked there are that many). Every size
/// is checked against the lattice that the key fields (bounded first) imply, so nothing is
/// sized from an unchecked field.
SnapshotFileHeader decodeHeader(const std::uint8_t* header) {
    if (std::memcmp(header, kMagic, sizeof kMagic) != 0)
        throw SnapshotFileError("not a voxtier snapshot file (magic)");
    Reader r(header + sizeof kMagic);
    const std::uint32_t version = r.u32(), rule = r.u32();
    if (version != kSnapshotFileVersion)
        throw SnapshotFileError("stale format version " + std::to_string(version) + " (expected " +
                                std::to_string(kSnapshotFileVersion) + ")");
    if (rule != kSnapshotLatticeRule)
        throw SnapshotFileError("stale lattice rule " + std::to_string(rule) + " (expected " +
                                std::to_string(kSnapshotLatticeRule) + ")");
    SnapshotFileHeader h;
    SnapshotFileKey& k = h.key;
    k.grid.lo = r.u64();
    k.grid.hi = r.u64();
    for (int c = 0; c < 3; ++c) k.dims[c] = r.i32();
    for (int c = 0; c < 3; ++c) k.view.lattice[c] = r.i32();
    k.sigma = r.f64();
    const std::uint32_t flags = r.u32();
    if (flags & ~kFlagDepth) throw SnapshotFileError("unknown flags");
    k.withDepth = flags & kFlagDepth;
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

std::filesystem::path SnapshotStore::pathOf(const SnapshotFileKey& key) const {
    return options_.dir / snapshotFileName(key);
}

void SnapshotStore::warn(const std::filesystem::path& file, const std::string& reason) {
    options_.warn("warning: " + file.string() + ": " + reason + "; baking it again");
}

bool SnapshotStore::contains(const SnapshotFileKey& key) const {
    std::error_code ec;
    return std::filesystem::is_regular_file(pathOf(key), ec);
}

std::optional<Snapshot> SnapshotStore::load(const SnapshotFileKey& key) {
    const auto t0 = std::chrono::steady_clock::now();
    const std::filesystem::path path = pathOf(key);
    const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) {
        std::lock_guard lock(mutex_);
        ++counters_.misses;
        return std::nullopt;
    }
    // Shared lock while reading: the evictor skips files it cannot lock exclusively.
    while (::flock(fd, LOCK_SH) != 0 && errno == EINTR) {
    }
    std::optional<Snapshot> snap;
    std::size_t bytes = 0;
    try {
        const std::vector<std::uint8_t> data = readFile(fd);
        bytes = data.size();
        DecodedSnapshotFile f = decodeSnapshotFile(data);
        if (!(f.key == key)) throw SnapshotFileError("written for another key");
        snap = std::move(f.snapshot);
        ::futimens(fd, nullptr); // now: most recently used (atime is unreliable: noatime)
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
    const auto t0 = std::chrono::steady_clock::now();
    const std::filesystem::path path = pathOf(key);
    const std::vector<std::uint8_t> bytes = encodeSnapshotFile(key, snap);
    // A name no other writer uses (pid + a process-wide counter): concurrent writers of one key
    // each rename a complete file of their own over the final name.
    static std::atomic<std::uint64_t> serial{0};
    std::filesystem::path tmp = path;
    tmp += ".tmp" + std::to_string(::getpid()) + "-" + std::to_string(serial++);
    std::error_code ec;
    std::filesystem::create_directories(path.parent_path(), ec);
    int err = 0;
    const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
    if (fd < 0) {
        err = errno;
    } else {
        // Held until the rename: the stale-temporary sweep never removes a live writer's file.
        ::flock(fd, LOCK_EX | LOCK_NB);
        for (std::size_t done = 0; done < bytes.size() && !err;) {
            const ssize_t n = ::write(fd, bytes.data() + done, bytes.size() - done);
            if (n < 0 && errno == EINTR) continue;
            if (n < 0) err = errno;
            if (n == 0) err = ENOSPC; // 0 for a non-empty buffer: nothing more fits
            if (n > 0) done += std::size_t(n);
        }
        // No fsync: a snapshot lost in a power cut is a checksum mismatch, re-baked on read.
        // close(2) is where NFS reports a failed flush: checked before the file gets its name.
        if (::close(fd) != 0 && !err && errno != EINTR) err = errno;
        if (!err && ::rename(tmp.c_str(), path.c_str()) != 0) err = errno;
        if (err) ::unlink(tmp.c_str());
    }
    if (err) {
        std::lock_guard lock(mutex_);
        if (counters_.writeFailures++ == 0)
            counters_.writeFailureReason = std::generic_category().message(err);
        return false;
    }
    {
        std::lock_guard lock(mutex_);
        ++counters_.writes;
        counters_.bytesWritten += bytes.size();
        counters_.writeMs += msSince(t0);
    }
    keepLimitAfterWrite(bytes.size());
    return true;
}

namespace {
/// A writer's temporary: "<digest>.snap.tmp<pid>-<serial>".
bool isTemporary(const std::filesystem::path& p) {
    return p.filename().string().find(".snap.tmp") != std::string::npos;
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
        if (!it->is_regular_file(fec) || it->path().extension() != ".snap") continue;
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
