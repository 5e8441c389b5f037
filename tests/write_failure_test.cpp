// A write that fails is never reported as done (issue 28): on a really full filesystem (a small
// tmpfs, else a loop-mounted image; skipped with the reason when neither can be mounted) every
// output of `render` and `bake` fails with exit 1, one line naming the file and the OS reason,
// and no partial file; `render --cache-dir` still succeeds with one warning line; a bake killed
// part-way leaves a directory a later render reads exactly, and its dead temporaries are removed
// by the store's rule; colliding outputs are refused.
#include "cli_support.hpp"
#include "core/error.hpp"
#include "core/file_write.hpp"
#include "image_files/image_files.hpp"
#include "impostor_cache/snapshot_store.hpp"

#include <gtest/gtest.h>
#include <sys/file.h>
#include <sys/mount.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <sys/wait.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <fcntl.h>
#include <filesystem>
#include <fstream>
#include <signal.h>
#include <string>
#include <thread>
#include <unistd.h>
#include <vector>

namespace voxtier {
namespace {

namespace fs = std::filesystem;

fs::path scratch() {
    return test::scratchDir("voxtier_write_failure", true);
}

/// Far entities in a row and one near: the far ones go through the snapshot cache.
std::string sceneText() {
    std::string entities;
    for (int k = 0; k < 6; ++k)
        entities += R"({"model": ")" + std::string(k % 2 ? "ball" : "crate") +
                    R"(", "position": [)" + std::to_string(-6 + 2.5 * k) + ", 0, " +
                    std::to_string(-20 - 8 * k) + R"(], "rotation_deg": [0, )" +
                    std::to_string(17 * k) + ", 0]},";
    return R"({"camera": {"position": [0, 2, 6], "target": [0, 1, -40], "size": [96, 64]},
        "camera_path": {"fps": 10, "keys": [
            {"time": 0, "position": [0, 3, 12], "target": [0, 1, -40]},
            {"time": 0.5, "position": [1, 2, 6], "target": [0, 1, -40]}]},
        "selector": {"metric": "error_budget", "budget_vpx": 1},
        "models": [{"name": "crate", "generator": "box", "size": [10, 10, 10], "index": 7},
                   {"name": "ball", "generator": "sphere", "radius": 8, "index": 6}],
        "entities": [)" +
           entities + R"({"model": "crate", "position": [0, 0, 0]}]})";
}

std::string scene() {
    return test::writeText(scratch(), "s.json", sceneText());
}

bool run(const std::string& cmd) {
    return std::system((cmd + " >/dev/null 2>&1").c_str()) == 0;
}

/// A filesystem with no free byte, mounted at `dir` for one test: a 64 KiB tmpfs, else a
/// loop-mounted 1 MiB ext2 image, filled up by a filler file. Unmounted in the destructor.
class FullDisk {
  public:
    explicit FullDisk(const fs::path& dir) : dir_(dir) {
        fs::create_directories(dir_);
        if (::mount("tmpfs", dir_.c_str(), "tmpfs", 0, "size=64k") == 0) {
            mounted_ = true;
        } else {
            why_ = std::string("tmpfs: ") + std::strerror(errno);
            image_ = dir_.string() + ".img";
            if (run("truncate -s 1M '" + image_ + "' && mkfs.ext2 -q -F '" + image_ + "'") &&
                run("mount -o loop '" + image_ + "' '" + dir_.string() + "'"))
                mounted_ = true;
            else
                why_ += "; loop-mounted ext2 image: mount refused";
        }
        if (!mounted_) return;
        // Fill it: write until the filesystem says it is full.
        const int fd = ::open((dir_ / "filler").c_str(), O_WRONLY | O_CREAT, 0644);
        std::vector<char> block(4096, 'x');
        while (fd >= 0 && ::write(fd, block.data(), block.size()) > 0) {
        }
        if (fd >= 0) ::close(fd);
    }
    ~FullDisk() {
        if (mounted_) ::umount2(dir_.c_str(), MNT_DETACH);
        if (!image_.empty()) fs::remove(image_);
    }
    bool mounted() const { return mounted_; }
    /// Why no full filesystem could be had (for GTEST_SKIP).
    const std::string& why() const { return why_; }
    /// Everything in it but the filler (what a failed write must not leave).
    std::vector<std::string> leftovers() const {
        std::vector<std::string> names;
        for (const auto& e : fs::recursive_directory_iterator(dir_))
            if (e.is_regular_file() && e.path().filename() != "filler")
                names.push_back(e.path().lexically_relative(dir_).string());
        return names;
    }

  private:
    fs::path dir_;
    std::string image_, why_;
    bool mounted_ = false;
};

#define REQUIRE_FULL_DISK(disk)                                                                    \
    if (!(disk).mounted())                                                                         \
    GTEST_SKIP() << "no full filesystem to test on (needs root to mount): " << (disk).why()

bool contains(const std::string& s, const std::string& part) {
    return s.find(part) != std::string::npos;
}

// Every image format, the numbered sequence and the animated GIF: exit 1, one line naming the
// file and "No space left on device", nothing left behind.
TEST(WriteFailure, EveryImageFormatOnAFullDiskFailsWithOneLineAndNoFile) {
    const std::string s = scene();
    const fs::path d = scratch() / "full";
    FullDisk disk(d);
    REQUIRE_FULL_DISK(disk);
    const std::pair<std::string, std::string> cases[] = {
        {"-o " + (d / "a.png").string(), (d / "a.png").string()},
        {"-o " + (d / "a.exr").string(), (d / "a.exr").string()},
        {"-o " + (d / "a.tif").string(), (d / "a.tif").string()},
        {"-o " + (d / "a.jpg").string(), (d / "a.jpg").string()},
        {"--frames 0:2 -o " + (d / "seq.png").string(), (d / "seq_0000.png").string()},
        {"--path -o " + (d / "anim.gif").string(), (d / "anim.gif").string()},
    };
    for (const auto& [args, file] : cases) {
        const test::CliRun r = test::runCli("render " + s + " --mode reference " + args);
        EXPECT_EQ(r.status, 1) << args << ": " << r.err;
        EXPECT_EQ(test::lineCount(r.err), 1u) << r.err;
        EXPECT_TRUE(contains(r.err, file + ": cannot write: No space left on device")) << r.err;
        EXPECT_EQ(disk.leftovers(), std::vector<std::string>{}) << args;
    }
}

// --overlay, --ids, --csv and --pops on the full disk while the image goes elsewhere: the run
// fails naming that file, and the file is not there.
TEST(WriteFailure, EverySideOutputOnAFullDiskFailsWithOneLineAndNoFile) {
    const std::string s = scene();
    const fs::path d = scratch() / "full";
    FullDisk disk(d);
    REQUIRE_FULL_DISK(disk);
    const std::string image = (scratch() / "image.png").string();
    for (const std::string option : {"--overlay", "--ids", "--csv", "--pops"}) {
        const std::string file =
            (d / (option.substr(2) + (option == "--csv" || option == "--pops" ? ".csv" : ".png")))
                .string();
        const test::CliRun r =
            test::runCli("render " + s + " -o " + image + " " + option + " " + file);
        EXPECT_EQ(r.status, 1) << option << ": " << r.err;
        EXPECT_EQ(test::lineCount(r.err), 1u) << r.err;
        EXPECT_TRUE(contains(r.err, file + ": cannot write: No space left on device")) << r.err;
        EXPECT_EQ(disk.leftovers(), std::vector<std::string>{}) << option;
    }
}

// A write that fails leaves the previous file as it was (the new one was never renamed over it).
TEST(WriteFailure, AFailedWriteKeepsThePreviousFile) {
    const fs::path d = scratch() / "ro";
    fs::create_directories(d);
    const fs::path file = d / "a.png";
    Image img(8, 4, 0);
    writeImage(file, img);
    const auto before = fs::file_size(file);
    // A read-only bind of the folder: the temporary cannot be created, as on a full disk.
    if (!run("mount --bind '" + d.string() + "' '" + d.string() + "'"))
        GTEST_SKIP() << "cannot bind-mount a folder here (needs root)";
    if (!run("mount -o remount,bind,ro '" + d.string() + "'")) {
        ::umount2(d.c_str(), MNT_DETACH);
        GTEST_SKIP() << "cannot remount a folder read-only here";
    }
    Image other(16, 16, 0);
    try {
        writeImage(file, other);
        ADD_FAILURE() << "the write into a read-only folder succeeded";
    } catch (const InputError& e) {
        EXPECT_EQ(std::string(e.what()), file.string() + ": cannot write: Read-only file system");
    }
    ::umount2(d.c_str(), MNT_DETACH);
    EXPECT_EQ(fs::file_size(file), before);
    EXPECT_EQ(readColorImage(file).width, 8);
}

// A symbolic link stays a link to the new file; a device node is written in place, not replaced.
TEST(WriteFailure, WholeFilesKeepSymlinksAndWriteDevicesInPlace) {
    const fs::path d = scratch() / "links";
    fs::create_directories(d);
    const fs::path real = d / "real.csv", link = d / "link.csv";
    writeFileWhole(real, std::string_view("old\n"));
    fs::create_symlink(real.filename(), link);
    writeFileWhole(link, std::string_view("new\n"));
    EXPECT_TRUE(fs::is_symlink(link));
    std::ifstream in(real);
    EXPECT_EQ(std::string(std::istreambuf_iterator<char>(in), {}), "new\n");
    // A private copy of /dev/null (mknod needs root), so that a wrong rename cannot hit /dev.
    const fs::path node = d / "null";
    if (::mknod(node.c_str(), S_IFCHR | 0666, makedev(1, 3)) != 0)
        GTEST_SKIP() << "mknod: " << std::strerror(errno);
    writeFileWhole(node, std::string_view("discarded"));
    EXPECT_TRUE(fs::is_character_file(node));
    for (const auto& e : fs::directory_iterator(d))
        EXPECT_FALSE(contains(e.path().filename().string(), std::string(kTempMarker))) << e.path();
}

// A path whose frame 2 cannot be written (its name is taken by a folder): the error names the
// frame, the frames before it are there, whole, and nothing after it.
TEST(WriteFailure, APathRenderFailingAtFrameKSaysWhichAndKeepsTheEarlierFrames) {
    const std::string s = scene();
    const fs::path d = scratch() / "seq";
    fs::create_directories(d / "r_0002.png");
    const test::CliRun r =
        test::runCli("render " + s + " --mode reference --frames 0:4 -o " + (d / "r.png").string());
    EXPECT_EQ(r.status, 1) << r.err;
    EXPECT_EQ(test::lineCount(r.err), 1u) << r.err;
    EXPECT_TRUE(contains(r.err, (d / "r_0002.png").string() + ": cannot write: Is a directory"))
        << r.err;
    EXPECT_TRUE(contains(r.err, "frame 2; the 2 frames before it are written")) << r.err;
    EXPECT_EQ(readColorImage(d / "r_0000.png").width, 96);
    EXPECT_EQ(readColorImage(d / "r_0001.png").width, 96);
    EXPECT_FALSE(fs::exists(d / "r_0003.png"));
    std::vector<std::string> names;
    for (const auto& e : fs::directory_iterator(d)) names.push_back(e.path().filename().string());
    std::sort(names.begin(), names.end());
    EXPECT_EQ(names, (std::vector<std::string>{"r_0000.png", "r_0001.png", "r_0002.png"}));
}

// An animated GIF reaches the disk only whole: a run that fails part-way (here its --ids file of
// frame 2) leaves no shorter GIF that looks complete.
TEST(WriteFailure, AGifRunFailingPartWayLeavesNoGif) {
    const std::string s = scene();
    const fs::path d = scratch() / "gif";
    fs::create_directories(d / "ids_0002.png");
    const test::CliRun r =
        test::runCli("render " + s + " --mode reference --path -o " + (d / "anim.gif").string() +
                     " --ids " + (d / "ids.png").string());
    EXPECT_EQ(r.status, 1) << r.err;
    EXPECT_EQ(test::lineCount(r.err), 1u) << r.err;
    EXPECT_TRUE(contains(r.err, "ids_0002.png: cannot write: Is a directory (frame 2; " +
                                    (d / "anim.gif").string() + " is not written)"))
        << r.err;
    EXPECT_FALSE(fs::exists(d / "anim.gif"));
    for (const auto& e : fs::directory_iterator(d))
        EXPECT_FALSE(contains(e.path().filename().string(), std::string(kTempMarker))) << e.path();
}

// bake into a full disk: exit 1, one line with the counts and the reason; --shard likewise.
TEST(WriteFailure, BakeOnAFullDiskFailsWithTheCountsAndTheReason) {
    const std::string s = scene();
    const fs::path d = scratch() / "full";
    FullDisk disk(d);
    REQUIRE_FULL_DISK(disk);
    for (const std::string shard : {"", " --shard 0/2"}) {
        const test::CliRun r =
            test::runCli("bake " + s + " --level 1 --cache-dir " + (d / "cache").string() + shard);
        EXPECT_EQ(r.status, 1) << shard << ": " << r.err;
        EXPECT_EQ(test::lineCount(r.err), 1u) << r.err;
        // 2 models x 26 views; a shard of 2 bakes one of the two models.
        const std::string count = shard.empty() ? "52 of 52" : "26 of 26";
        EXPECT_TRUE(contains(r.err, (d / "cache").string() + ": --cache-dir: " + count +
                                        " snapshots could not be written (No space left on "
                                        "device); 0 written"))
            << r.err;
        for (const std::string& f : disk.leftovers())
            EXPECT_FALSE(contains(f, ".pack") || contains(f, ".snap")) << f;
    }
}

// render --cache-dir on a full disk: the render succeeds with the right image and one warning
// line with the count and the reason; no snapshot file or temporary is left.
TEST(WriteFailure, RenderWithACacheDirOnAFullDiskWarnsOnceAndSucceeds) {
    const std::string s = scene();
    const fs::path d = scratch() / "full";
    FullDisk disk(d);
    REQUIRE_FULL_DISK(disk);
    const std::string plain = (scratch() / "plain.png").string();
    const std::string cached = (scratch() / "cached.png").string();
    ASSERT_EQ(test::runCli("render " + s + " --mode far -o " + plain).status, 0);
    const test::CliRun r = test::runCli("render " + s + " --mode far -o " + cached +
                                        " --cache-dir " + (d / "cache").string());
    EXPECT_EQ(r.status, 0) << r.err;
    EXPECT_EQ(test::lineCount(test::withoutFarWarning(r.err)), 1u) << r.err;
    EXPECT_TRUE(contains(r.err, "warning: cache dir " + (d / "cache").string() + ": ")) << r.err;
    EXPECT_TRUE(contains(r.err, " snapshots could not be written (No space left on device)"))
        << r.err;
    EXPECT_EQ(readColorImage(plain).color, readColorImage(cached).color);
    for (const std::string& f : disk.leftovers())
        EXPECT_FALSE(contains(f, ".pack") || contains(f, ".snap")) << f;
}

// Outputs that are one file (or the input) are refused before anything is rendered.
TEST(WriteFailure, CollidingOutputsAreRefusedWithOneLine) {
    const std::string s = scene();
    const std::string a = (scratch() / "a.png").string();
    const std::string x = (scratch() / "x.csv").string();
    const struct {
        std::string args, expect;
    } cases[] = {
        {"-o " + a + " --overlay " + a, "--overlay: " + a + " is also --out's file"},
        {"-o " + a + " --ids " + (scratch() / "." / "a.png").string(), "is also --out's file"},
        {"-o " + a + " --csv " + x + " --pops " + x, "--pops: " + x + " is also --csv's file"},
        {"-o " + a + " --csv " + s, "--csv: " + s + " is the input file"},
    };
    for (const auto& c : cases) {
        const test::CliRun r = test::runCli("render " + s + " " + c.args);
        EXPECT_EQ(r.status, 2) << c.args << ": " << r.err;
        EXPECT_EQ(test::lineCount(r.err), 1u) << r.err;
        EXPECT_TRUE(contains(r.err, c.expect)) << r.err;
        EXPECT_FALSE(fs::exists(a)) << c.args;
        EXPECT_FALSE(fs::exists(x)) << c.args;
    }
    EXPECT_EQ(sceneText(), [&] {
        std::ifstream in(s);
        return std::string(std::istreambuf_iterator<char>(in), {});
    }()) << "the scene was overwritten";
}

// A scene given to bake without --cache-dir: one line saying to add it (issue 27).
TEST(WriteFailure, BakeOfASceneWithoutACacheDirSaysToAddOne) {
    const test::CliRun r = test::runCli("bake " + scene());
    EXPECT_EQ(r.status, 1) << r.err;
    EXPECT_EQ(test::lineCount(r.err), 1u) << r.err;
    EXPECT_TRUE(contains(r.err, "add --cache-dir DIR")) << r.err;
}

std::vector<fs::path> filesWith(const fs::path& dir, const std::string& part) {
    std::vector<fs::path> out;
    for (const auto& e : fs::recursive_directory_iterator(dir))
        if (e.is_regular_file() && contains(e.path().filename().string(), part))
            out.push_back(e.path());
    return out;
}

/// The packs of a directory (not the temporaries they are written as).
std::vector<fs::path> packs(const fs::path& dir) {
    std::vector<fs::path> out;
    for (const fs::path& f : filesWith(dir, ".pack"))
        if (f.extension() == ".pack") out.push_back(f);
    return out;
}

void makeOld(const fs::path& p) {
    fs::last_write_time(p, fs::file_time_type::clock::now() - std::chrono::hours(2));
}

// A bake SIGKILLed part-way: a later render reads the directory and draws exactly the cold
// image; the temporaries of dead writers (an hour old, held by no one) are removed when the
// store is opened, while a fresh one and one a live process holds stay.
TEST(WriteFailure, AKilledBakeLeavesADirectoryALaterRenderReadsExactly) {
    const std::string s = scene();
    const fs::path cache = scratch() / "cache";
    const std::string cold = (scratch() / "cold.png").string();
    ASSERT_EQ(test::runCli("render " + s + " --mode far -o " + cold).status, 0);

    const pid_t child = fork();
    ASSERT_GE(child, 0);
    if (child == 0) {
        // Level 16 (6,146 views per model, a pack per model): long enough to be killed while it
        // bakes the second model.
        const std::string cli = VOXTIER_CLI;
        ::execl(cli.c_str(), cli.c_str(), "bake", s.c_str(), "--level", "16", "--cache-dir",
                cache.c_str(), "--threads", "1", static_cast<char*>(nullptr));
        ::_exit(127);
    }
    // Killed once the first model's pack is written (or after a minute: then it is killed
    // anyway), while it bakes the second.
    for (int k = 0; k < 6000; ++k) {
        std::error_code ec;
        if (fs::exists(cache, ec) && !packs(cache).empty()) break;
        std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    ASSERT_EQ(::kill(child, SIGKILL), 0);
    int status = 0;
    ASSERT_EQ(::waitpid(child, &status, 0), child);
    ASSERT_TRUE(WIFSIGNALED(status)) << "the bake ended before it was killed";

    // What a dead writer leaves, whether or not the kill hit a write: temporaries an hour old.
    const fs::path sub = packs(cache).front().parent_path();
    test::writeText(sub, "0123.pack.tmp999999-0", "half a pack");
    test::writeText(sub, "cdef.snap.tmp999999-0", "half a snapshot (the former layout)");
    for (const fs::path& t : filesWith(cache, ".tmp")) makeOld(t);
    const std::size_t dead = filesWith(cache, ".tmp").size();
    // A live writer's: fresh, or old but locked.
    const std::string fresh = test::writeText(sub, "4567.pack.tmp999998-0", "being written");
    const std::string held = test::writeText(sub, "89ab.pack.tmp999997-0", "being written");
    makeOld(held);
    const int fd = ::open(held.c_str(), O_RDONLY);
    ASSERT_EQ(::flock(fd, LOCK_EX), 0);

    const std::string warm = (scratch() / "warm.png").string();
    const test::CliRun r =
        test::runCli("render " + s + " --mode far -o " + warm + " --cache-dir " + cache.string());
    ::close(fd);
    ASSERT_EQ(r.status, 0) << r.err;
    // It read what the killed bake wrote (the rest it baked).
    const std::size_t at = r.out.find(" snapshots read");
    ASSERT_NE(at, std::string::npos) << r.out;
    const std::size_t from = r.out.rfind(' ', at - 1) + 1;
    EXPECT_GT(std::stoul(r.out.substr(from, at - from)), 0u) << r.out;
    EXPECT_EQ(readColorImage(cold).color, readColorImage(warm).color);
    EXPECT_GE(dead, 2u);
    std::vector<fs::path> left = filesWith(cache, ".tmp");
    std::sort(left.begin(), left.end());
    EXPECT_EQ(left, (std::vector<fs::path>{fresh, held})) << "only the live writers' stay";
}

// The store's rule directly, as the size limit's sweep applies it too.
TEST(WriteFailure, StaleTemporariesAreRemovedOnlyWhenOldAndUnheld) {
    const fs::path dir = scratch() / "store";
    fs::create_directories(dir / "ab");
    const std::string old = test::writeText(dir / "ab", "x.pack.tmp1-0", "x");
    const std::string young = test::writeText(dir / "ab", "y.pack.tmp1-1", "y");
    const std::string notTemp = test::writeText(dir / "ab", "z.pack", "z");
    makeOld(old);
    makeOld(notTemp);
    SnapshotStore store({.dir = dir});
    EXPECT_FALSE(fs::exists(old));
    EXPECT_TRUE(fs::exists(young));
    EXPECT_TRUE(fs::exists(notTemp)); // a snapshot is the size limit's business, not this rule's
    EXPECT_EQ(store.counters().staleTempsRemoved, 1u);
    makeOld(young);
    EXPECT_EQ(store.removeStaleTemporaries(), 1u);
    EXPECT_FALSE(fs::exists(young));
}

} // namespace
} // namespace voxtier
