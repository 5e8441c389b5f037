#include "impostor_cache/snapshot_store.hpp"

#include "core/error.hpp"
#include "core/stopwatch.hpp"

#include <sys/file.h>
#include <sys/stat.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fcntl.h>
#include <new>
#include <system_error>
#include <thread>
#include <unistd.h>
#include <utility>

namespace voxtier {

namespace fs = std::filesystem;

namespace {

/// A descriptor, closed when it goes out of scope (on every path, exceptions included: a lock
/// lives as long as its descriptor).
class UniqueFd {
  public:
    UniqueFd() = default;
    explicit UniqueFd(int fd) : fd_(fd) {}
    UniqueFd(UniqueFd&& o) noexcept : fd_(std::exchange(o.fd_, -1)) {}
    UniqueFd& operator=(UniqueFd&& o) noexcept {
        reset(std::exchange(o.fd_, -1));
        return *this;
    }
    UniqueFd(const UniqueFd&) = delete;
    UniqueFd& operator=(const UniqueFd&) = delete;
    ~UniqueFd() { reset(); }
    int get() const { return fd_; }
    explicit operator bool() const { return fd_ >= 0; }
    void reset(int fd = -1) {
        if (fd_ >= 0) ::close(fd_);
        fd_ = fd;
    }
    /// Closes now; returns close's errno, 0 when fine (where NFS reports a failed flush).
    int close() {
        const int fd = std::exchange(fd_, -1);
        if (fd < 0 || ::close(fd) == 0 || errno == EINTR) return 0;
        return errno;
    }

  private:
    int fd_ = -1;
};

std::string errnoText(int error) {
    return std::generic_category().message(error);
}

const char* kindOf(mode_t mode) {
    if (S_ISDIR(mode)) return "a directory";
    if (S_ISFIFO(mode)) return "a FIFO";
    if (S_ISLNK(mode)) return "a symbolic link";
    if (S_ISSOCK(mode)) return "a socket";
    if (S_ISCHR(mode)) return "a character device";
    if (S_ISBLK(mode)) return "a block device";
    return "of an unknown kind";
}

/// What is at a path of the directory, looked at before it is believed: opened read-only,
/// without following a symbolic link, without blocking (a FIFO would block open() until a
/// writer came), and kept only when fstat says it is a regular file.
struct Opened {
    UniqueFd fd;            ///< a regular file, or none
    int error = 0;          ///< open's errno when there is nothing usable (ENOENT: nothing)
    std::string notRegular; ///< what is there instead of a regular file, or ""
    std::uint64_t size = 0; ///< of the regular file
};

Opened openFile(const fs::path& p) {
    Opened o;
    o.fd.reset(::open(p.c_str(), O_RDONLY | O_CLOEXEC | O_NOFOLLOW | O_NONBLOCK | O_NOCTTY));
    struct stat st {};
    if (!o.fd) {
        o.error = errno;
        // ELOOP: the name is a symbolic link (O_NOFOLLOW); ENXIO: a socket. Say which.
        if ((o.error == ELOOP || o.error == ENXIO) && ::lstat(p.c_str(), &st) == 0 &&
            !S_ISREG(st.st_mode))
            o.notRegular = kindOf(st.st_mode);
        return o;
    }
    if (::fstat(o.fd.get(), &st) != 0) {
        o.error = errno;
        o.fd.reset();
    } else if (!S_ISREG(st.st_mode)) {
        o.notRegular = kindOf(st.st_mode);
        o.fd.reset();
    } else {
        o.size = std::uint64_t(st.st_size);
    }
    return o;
}

/// A shared lock without waiting. False only when another process holds the file exclusively:
/// the evictor, about to remove it. Where there are no locks (ENOLCK) it reads unlocked.
bool lockSharedNow(int fd) {
    while (::flock(fd, LOCK_SH | LOCK_NB) != 0) {
        if (errno == EINTR) continue;
        return errno != EWOULDBLOCK;
    }
    return true;
}

bool sameInode(int fd, const fs::path& p) {
    struct stat held {
    }, named{};
    return ::fstat(fd, &held) == 0 && ::lstat(p.c_str(), &named) == 0 &&
           held.st_ino == named.st_ino && held.st_dev == named.st_dev;
}

/// A subdirectory's ".lock", taken exclusively, once, without waiting.
enum class FolderLockTry { Held, Busy, Unlockable };
FolderLockTry tryLockFolder(const fs::path& folder, UniqueFd& held) {
    const fs::path lockPath = folder / ".lock";
    UniqueFd fd(
        ::open(lockPath.c_str(), O_RDWR | O_CREAT | O_CLOEXEC | O_NOFOLLOW | O_NONBLOCK, 0666));
    // A .lock that cannot be opened (a filesystem without the file, a directory in its place):
    // write without, as where flock does not reach (at worst a view is baked again later).
    if (!fd) return FolderLockTry::Unlockable;
    while (::flock(fd.get(), LOCK_EX | LOCK_NB) != 0) {
        if (errno == EINTR) continue;
        return errno == EWOULDBLOCK ? FolderLockTry::Busy : FolderLockTry::Unlockable;
    }
    // Someone may have removed the .lock meanwhile, and another writer then locks a new one:
    // the lock counts only while it is the file under that name.
    if (!sameInode(fd.get(), lockPath)) return FolderLockTry::Busy;
    held = std::move(fd);
    return FolderLockTry::Held;
}

/// A writer's temporary: removed on every path unless renamed to its final name.
class Temporary {
  public:
    explicit Temporary(fs::path path) : path_(std::move(path)) {}
    Temporary(const Temporary&) = delete;
    Temporary& operator=(const Temporary&) = delete;
    ~Temporary() {
        fd.reset();
        if (created_ && !renamed_) ::unlink(path_.c_str());
    }
    /// errno of the creation, 0 when created (and locked: see removeStaleTemporaries).
    int create() {
        fd.reset(::open(path_.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC | O_NOFOLLOW, 0666));
        if (!fd) return errno;
        created_ = true;
        ::flock(fd.get(), LOCK_EX | LOCK_NB); // held until the rename
        return 0;
    }
    int renameTo(const fs::path& final) {
        if (::rename(path_.c_str(), final.c_str()) != 0) return errno;
        renamed_ = true;
        return 0;
    }
    UniqueFd fd;

  private:
    fs::path path_;
    bool created_ = false, renamed_ = false;
};

/// A writer's temporary: "<digest>.pack.tmp<pid>-<serial>" (or the former "*.snap.tmp*").
bool isTemporary(const fs::path& p) {
    const std::string name = p.filename().string();
    return name.find(".pack.tmp") != std::string::npos ||
           name.find(".snap.tmp") != std::string::npos;
}

/// VOXTIER_STORE_FAULT ("alloc@STEP" or "stop@STEP") as a beforeStep hook; stop happens once
/// per process (a stopped writer, continued, then goes on like any other).
std::function<void(std::string_view)> faultFromEnvironment() {
    const char* spec = std::getenv("VOXTIER_STORE_FAULT");
    if (!spec) return {};
    const std::string s = spec;
    const std::size_t at = s.find('@');
    if (at == std::string::npos) return {};
    const std::string what = s.substr(0, at), where = s.substr(at + 1);
    return [what, where](std::string_view step) {
        static std::atomic<bool> stopped{false};
        if (step != where) return;
        if (what == "alloc") throw std::bad_alloc();
        if (what == "stop" && !stopped.exchange(true)) ::raise(SIGSTOP);
    };
}

} // namespace

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
    if (::fstat(fd, &st) != 0) throw SnapshotFileError("cannot stat: " + errnoText(errno));
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
    fs::create_directories(options_.dir, ec);
    if (ec || !fs::is_directory(options_.dir))
        throw InputError(options_.dir.string(), "--cache-dir",
                         "cannot create the directory" + (ec ? ": " + ec.message() : ""));
    if (!options_.warn)
        options_.warn = [](const std::string& line) { std::fprintf(stderr, "%s\n", line.c_str()); };
    if (!options_.beforeStep) options_.beforeStep = faultFromEnvironment();
    removeStaleTemporaries();
}

SnapshotStore::~SnapshotStore() {
    // A destructor must not throw; what could not be written is baked again when next needed.
    try {
        flush();
    } catch (...) {
    }
}

fs::path SnapshotStore::pathOf(const SnapshotFileKey& key) const {
    return options_.dir / snapshotPackName(key);
}

void SnapshotStore::step(std::string_view name) const {
    if (options_.beforeStep) options_.beforeStep(name);
}

bool SnapshotStore::warnOnce(const fs::path& file, const std::string& reason) {
    bool first = false;
    {
        std::lock_guard lock(mutex_);
        first = warnedPacks_.insert(file.lexically_relative(options_.dir).string()).second;
    }
    if (first) options_.warn("warning: " + file.string() + ": " + reason + "; baking it again");
    return first;
}

void SnapshotStore::reject(const fs::path& file, const std::string& reason) {
    warnOnce(file, reason);
    std::lock_guard lock(mutex_);
    ++counters_.rejected;
}

bool SnapshotStore::contains(const SnapshotFileKey& key) const {
    const std::string rel = snapshotPackName(key).string();
    {
        std::lock_guard lock(mutex_);
        const auto p = pending_.find(rel);
        if (p != pending_.end() && p->second.files.count(viewOrder(key.view))) return true;
    }
    const Opened o = openFile(options_.dir / rel);
    if (o.fd) {
        try {
            const auto cached = readPackIndex(o.fd.get(), rel);
            if (sameFrame(cached->index.frame, key) && cached->index.find(key.view)) return true;
        } catch (const SnapshotFileError&) {
            // load() says what is wrong with it
        }
    }
    struct stat st {};
    return ::lstat((options_.dir / snapshotFileName(key)).c_str(), &st) == 0 && S_ISREG(st.st_mode);
}

std::optional<Snapshot> SnapshotStore::load(const SnapshotFileKey& key) {
    const auto t0 = std::chrono::steady_clock::now();
    const fs::path rel = snapshotPackName(key);
    File buffered;
    {
        // Buffered by this process and not written yet.
        std::lock_guard lock(mutex_);
        const auto p = pending_.find(rel.string());
        if (p != pending_.end()) {
            const auto f = p->second.files.find(viewOrder(key.view));
            if (f != p->second.files.end()) buffered = f->second;
        }
    }
    const fs::path path = options_.dir / rel;
    std::optional<Snapshot> snap;
    std::uint64_t bytes = 0;
    if (buffered) {
        // This process's own bytes: decoded, not checked against anything but themselves.
        snap = decodeSnapshotFile(*buffered).snapshot;
        bytes = buffered->size();
    } else {
        const Opened o = openFile(path);
        if (!o.fd) {
            if (!o.notRegular.empty()) {
                reject(path, "not a regular file (" + o.notRegular + ")");
                return std::nullopt;
            }
            // Nothing there (or no subdirectory): perhaps a file of the former layout.
            if (o.error == ENOENT || o.error == ENOTDIR) return loadFormerFile(key, t0);
            reject(path, "cannot open: " + errnoText(o.error));
            return std::nullopt;
        }
        // Shared lock while reading: the evictor skips packs it cannot lock exclusively. One it
        // holds is being removed: a miss, not a wait.
        if (!lockSharedNow(o.fd.get())) {
            std::lock_guard lock(mutex_);
            ++counters_.misses;
            return std::nullopt;
        }
        try {
            const auto cached = readPackIndex(o.fd.get(), rel.string());
            if (!sameFrame(cached->index.frame, key))
                throw SnapshotFileError("written for another key");
            const PackIndexEntry* e = cached->index.find(key.view);
            if (!e) return loadFormerFile(key, t0);
            snap = readPackEntry(o.fd.get(), *e, key).snapshot;
            bytes = e->bytes;
            ::futimens(o.fd.get(), nullptr); // now: most recently used (atime is unreliable)
        } catch (const SnapshotFileError& e) {
            // One line per pack, however many of its views are asked for or bad.
            reject(path, e.what());
            return std::nullopt;
        }
    }
    std::lock_guard lock(mutex_);
    ++counters_.reads;
    counters_.bytesRead += bytes;
    counters_.readMs += msSince(t0);
    return snap;
}

std::optional<Snapshot> SnapshotStore::loadFormerFile(const SnapshotFileKey& key,
                                                      std::chrono::steady_clock::time_point t0) {
    const fs::path path = options_.dir / snapshotFileName(key);
    const Opened o = openFile(path);
    if (!o.fd && o.notRegular.empty()) {
        std::lock_guard lock(mutex_);
        ++counters_.misses;
        return std::nullopt;
    }
    if (!o.fd) {
        reject(path, "not a regular file (" + o.notRegular + ")");
        return std::nullopt;
    }
    if (!lockSharedNow(o.fd.get())) {
        std::lock_guard lock(mutex_);
        ++counters_.misses;
        return std::nullopt;
    }
    std::optional<Snapshot> snap;
    std::size_t bytes = 0;
    try {
        const std::vector<std::uint8_t> data = readSnapshotFile(o.fd.get(), key);
        bytes = data.size();
        snap = decodeSnapshotFile(data).snapshot;
        ::futimens(o.fd.get(), nullptr);
    } catch (const SnapshotFileError& e) {
        reject(path, e.what());
        return std::nullopt;
    }
    std::lock_guard lock(mutex_);
    ++counters_.reads;
    counters_.bytesRead += bytes;
    counters_.readMs += msSince(t0);
    return snap;
}

bool SnapshotStore::save(const SnapshotFileKey& key, const Snapshot& snap) {
    auto file = std::make_shared<const std::vector<std::uint8_t>>(encodeSnapshotFile(key, snap));
    const std::string rel = snapshotPackName(key).string();
    const auto now = std::chrono::steady_clock::now();
    bool due = false;
    {
        std::lock_guard lock(mutex_);
        if (pending_.empty()) pendingSince_ = now;
        Pending& p = pending_[rel];
        p.frame = key;
        pendingBytes_ += file->size();
        auto [it, added] = p.files.try_emplace(viewOrder(key.view), std::move(file));
        if (!added) pendingBytes_ -= it->second->size(); // the same bytes again
        due = !options_.writeOnlyOnFlush &&
              (pendingBytes_ >= options_.flushBytes || now - pendingSince_ >= options_.flushAfter);
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
    using Clock = std::chrono::steady_clock;
    std::map<std::string, Pending> work;
    try {
        std::lock_guard lock(mutex_);
        work = pending_; // shared files: load() keeps finding these until they are in their pack
    } catch (const std::bad_alloc&) {
        return false; // still buffered: the next flush tries again
    }
    // By subdirectory: one lock each, taken once for all of its packs.
    std::map<std::string, std::vector<const std::pair<const std::string, Pending>*>> folders;
    for (const auto& item : work)
        folders[fs::path(item.first).parent_path().string()].push_back(&item);

    bool ok = true;
    std::set<std::string> handled;
    std::uint64_t grown = 0; // bytes the directory grew by: the size limit is kept at the end,
                             // with no folder lock held while it scans
    // Written or failed, a pack's snapshots leave the buffer: a failed one is baked again when
    // next needed, as a snapshot that was never saved.
    const auto done = [&](const std::string& rel, const Pending& p, const PackWrite& w,
                          const std::string& reason, double ms) {
        handled.insert(rel);
        {
            std::lock_guard lock(mutex_);
            if (w.error == 0 && reason.empty()) {
                counters_.writes += p.files.size();
                ++counters_.packWrites;
                counters_.bytesWritten += w.bytes;
                counters_.writeMs += ms;
                warnedPacks_.erase(rel);
            } else if ((counters_.writeFailures += p.files.size()) == p.files.size()) {
                counters_.writeFailureReason = reason.empty() ? errnoText(w.error) : reason;
            }
            Pending& left = pending_[rel];
            for (const auto& [view, file] : p.files)
                if (left.files.erase(view)) pendingBytes_ -= file->size();
            if (left.files.empty()) pending_.erase(rel);
            if (pending_.empty()) pendingBytes_ = 0;
        }
        if (w.error == 0 && reason.empty() && w.bytes > w.replacedBytes)
            grown += w.bytes - w.replacedBytes;
        ok = ok && w.error == 0 && reason.empty();
    };
    const auto failFolder = [&](const std::string& folder, const PackWrite& w,
                                const std::string& reason) {
        for (const auto* item : folders[folder])
            if (!handled.count(item->first)) done(item->first, item->second, w, reason, 0.0);
    };
    // Writes the folder's packs if its lock can be had now; false when another process holds it.
    const auto tryFolder = [&](const std::string& folder) {
        const fs::path dir = options_.dir / folder;
        PackWrite failed;
        try {
            step("folder");
            std::error_code ec;
            fs::create_directories(dir, ec);
            // The step's own reason (a full inode table is ENOSPC here), not what the opens
            // that follow would say about a folder that is not there.
            if (ec) {
                failed.error = ec.value();
            } else {
                UniqueFd lock;
                if (tryLockFolder(dir, lock) == FolderLockTry::Busy) return false;
                stuckFolders_.erase(folder);
                step("locked");
                for (const auto* item : folders[folder]) {
                    const auto t0 = Clock::now();
                    const PackWrite w = writePack(options_.dir / item->first, item->second);
                    done(item->first, item->second, w, "", msSince(t0));
                }
                return true;
            }
        } catch (const std::bad_alloc&) {
            failed.error = ENOMEM;
        } catch (const std::exception&) {
            failed.error = EIO;
        }
        failFolder(folder, failed, "");
        return true;
    };

    std::vector<std::string> waiting;
    for (const auto& [folder, items] : folders) {
        if (tryFolder(folder)) continue;
        if (stuckFolders_.count(folder))
            failFolder(folder, {},
                       (options_.dir / folder).string() + ": still locked by another process");
        else
            waiting.push_back(folder);
    }
    // Held by another process: retried, with back-off, until the flush's deadline.
    const auto deadline = Clock::now() + options_.lockWait;
    auto pause = std::chrono::milliseconds(1);
    double sleptMs = 0.0;
    while (!waiting.empty() && Clock::now() < deadline) {
        const auto t0 = Clock::now();
        std::this_thread::sleep_for(std::min<Clock::duration>(pause, deadline - t0));
        sleptMs += msSince(t0);
        pause = std::min(pause * 2, std::chrono::milliseconds(50));
        std::erase_if(waiting, tryFolder);
    }
    if (sleptMs > 0.0) {
        std::lock_guard lock(mutex_);
        counters_.lockWaitMs += sleptMs;
    }
    char waited[32];
    std::snprintf(waited, sizeof waited, "%.1f s", options_.lockWait.count() / 1000.0);
    for (const std::string& folder : waiting) {
        stuckFolders_.insert(folder);
        failFolder(folder, {},
                   (options_.dir / folder).string() + ": locked by another process for over " +
                       waited);
    }
    if (grown > 0) {
        try {
            keepLimitAfterWrite(grown);
        } catch (const std::exception&) {
            // The limit is kept at the next write; the packs are written.
        }
    }
    return ok;
}

SnapshotStore::PackWrite SnapshotStore::writePack(const fs::path& path, const Pending& pending) {
    PackWrite out;
    int& err = out.error;
    try {
        step("read");
        // The pack's valid snapshots (those not written again now); a pack or a snapshot that
        // fails its checks is left out. Checked in pieces here, copied in pieces below.
        std::vector<PackSource> sources;
        const Opened old = openFile(path);
        if (old.fd) {
            out.replacedBytes = old.size;
            if (lockSharedNow(old.fd.get())) { // else the evictor is removing it: nothing to keep
                try {
                    const PackHead head = readPackHead(old.fd.get(), old.size);
                    if (sameFrame(head.frame, pending.frame)) {
                        const PackIndex index = voxtier::readPackIndex(old.fd.get(), head);
                        for (const PackIndexEntry& e : index.entries) {
                            if (pending.files.count(viewOrder(e.view))) continue;
                            SnapshotFileKey key = pending.frame;
                            key.view = e.view;
                            try {
                                checkPackEntry(old.fd.get(), e, key);
                                sources.push_back({e.view, {}, old.fd.get(), e.offset, e.bytes});
                            } catch (const SnapshotFileError&) {
                            }
                        }
                    }
                } catch (const SnapshotFileError&) {
                }
            }
        } else if (old.notRegular == "a directory") {
            // The rename cannot replace a directory; other kinds it replaces (a link itself,
            // never what it points to).
            std::error_code ec;
            fs::remove_all(path, ec);
            if (ec) return err = ec.value(), out;
        }
        for (const auto& [view, file] : pending.files)
            sources.push_back({ViewId{glm::ivec3(view[0], view[1], view[2])}, *file});

        step("write");
        // A name no other writer uses (pid + a process-wide counter).
        static std::atomic<std::uint64_t> serial{0};
        fs::path tmpPath = path;
        tmpPath += ".tmp" + std::to_string(::getpid()) + "-" + std::to_string(serial++);
        Temporary tmp(tmpPath);
        if ((err = tmp.create())) return out;
        // (Were the old pack damaged in place between the check and the copy, the copy holds a
        // snapshot whose own checksum fails: rejected when read, never used.)
        out.bytes = writePackTo(tmp.fd.get(), pending.frame, std::move(sources));
        // No fsync: a pack lost in a power cut is a checksum mismatch, re-baked on read.
        // close(2) is where NFS reports a failed flush: checked before the file gets its name.
        if ((err = tmp.fd.close())) return out;
        step("rename");
        err = tmp.renameTo(path);
    } catch (const std::bad_alloc&) {
        err = ENOMEM;
    } catch (const std::system_error& e) {
        err = e.code().value();
    } catch (const std::exception&) {
        err = EIO; // a source that could no longer be read
    }
    return out;
}

std::size_t SnapshotStore::removeStaleTemporaries() {
    const auto now = fs::file_time_type::clock::now();
    std::size_t removed = 0;
    std::uint64_t bytes = 0;
    std::error_code ec;
    for (auto it = fs::recursive_directory_iterator(options_.dir, ec);
         !ec && it != fs::recursive_directory_iterator(); it.increment(ec)) {
        if (it.depth() >= 1) it.disable_recursion_pending();
        if (!isTemporary(it->path())) continue;
        std::error_code fec;
        if (!it->is_regular_file(fec) || it->is_symlink(fec)) continue;
        const auto time = it->last_write_time(fec);
        if (fec || now - time < options_.staleTempAge) continue;
        const Opened o = openFile(it->path());
        if (!o.fd) continue; // renamed or removed meanwhile
        // Not waiting: a temporary someone holds is a live writer's, whatever its age.
        if (::flock(o.fd.get(), LOCK_EX | LOCK_NB) == 0 && sameInode(o.fd.get(), it->path()) &&
            ::unlink(it->path().c_str()) == 0) {
            ++removed;
            bytes += o.size;
        }
    }
    if (removed > 0) {
        std::lock_guard lock(mutex_);
        counters_.staleTempsRemoved += removed;
        counters_.staleTempBytes += bytes;
    }
    return removed;
}

/// What the directory holds, as the size limit counts it.
struct SnapshotStore::Scan {
    std::vector<SnapshotStoreFile> files; ///< packs and former snapshot files, oldest use first
    std::uint64_t fileBytes = 0;
    std::uint64_t tempBytes = 0, temps = 0; ///< writers' temporaries, live or dead
};

SnapshotStore::Scan SnapshotStore::scan() const {
    Scan s;
    std::error_code ec;
    for (auto it = fs::recursive_directory_iterator(options_.dir, ec);
         !ec && it != fs::recursive_directory_iterator(); it.increment(ec)) {
        if (it.depth() >= 1) it.disable_recursion_pending();
        std::error_code fec;
        // Regular files only: a link to a huge file, a FIFO or a directory is not the cache's.
        if (it->is_symlink(fec) || !it->is_regular_file(fec)) continue;
        const std::uint64_t size = it->file_size(fec);
        if (fec) continue;
        if (isTemporary(it->path())) {
            s.tempBytes += size;
            ++s.temps;
            continue;
        }
        if (it->path().extension() != ".pack" && it->path().extension() != ".snap") continue;
        const auto time = it->last_write_time(fec);
        if (!fec) {
            s.files.push_back({it->path(), size, time});
            s.fileBytes += size;
        }
    }
    std::sort(s.files.begin(), s.files.end(),
              [](const SnapshotStoreFile& a, const SnapshotStoreFile& b) {
                  return a.lastUse < b.lastUse || (a.lastUse == b.lastUse && a.path < b.path);
              });
    return s;
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
    const Scan s = scan();
    std::uint64_t total = s.fileBytes + s.tempBytes;
    if (total > options_.limitBytes) {
        total = evictDownTo(options_.limitBytes / 10 * 9);
    } else {
        std::lock_guard lock(mutex_);
        ++counters_.limitScans;
        counters_.countedBytes = total;
        counters_.countedTempBytes = s.tempBytes;
        counters_.countedTemps = s.temps;
    }
    approxBytes_ = total;
}

std::vector<SnapshotStoreFile> SnapshotStore::list() const {
    return scan().files;
}

std::uint64_t SnapshotStore::evictDownTo(std::uint64_t targetBytes) {
    removeStaleTemporaries(); // they take space too, and nothing else removes them
    const Scan s = scan();
    // Temporaries count (they take the disk's space) but only packs can go: a live writer's
    // temporary becomes a pack, a dead one's goes when stale.
    std::uint64_t total = s.fileBytes + s.tempBytes;
    for (const SnapshotStoreFile& f : s.files) {
        if (total <= targetBytes) break;
        const Opened o = openFile(f.path);
        if (!o.fd) {
            total -= f.bytes; // removed by someone else meanwhile
            continue;
        }
        // Not waiting: a file someone is reading stays; the next oldest goes instead. Still the
        // same file under that name (not replaced by a fresh write meanwhile)?
        if (::flock(o.fd.get(), LOCK_EX | LOCK_NB) == 0 && sameInode(o.fd.get(), f.path) &&
            ::unlink(f.path.c_str()) == 0) {
            total -= f.bytes;
            std::lock_guard lock(mutex_);
            ++counters_.evicted;
            counters_.bytesEvicted += f.bytes;
        }
    }
    std::lock_guard lock(mutex_);
    ++counters_.limitScans;
    counters_.countedBytes = total;
    counters_.countedTempBytes = s.tempBytes;
    counters_.countedTemps = s.temps;
    return total;
}

SnapshotStoreCounters SnapshotStore::counters() const {
    std::lock_guard lock(mutex_);
    return counters_;
}

} // namespace voxtier
