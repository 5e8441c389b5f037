#include "impostor_cache/snapshot_store.hpp"

#include "core/error.hpp"
#include "core/stopwatch.hpp"

#include <sys/file.h>
#include <sys/stat.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <fcntl.h>
#include <system_error>
#include <unistd.h>

namespace voxtier {

/// A parsed index and what identifies the pack it came from: a pack is never changed in place
/// (a writer renames a new file over it), so the same file, size, header and index checksum is
/// the same index. (Were it damaged in place meanwhile, each snapshot still has its own key and
/// checksum: a wrong offset is a rejected snapshot, never a wrong one.)
struct SnapshotStore::CachedIndex {
    dev_t dev = 0;
    ino_t ino = 0;
    PackHead head;
    PackIndex index;
};

/// The index of an open pack: the header, the index checksum, then (unless this store parsed
/// that very index already) exactly the index they imply.
std::shared_ptr<const SnapshotStore::CachedIndex>
SnapshotStore::readPackIndex(int fd, const std::string& rel) const {
    struct stat st {};
    if (fstat(fd, &st) != 0) throw SnapshotFileError("cannot stat");
    auto fresh = std::make_shared<CachedIndex>();
    fresh->dev = st.st_dev;
    fresh->ino = st.st_ino;
    fresh->head = voxtier::readPackHead(fd, std::uint64_t(st.st_size));
    {
        std::lock_guard lock(mutex_);
        const auto known = indexes_.find(rel);
        if (known != indexes_.end() && known->second->dev == fresh->dev &&
            known->second->ino == fresh->ino && known->second->head.size == fresh->head.size &&
            known->second->head.bytes == fresh->head.bytes)
            return known->second;
    }
    fresh->index = voxtier::readPackIndex(fd, fresh->head);
    std::lock_guard lock(mutex_);
    if (indexes_.size() >= kMaxCachedIndexes) indexes_.clear();
    indexes_[rel] = fresh;
    return fresh;
}

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
            found = sameFrame(cached->index.frame, key) && cached->index.find(key.view) != nullptr;
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
            const PackIndexEntry* e = cached->index.find(key.view);
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
        const std::vector<std::uint8_t> data = readSnapshotFile(fd);
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
