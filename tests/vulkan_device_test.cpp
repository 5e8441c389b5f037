// The headless Vulkan device: it exists here (lavapipe), validation is on in tests and catches
// what it should (a deliberately leaked buffer is reported at teardown, so "zero messages" in the
// other suites means something), a full render-and-destroy cycle leaks nothing, and without any
// Vulkan driver the CLI fails with one clear line while --mode reference keeps working.
#include "cli_support.hpp"
#include "device/vulkan_device.hpp"
#include "device/vulkan_device_info.hpp"
#include "image_checks.hpp"
#include "test_models.hpp"
#include "view_sweeps.hpp"
#include "vulkan_test_env.hpp"

#include <gtest/gtest.h>
#include <sys/wait.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <unistd.h>
#include <utility>

namespace voxtier {
namespace {

const auto* const kEnv = ::testing::AddGlobalTestEnvironment(new test::NearRendererEnvironment);

using test::VulkanTest;
class NearDevice : public VulkanTest {};

VulkanDeviceOptions validated() {
    VulkanDeviceOptions o;
    o.validation = true;
    o.echoMessages = false;
    return o;
}

TEST_F(NearDevice, DeviceExistsAndRunsWithValidation) {
    NearRenderer& nr = nearRenderer();
    EXPECT_FALSE(nr.deviceName().empty());
    EXPECT_TRUE(nr.validationEnabled());
    std::printf("Vulkan device: %s (%s)\n", nr.deviceName().c_str(),
                nr.deviceIsCpu() ? "CPU" : "GPU");
}

TEST(VulkanDevice, PrefersAGpuAndFallsBackToLavapipe) {
    auto log = std::make_shared<VulkanMessageLog>();
    VulkanDevice dev(validated(), log);
    // This machine has no GPU: the fallback must be the CPU rasterizer.
    std::uint32_t n = 0;
    vkEnumeratePhysicalDevices(dev.instance(), &n, nullptr);
    std::vector<VkPhysicalDevice> all(n);
    vkEnumeratePhysicalDevices(dev.instance(), &n, all.data());
    bool anyGpu = false;
    for (VkPhysicalDevice pd : all) {
        VkPhysicalDeviceProperties p{};
        vkGetPhysicalDeviceProperties(pd, &p);
        anyGpu |= p.deviceType == VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU ||
                  p.deviceType == VK_PHYSICAL_DEVICE_TYPE_INTEGRATED_GPU;
    }
    EXPECT_EQ(dev.isCpu(), !anyGpu) << dev.name();
    EXPECT_GE(dev.properties().apiVersion, VK_API_VERSION_1_2);
    EXPECT_TRUE(dev.hasPipelineStatistics());
    EXPECT_TRUE(dev.hasFragmentAtomics());
}

// The teardown check is real: a buffer that is never destroyed is reported while the device is
// destroyed, into the log that outlives it.
// The leaked buffer's host memory comes from a test-owned allocator and is freed once the
// device is gone: the leak is the Vulkan object, not process memory, so LeakSanitizer (which
// cannot see into the driver once the loader has unloaded it) stays quiet in sanitizer builds.
struct OwnedHostAllocations {
    std::vector<void*> blocks;
    ~OwnedHostAllocations() {
        for (void* p : blocks) std::free(p);
    }
    static void* VKAPI_PTR allocate(void* self, std::size_t size, std::size_t align,
                                    VkSystemAllocationScope) {
        void* p = std::aligned_alloc(align, (size + align - 1) / align * align);
        if (p) static_cast<OwnedHostAllocations*>(self)->blocks.push_back(p);
        return p;
    }
    static void* VKAPI_PTR reallocate(void*, void*, std::size_t, std::size_t,
                                      VkSystemAllocationScope) {
        return nullptr; // never called for a buffer that is created once
    }
    static void VKAPI_PTR release(void* self, void* p) {
        auto& b = static_cast<OwnedHostAllocations*>(self)->blocks;
        if (const auto it = std::find(b.begin(), b.end(), p); it != b.end()) {
            std::free(p);
            b.erase(it);
        }
    }
    VkAllocationCallbacks callbacks() {
        VkAllocationCallbacks c{};
        c.pUserData = this;
        c.pfnAllocation = &allocate;
        c.pfnReallocation = &reallocate;
        c.pfnFree = &release;
        return c;
    }
};

TEST(VulkanDevice, ValidationReportsALeakedObjectAtTeardown) {
    auto log = std::make_shared<VulkanMessageLog>();
    OwnedHostAllocations host;
    {
        VulkanDevice dev(validated(), log);
        VkBufferCreateInfo bci{VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO};
        bci.size = 256;
        bci.usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT;
        VkBuffer leaked = VK_NULL_HANDLE;
        const VkAllocationCallbacks alloc = host.callbacks();
        VK_CHECK(vkCreateBuffer(dev.device(), &bci, &alloc, &leaked));
        EXPECT_EQ(log->count(), 0u);
    }
    ASSERT_GE(log->count(), 1u);
    EXPECT_NE(log->joined().find("VkBuffer"), std::string::npos) << log->joined();
}

// A whole renderer lifecycle (pipelines, atlas growth, targets, queries, counters) destroys
// everything it created: no leak report at teardown, no message at all.
TEST(VulkanDevice, RenderAndTeardownLeaveNoValidationMessages) {
    auto log = std::make_shared<VulkanMessageLog>();
    {
        NearRenderer nr(validated(), log);
        const auto v = test::viewAlong(test::solidBox({5, 7, 3}), glm::dvec3(1, 2, -1), 2.0, 3);
        // The trace (a GPU's default), and the draw over two proxies (a CPU device's).
        const std::pair<NearPixels, NearProxy> ways[] = {{NearPixels::Compute, NearProxy::Hull},
                                                         {NearPixels::Raster, NearProxy::Quad},
                                                         {NearPixels::Raster, NearProxy::Box}};
        for (const auto& [pixels, proxy] : ways) {
            NearOptions o;
            o.pixels = pixels;
            o.proxy = proxy;
            o.countSteps = true;
            const auto r = test::renderBoth(nr, v.scene, 0.0, o);
            EXPECT_GT(test::drawnPixels(r.near), 0u);
        }
    }
    EXPECT_EQ(log->count(), 0u) << log->joined();
}

TEST(VulkanCheck, FailedCallThrowsVulkanErrorNamingCallAndResult) {
    try {
        VK_CHECK(VK_ERROR_DEVICE_LOST);
        FAIL() << "VK_CHECK did not throw";
    } catch (const VulkanError& e) {
        const std::string what = e.what();
        EXPECT_NE(what.find("VK_ERROR_DEVICE_LOST"), std::string::npos) << what;
        EXPECT_NE(what.find("vulkan_device_test.cpp"), std::string::npos) << what;
        EXPECT_EQ(what.find('\n'), std::string::npos);
        EXPECT_EQ(e.result(), VK_ERROR_DEVICE_LOST);
    }
}

// ---------------------------------------------------------------------------------------------
// The CLI as a child process.

std::string slurp(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
}

/// A scratch directory of this test alone: CTest runs the tests of this file in parallel
/// processes, so shared file names would race.
std::string scratchDir() {
    const std::string dir = ::testing::TempDir() + "voxtier_" +
                            ::testing::UnitTest::GetInstance()->current_test_info()->name() + "_" +
                            std::to_string(::getpid());
    std::filesystem::create_directories(dir);
    return dir;
}

/// Removes the scratch directory when a CLI test ends.
class VulkanCli : public ::testing::Test {
  protected:
    void TearDown() override { std::filesystem::remove_all(scratchDir()); }
};

using test::CliRun;
using test::lineCount;

// Both variables: VK_DRIVER_FILES is the current name, VK_ICD_FILENAMES the older one.
const std::string kNoDriver = "VK_DRIVER_FILES=/nonexistent/voxtier_none.json "
                              "VK_ICD_FILENAMES=/nonexistent/voxtier_none.json";

TEST_F(VulkanCli, NoVulkanDeviceIsOneClearLineAndNonZeroExit) {
    const std::string scene = std::string(VOXTIER_SOURCE_DIR) + "/scenes/golden/arrows.json";
    const std::string out = scratchDir() + "/no_device.png";
    for (const std::string& extra : {std::string(), std::string(" VOXTIER_VALIDATION=1")}) {
        const CliRun r =
            test::runCli("render " + scene + " --mode near --out " + out, kNoDriver + extra);
        EXPECT_NE(r.status, 0);
        EXPECT_EQ(r.err, std::string("voxtier: error: ") + kNoVulkanDeviceMessage + "\n")
            << "stderr was:\n"
            << r.err;
        EXPECT_EQ(lineCount(r.err), 1u);
    }
    // An empty driver manifest is the same situation.
    const std::string empty = scratchDir() + "/empty_icd.json";
    std::ofstream(empty) << "{}\n";
    const CliRun r = test::runCli("render " + scene + " --mode near --out " + out,
                                  "VK_DRIVER_FILES=" + empty + " VK_ICD_FILENAMES=" + empty);
    EXPECT_NE(r.status, 0);
    EXPECT_EQ(r.err, std::string("voxtier: error: ") + kNoVulkanDeviceMessage + "\n")
        << "stderr was:\n"
        << r.err;
}

TEST_F(VulkanCli, ReferenceModeWorksWithoutAnyVulkanDriver) {
    const std::string scene = std::string(VOXTIER_SOURCE_DIR) + "/scenes/golden/arrows.json";
    const std::string out = scratchDir() + "/reference.png";
    const CliRun r = test::runCli("render " + scene + " --mode reference --out " + out, kNoDriver);
    EXPECT_EQ(r.status, 0) << r.err;
    EXPECT_EQ(r.err, "");
    EXPECT_TRUE(std::filesystem::exists(out));
}

TEST_F(VulkanCli, NearModePrintsTheDeviceAndMatchesReferenceFile) {
    const std::string scene = std::string(VOXTIER_SOURCE_DIR) + "/scenes/golden/topdown.json";
    const std::string nearPng = scratchDir() + "/near.png";
    const std::string refPng = scratchDir() + "/reference.png";
    const CliRun n =
        test::runCli("render " + scene + " --mode near --out " + nearPng, "VOXTIER_VALIDATION=1");
    ASSERT_EQ(n.status, 0) << n.err;
    EXPECT_EQ(n.err, "") << "validation messages";
    EXPECT_NE(n.out.find("Vulkan device: "), std::string::npos) << n.out;
    const CliRun r = test::runCli("render " + scene + " --mode reference --out " + refPng, "");
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_TRUE(slurp(nearPng) == slurp(refPng));
}

// `voxtier check` says where each buffer class lives on the machine's device: on lavapipe one
// memory type serves all four, the shaders' data is written directly and read back cached.
TEST_F(VulkanCli, CheckPrintsTheMemoryEachBufferClassGets) {
    const std::string scene = std::string(VOXTIER_SOURCE_DIR) + "/scenes/golden/arrows.json";
    const CliRun r = test::runCli("check " + scene, "");
    ASSERT_EQ(r.status, 0) << r.err;
    for (const char* c : {"ShaderRead", "DeviceOnly", "Staging", "Readback"})
        EXPECT_NE(r.out.find(std::string("Vulkan memory: ") + c + ": type "), std::string::npos)
            << c << "\n"
            << r.out;
    VulkanDeviceOptions o;
    o.echoMessages = false;
    if (!VulkanDevice(o).isCpu()) GTEST_SKIP() << "the rest describes lavapipe";
    EXPECT_NE(r.out.find("Vulkan memory: ShaderRead: type 0 (DEVICE_LOCAL|HOST_VISIBLE|"
                         "HOST_COHERENT|HOST_CACHED), heap 0 of "),
              std::string::npos)
        << r.out;
    EXPECT_NE(r.out.find("host writes directly"), std::string::npos) << r.out;
}

// With a driver installed beside lavapipe that does not load, check still runs (on lavapipe) and
// names the driver that did not load.
TEST_F(VulkanCli, CheckNamesAnInstalledDriverThatDoesNotLoad) {
    const std::string dir = scratchDir();
    const std::string fake = dir + "/needs_dep_icd.json";
    std::ofstream(fake) << R"({"file_format_version": "1.0.0", "ICD": {"library_path": ")"
                        << VOXTIER_TEST_ICD << R"("}})";
    std::string drivers = fake;
    for (const auto& e : std::filesystem::directory_iterator("/usr/share/vulkan/icd.d"))
        if (e.path().filename().string().rfind("lvp_icd", 0) == 0)
            drivers += ":" + e.path().string();
    const std::string scene = std::string(VOXTIER_SOURCE_DIR) + "/scenes/golden/arrows.json";
    const CliRun r = test::runCli("check " + scene, "VK_DRIVER_FILES=" + drivers);
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_NE(r.out.find("Vulkan driver not loaded: " + fake + " (" + VOXTIER_TEST_ICD +
                         "): libvoxtier_test_icd_dependency.so"),
              std::string::npos)
        << r.out;
}

TEST(VulkanDevice, ForcedStagingFromTheEnvironmentShowsInThePlacements) {
    ::setenv("VOXTIER_FORCE_STAGING", "1", 1);
    const std::vector<std::string> lines = describeMemoryPlacements();
    ::unsetenv("VOXTIER_FORCE_STAGING");
    ASSERT_EQ(lines.size(), 4u);
    EXPECT_EQ(lines[0].rfind("ShaderRead: ", 0), 0u) << lines[0];
    EXPECT_NE(lines[0].find("host writes through staging"), std::string::npos) << lines[0];
    VulkanDeviceOptions o;
    o.echoMessages = false;
    if (VulkanDevice(o).isCpu()) {
        EXPECT_NE(describeMemoryPlacements()[0].find("host writes directly"), std::string::npos)
            << "lavapipe, unforced";
    }
}

TEST_F(VulkanCli, ValidationWithoutTheLayerInstalledIsAClearError) {
    const std::string scene = std::string(VOXTIER_SOURCE_DIR) + "/scenes/golden/arrows.json";
    const std::string out = scratchDir() + "/no_layer.png";
    // VK_LAYER_PATH replaces the loader's explicit-layer search path: no validation layer found.
    const CliRun r = test::runCli("render " + scene + " --mode near --out " + out,
                                  "VOXTIER_VALIDATION=1 VK_LAYER_PATH=/nonexistent/layers");
    EXPECT_NE(r.status, 0);
    EXPECT_NE(r.err.find("VK_LAYER_KHRONOS_validation is not installed"), std::string::npos)
        << r.err;
    EXPECT_EQ(lineCount(r.err), 1u) << r.err;
}

} // namespace
} // namespace voxtier
