#pragma once
// Running the built `voxtier` binary from a test: exit status, stdout and stderr separately.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <mutex>
#include <set>
#include <string>
#include <unistd.h>

namespace voxtier::test {

struct CliRun {
    int status = -1; ///< exit code; -1 when the process died from a signal
    std::string out, err;
};

/// Runs `VOXTIER_CLI args` with `env` assignments prefixed (e.g. "LP_NUM_THREADS=1"). Output
/// files are unique per process and test case, so CTest may run cases in parallel.
inline CliRun runCli(const std::string& args, const std::string& env = "") {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    std::string name = info ? std::string(info->test_suite_name()) + "_" + info->name() : "cli";
    for (char& c : name)
        if (c == '/') c = '_';
    const std::string stem =
        ::testing::TempDir() + "/voxtier_cli_" + std::to_string(getpid()) + "_" + name;
    const std::string outFile = stem + ".out", errFile = stem + ".err";
    const std::string cmd =
        env + " '" + VOXTIER_CLI + "' " + args + " >'" + outFile + "' 2>'" + errFile + "'";
    CliRun r;
    const int raw = std::system(cmd.c_str());
    r.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
    auto slurp = [](const std::string& p) {
        std::ifstream in(p);
        return std::string(std::istreambuf_iterator<char>(in), {});
    };
    r.out = slurp(outFile);
    r.err = slurp(errFile);
    std::remove(outFile.c_str());
    std::remove(errFile.c_str());
    return r;
}

/// A scratch folder under the test temp dir, one per process (CTest runs cases as separate
/// processes) and, with perTest, one per test case too. Emptied the first time this process asks
/// for it: the folders outlive their processes, and one named by a pid that a later process gets
/// again still holds the earlier run's files (with 674 such folders in /tmp and pids up to 32,768,
/// RenderOutput.PathToGifIsOneAnimatedGif found the 11 PNGs of an earlier run beside its GIF).
inline std::filesystem::path scratchDir(const std::string& prefix, bool perTest = false) {
    std::filesystem::path d =
        std::filesystem::path(::testing::TempDir()) / (prefix + "_" + std::to_string(getpid()));
    if (perTest) d /= ::testing::UnitTest::GetInstance()->current_test_info()->name();
    static std::mutex mutex;
    static std::set<std::string> emptied;
    std::lock_guard<std::mutex> lock(mutex);
    if (emptied.insert(d.string()).second) std::filesystem::remove_all(d);
    std::filesystem::create_directories(d);
    return d;
}

/// Writes `text` to dir/name and returns the path.
inline std::string writeText(const std::filesystem::path& dir, const std::string& name,
                             const std::string& text) {
    const std::filesystem::path p = dir / name;
    std::ofstream(p) << text;
    return p.string();
}

/// `err` without the line a render prints when it drew far sprites predicted over 1 vpx off
/// (apps/cmd_render.cpp): for tests of the other lines on stderr of a far or hybrid render.
inline std::string withoutFarWarning(const std::string& err) {
    std::string kept;
    std::size_t at = 0;
    while (at < err.size()) {
        const std::size_t end = std::min(err.find('\n', at), err.size());
        const std::string line = err.substr(at, end - at);
        if (!(line.rfind("voxtier: warning: ", 0) == 0 &&
              line.find(" drawn from snapshots predicted to be off by over 1 virtual pixel") !=
                  std::string::npos))
            kept += line + (end < err.size() ? "\n" : "");
        at = end + 1;
    }
    return kept;
}

inline std::size_t lineCount(const std::string& s) {
    std::size_t n = 0;
    for (char c : s) n += c == '\n';
    return n + (!s.empty() && s.back() != '\n');
}

} // namespace voxtier::test
