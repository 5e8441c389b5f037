// A render does not depend on which process baked its snapshots (issue 28). Root cause of the
// once-seen difference between concurrent renders sharing one --cache-dir: the error-budget
// planner preferred any view it could have without a bake, and it counted a file in the
// directory as such; a directory holding a finer level's view but not the coarsest one (other
// processes' views, a size limit's evictions) made it pick that finer view where a cold render
// bakes the coarsest: a different view, a few different pixels. Files now spare bakes but are
// never preferred. Two tests: a partial directory built on purpose (deterministic: it failed on
// every run before the fix), and processes rendering and baking into one size-limited directory
// at once and staggered, round after round, each image compared with a lone render.
#include "cli_support.hpp"
#include "image_files/image_files.hpp"
#include "impostor_cache/snapshot_store.hpp"

#include <gtest/gtest.h>
#include <sys/mount.h>
#include <sys/wait.h>

#include <cstdlib>
#include <fcntl.h>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <set>
#include <spawn.h>
#include <string>
#include <thread>
#include <vector>

extern char** environ;

namespace voxtier {
namespace {

namespace fs = std::filesystem;

const std::string kScene = std::string(VOXTIER_SOURCE_DIR) + "/scenes/default.json";
const std::vector<int> kFrames = {0, 5, 10, 15, 20};
// --no-cost-bound: the cost bound on bakes learns from measured times, so a lone render beside
// four busy processes drew 3 bakes near that a quiet one drew far, with no cache directory at
// all (10 of 12 such rounds); the images compared here must depend on the directory only.
const std::vector<std::string> kRender = {"render",         kScene,      "--frames",       "0:20:5",
                                          "--near-backend", "reference", "--no-cost-bound"};

/// The test's directory: a tmpfs of its own where it can be mounted (CI runs as root), since
/// rounds of thousands of small file writes cost 3.5 times as much on the CI machine's ext4
/// (8.6 s a round against 2.4 s); rename, flock and the size limit work alike on both.
class WorkDir {
  public:
    WorkDir() : dir_(test::scratchDir("voxtier_shared_cache", true)) {
        mounted_ = ::mount("tmpfs", dir_.c_str(), "tmpfs", 0, "size=512m") == 0;
    }
    ~WorkDir() {
        if (mounted_) ::umount2(dir_.c_str(), MNT_DETACH);
    }
    const fs::path& path() const { return dir_; }

  private:
    fs::path dir_;
    bool mounted_ = false;
};

std::string frameFile(const fs::path& dir, int frame) {
    char name[32];
    std::snprintf(name, sizeof name, "f_%04d.png", frame);
    return (dir / name).string();
}

/// Starts `voxtier args...` with its output discarded; returns the pid.
pid_t start(std::vector<std::string> args) {
    args.insert(args.begin(), VOXTIER_CLI);
    std::vector<char*> argv;
    for (std::string& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    posix_spawn_file_actions_t io;
    posix_spawn_file_actions_init(&io);
    posix_spawn_file_actions_addopen(&io, 1, "/dev/null", O_WRONLY, 0);
    posix_spawn_file_actions_addopen(&io, 2, "/dev/null", O_WRONLY, 0);
    pid_t pid = -1;
    const int err = posix_spawn(&pid, VOXTIER_CLI, &io, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&io);
    EXPECT_EQ(err, 0);
    return pid;
}

int finish(pid_t pid) {
    int status = 0;
    if (pid <= 0 || waitpid(pid, &status, 0) != pid) return -1;
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

std::vector<std::string> renderArgs(const fs::path& out, const std::string& cacheDir = "",
                                    const char* limitMb = nullptr) {
    std::vector<std::string> a = kRender;
    a.insert(a.end(), {"-o", (out / "f.png").string()});
    if (!cacheDir.empty()) a.insert(a.end(), {"--cache-dir", cacheDir});
    if (limitMb) a.insert(a.end(), {"--cache-dir-mb", limitMb});
    return a;
}

/// The lone, cold render's frames (no cache directory).
const std::vector<Image>& loneFrames() {
    static const std::vector<Image> frames = [] {
        const fs::path d = test::scratchDir("voxtier_shared_cache_lone");
        EXPECT_EQ(finish(start(renderArgs(d))), 0);
        std::vector<Image> f;
        for (int k : kFrames) f.push_back(readColorImage(frameFile(d, k)));
        return f;
    }();
    return frames;
}

/// "" when every frame in `dir` equals the lone render's, else which differ and by how much.
std::string differences(const fs::path& dir) {
    std::string out;
    for (std::size_t i = 0; i < kFrames.size(); ++i) {
        const Image got = readColorImage(frameFile(dir, kFrames[i]));
        const Image& want = loneFrames()[i];
        if (got.width != want.width || got.height != want.height) {
            out += " frame " + std::to_string(kFrames[i]) + ": size";
            continue;
        }
        std::size_t n = 0;
        for (std::size_t p = 0; p < got.pixelCount(); ++p) n += got.color[p] != want.color[p];
        if (n) out += " frame " + std::to_string(kFrames[i]) + ": " + std::to_string(n) + " px";
    }
    return out;
}

std::vector<std::uint8_t> readBytes(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), {}};
}
std::string viewName(ViewId v) {
    return std::to_string(v.lattice.x) + "," + std::to_string(v.lattice.y) + "," +
           std::to_string(v.lattice.z);
}

/// Every snapshot of a directory: "<pack>:<view>".
std::set<std::string> snapshotNames(const fs::path& dir) {
    std::set<std::string> names;
    for (const auto& e : fs::recursive_directory_iterator(dir))
        if (e.path().extension() == ".pack")
            for (const SnapshotPackEntry& s : decodeSnapshotPack(readBytes(e.path())).entries)
                names.insert(e.path().lexically_relative(dir).string() + ":" + viewName(s.view));
    return names;
}

/// Rewrites the packs of `dir` without the snapshots named in `drop` (snapshotNames').
void removeSnapshots(const fs::path& dir, const std::set<std::string>& drop) {
    for (const auto& e : fs::recursive_directory_iterator(dir)) {
        if (e.path().extension() != ".pack") continue;
        DecodedSnapshotPack pack = decodeSnapshotPack(readBytes(e.path()));
        std::vector<SnapshotPackEntry> kept;
        for (SnapshotPackEntry& s : pack.entries)
            if (!drop.count(e.path().lexically_relative(dir).string() + ":" + viewName(s.view)))
                kept.push_back(std::move(s));
        const std::vector<std::uint8_t> bytes = encodeSnapshotPack(pack.frame, std::move(kept));
        std::ofstream(e.path(), std::ios::binary | std::ios::trunc)
            .write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
    }
}

// The finer ladder level's views on disk, the coarsest level's not: what a shared directory
// holds after others rendered other frames or a size limit removed files. Before the fix this
// drew 132 to 968 pixels differently at every frame, on every run.
TEST(SharedCache, ADirectoryWithoutTheCoarsestViewsGivesTheLoneImage) {
    const WorkDir work;
    const fs::path& d = work.path();
    ASSERT_EQ(finish(start({"bake", kScene, "--level", "1", "--cache-dir", (d / "l1").string()})),
              0);
    ASSERT_EQ(finish(start({"bake", kScene, "--level", "2", "--cache-dir", (d / "l2").string()})),
              0);
    const std::set<std::string> coarse = snapshotNames(d / "l1");
    ASSERT_FALSE(coarse.empty());
    removeSnapshots(d / "l2", coarse);
    // Decoded once: each decode digests every pack, and under ASan one per name took minutes.
    const std::set<std::string> left = snapshotNames(d / "l2");
    ASSERT_GT(left.size(), 0u);
    for (const std::string& name : coarse) ASSERT_EQ(left.count(name), 0u);
    ASSERT_EQ(finish(start(renderArgs(d / "out", (d / "l2").string()))), 0);
    EXPECT_EQ(differences(d / "out"), "");
}

// Rounds of: two renders at once into a fresh directory of 1 MiB, a bake of the finer views
// into it, two more renders started while those run. Every image must equal the lone render.
// With the planner fix reverted 8 of 8 rounds had a differing image, one by exactly the issue's
// 1 pixel at three frames (docs/baking.md), so 4 rounds by default still catch it;
// VOXTIER_STRESS_ROUNDS=N runs N rounds.
TEST(SharedCache, ConcurrentRendersAndBakesIntoOneLimitedDirectoryDrawTheLoneImage) {
    const char* env = std::getenv("VOXTIER_STRESS_ROUNDS");
    const int rounds = env ? std::atoi(env) : 4;
    ASSERT_FALSE(loneFrames().empty());
    const WorkDir work;
    std::string failures;
    for (int r = 0; r < rounds; ++r) {
        const fs::path d = work.path() / ("round" + std::to_string(r));
        fs::remove_all(d);
        const std::string cache = (d / "cache").string();
        std::vector<pid_t> renders;
        renders.push_back(start(renderArgs(d / "p0", cache, "1")));
        renders.push_back(start(renderArgs(d / "p1", cache, "1")));
        const pid_t bake = start({"bake", kScene, "--level", "2", "--cache-dir", cache,
                                  "--cache-dir-mb", "1", "--threads", "1"});
        // Staggered: the later two start once the first files are there (or the first two are
        // done), so they read what the others wrote and evicted.
        for (int k = 0; k < 2000 && !fs::exists(cache); ++k)
            std::this_thread::sleep_for(std::chrono::milliseconds(1));
        renders.push_back(start(renderArgs(d / "p2", cache, "1")));
        renders.push_back(start(renderArgs(d / "p3", cache, "1")));
        for (std::size_t p = 0; p < renders.size(); ++p) {
            ASSERT_EQ(finish(renders[p]), 0) << "round " << r << " render " << p;
            const std::string diff = differences(d / ("p" + std::to_string(p)));
            if (!diff.empty())
                failures += "round " + std::to_string(r) + " render " + std::to_string(p) + ":" +
                            diff + "\n";
        }
        EXPECT_EQ(finish(bake), 0) << "round " << r;
        fs::remove_all(d);
    }
    EXPECT_EQ(failures, "");
}

} // namespace
} // namespace voxtier
