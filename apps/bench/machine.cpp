// The machine's own figures beside the bench's (apps/bench/machine.hpp).
#include "apps/bench/machine.hpp"

#include "apps/bench/harness.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <span>
#include <vector>

namespace voxtier::bench {

using cli::median;

double memcpyMs(std::size_t bytes) {
    if (bytes == 0) return 0.0;
    std::vector<unsigned char> src(bytes, 1), dst(bytes, 0);
    constexpr std::size_t kBlock = 256 << 10;
    const std::size_t blocks = (bytes + kBlock - 1) / kBlock;
    auto copy = [&] {
        tbb::parallel_for(std::size_t(0), blocks, [&](std::size_t b) {
            const std::size_t at = b * kBlock;
            std::memcpy(dst.data() + at, src.data() + at, std::min(kBlock, bytes - at));
        });
    };
    const std::vector<double> ms = cli::timedRepeats(1, 5, copy);
    if (dst[bytes / 2] != 1) std::abort(); // keeps the copies observable
    return median(ms);
}

// Colour alone is what a PNG frame drawn wholly on Vulkan reads back; the three planes, what
// every frame read back before the far pass moved to the GPU.
std::string fixedFrameCost(NearRenderer& near, const Scene& scene) {
    const CameraFrame cam = makeCameraFrame(scene.cameraAt(0.0));
    const std::vector<std::shared_ptr<VoxelModel>> none;
    std::vector<double> three, one;
    for (int k = 0; k < 22; ++k)
        for (const bool all : {true, false}) {
            NearOptions no;
            no.readDepthAndIds = all;
            const double ms = cli::timedMs([&] {
                (void)near.render(cam, none, std::span<const SpriteSetup* const>{}, 0, no);
            });
            if (k > 0) (all ? three : one).push_back(ms); // the first warms up
        }
    char buf[200];
    std::snprintf(buf, sizeof buf,
                  "Vulkan frame with no sprite, %dx%d: %.2f ms reading back colour, depth and "
                  "ids; %.2f ms reading back colour alone (median of 21 each)",
                  cam.width, cam.height, median(three), median(one));
    return buf;
}

std::string cpuName() {
    std::ifstream in("/proc/cpuinfo");
    std::string line;
    while (std::getline(in, line))
        if (line.rfind("model name", 0) == 0) {
            const auto colon = line.find(':');
            return colon == std::string::npos ? line : line.substr(colon + 2);
        }
    return "unknown CPU";
}

} // namespace voxtier::bench
