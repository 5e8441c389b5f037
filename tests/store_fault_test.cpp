// The on-disk store's fault handling in one process (issue 37; the command-line cases are
// tests/cache_fault_test.cpp): an exception at any step of a pack write leaves no lock held and
// no temporary; a held folder lock costs a flush at most its lock wait and is one reason naming
// the folder; a reader never waits for a lock; writers' temporaries count in the size limit;
// a full inode table is reported as what it is; a bake's packs are written once; the digest is
// the same however its input is cut.
#include "impostor_cache/snapshot_cache.hpp"
#include "impostor_cache/snapshot_store.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>
#include <sys/file.h>
#include <sys/mount.h>
#include <sys/stat.h>

#include <cerrno>
#include <fcntl.h>
#include <filesystem>
#include <fstream>
#include <new>
#include <string>
#include <unistd.h>
#include <vector>

namespace voxtier {
namespace {

namespace fs = std::filesystem;

fs::path freshDir() {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    const fs::path d = fs::path(::testing::TempDir()) /
                       ("voxtier_store_fault_" + std::to_string(::getpid())) / info->name();
    fs::remove_all(d);
    fs::create_directories(d);
    return d;
}

/// `n` views of one small model frame, baked, with their keys.
struct Views {
    std::vector<SnapshotFileKey> keys;
    std::vector<std::shared_ptr<const Snapshot>> snaps;
};
Views bakeViews(int n, glm::ivec3 dims = {6, 5, 4}) {
    const auto m = test::solidBox(dims);
    SnapshotCache cache;
    Views v;
    for (int i = 0; i < n; ++i) {
        const ViewId view = viewIdOf(ViewSet::Cube26, i);
        v.keys.push_back({digestGrid(m->frame(0)), m->frame(0).dims(), view, 1.0, false});
        v.snaps.push_back(cache.get(*m, 0, view, 1.0));
    }
    return v;
}

/// Whether another descriptor can take the folder's lock now (none of this process's left).
bool lockFree(const fs::path& folder) {
    const int fd = ::open((folder / ".lock").c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) return true;
    const bool free = ::flock(fd, LOCK_EX | LOCK_NB) == 0;
    ::close(fd);
    return free;
}

std::vector<fs::path> filesUnder(const fs::path& dir) {
    std::vector<fs::path> files;
    for (const auto& e : fs::recursive_directory_iterator(dir))
        if (e.is_regular_file() && e.path().filename() != ".lock") files.push_back(e.path());
    return files;
}

// An allocation failure (or any exception) at each step: the flush fails with the reason, the
// folder's lock is free again, nothing but the old pack is there, and the store still works.
TEST(StoreFaults, AnExceptionAtAnyStepOfAWriteReleasesTheLockAndLeavesNoFile) {
    const Views v = bakeViews(3);
    for (const char* failing : {"folder", "locked", "read", "write", "rename"}) {
        const fs::path dir = freshDir() / failing;
        {
            SnapshotStore first({.dir = dir});
            ASSERT_TRUE(first.save(v.keys[0], *v.snaps[0]));
            ASSERT_TRUE(first.flush());
        }
        const fs::path pack = dir / snapshotPackName(v.keys[0]);
        const std::uintmax_t before = fs::file_size(pack);
        {
            SnapshotStore store({.dir = dir, .beforeStep = [&](std::string_view step) {
                                     if (step == failing) throw std::bad_alloc();
                                 }});
            ASSERT_TRUE(store.save(v.keys[1], *v.snaps[1]));
            EXPECT_FALSE(store.flush()) << failing;
            EXPECT_EQ(store.counters().writeFailures, 1u) << failing;
            EXPECT_EQ(store.counters().writeFailureReason, "Cannot allocate memory") << failing;
            EXPECT_TRUE(lockFree(pack.parent_path())) << failing;
            EXPECT_EQ(filesUnder(dir), std::vector<fs::path>{pack}) << failing;
            EXPECT_EQ(fs::file_size(pack), before) << failing;
            // Buffered again and flushed by the destructor, which fails the same way and returns.
            ASSERT_TRUE(store.save(v.keys[2], *v.snaps[2]));
        }
        EXPECT_TRUE(lockFree(pack.parent_path())) << failing;
        SnapshotStore again({.dir = dir});
        ASSERT_TRUE(again.save(v.keys[1], *v.snaps[1]));
        EXPECT_TRUE(again.flush()) << failing;
        EXPECT_TRUE(again.load(v.keys[0]).has_value());
        EXPECT_TRUE(again.load(v.keys[1]).has_value());
    }
}

// What issue 37 found: a lock left held by this very process (another descriptor of the same
// .lock) made the destructor's flush wait for ever. Now a flush waits at most lockWait, fails
// those packs with a reason naming the folder, and a later flush does not wait again.
TEST(StoreFaults, AHeldFolderLockCostsAFlushAtMostItsWaitAndNamesTheFolder) {
    const fs::path dir = freshDir();
    const Views v = bakeViews(2);
    const fs::path folder = dir / snapshotPackName(v.keys[0]).parent_path();
    fs::create_directories(folder);
    const int holder = ::open((folder / ".lock").c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    ASSERT_GE(holder, 0);
    ASSERT_EQ(::flock(holder, LOCK_EX), 0);
    {
        SnapshotStore store({.dir = dir, .lockWait = std::chrono::milliseconds(200)});
        ASSERT_TRUE(store.save(v.keys[0], *v.snaps[0]));
        EXPECT_FALSE(store.flush());
        EXPECT_EQ(store.counters().writeFailureReason,
                  folder.string() + ": locked by another process for over 0.2 s");
        // Later flushes (and the destructor's) try once without waiting.
        ASSERT_TRUE(store.save(v.keys[1], *v.snaps[1]));
        EXPECT_FALSE(store.flush());
        EXPECT_EQ(store.counters().writeFailures, 2u);
        ASSERT_TRUE(store.save(v.keys[1], *v.snaps[1]));
    }
    EXPECT_TRUE(filesUnder(dir).empty());
    ::close(holder);
    SnapshotStore store({.dir = dir});
    ASSERT_TRUE(store.save(v.keys[0], *v.snaps[0]));
    EXPECT_TRUE(store.flush());
}

// A pack someone holds exclusively (the evictor, between its lock and its unlink) is a miss for
// a reader, not a wait and not a warning.
TEST(StoreFaults, AReaderNeverWaitsForALock) {
    const fs::path dir = freshDir();
    const Views v = bakeViews(1);
    {
        SnapshotStore store({.dir = dir});
        ASSERT_TRUE(store.save(v.keys[0], *v.snaps[0]));
    }
    const fs::path pack = dir / snapshotPackName(v.keys[0]);
    const int evictor = ::open(pack.c_str(), O_RDONLY | O_CLOEXEC);
    ASSERT_EQ(::flock(evictor, LOCK_EX), 0);
    std::vector<std::string> warnings;
    SnapshotStore store({.dir = dir, .warn = [&](const std::string& w) { warnings.push_back(w); }});
    EXPECT_FALSE(store.load(v.keys[0]).has_value());
    EXPECT_EQ(store.counters().misses, 1u);
    EXPECT_TRUE(warnings.empty());
    ::close(evictor);
    EXPECT_TRUE(store.load(v.keys[0]).has_value());
}

// Temporaries take the disk's space: the size limit counts them (and says so), so packs go to
// make room for them; only stale ones are removed, and the summary counts those too.
TEST(StoreFaults, TemporariesCountInTheSizeLimit) {
    const fs::path dir = freshDir();
    const Views v = bakeViews(2);
    fs::create_directories(dir / "ab");
    const std::string half(20000, 'x');
    for (const char* name : {"ab/1.pack.tmp1-0", "ab/2.pack.tmp1-1"})
        std::ofstream(dir / name) << half;
    std::ofstream(dir / "ab/3.pack.tmp1-2") << half;
    fs::last_write_time(dir / "ab/3.pack.tmp1-2",
                        fs::file_time_type::clock::now() - std::chrono::hours(2));
    SnapshotStore store({.dir = dir, .limitBytes = 30000});
    EXPECT_EQ(store.counters().staleTempsRemoved, 1u);
    EXPECT_EQ(store.counters().staleTempBytes, half.size());
    ASSERT_TRUE(store.save(v.keys[0], *v.snaps[0]));
    ASSERT_TRUE(store.flush());
    const SnapshotStoreCounters c = store.counters();
    // The two live temporaries alone are over the limit: the pack just written is evicted.
    EXPECT_EQ(c.countedTemps, 2u);
    EXPECT_EQ(c.countedTempBytes, 2 * half.size());
    EXPECT_EQ(c.evicted, 1u);
    EXPECT_EQ(c.countedBytes, 2 * half.size());
    EXPECT_FALSE(fs::exists(dir / snapshotPackName(v.keys[0])));
}

// A filesystem out of inodes: the folder cannot be created, and the reason is that (no space),
// not what an open in a missing folder says (no such file or directory).
TEST(StoreFaults, AFullInodeTableIsReportedAsNoSpace) {
    const fs::path dir = freshDir();
    if (::mount("tmpfs", dir.c_str(), "tmpfs", 0, "size=1m,nr_inodes=8") != 0)
        GTEST_SKIP() << "cannot mount a tmpfs here (needs root)";
    struct Unmount {
        fs::path d;
        ~Unmount() { ::umount2(d.c_str(), MNT_DETACH); }
    } unmount{dir};
    const Views v = bakeViews(1);
    SnapshotStore store({.dir = dir / "cache"});
    for (int k = 0;; ++k) { // take every inode left
        const int fd = ::open((dir / ("f" + std::to_string(k))).c_str(), O_CREAT | O_WRONLY, 0644);
        if (fd < 0) break;
        ::close(fd);
    }
    ASSERT_TRUE(store.save(v.keys[0], *v.snaps[0]));
    EXPECT_FALSE(store.flush());
    EXPECT_EQ(store.counters().writeFailureReason, "No space left on device");
}

// writeOnlyOnFlush (what bake uses): however small flushBytes and flushAfter, a pack is written
// once, at flush(), and the bytes written are its size; without it the same saves rewrite it.
TEST(StoreFaults, WriteOnlyOnFlushWritesEachPackOnce) {
    const Views v = bakeViews(26);
    for (const bool once : {true, false}) {
        const fs::path dir = freshDir() / (once ? "once" : "rewritten");
        SnapshotStore store({.dir = dir,
                             .flushBytes = 1,
                             .flushAfter = std::chrono::milliseconds(0),
                             .writeOnlyOnFlush = once});
        for (std::size_t i = 0; i < v.keys.size(); ++i)
            ASSERT_TRUE(store.save(v.keys[i], *v.snaps[i]));
        ASSERT_TRUE(store.flush());
        const SnapshotStoreCounters c = store.counters();
        const std::uintmax_t pack = fs::file_size(dir / snapshotPackName(v.keys[0]));
        if (once) {
            EXPECT_EQ(c.packWrites, 1u);
            EXPECT_EQ(c.bytesWritten, pack);
        } else {
            EXPECT_EQ(c.packWrites, 26u);
            EXPECT_GT(c.bytesWritten, 10 * pack);
        }
        EXPECT_EQ(c.writes, 26u);
    }
}

// The digest of bytes given in pieces is the digest of the whole, however it is cut (what lets
// a writer check an old pack's snapshots in pieces).
TEST(StoreFaults, TheDigestIsTheSameHoweverItsInputIsCut) {
    std::vector<std::uint8_t> bytes(1000);
    for (std::size_t i = 0; i < bytes.size(); ++i) bytes[i] = std::uint8_t(i * 131 + 7);
    for (std::size_t n : {0u, 1u, 15u, 16u, 17u, 999u, 1000u}) {
        const std::span<const std::uint8_t> all(bytes.data(), n);
        const Digest128 whole = digestBytes(all, 42);
        for (std::size_t cut : {1u, 3u, 16u, 33u}) {
            DigestStream d(42);
            for (std::size_t at = 0; at < n; at += cut)
                d.add(all.subspan(at, std::min(cut, n - at)));
            EXPECT_EQ(d.finish(), whole) << n << " cut " << cut;
        }
    }
    // And it is the digest the files were named and checked by before it could be cut (values
    // of the former one-shot function at ffa5841): every existing directory stays valid.
    const std::span<const std::uint8_t> all(bytes);
    EXPECT_EQ(digestBytes(all.first(0), 42),
              (Digest128{0xe9b3fba7da8c94c3ull, 0x2a96edcc789101b0ull}));
    EXPECT_EQ(digestBytes(all.first(17), 42),
              (Digest128{0xe8c5da950580aad5ull, 0xc9e2a67104eddfd2ull}));
    EXPECT_EQ(digestBytes(all, 42), (Digest128{0x85a7768fcea8b70dull, 0x1885b61ab233b963ull}));
}

} // namespace
} // namespace voxtier
