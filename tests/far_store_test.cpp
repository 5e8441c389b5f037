// The on-disk snapshot cache (impostor_cache/snapshot_store.hpp): a render with a pre-baked
// directory bakes nothing and writes the same image; damaged packs are rejected with one line,
// re-baked and replaced; concurrent writers both succeed; the size limit removes the least
// recently used packs and never one that is being read; files of the former one-file-per-snapshot
// layout are still read.
#include "cli_support.hpp"
#include "compose/frame.hpp"
#include "frame_test_support.hpp"
#include "impostor_cache/snapshot_cache.hpp"
#include "impostor_cache/snapshot_store.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <sys/file.h>
#include <sys/wait.h>

#include <chrono>
#include <fcntl.h>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <string>
#include <unistd.h>
#include <vector>

namespace voxtier {
namespace {

namespace fs = std::filesystem;

/// What this process's test cases write (directories and images beside them) starts with this.
std::string scratchPrefix() {
    return "voxtier_store_" + std::to_string(getpid()) + "_";
}

/// Removes this process's scratch files when the tests are done.
class ScratchCleanup : public ::testing::Environment {
  public:
    void TearDown() override {
        std::error_code ec;
        for (const auto& e : fs::directory_iterator(::testing::TempDir(), ec))
            if (e.path().filename().string().rfind(scratchPrefix(), 0) == 0)
                fs::remove_all(e.path(), ec);
    }
};
const auto* kCleanup = ::testing::AddGlobalTestEnvironment(new ScratchCleanup);

/// An empty directory of its own for the running test case.
fs::path freshDir(const std::string& tag = "") {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    std::string name = std::string(info->test_suite_name()) + "_" + info->name() + tag;
    for (char& c : name)
        if (c == '/') c = '_';
    const fs::path dir = fs::path(::testing::TempDir()) / (scratchPrefix() + name);
    fs::remove_all(dir);
    return dir;
}

std::vector<std::uint8_t> readBytes(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), {}};
}
void writeBytes(const fs::path& p, const std::vector<std::uint8_t>& bytes) {
    std::ofstream(p, std::ios::binary | std::ios::trunc)
        .write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
}

struct FarFrame {
    Image image;
    SnapshotCacheCounters cache;
    SnapshotStoreCounters store;
};

/// One far-tier frame of the hard-case world (three models, four entities) by a fresh renderer
/// (an empty in-memory cache) over the on-disk cache `dir`.
FarFrame renderFarWith(const fs::path& dir) {
    Scene scene = test::hardCaseWorld(glm::dvec3(0.0));
    FrameOptions o = test::cpuNear();
    o.cacheDir = dir.string();
    FrameRenderer renderer(scene, o);
    FarFrame f;
    f.image = renderer.render(0.0, RenderMode::Far).image;
    f.cache = renderer.snapshotCache().counters();
    renderer.snapshotCache().config().store->flush(); // what the renderer's end would write
    f.store = renderer.snapshotCache().config().store->counters();
    return f;
}

/// The packs of a directory (and any other file but the subdirectories' empty ".lock" files).
std::vector<fs::path> snapshotFiles(const fs::path& dir) {
    std::vector<fs::path> files;
    for (const auto& e : fs::recursive_directory_iterator(dir))
        if (e.is_regular_file() && e.path().filename() != ".lock") files.push_back(e.path());
    std::sort(files.begin(), files.end());
    return files;
}

/// The snapshots in the packs of a directory.
std::size_t snapshotCount(const fs::path& dir) {
    std::size_t n = 0;
    for (const fs::path& f : snapshotFiles(dir))
        n += decodeSnapshotPack(readBytes(f)).entries.size();
    return n;
}

TEST(SnapshotStore, PreBakedDirectoryMeansZeroBakesAndTheSameImage) {
    const fs::path dir = freshDir();
    const FarFrame cold = renderFarWith(dir);
    ASSERT_GT(cold.cache.bakes, 0u);
    EXPECT_EQ(cold.store.writes, cold.cache.bakes);
    EXPECT_EQ(snapshotCount(dir), cold.cache.bakes);
    // One pack per model frame (three models), each written once; no temporary left.
    EXPECT_EQ(snapshotFiles(dir).size(), 3u);
    EXPECT_EQ(cold.store.packWrites, 3u);
    for (const fs::path& f : snapshotFiles(dir)) EXPECT_EQ(f.extension(), ".pack") << f;
    EXPECT_GT(test::drawnPixels(cold.image), 0u);

    const FarFrame warm = renderFarWith(dir);
    EXPECT_EQ(warm.cache.bakes, 0u);
    EXPECT_EQ(warm.cache.scenesBuilt, 0u); // not even an Embree scene
    EXPECT_EQ(warm.cache.diskLoads, cold.cache.bakes);
    EXPECT_EQ(warm.store.writes, 0u);
    EXPECT_EQ(test::describeDifference(cold.image, warm.image, "cold", "pre-baked"), "");
}

TEST(SnapshotStore, FileRoundTripsAndIsNamedByItsKey) {
    const auto m = test::solidBox({7, 4, 3});
    SnapshotCache cache;
    const ViewId view = viewIdOf(ViewSet::Cube26, 20);
    const Snapshot& s = *cache.get(*m, 0, view, 1.5);
    const SnapshotFileKey key{digestGrid(m->frame(0)), m->frame(0).dims(), view, 1.5, false};
    const DecodedSnapshotFile d = decodeSnapshotFile(encodeSnapshotFile(key, s));
    EXPECT_EQ(d.key, key);
    EXPECT_EQ(d.snapshot.cells, s.cells);
    EXPECT_EQ(d.snapshot.lattice.cellRange, s.lattice.cellRange);
    EXPECT_EQ(d.snapshot.w, s.w);
    // Every key field changes the name; the palette is not in the key at all.
    SnapshotFileKey other = key;
    other.sigma = 2.0;
    EXPECT_NE(snapshotFileName(other), snapshotFileName(key));
    other = key;
    other.view = viewIdOf(ViewSet::Cube26, 21);
    EXPECT_NE(snapshotFileName(other), snapshotFileName(key));
    VoxelGrid g = m->frame(0);
    g.set({0, 0, 0}, 0);
    EXPECT_NE(digestGrid(g), key.grid);

    // A pack holds every view of a model frame: its name leaves the view out, not the rest.
    other = key;
    other.view = viewIdOf(ViewSet::Cube26, 21);
    EXPECT_EQ(snapshotPackName(other), snapshotPackName(key));
    other.sigma = 2.0;
    EXPECT_NE(snapshotPackName(other), snapshotPackName(key));
    other = key;
    other.withDepth = true;
    EXPECT_NE(snapshotPackName(other), snapshotPackName(key));
    // Its bytes depend on the set of views only, not on the order they come in.
    std::vector<SnapshotPackEntry> entries;
    for (int v : {20, 3, 11}) {
        SnapshotFileKey k = key;
        k.view = viewIdOf(ViewSet::Cube26, v);
        entries.push_back({k.view, encodeSnapshotFile(k, *cache.get(*m, 0, k.view, 1.5))});
    }
    const std::vector<std::uint8_t> pack = encodeSnapshotPack(key, entries);
    std::swap(entries[0], entries[2]);
    EXPECT_EQ(encodeSnapshotPack(key, entries), pack);
    std::uint64_t files = 0;
    for (const SnapshotPackEntry& e : entries) files += e.file.size();
    EXPECT_EQ(pack.size(), snapshotPackOverhead(3) + files);
    const DecodedSnapshotPack p = decodeSnapshotPack(pack);
    ASSERT_EQ(p.entries.size(), 3u);
    for (const SnapshotPackEntry& e : p.entries) {
        const DecodedSnapshotFile f = decodeSnapshotFile(e.file);
        EXPECT_EQ(f.key.view, e.view);
        EXPECT_EQ(f.snapshot.cells, cache.get(*m, 0, e.view, 1.5)->cells);
    }
}

TEST(SnapshotStore, SizeFieldsAreBoundedBeforeAnyAllocation) {
    const auto m = test::solidBox({4, 4, 4});
    SnapshotCache cache;
    const ViewId view = viewIdOf(ViewSet::Cube26, 0);
    const SnapshotFileKey key{digestGrid(m->frame(0)), {4, 4, 4}, view, 1.0, false};
    const std::vector<std::uint8_t> good = encodeSnapshotFile(key, *cache.get(*m, 0, view, 1.0));
    auto patched = [&](std::size_t offset, std::vector<std::uint8_t> field) {
        std::vector<std::uint8_t> b = good;
        std::copy(field.begin(), field.end(), b.begin() + std::ptrdiff_t(offset));
        return b;
    };
    auto reason = [](const std::vector<std::uint8_t>& b) {
        try {
            decodeSnapshotFile(b);
        } catch (const SnapshotFileError& e) {
            return std::string(e.what());
        }
        return std::string("accepted");
    };
    // Offsets of the layout in snapshot_store.cpp: dims at 32, view at 44, sigma at 56, cell
    // count at 84.
    EXPECT_EQ(reason(patched(32, {0, 2, 0, 0})), "dims out of range"); // 512
    EXPECT_EQ(reason(patched(44, {0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0})),
              "view is not a primitive lattice vector");
    EXPECT_EQ(reason(patched(44, {2, 0, 0, 0, 2, 0, 0, 0})),
              "view is not a primitive lattice vector");
    EXPECT_EQ(reason(patched(44, {0, 0, 0, 0x80})), "view out of range");                 // INT_MIN
    EXPECT_EQ(reason(patched(56, {0, 0, 0, 0, 0, 0, 0xf0, 0x7f})), "sigma out of range"); // inf
    EXPECT_EQ(reason(patched(84, {0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0x7f})),
              "cell count does not match the key");
    EXPECT_EQ(reason(good), "accepted");

    // A pack's fields likewise: the entry count at 56, the pack size at 60, the index from 68.
    const std::vector<std::uint8_t> pack = encodeSnapshotPack(key, {{view, good}});
    auto packReason = [](const std::vector<std::uint8_t>& b) {
        try {
            decodeSnapshotPack(b);
        } catch (const SnapshotFileError& e) {
            return std::string(e.what());
        }
        return std::string("accepted");
    };
    auto patchedPack = [&](std::size_t offset, std::vector<std::uint8_t> field) {
        std::vector<std::uint8_t> b = pack;
        std::copy(field.begin(), field.end(), b.begin() + std::ptrdiff_t(offset));
        return b;
    };
    EXPECT_EQ(packReason(patchedPack(56, {0xff, 0xff, 0xff, 0x7f})),
              "entry count does not fit the pack");
    EXPECT_EQ(packReason(patchedPack(60, {0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0x7f}))
                  .rfind("truncated", 0),
              0u);
    EXPECT_EQ(packReason(patchedPack(68, {2})), "index checksum mismatch (corrupted)");
    EXPECT_EQ(packReason({pack.begin(), pack.begin() + 50}).rfind("truncated", 0), 0u);
    EXPECT_EQ(packReason(pack), "accepted");
}

// ---- untrusted files: each case rejected with one line, re-baked, replaced ------------------

struct Damage {
    const char* name;
    const char* reason; ///< what the warning must say
    /// Damages `file`; `other` is another valid pack of the same directory.
    void (*apply)(const fs::path& file, const fs::path& other);
    bool oneSnapshot = false; ///< only one snapshot of the pack is bad (else the whole pack)
};

const Damage kDamages[] = {
    {"truncated", "truncated",
     [](const fs::path& f, const fs::path&) { fs::resize_file(f, fs::file_size(f) / 2); }},
    {"empty", "truncated", [](const fs::path& f, const fs::path&) { fs::resize_file(f, 0); }},
    {"corrupted", "checksum mismatch",
     [](const fs::path& f, const fs::path&) {
         std::vector<std::uint8_t> b = readBytes(f);
         b[b.size() - 20] ^= 0x5a; // a payload byte of the last snapshot
         writeBytes(f, b);
     },
     true},
    {"corrupted_index", "index checksum mismatch",
     [](const fs::path& f, const fs::path&) {
         std::vector<std::uint8_t> b = readBytes(f);
         b[68] ^= 0x01; // the first view's x
         writeBytes(f, b);
     }},
    {"foreign", "magic",
     [](const fs::path& f, const fs::path&) {
         std::vector<std::uint8_t> b = readBytes(f);
         const char png[8] = {'\x89', 'P', 'N', 'G', '\r', '\n', '\x1a', '\n'};
         std::copy(png, png + 8, b.begin());
         writeBytes(f, b);
     }},
    {"stale_version", "stale format version",
     [](const fs::path& f, const fs::path&) {
         std::vector<std::uint8_t> b = readBytes(f);
         b[8] = std::uint8_t(kSnapshotPackVersion + 1); // the version field, little-endian
         writeBytes(f, b);
     }},
    {"wrong_key", "written for another key",
     [](const fs::path& f, const fs::path& other) {
         fs::copy_file(other, f, fs::copy_options::overwrite_existing);
     }},
};

void PrintTo(const Damage& d, std::ostream* os) {
    *os << d.name;
}

class UntrustedFile : public ::testing::TestWithParam<Damage> {};

TEST_P(UntrustedFile, IsRejectedWithOneLineRebakedAndReplaced) {
    const Damage& d = GetParam();
    const fs::path dir = freshDir();
    const FarFrame cold = renderFarWith(dir);
    const std::vector<fs::path> files = snapshotFiles(dir);
    ASSERT_GE(files.size(), 2u);
    // The pack with the most views (two entities see one model from two directions).
    fs::path victim = files[0];
    std::size_t victimViews = 0;
    for (const fs::path& f : files) {
        const std::size_t n = decodeSnapshotPack(readBytes(f)).entries.size();
        if (n > victimViews) victim = f, victimViews = n;
    }
    ASSERT_EQ(victimViews, 2u);
    d.apply(victim, victim == files[0] ? files[1] : files[0]);
    const std::size_t bad = d.oneSnapshot ? 1 : victimViews;

    ::testing::internal::CaptureStderr();
    const FarFrame again = renderFarWith(dir);
    const std::string err = ::testing::internal::GetCapturedStderr();
    EXPECT_EQ(test::lineCount(err), 1u) << err; // one line per pack, not per view
    EXPECT_NE(err.find(victim.string()), std::string::npos) << err;
    EXPECT_NE(err.find(d.reason), std::string::npos) << err;
    EXPECT_EQ(again.store.rejected, bad);
    EXPECT_EQ(again.cache.bakes, bad);
    EXPECT_EQ(again.cache.diskLoads, cold.cache.bakes - bad);
    EXPECT_EQ(test::describeDifference(cold.image, again.image, "cold", "after re-bake"), "");

    // Replaced: a valid pack again, every snapshot in it valid, read by the next render without a
    // word.
    const DecodedSnapshotPack replaced = decodeSnapshotPack(readBytes(victim));
    EXPECT_EQ(replaced.entries.size(), victimViews);
    for (const SnapshotPackEntry& e : replaced.entries) EXPECT_NO_THROW(decodeSnapshotFile(e.file));
    ::testing::internal::CaptureStderr();
    const FarFrame third = renderFarWith(dir);
    EXPECT_EQ(::testing::internal::GetCapturedStderr(), "");
    EXPECT_EQ(third.cache.bakes, 0u);
    EXPECT_EQ(snapshotFiles(dir).size(), files.size());
}

INSTANTIATE_TEST_SUITE_P(Cases, UntrustedFile, ::testing::ValuesIn(kDamages),
                         [](const auto& info) { return std::string(info.param.name); });

// ---- the size limit --------------------------------------------------------------------------

/// Sets a file's last use (mtime) to `secondsAgo` before now.
void setLastUse(const fs::path& f, int secondsAgo) {
    fs::last_write_time(f, fs::file_time_type::clock::now() - std::chrono::seconds(secondsAgo));
}

TEST(SnapshotStore, SizeLimitRemovesLeastRecentlyUsedPacksButNeverOneBeingRead) {
    const fs::path dir = freshDir();
    // Six model frames (boxes of six sizes), two views each: six packs.
    SnapshotCache cache;
    std::vector<SnapshotFileKey> keys;
    {
        SnapshotStore store({.dir = dir});
        for (int i = 0; i < 6; ++i) {
            const auto m = test::solidBox({3 + i, 4, 3});
            for (int v : {0, 7}) {
                const ViewId view = viewIdOf(ViewSet::Cube26, v);
                const SnapshotFileKey key{digestGrid(m->frame(0)), m->frame(0).dims(), view, 1.0,
                                          false};
                ASSERT_TRUE(store.save(key, *cache.get(*m, 0, view, 1.0)));
                if (v == 0) keys.push_back(key);
            }
        }
        ASSERT_TRUE(store.flush());
        EXPECT_EQ(store.counters().packWrites, 6u);
    }
    std::vector<fs::path> files;
    for (const SnapshotFileKey& k : keys) files.push_back(dir / snapshotPackName(k));
    EXPECT_EQ(snapshotFiles(dir).size(), files.size());
    // A known order of last use: files[0] the oldest ... files.back() the newest.
    for (std::size_t i = 0; i < files.size(); ++i) setLastUse(files[i], 1000 - int(i));
    std::uint64_t total = 0;
    for (const fs::path& f : files) total += fs::file_size(f);

    // Another "process" is reading the oldest pack: it holds the readers' shared lock.
    const int reader = ::open(files[0].c_str(), O_RDONLY);
    ASSERT_GE(reader, 0);
    ASSERT_EQ(::flock(reader, LOCK_SH), 0);

    // Room for all but the second and third oldest: the oldest is being read, so exactly those
    // two go, and nothing newer.
    const std::uint64_t target = total - fs::file_size(files[1]) - fs::file_size(files[2]);
    SnapshotStore store({.dir = dir});
    const std::uint64_t left = store.evictDownTo(target);
    ::close(reader);
    EXPECT_LE(left, target);
    EXPECT_TRUE(fs::exists(files[0])) << "removed while being read";
    EXPECT_FALSE(fs::exists(files[1]));
    EXPECT_FALSE(fs::exists(files[2]));
    for (std::size_t i = 3; i < files.size(); ++i) EXPECT_TRUE(fs::exists(files[i])) << i;
    EXPECT_EQ(store.counters().evicted, 2u);

    // A read marks its pack used: the oldest pack, read again, is no longer the oldest by far;
    // the removed ones' snapshots are gone with them.
    const auto readBefore = fs::last_write_time(files[0]);
    EXPECT_TRUE(store.load(keys[0]).has_value());
    EXPECT_FALSE(store.load(keys[1]).has_value());
    EXPECT_EQ(store.counters().misses, 1u);
    EXPECT_GT(fs::last_write_time(files[0]), readBefore + std::chrono::seconds(900));
}

// Files of the former layout (one "ab/<hex>.snap" per snapshot) are still read, exactly; new
// snapshots go to packs.
TEST(SnapshotStore, FormerSingleSnapshotFilesAreStillRead) {
    const fs::path dir = freshDir();
    const auto m = test::solidBox({5, 4, 3});
    SnapshotCache cache;
    const ViewId view = viewIdOf(ViewSet::Cube26, 4);
    const SnapshotFileKey key{digestGrid(m->frame(0)), m->frame(0).dims(), view, 1.0, false};
    const Snapshot& s = *cache.get(*m, 0, view, 1.0);
    fs::create_directories((dir / snapshotFileName(key)).parent_path());
    writeBytes(dir / snapshotFileName(key), encodeSnapshotFile(key, s));
    SnapshotStore store({.dir = dir});
    EXPECT_TRUE(store.contains(key));
    const std::optional<Snapshot> got = store.load(key);
    ASSERT_TRUE(got.has_value());
    EXPECT_EQ(got->cells, s.cells);
    EXPECT_EQ(store.counters().reads, 1u);
    EXPECT_EQ(store.list().size(), 1u); // and the size limit sees it
}

TEST(SnapshotStore, WritesKeepTheDirectoryUnderItsLimit) {
    const fs::path dir = freshDir();
    Scene scene = test::hardCaseWorld(glm::dvec3(0.0));
    FrameOptions o = test::cpuNear();
    o.cacheDir = dir.string();
    o.cacheDirBytes = 2000; // the hard-case world writes 3 packs, 3430 bytes
    FrameRenderer renderer(scene, o);
    renderer.render(0.0, RenderMode::Far);
    renderer.snapshotCache().config().store->flush();
    const SnapshotStoreCounters c = renderer.snapshotCache().config().store->counters();
    std::uint64_t total = 0;
    for (const fs::path& f : snapshotFiles(dir)) total += fs::file_size(f);
    EXPECT_GT(c.evicted, 0u);
    EXPECT_LE(total, o.cacheDirBytes);
    EXPECT_EQ(c.bytesWritten - c.bytesEvicted, total);
}

// ---- processes ---------------------------------------------------------------------------------

TEST(SnapshotStore, TwoProcessesBakingIntoOneDirectoryBothSucceed) {
    const fs::path dir = freshDir();
    const std::string render = "render '" + std::string(VOXTIER_SOURCE_DIR) +
                               "/scenes/vox/mmmm/chr_cop1.vox' --mode far --size 96x64 "
                               "--near-backend reference --cache-dir '" +
                               dir.string() + "'";
    // Both start on an empty directory and bake (and write) the same keys at the same time.
    const std::string cli = "'" + std::string(VOXTIER_CLI) + "' ";
    const std::string errFile = dir.string() + "_err.txt";
    const std::string cmd = cli + render + " -o " + dir.string() + "_a.png >/dev/null 2>>" +
                            errFile + " & a=$!; " + cli + render + " -o " + dir.string() +
                            "_b.png >/dev/null 2>>" + errFile + " & b=$!; wait $a && wait $b";
    test::CliRun both;
    both.status = std::system(cmd.c_str());
    const std::vector<std::uint8_t> errBytes = readBytes(errFile);
    both.err.assign(errBytes.begin(), errBytes.end());
    EXPECT_EQ(both.status, 0) << both.err;
    EXPECT_EQ(test::withoutFarWarning(both.err).find("warning"), std::string::npos) << both.err;
    const std::vector<fs::path> files = snapshotFiles(dir);
    ASSERT_FALSE(files.empty());
    for (const fs::path& f : files) {
        EXPECT_EQ(f.extension(), ".pack") << f; // no temporary file left behind
        for (const SnapshotPackEntry& e : decodeSnapshotPack(readBytes(f)).entries)
            EXPECT_NO_THROW(decodeSnapshotFile(e.file)) << f;
    }
    EXPECT_EQ(readBytes(dir.string() + "_a.png"), readBytes(dir.string() + "_b.png"));
    const test::CliRun warm = test::runCli(render + " -o " + dir.string() + "_c.png");
    EXPECT_EQ(warm.status, 0) << warm.err;
    EXPECT_NE(warm.out.find(", 0 bakes,"), std::string::npos) << warm.out;
    EXPECT_EQ(readBytes(dir.string() + "_a.png"), readBytes(dir.string() + "_c.png"));
}

// Writers in several processes adding views of one model frame at once: each view rewrites the
// pack (a flush per save, the most contention there can be), and the subdirectory's lock makes
// each merge see the others' views, so none is dropped; the pack is the one a lone writer gives.
TEST(SnapshotStore, WritersInSeveralProcessesAddTheirViewsToOnePack) {
    const fs::path dir = freshDir(), alone = freshDir("_alone");
    const auto m = test::solidBox({6, 5, 4});
    // Every process bakes the views itself, and the writers are forked before anything starts a
    // thread: a child forked while a TBB worker held a lock of the allocator (ASan's, here)
    // waits on it for ever.
    using Views = std::vector<std::pair<SnapshotFileKey, std::shared_ptr<const Snapshot>>>;
    const auto bakeViews = [&] {
        SnapshotCache cache;
        Views views;
        for (int v = 0; v < 26; ++v) {
            const ViewId view = viewIdOf(ViewSet::Cube26, v);
            views.push_back({{digestGrid(m->frame(0)), m->frame(0).dims(), view, 1.0, false},
                             cache.get(*m, 0, view, 1.0)});
        }
        return views;
    };
    constexpr int kWriters = 4;
    std::vector<pid_t> writers;
    for (int p = 0; p < kWriters; ++p) {
        const pid_t pid = fork();
        ASSERT_GE(pid, 0);
        if (pid == 0) {
            bool ok = true;
            {
                const Views views = bakeViews();
                SnapshotStore store({.dir = dir});
                for (std::size_t v = std::size_t(p); v < views.size(); v += kWriters)
                    ok = store.save(views[v].first, *views[v].second) && store.flush() && ok;
            }
            ::_exit(ok ? 0 : 1);
        }
        writers.push_back(pid);
    }
    for (const pid_t w : writers) {
        int status = 0;
        ASSERT_EQ(::waitpid(w, &status, 0), w);
        EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << status;
    }
    const Views views = bakeViews();
    {
        SnapshotStore store({.dir = alone});
        for (const auto& [key, snap] : views) ASSERT_TRUE(store.save(key, *snap));
    }
    const fs::path pack = snapshotPackName(views[0].first);
    EXPECT_EQ(decodeSnapshotPack(readBytes(dir / pack)).entries.size(), views.size());
    EXPECT_TRUE(readBytes(dir / pack) == readBytes(alone / pack));
    EXPECT_EQ(snapshotFiles(dir).size(), 1u); // no temporary left
}

// ---- pre-baking: voxtier bake --cache-dir [--shard I/N] ------------------------------------

std::string quoted(const fs::path& p) {
    return "'" + p.string() + "'";
}
const std::string kDefaultScene = std::string(VOXTIER_SOURCE_DIR) + "/scenes/default.json";

/// Every file of a directory tree by relative path, with its bytes.
std::map<std::string, std::vector<std::uint8_t>> directoryContents(const fs::path& dir) {
    std::map<std::string, std::vector<std::uint8_t>> files;
    for (const fs::path& f : snapshotFiles(dir))
        files[fs::relative(f, dir).string()] = readBytes(f);
    return files;
}

TEST(BakeCli, PreBakedSceneRendersWithZeroBakesAndTheSameImage) {
    const fs::path dir = freshDir();
    // What the scene's renders at that size ask for (tests/path_bake_test.cpp has the path).
    const test::CliRun bake =
        test::runCli("bake " + kDefaultScene + " --size 240x136 --cache-dir " + quoted(dir));
    ASSERT_EQ(bake.status, 0) << bake.err;
    EXPECT_NE(bake.out.find("(0 already in the directory)"), std::string::npos) << bake.out;
    EXPECT_NE(bake.out.find("Mrays/s"), std::string::npos) << bake.out;
    const std::string render =
        "render " + kDefaultScene + " --size 240x136 --near-backend reference -o " + dir.string();
    const test::CliRun cold = test::runCli(render + "_cold.png");
    const test::CliRun warm = test::runCli(render + "_warm.png --cache-dir " + quoted(dir));
    ASSERT_EQ(cold.status, 0) << cold.err;
    ASSERT_EQ(warm.status, 0) << warm.err;
    EXPECT_EQ(cold.out.find(", 0 bakes,"), std::string::npos) << cold.out;
    EXPECT_NE(warm.out.find(", 0 bakes,"), std::string::npos) << warm.out;
    EXPECT_NE(warm.out.find("0 written"), std::string::npos) << warm.out;
    EXPECT_EQ(readBytes(dir.string() + "_cold.png"), readBytes(dir.string() + "_warm.png"));
    // A second bake finds everything there and writes nothing.
    const test::CliRun again =
        test::runCli("bake " + kDefaultScene + " --size 240x136 --cache-dir " + quoted(dir));
    EXPECT_NE(again.out.find("baked 0 of"), std::string::npos) << again.out;
}

// A scene whose far tier reads finer snapshots (issue 29) is pre-baked as its renders ask for
// them: at snapshot_scale x its sigma, with that outline stride.
TEST(BakeCli, PreBakesTheFinerSnapshotsASceneAsksFor) {
    const fs::path dir = freshDir();
    fs::create_directories(dir);
    nlohmann::json scene = nlohmann::json::parse(
        std::ifstream(std::string(VOXTIER_SOURCE_DIR) + "/scenes/golden/crowd.json"));
    scene["selector"]["snapshot_scale"] = 3;
    const fs::path file = dir / "crowd_x3.json";
    std::ofstream(file) << scene.dump();
    const fs::path cache = dir / "cache";
    const test::CliRun bake =
        test::runCli("bake " + quoted(file) + " --mode far --cache-dir " + quoted(cache));
    ASSERT_EQ(bake.status, 0) << bake.err;
    EXPECT_NE(bake.out.find("at sigma 3"), std::string::npos) << bake.out;
    const test::CliRun warm =
        test::runCli("render " + quoted(file) + " --mode far --near-backend reference -o " +
                     quoted(dir / "warm.png") + " --cache-dir " + quoted(cache));
    ASSERT_EQ(warm.status, 0) << warm.err;
    EXPECT_NE(warm.out.find(", 0 bakes,"), std::string::npos) << warm.out;
}

TEST(BakeCli, ShardsTogetherAreTheUnshardedBakeFileForFile) {
    const std::string inputs = kDefaultScene + " '" + VOXTIER_SOURCE_DIR +
                               "/scenes/vox/mmmm/chr_cop1.vox' --ladder --frames all";
    const fs::path whole = freshDir("_whole");
    ASSERT_EQ(test::runCli("bake " + inputs + " --cache-dir " + quoted(whole)).status, 0);
    const auto expected = directoryContents(whole);
    ASSERT_GT(expected.size(), 50u); // packs: the scene's 51 model frames and the character's
    ASSERT_GT(snapshotCount(whole), 10000u);
    for (int n : {1, 3, 7}) {
        // N independent processes at once, each with its own index, into one directory.
        const fs::path dir = freshDir("_" + std::to_string(n));
        std::string cmd;
        for (int i = 0; i < n; ++i)
            cmd += "'" + std::string(VOXTIER_CLI) + "' bake " + inputs + " --cache-dir " +
                   quoted(dir) + " --shard " + std::to_string(i) + "/" + std::to_string(n) +
                   " >/dev/null & p" + std::to_string(i) + "=$!; ";
        for (int i = 0; i < n; ++i) cmd += "wait $p" + std::to_string(i) + " && ";
        cmd += "true";
        ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
        const auto got = directoryContents(dir);
        EXPECT_EQ(got.size(), expected.size()) << n << " shards";
        EXPECT_TRUE(got == expected) << n << " shards: not the same files and bytes";
    }
}

TEST(BakeCli, BadOptionsAreOneLineErrors) {
    const fs::path dir = freshDir();
    const std::string vox =
        "'" + std::string(VOXTIER_SOURCE_DIR) + "/scenes/vox/mmmm/chr_cop1.vox'";
    fs::create_directories(dir);
    std::ofstream(dir / "a_file") << "x";
    struct Case {
        std::string args;
        int status;
        std::string expect;
    };
    const Case cases[] = {
        {"bake " + vox + " --cache-dir " + quoted(dir) + " --shard 3/3", 2, "--shard"},
        {"bake " + vox + " --cache-dir " + quoted(dir) + " --shard 1", 2, "--shard"},
        {"bake " + vox + " --cache-dir " + quoted(dir) + " --frames some", 2, "--frames"},
        {"bake " + vox + " --shard 0/2", 2, "--shard"},
        {"bake " + vox + " --cache-dir " + quoted(dir) + " --views 98 --level 2", 2, "--level"},
        {"bake " + vox + " --cache-dir-mb 10", 2, "--cache-dir"},
        {"render " + vox + " --cache-dir " + quoted(dir) + " --cache-dir-mb 0", 2,
         "--cache-dir-mb"},
        {"render " + vox + " --cache-dir " + quoted(dir / "a_file" / "sub"), 1, "--cache-dir"},
    };
    for (const Case& c : cases) {
        const test::CliRun r = test::runCli(c.args);
        EXPECT_EQ(r.status, c.status) << c.args << ": " << r.err;
        EXPECT_EQ(test::lineCount(r.err), 1u) << c.args << ": " << r.err;
        EXPECT_NE(r.err.find(c.expect), std::string::npos) << c.args << ": " << r.err;
    }
}

} // namespace
} // namespace voxtier
