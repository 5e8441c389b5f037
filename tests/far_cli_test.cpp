// The far tier's command-line surface: `voxtier bake` (with a contact sheet), `voxtier bake
// --bench` on a small model, `voxtier render --mode far`.
#include "cli_support.hpp"
#include "image_files/image_files.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <string>
#include <unistd.h>

namespace {

namespace fs = std::filesystem;

/// The CLI with stderr folded into stdout (these tests read both as one text).
voxtier::test::CliRun run(const std::string& args) {
    voxtier::test::CliRun r = voxtier::test::runCli(args);
    r.out += r.err;
    return r;
}
using voxtier::test::CliRun;

fs::path tempDir() {
    const fs::path d =
        fs::temp_directory_path() / ("voxtier_far_cli_" + std::to_string(::getpid()));
    fs::create_directories(d);
    return d;
}

TEST(BakeCommand, BakesAllViewsPrintsCostsAndWritesALabelledContactSheet) {
    const fs::path sheet = tempDir() / "cop_sheet.png";
    const CliRun r =
        run("bake scenes/vox/mmmm/chr_cop1.vox --views 26 --sigma 2 --geometry quads --sheet " +
            sheet.string());
    ASSERT_EQ(r.status, 0) << r.out;
    EXPECT_NE(r.out.find("baked 26 views"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("Mrays/s"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("bytes"), std::string::npos) << r.out;
    const voxtier::Image img = voxtier::readColorImage(sheet);
    EXPECT_GT(img.width, 200);
    EXPECT_GT(img.height, 200);
}

TEST(BakeCommand, RejectsAnUnknownViewSetOrGeometry) {
    const CliRun views = run("bake scenes/vox/mmmm/chr_cop1.vox --views 27");
    EXPECT_NE(views.status, 0);
    EXPECT_NE(views.out.find("--views: unknown view set '27' (expected: 26, 98, 218)"),
              std::string::npos)
        << views.out;
    const CliRun geometry = run("bake scenes/vox/mmmm/chr_cop1.vox --geometry spheres");
    EXPECT_NE(geometry.status, 0);
    EXPECT_NE(geometry.out.find("--geometry: unknown Embree geometry 'spheres' (expected: quads, "
                                "boxes)"),
              std::string::npos)
        << geometry.out;
}

TEST(BakeCommand, BenchComparesEmbreeWithTheScalarDdaSideBySide) {
    const CliRun r = run("bake --bench --repeats 1 scenes/vox/mmmm/chr_cop1.vox");
    ASSERT_EQ(r.status, 0) << r.out;
    EXPECT_NE(r.out.find("scalar DDA"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("embree boxes packet8"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("embree quads stream"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("identical to the scalar DDA: yes"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("memory per cached model"), std::string::npos) << r.out;
}

TEST(RenderCommand, FarModeDrawsTheDefaultScene) {
    const fs::path out = tempDir() / "default_far.png";
    const CliRun r = run("render scenes/default.json --mode far -o " + out.string());
    ASSERT_EQ(r.status, 0) << r.out;
    EXPECT_NE(r.out.find("far"), std::string::npos) << r.out;
    EXPECT_TRUE(fs::exists(out));
}

} // namespace
