// The on-disk snapshot cache against hostile files and stuck writers (issue 37): whatever is in
// the directory, `voxtier render --cache-dir` exits 0 within its time limit, draws the image a
// render without the directory draws (`--no-cost-bound`), with a max RSS within 1.5x of that
// render's, and leaves no lock held and no temporary behind; a pack that is not a regular file,
// or not this model frame's, is one warning line and is replaced. Each case runs the command-line
// tool as a child with a time limit (killed past it: a failure, never a hung CI).
//
// The random rounds (CacheFaults.RandomRounds) mix the cases on random packs, with injected
// allocation failures and a stopped lock holder; VOXTIER_FAULT_ROUNDS=N runs N rounds (CI: 4).
#include "cli_support.hpp"
#include "image_files/image_files.hpp"
#include "impostor_cache/snapshot_store.hpp"

#include <gtest/gtest.h>
#include <sys/file.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>

#include <algorithm>
#include <chrono>
#include <csignal>
#include <cstdlib>
#include <fcntl.h>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <optional>
#include <random>
#include <spawn.h>
#include <string>
#include <thread>
#include <unistd.h>
#include <vector>

extern char** environ;

namespace voxtier {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

/// A child's time limit: far beyond a render of the scene below (well under a second, a few
/// under the sanitizers), so only a hang reaches it.
constexpr auto kTimeLimit = std::chrono::seconds(120);

fs::path scratch() {
    return test::scratchDir("voxtier_cache_fault", true);
}

/// Four model frames (four packs), eight far entities and a near one: small enough for a render
/// in a fraction of a second, every far sprite through the snapshot cache.
std::string sceneText() {
    const char* models[] = {"crate", "ball", "arrow", "shell"};
    std::string entities;
    for (int k = 0; k < 8; ++k)
        entities += R"({"model": ")" + std::string(models[k % 4]) + R"(", "position": [)" +
                    std::to_string(-7 + 2 * k) + ", 0, " + std::to_string(-24 - 6 * k) +
                    R"(], "rotation_deg": [0, )" + std::to_string(23 * k) + ", 0]},";
    return R"({"camera": {"position": [0, 2, 6], "target": [0, 1, -40], "size": [96, 64]},
        "selector": {"metric": "error_budget", "budget_vpx": 1},
        "models": [{"name": "crate", "generator": "box", "size": [10, 10, 10], "index": 7},
                   {"name": "ball", "generator": "sphere", "radius": 8, "index": 6},
                   {"name": "arrow", "generator": "arrow", "length": 16},
                   {"name": "shell", "generator": "shell", "size": [12, 12, 12]}],
        "entities": [)" +
           entities + R"({"model": "crate", "position": [0, 0, 0]}]})";
}

const std::string& scene() {
    static const std::string path =
        test::writeText(test::scratchDir("voxtier_cache_fault_scene"), "s.json", sceneText());
    return path;
}

struct ChildRun {
    int status = -1;       ///< exit status; -1 when killed by a signal
    bool timedOut = false; ///< killed at the time limit
    long maxRssKb = 0;     ///< ru_maxrss of the child
    double ms = 0.0;       ///< wall time
    std::string out, err;
};

std::string slurp(const fs::path& p) {
    std::ifstream in(p);
    return {std::istreambuf_iterator<char>(in), {}};
}

/// Starts `voxtier args...` with `env` added to the environment, stdout and stderr to files
/// ("" for /dev/null), in a process group of its own when `group`. Returns the pid.
pid_t spawnCli(std::vector<std::string> args, const std::vector<std::string>& env,
               const std::string& outFile, const std::string& errFile, bool group) {
    args.insert(args.begin(), VOXTIER_CLI);
    std::vector<char*> argv;
    for (std::string& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    std::vector<std::string> envStrings(env);
    for (char** e = environ; *e; ++e) envStrings.emplace_back(*e);
    std::vector<char*> envp;
    for (std::string& e : envStrings) envp.push_back(e.data());
    envp.push_back(nullptr);
    posix_spawn_file_actions_t io;
    posix_spawn_file_actions_init(&io);
    const auto to = [](const std::string& f) { return f.empty() ? "/dev/null" : f.c_str(); };
    posix_spawn_file_actions_addopen(&io, 1, to(outFile), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_addopen(&io, 2, to(errFile), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawnattr_t attr;
    posix_spawnattr_init(&attr);
    if (group) {
        posix_spawnattr_setflags(&attr, POSIX_SPAWN_SETPGROUP);
        posix_spawnattr_setpgroup(&attr, 0);
    }
    pid_t pid = -1;
    const int spawned = posix_spawn(&pid, VOXTIER_CLI, &io, &attr, argv.data(), envp.data());
    posix_spawn_file_actions_destroy(&io);
    posix_spawnattr_destroy(&attr);
    EXPECT_EQ(spawned, 0);
    return spawned == 0 ? pid : -1;
}

/// Runs `voxtier args...` (with `env` added to the environment) in a process group of its own;
/// past kTimeLimit the group is killed and the run says so.
ChildRun runCli(const std::vector<std::string>& args, const fs::path& errFile,
                const std::vector<std::string>& env = {}) {
    const std::string outFile = errFile.string() + ".out";
    ChildRun r;
    const auto t0 = Clock::now();
    const pid_t pid = spawnCli(args, env, outFile, errFile.string(), true);
    if (pid < 0) return r;
    int status = 0;
    rusage ru{};
    for (auto pause = std::chrono::milliseconds(1);;) {
        const pid_t got = ::wait4(pid, &status, WNOHANG, &ru);
        if (got == pid) break;
        if (Clock::now() - t0 > kTimeLimit) {
            r.timedOut = true;
            ::kill(-pid, SIGKILL);
            ::wait4(pid, &status, 0, &ru);
            break;
        }
        std::this_thread::sleep_for(pause);
        pause = std::min(pause * 2, std::chrono::milliseconds(20));
    }
    r.ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
    r.status = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    r.maxRssKb = ru.ru_maxrss;
    r.err = slurp(errFile);
    r.out = slurp(outFile);
    return r;
}

std::vector<std::string> renderArgs(const fs::path& png, const fs::path& cacheDir = {}) {
    std::vector<std::string> a = {"render",        scene(), "--near-backend",  "reference",
                                  "--far-backend", "cpu",   "--no-cost-bound", "-o",
                                  png.string()};
    if (!cacheDir.empty()) a.insert(a.end(), {"--cache-dir", cacheDir.string()});
    return a;
}

/// The render without a directory: its image and max RSS.
struct Lone {
    Image image;
    long maxRssKb = 0;
};
const Lone& lone() {
    static const Lone l = [] {
        const fs::path d = test::scratchDir("voxtier_cache_fault_lone");
        Lone out;
        const ChildRun r = runCli(renderArgs(d / "lone.png"), d / "err.txt");
        EXPECT_EQ(r.status, 0) << r.err;
        out.maxRssKb = r.maxRssKb;
        out.image = readColorImage(d / "lone.png");
        return out;
    }();
    return l;
}

/// A directory a render filled (every pack the render needs), copied per case.
const fs::path& baked() {
    static const fs::path dir = [] {
        const fs::path d = test::scratchDir("voxtier_cache_fault_baked");
        const ChildRun r = runCli(renderArgs(d / "baked.png", d / "cache"), d / "err.txt");
        EXPECT_EQ(r.status, 0) << r.err;
        return d / "cache";
    }();
    return dir;
}

std::vector<fs::path> packsOf(const fs::path& dir) {
    std::vector<fs::path> packs;
    for (const auto& e : fs::recursive_directory_iterator(dir))
        if (e.path().extension() == ".pack") packs.push_back(e.path());
    std::sort(packs.begin(), packs.end());
    return packs;
}

fs::path freshCopy(const fs::path& to) {
    fs::remove_all(to);
    fs::copy(baked(), to, fs::copy_options::recursive);
    return to;
}

/// What every case must show: a timely exit 0, the lone image, bounded RSS, no lock held and no
/// temporary left. Returns "" or what failed.
std::string checkRun(const ChildRun& r, const fs::path& png, const fs::path& dir) {
    std::string bad;
    if (r.timedOut) bad += " still running after its time limit (killed);";
    if (r.status != 0) bad += " exit " + std::to_string(r.status) + ";";
    if (r.status == 0 && !r.timedOut) {
        const Image got = readColorImage(png);
        if (got.color != lone().image.color) bad += " image differs from the render without;";
    }
    if (double(r.maxRssKb) > 1.5 * double(lone().maxRssKb))
        bad += " max RSS " + std::to_string(r.maxRssKb) + " KB over 1.5x " +
               std::to_string(lone().maxRssKb) + " KB;";
    std::error_code ec;
    for (auto it = fs::recursive_directory_iterator(dir, ec);
         !ec && it != fs::recursive_directory_iterator(); it.increment(ec)) {
        if (it.depth() >= 1) it.disable_recursion_pending();
        const std::string name = it->path().filename().string();
        if (name.find(".tmp") != std::string::npos) bad += " temporary left: " + name + ";";
        if (name != ".lock" || it->is_symlink() || !it->is_regular_file()) continue;
        const int fd = ::open(it->path().c_str(), O_RDONLY | O_CLOEXEC);
        if (fd >= 0 && ::flock(fd, LOCK_EX | LOCK_NB) != 0)
            bad += " " + it->path().string() + " still locked;";
        if (fd >= 0) ::close(fd);
    }
    return bad.empty() ? "" : bad + (r.err.empty() ? "" : " stderr: " + r.err);
}

std::size_t warnings(const std::string& err) {
    std::size_t n = 0;
    for (std::size_t at = err.find("warning: "); at != std::string::npos;
         at = err.find("warning: ", at + 1))
        ++n;
    return n;
}

// ---- each kind of hostile file, on one pack ---------------------------------------------------

struct Hostile {
    const char* name;
    const char* says; ///< what its warning line says
    void (*apply)(const fs::path& pack, const fs::path& other, const fs::path& outside);
};

void sparse(const fs::path& f, std::uintmax_t bytes) {
    std::ofstream(f, std::ios::app).flush();
    fs::resize_file(f, bytes);
}
void makeFifo(const fs::path& f) {
    ASSERT_EQ(::mkfifo(f.c_str(), 0644), 0) << f;
}

const Hostile kHostile[] = {
    {"SparseTebibyte", "wrong size (1099511627776 bytes",
     [](const fs::path& p, const fs::path&, const fs::path&) {
         sparse(p, std::uintmax_t(1) << 40);
     }},
    {"SymlinkToSparseTebibyte", "not a regular file (a symbolic link)",
     [](const fs::path& p, const fs::path&, const fs::path& outside) {
         sparse(outside / "huge", std::uintmax_t(1) << 40);
         fs::remove(p);
         fs::create_symlink(outside / "huge", p);
     }},
    {"SparseTwoGibibytesWithItsOwnHeader", "wrong size (2147483648 bytes",
     [](const fs::path& p, const fs::path&, const fs::path&) {
         sparse(p, std::uintmax_t(2) << 30);
     }},
    {"Fifo", "not a regular file (a FIFO)",
     [](const fs::path& p, const fs::path&, const fs::path&) {
         fs::remove(p);
         makeFifo(p);
     }},
    {"Directory", "not a regular file (a directory)",
     [](const fs::path& p, const fs::path&, const fs::path&) {
         fs::remove(p);
         fs::create_directories(p / "inside");
         std::ofstream(p / "inside" / "file") << "x";
     }},
    {"SymlinkLoop", "not a regular file (a symbolic link)",
     [](const fs::path& p, const fs::path&, const fs::path&) {
         fs::remove(p);
         fs::create_symlink(p.filename(), p);
     }},
    {"AnotherModelsPack", "written for another key",
     [](const fs::path& p, const fs::path& other, const fs::path&) {
         fs::copy_file(other, p, fs::copy_options::overwrite_existing);
     }},
    {"EveryViewDamaged", "checksum mismatch",
     [](const fs::path& p, const fs::path&, const fs::path&) {
         // The last byte before each view's checksum: every view bad, one line for the pack.
         const DecodedSnapshotPack pack = [&] {
             std::ifstream in(p, std::ios::binary);
             const std::vector<std::uint8_t> b{std::istreambuf_iterator<char>(in), {}};
             return decodeSnapshotPack(b);
         }();
         std::vector<SnapshotPackEntry> entries = pack.entries;
         for (SnapshotPackEntry& e : entries) e.file[e.file.size() - 17] ^= 0x5a;
         const std::vector<std::uint8_t> bytes = encodeSnapshotPack(pack.frame, entries);
         std::ofstream(p, std::ios::binary | std::ios::trunc)
             .write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
     }},
};

void PrintTo(const Hostile& h, std::ostream* os) {
    *os << h.name;
}

class HostileFile : public ::testing::TestWithParam<Hostile> {};

TEST_P(HostileFile, IsOneWarningThenReplacedAndTheRenderIsUnchanged) {
    const Hostile& h = GetParam();
    const fs::path d = scratch();
    const fs::path dir = freshCopy(d / "cache");
    const std::vector<fs::path> packs = packsOf(dir);
    ASSERT_GE(packs.size(), 4u);
    fs::create_directories(d / "outside");
    h.apply(packs[0], packs[1], d / "outside");

    const ChildRun r = runCli(renderArgs(d / "a.png", dir), d / "err.txt");
    EXPECT_EQ(checkRun(r, d / "a.png", dir), "");
    EXPECT_EQ(warnings(test::withoutFarWarning(r.err)), 1u) << r.err;
    EXPECT_NE(r.err.find(packs[0].string() + ": "), std::string::npos) << r.err;
    EXPECT_NE(r.err.find(h.says), std::string::npos) << r.err;
    // Replaced: a regular pack again (a link replaced, never what it points to), read by the
    // next render without a word.
    struct stat st {};
    ASSERT_EQ(::lstat(packs[0].c_str(), &st), 0);
    EXPECT_TRUE(S_ISREG(st.st_mode));
    if (fs::exists(d / "outside" / "huge")) {
        EXPECT_EQ(fs::file_size(d / "outside" / "huge"), std::uintmax_t(1) << 40);
    }
    const ChildRun again = runCli(renderArgs(d / "b.png", dir), d / "err2.txt");
    EXPECT_EQ(checkRun(again, d / "b.png", dir), "");
    EXPECT_EQ(warnings(test::withoutFarWarning(again.err)), 0u) << again.err;
}

INSTANTIATE_TEST_SUITE_P(Cases, HostileFile, ::testing::ValuesIn(kHostile),
                         [](const auto& info) { return std::string(info.param.name); });

// ---- an exception inside a write --------------------------------------------------------------

// An allocation failure injected at each step of a pack write: the render still exits 0 with
// the same image, says once that snapshots were not written and why, leaves no temporary and
// no lock (the exit itself would not come if its own lock were left held: the store's final
// flush used to wait on it for ever).
TEST(CacheFaults, AnAllocationFailureInsideAWriteLeavesNoLockAndNoFile) {
    const fs::path d = scratch();
    for (const char* step : {"folder", "locked", "read", "write", "rename"}) {
        const fs::path dir = d / step;
        const ChildRun r = runCli(renderArgs(d / "a.png", dir), d / "err.txt",
                                  {std::string("VOXTIER_STORE_FAULT=alloc@") + step});
        EXPECT_EQ(checkRun(r, d / "a.png", dir), "") << step;
        EXPECT_EQ(warnings(test::withoutFarWarning(r.err)), 1u) << step << ": " << r.err;
        EXPECT_NE(r.err.find("could not be written (Cannot allocate memory)"), std::string::npos)
            << step << ": " << r.err;
        EXPECT_TRUE(packsOf(dir).empty()) << step;
    }
}

// ---- a stopped writer -------------------------------------------------------------------------

/// A child process that is killed and reaped when this goes out of scope, whatever happened.
struct Reaped {
    pid_t pid = -1;
    ~Reaped() {
        if (pid <= 0) return;
        ::kill(pid, SIGKILL);
        ::kill(pid, SIGCONT);
        ::waitpid(pid, nullptr, 0);
    }
};

/// The subdirectories of `dir` whose .lock another process holds.
std::vector<fs::path> heldFolders(const fs::path& dir) {
    std::vector<fs::path> held;
    std::error_code ec;
    for (const auto& e : fs::directory_iterator(dir, ec)) {
        const int fd = ::open((e.path() / ".lock").c_str(), O_RDONLY | O_CLOEXEC);
        if (fd < 0) continue;
        if (::flock(fd, LOCK_EX | LOCK_NB) != 0) held.push_back(e.path());
        ::close(fd);
    }
    return held;
}

// A bake stopped (SIGSTOP) while it holds a subdirectory's lock, as a suspended laptop or a hung
// NFS client would: a render writing into that subdirectory gives its packs there up after its
// lock wait (2 s) with one warning line naming the folder, and draws the same image; the bake,
// continued, finishes its work.
TEST(CacheFaults, AStoppedWriterCostsARenderAtMostTheLockWait) {
    const fs::path d = scratch();
    const fs::path dir = d / "cache";
    Reaped bake;
    bake.pid =
        spawnCli({"bake", scene(), "--level", "1", "--cache-dir", dir.string()},
                 {"VOXTIER_STORE_FAULT=stop@locked"}, "", (d / "bake_err.txt").string(), false);
    ASSERT_GT(bake.pid, 0);
    // Until it stops (holding the lock of its first pack's folder), within the time limit.
    int status = 0;
    const auto t0 = Clock::now();
    while (::waitpid(bake.pid, &status, WUNTRACED | WNOHANG) == 0 && Clock::now() - t0 < kTimeLimit)
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
    ASSERT_TRUE(WIFSTOPPED(status)) << "the bake did not stop at its first pack";
    const std::vector<fs::path> held = heldFolders(dir);
    ASSERT_EQ(held.size(), 1u);

    const ChildRun r = runCli(renderArgs(d / "a.png", dir), d / "err.txt");
    EXPECT_EQ(r.status, 0) << r.err;
    EXPECT_FALSE(r.timedOut);
    EXPECT_EQ(readColorImage(d / "a.png").color, lone().image.color);
    EXPECT_LE(double(r.maxRssKb), 1.5 * double(lone().maxRssKb));
    EXPECT_EQ(warnings(test::withoutFarWarning(r.err)), 1u) << r.err;
    EXPECT_NE(r.err.find("(" + held[0].string() + ": locked by another process for over 2.0 s)"),
              std::string::npos)
        << r.err;
    std::printf("render beside a stopped writer: %.0f ms (lock wait 2000 ms)\n", r.ms);
    EXPECT_NE(r.out.find(" ms waiting for other processes' locks"), std::string::npos) << r.out;

    ASSERT_EQ(::kill(bake.pid, SIGCONT), 0);
    while (::waitpid(bake.pid, &status, WNOHANG) == 0 && Clock::now() - t0 < kTimeLimit)
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
    ASSERT_TRUE(WIFEXITED(status)) << "the bake did not finish once continued";
    EXPECT_EQ(WEXITSTATUS(status), 0);
    bake.pid = -1;
    EXPECT_TRUE(heldFolders(dir).empty());
}

// ---- random rounds ----------------------------------------------------------------------------

/// Holds a subdirectory's lock from a stopped child process (what a stopped writer leaves).
struct StoppedHolder {
    Reaped child;
    explicit StoppedHolder(const fs::path& folder) {
        child.pid = ::fork();
        if (child.pid == 0) {
            const int fd = ::open((folder / ".lock").c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
            if (fd < 0 || ::flock(fd, LOCK_EX) != 0) ::_exit(1);
            ::raise(SIGSTOP);
            ::_exit(0);
        }
        int status = 0;
        ::waitpid(child.pid, &status, WUNTRACED);
    }
};

TEST(CacheFaults, RandomRounds) {
    const char* env = std::getenv("VOXTIER_FAULT_ROUNDS");
    const int rounds = env ? std::atoi(env) : 4;
    const char* seedEnv = std::getenv("VOXTIER_FAULT_SEED");
    const unsigned seed = seedEnv ? unsigned(std::atoi(seedEnv)) : 37u;
    std::mt19937 rng(seed);
    const fs::path d = scratch();
    const char* steps[] = {"folder", "locked", "read", "write", "rename"};
    std::string failures;
    int stopped = 0, injected = 0;
    std::map<std::string, int> kinds;
    double worstRss = 0.0, worstMs = 0.0;
    for (int round = 0; round < rounds; ++round) {
        const fs::path dir = freshCopy(d / "cache");
        fs::remove_all(d / "outside");
        fs::create_directories(d / "outside");
        std::vector<fs::path> packs = packsOf(dir);
        std::shuffle(packs.begin(), packs.end(), rng);
        // 1 to 3 packs damaged, each by a random kind (a truncation or a flipped byte too).
        const int damaged = 1 + int(rng() % 3);
        std::string what;
        for (int k = 0; k < damaged; ++k) {
            const std::size_t kind = rng() % (std::size(kHostile) + 2);
            const fs::path& p = packs[std::size_t(k)];
            if (kind < std::size(kHostile)) {
                kHostile[kind].apply(p, packs.back(), d / "outside");
                what += std::string(" ") + kHostile[kind].name;
                ++kinds[kHostile[kind].name];
            } else if (kind == std::size(kHostile)) {
                fs::resize_file(p, rng() % fs::file_size(p));
                what += " Truncated";
                ++kinds["Truncated"];
            } else {
                std::fstream f(p, std::ios::in | std::ios::out | std::ios::binary);
                const auto at = std::streamoff(rng() % fs::file_size(p));
                f.seekg(at);
                const char c = char(f.get() ^ (1 + rng() % 255));
                f.seekp(at);
                f.put(c);
                what += " FlippedByte";
                ++kinds["FlippedByte"];
            }
        }
        std::vector<std::string> faultEnv;
        if (rng() % 3 == 0) {
            faultEnv.push_back(std::string("VOXTIER_STORE_FAULT=alloc@") + steps[rng() % 5]);
            what += " " + faultEnv.back();
            ++injected;
        }
        std::optional<StoppedHolder> holder;
        if (rng() % 4 == 0) {
            holder.emplace(packs[0].parent_path());
            what += " StoppedHolder";
            ++stopped;
        }
        const ChildRun r = runCli(renderArgs(d / "a.png", dir), d / "err.txt", faultEnv);
        holder.reset();
        const std::string bad = checkRun(r, d / "a.png", dir);
        worstRss = std::max(worstRss, double(r.maxRssKb) / double(lone().maxRssKb));
        worstMs = std::max(worstMs, r.ms);
        if (!bad.empty()) failures += "round " + std::to_string(round) + what + ":" + bad + "\n";
    }
    std::string counts;
    for (const auto& [kind, n] : kinds) counts += " " + kind + " " + std::to_string(n);
    std::printf("%d rounds (seed %u): damaged packs:%s; %d allocation failures injected, %d "
                "stopped lock holders; worst max RSS %.2fx the render without (%ld KB), slowest "
                "render %.0f ms\n",
                rounds, seed, counts.c_str(), injected, stopped, worstRss, lone().maxRssKb,
                worstMs);
    EXPECT_EQ(failures, "");
}

} // namespace
} // namespace voxtier
