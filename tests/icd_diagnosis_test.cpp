// Seeing the driver's failure (device/icd_diagnosis.hpp, issue 35 Deliver 6): a driver manifest
// whose library is missing, or whose library needs a library that is missing, is named in the
// no-device message with dlopen's reason, instead of the advice to install lavapipe. Runs
// without any GPU: the manifests are written here, and the driver with a missing dependency is a
// library this build makes (tests/icd_fixtures/).
#include "cli_support.hpp"
#include "device/icd_diagnosis.hpp"
#include "device/vulkan_device.hpp"

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <map>
#include <optional>
#include <string>

namespace voxtier {
namespace {

namespace fs = std::filesystem;

std::string manifest(const std::string& libraryPath) {
    return R"({"file_format_version": "1.0.0", "ICD": {"library_path": ")" + libraryPath +
           R"(", "api_version": "1.3.0"}})";
}

/// Sets environment variables for one test and restores them after.
class ScopedEnv {
  public:
    void set(const std::string& name, const std::optional<std::string>& value) {
        if (!saved_.count(name)) {
            const char* old = std::getenv(name.c_str());
            saved_[name] = old ? std::optional<std::string>(old) : std::nullopt;
        }
        if (value)
            ::setenv(name.c_str(), value->c_str(), 1);
        else
            ::unsetenv(name.c_str());
    }
    ~ScopedEnv() {
        for (const auto& [name, value] : saved_) {
            if (value)
                ::setenv(name.c_str(), value->c_str(), 1);
            else
                ::unsetenv(name.c_str());
        }
    }

  private:
    std::map<std::string, std::optional<std::string>> saved_;
};

TEST(IcdDiagnosis, AMissingLibraryIsNamedWithDlopensReason) {
    const auto dir = test::scratchDir("voxtier_icd", true);
    const std::string m =
        test::writeText(dir, "gone_icd.json", manifest("/nonexistent/libvoxtier_gone_icd.so"));
    const std::vector<IcdLoadFailure> f = findIcdLoadFailures({m});
    ASSERT_EQ(f.size(), 1u);
    EXPECT_EQ(f[0].manifest, m);
    EXPECT_EQ(f[0].library, "/nonexistent/libvoxtier_gone_icd.so");
    EXPECT_NE(f[0].reason.find("cannot open shared object file"), std::string::npos) << f[0].reason;
}

TEST(IcdDiagnosis, AMissingDependencyIsNamed) {
    ASSERT_TRUE(fs::exists(VOXTIER_TEST_ICD)) << VOXTIER_TEST_ICD;
    const auto dir = test::scratchDir("voxtier_icd", true);
    const std::string m = test::writeText(dir, "needs_dep_icd.json", manifest(VOXTIER_TEST_ICD));
    const std::vector<IcdLoadFailure> f = findIcdLoadFailures({m});
    ASSERT_EQ(f.size(), 1u);
    EXPECT_EQ(f[0].library, VOXTIER_TEST_ICD);
    // The driver exists; what is missing is the library it needs, and dlerror names that one.
    EXPECT_NE(f[0].reason.find("libvoxtier_test_icd_dependency.so"), std::string::npos)
        << f[0].reason;
}

TEST(IcdDiagnosis, RelativeLibraryPathsAreTheManifestFoldersAndLoadableOnesAreFine) {
    const auto dir = test::scratchDir("voxtier_icd", true);
    // A relative path with a slash is resolved against the manifest's folder, as the loader does.
    const std::string relative = test::writeText(dir, "relative.json", manifest("./libnone.so"));
    // A bare name goes through the dynamic linker's search: the C library always loads.
    const std::string loads = test::writeText(dir, "libc.json", manifest("libc.so.6"));
    // A manifest with no ICD.library_path is not a driver: the loader skips it, and so do we.
    const std::string empty = test::writeText(dir, "empty.json", "{}\n");
    const std::string broken = test::writeText(dir, "broken.json", "{\"ICD\": ");
    const std::vector<IcdLoadFailure> f = findIcdLoadFailures({relative, loads, empty, broken});
    ASSERT_EQ(f.size(), 2u);
    EXPECT_EQ(f[0].manifest, relative);
    EXPECT_NE(f[0].reason.find((dir / "libnone.so").string()), std::string::npos) << f[0].reason;
    EXPECT_EQ(f[1].manifest, broken);
    EXPECT_EQ(f[1].library, "");
    EXPECT_NE(f[1].reason.find("is not valid JSON"), std::string::npos) << f[1].reason;
}

TEST(IcdDiagnosis, ManifestsAreSearchedWhereTheLoaderLooks) {
    const auto dir = test::scratchDir("voxtier_icd", true);
    for (const char* sub : {"config/vulkan/icd.d", "data/vulkan/icd.d", "only"})
        fs::create_directories(dir / sub);
    const std::string inConfig = test::writeText(dir / "config/vulkan/icd.d", "a.json", "{}");
    const std::string inData = test::writeText(dir / "data/vulkan/icd.d", "b.json", "{}");
    const std::string onlyA = test::writeText(dir / "only", "z.json", "{}");
    const std::string onlyB = test::writeText(dir / "only", "y.json", "{}");
    test::writeText(dir / "only", "not_a_manifest.txt", "");
    ScopedEnv env;
    env.set("VK_DRIVER_FILES", std::nullopt);
    env.set("VK_ICD_FILENAMES", std::nullopt);
    env.set("VK_ADD_DRIVER_FILES", std::nullopt);
    env.set("XDG_CONFIG_HOME", (dir / "config").string());
    env.set("XDG_DATA_HOME", (dir / "data").string());
    std::vector<std::string> found = icdManifestFiles();
    const auto at = [&](const std::string& f) {
        return std::find(found.begin(), found.end(), f) - found.begin();
    };
    ASSERT_LT(std::size_t(at(inConfig)), found.size());
    ASSERT_LT(std::size_t(at(inData)), found.size());
    EXPECT_LT(at(inConfig), at(inData)) << "config folders come before data folders";

    // VK_ICD_FILENAMES (the old name) replaces the search; a folder gives its .json files sorted.
    env.set("VK_ICD_FILENAMES", (dir / "only").string() + ":" + inData);
    found = icdManifestFiles();
    EXPECT_EQ(found, (std::vector<std::string>{onlyB, onlyA, inData}));
    // VK_DRIVER_FILES (the current name) wins over it.
    env.set("VK_DRIVER_FILES", inConfig);
    EXPECT_EQ(icdManifestFiles(), std::vector<std::string>{inConfig});
}

TEST(IcdDiagnosis, TheNoDeviceMessageNamesTheFailingDriverOnOneLine) {
    const auto dir = test::scratchDir("voxtier_icd", true);
    const std::string m = test::writeText(dir, "needs_dep_icd.json", manifest(VOXTIER_TEST_ICD));
    ScopedEnv env;
    env.set("VK_DRIVER_FILES", m);
    const std::string msg = noVulkanDeviceMessage();
    EXPECT_EQ(msg.rfind("no Vulkan device: the driver of " + m + " (" + VOXTIER_TEST_ICD +
                            ") does not load: ",
                        0),
              0u)
        << msg;
    EXPECT_NE(msg.find("libvoxtier_test_icd_dependency.so"), std::string::npos) << msg;
    EXPECT_EQ(msg.find('\n'), std::string::npos);
    EXPECT_EQ(msg.find("install mesa-vulkan-drivers"), std::string::npos) << msg;
    // No manifest at all: the advice stays what it was.
    env.set("VK_DRIVER_FILES", (dir / "none.json").string());
    EXPECT_EQ(noVulkanDeviceMessage(), kNoVulkanDeviceMessage);
}

// The user's view: the CLI's one error line names the driver and the missing library.
TEST(IcdDiagnosis, TheCliSaysWhichDriverFailedToLoad) {
    const auto dir = test::scratchDir("voxtier_icd", true);
    const std::string m = test::writeText(dir, "needs_dep_icd.json", manifest(VOXTIER_TEST_ICD));
    const std::string scene = std::string(VOXTIER_SOURCE_DIR) + "/scenes/golden/arrows.json";
    const test::CliRun r =
        test::runCli("render " + scene + " --mode near --out " + (dir / "x.png").string(),
                     "VK_DRIVER_FILES=" + m + " VK_ICD_FILENAMES=" + m);
    EXPECT_NE(r.status, 0);
    EXPECT_EQ(r.err.rfind("voxtier: error: no Vulkan device: the driver of " + m, 0), 0u) << r.err;
    EXPECT_NE(r.err.find("libvoxtier_test_icd_dependency.so"), std::string::npos) << r.err;
    EXPECT_EQ(test::lineCount(r.err), 1u) << r.err;
}

} // namespace
} // namespace voxtier
