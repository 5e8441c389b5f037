// The far tier's command-line surface: `voxtier bake` (with a contact sheet), `voxtier bake
// --bench` on a small model, `voxtier render --mode far`.
#include "core/image_io.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <string>
#include <unistd.h>

namespace {

namespace fs = std::filesystem;

struct CliRun {
    int status = -1;
    std::string out;
};
CliRun run(const std::string& args) {
    CliRun r;
    const std::string cmd = std::string(VOXTIER_CLI) + " " + args + " 2>&1";
    std::unique_ptr<FILE, int (*)(FILE*)> pipe(popen(cmd.c_str(), "r"), pclose);
    if (!pipe) return r;
    char buf[512];
    while (fgets(buf, sizeof buf, pipe.get())) r.out += buf;
    r.status = pclose(pipe.release());
    return r;
}

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
    EXPECT_NE(run("bake scenes/vox/mmmm/chr_cop1.vox --views 27").status, 0);
    EXPECT_NE(run("bake scenes/vox/mmmm/chr_cop1.vox --geometry spheres").status, 0);
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
