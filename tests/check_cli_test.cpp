// `voxtier check`: the identity a machine checks with the CLI alone (tools/gpu_check.sh runs it
// on the GPU machine, where there is no test suite). On a golden scene it reports 0 differing
// pixels per plane, the device, and a CSV row; a scene that draws nothing fails (identical empty
// images prove nothing), with one error line.
#include "cli_support.hpp"

#include <gtest/gtest.h>

#include <fstream>
#include <iterator>
#include <string>

namespace voxtier {
namespace {

std::string readText(const std::string& file) {
    std::ifstream in(file);
    return std::string(std::istreambuf_iterator<char>(in), {});
}

TEST(CheckCli, GoldenSceneIsIdenticalInEveryPlane) {
    const auto dir = test::scratchDir("voxtier_check_cli", true);
    const std::string csv = (dir / "check.csv").string();
    const test::CliRun r = test::runCli("check " + std::string(VOXTIER_SOURCE_DIR) +
                                        "/scenes/golden/crowd.json --csv " + csv);
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_NE(r.out.find("Vulkan device: "), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("crowd.json t=0.000: Vulkan near vs CPU reference: 0 colour, 0 depth, "
                         "0 id pixels differ of 40960"),
              std::string::npos)
        << r.out;
    EXPECT_NE(r.out.find("1 of 1 checks identical"), std::string::npos) << r.out;
    const std::string rows = readText(csv);
    EXPECT_EQ(rows.rfind("scene,time,check,device,width,height,drawn_pixels,colour_diffs,"
                         "depth_diffs,id_diffs,result\n",
                         0),
              0u)
        << rows;
    EXPECT_NE(rows.find(",near_vulkan_vs_reference,"), std::string::npos) << rows;
    EXPECT_NE(rows.find(",256,160,2303,0,0,0,identical\n"), std::string::npos) << rows;
}

TEST(CheckCli, ASceneThatDrawsNothingFails) {
    const std::string scene =
        test::writeText(test::scratchDir("voxtier_check_cli", true), "behind.json",
                        R"({"camera": {"position": [0, 1, 3], "target": [0, 0.5, 10],
                            "size": [48, 32]}, "models": [{"name": "b", "generator": "box"}],
                            "entities": [{"model": "b"}]})");
    const test::CliRun r = test::runCli("check " + scene);
    EXPECT_EQ(r.status, 1);
    EXPECT_NE(r.out.find("(0 drawn): NOTHING DRAWN"), std::string::npos) << r.out;
    EXPECT_EQ(r.err, "voxtier: error: 1 of 1 checks failed\n");
}

} // namespace
} // namespace voxtier
