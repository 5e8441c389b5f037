// Resource hygiene (issue 8): a long hybrid camera path with voxel edits keeps memory flat (no
// growth beyond the cache budget), and every Vulkan object is destroyed (the validation layer
// reports no leak when the renderer goes away).
#include "compose/frame.hpp"
#include "core/procedural.hpp"
#include "impostor_cache/snapshot_cache.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>
#include <string>

namespace voxtier {
namespace {

/// Resident set size of this process in MiB (Linux /proc).
double residentMiB() {
    std::ifstream in("/proc/self/status");
    std::string line;
    while (std::getline(in, line))
        if (line.rfind("VmRSS:", 0) == 0) return std::stod(line.substr(6)) / 1024.0;
    return 0.0;
}

Scene longPath(int frames) {
    Scene s;
    s.models = {makeArrow(16), makeBox({8, 8, 8}), makeSphere(6), makeShell({12, 10, 14}, 1)};
    for (int i = 0; i < 40; ++i) {
        Entity e;
        e.model = i % 4;
        e.position = {-6.0 + 3.0 * (i % 5), 0.0, -3.0 * (i / 5)};
        e.rotation = glm::angleAxis(0.4 * i, glm::dvec3(0, 1, 0));
        s.entities.push_back(e);
    }
    s.camera.width = 160;
    s.camera.height = 120;
    CameraPath path;
    path.fps = 30;
    // Back and forth through the selector band, orbiting so views change too.
    for (int k = 0; k <= 8; ++k) {
        CameraKey key;
        key.time = k * (frames / 30.0) / 8.0;
        const double a = 0.8 * k;
        const double r = k % 2 ? 40.0 : 6.0;
        key.position = {r * std::sin(a), 2.0 + k % 3, 4.0 + r * std::cos(a)};
        key.target = {0.0, 0.0, -10.0};
        path.keys.push_back(key);
    }
    s.path = path;
    s.selector.nearAt = 12;
    s.selector.farAt = 16;
    s.selector.crossfadeFrames = 3;
    // An edit every 25 frames on the shell (alternately filling and clearing a box), so the far
    // tier keeps re-baking and the near tier keeps re-uploading dirty boxes.
    for (int f = 25; f < frames; f += 25) {
        ScriptedEdit e;
        e.atFrame = f;
        e.model = 3;
        e.op = (f / 25) % 2 ? ScriptedEdit::Op::Fill : ScriptedEdit::Op::Clear;
        const int x = (f / 25) % 9;
        e.box = {{x, 1, 2}, {x + 3, 4, 6}};
        e.index = 5;
        s.edits.push_back(e);
    }
    return s;
}

TEST(ResourceHygiene, LongHybridPathWithEditsKeepsMemoryFlatAndLeaksNothing) {
    const int frames = 1500;
    Scene s = longPath(frames);
    FrameOptions o;
    o.nearBackend = NearBackend::Vulkan;
    o.vulkan.validation = true;
    o.vulkan.echoMessages = false;
    o.vulkanLog = std::make_shared<VulkanMessageLog>();
    // 16 KiB, below the working set: eviction all the time. (128 KiB was once enough for that,
    // when every edit left the old version's snapshots in the cache; they are dropped now.)
    o.cacheBudgetBytes = std::size_t(16) << 10;
    double rssWarm = 0.0, rssEnd = 0.0;
    std::size_t maxCache = 0;
    int switches = 0, bakes = 0;
    {
        FrameRenderer r(s, o);
        // lavapipe sets up its rasteriser (tens of MiB) on the first frame that rasterises a
        // sprite, which this path may reach late (cell-rate sprites are not rasterised): one
        // per-pixel near frame first puts it in the warm-up.
        r.options().nearRate = NearRate::Fragment;
        (void)r.render(s.timeOfFrame(0), RenderMode::Near, 0);
        r.options().nearRate = o.nearRate;
        for (int f = 0; f < frames; ++f) {
            r.applyEditsThrough(f);
            const FrameResult fr = r.render(s.timeOfFrame(f), RenderMode::Hybrid, f);
            maxCache = std::max(maxCache, fr.stats.cacheBytes);
            switches += fr.stats.plan.switchesToFar + fr.stats.plan.switchesToNear;
            bakes += fr.stats.far.bakes;
            if (f == 300) rssWarm = residentMiB();
        }
        rssEnd = residentMiB();
        const auto c = r.snapshotCache().counters();
        EXPECT_GT(c.evictions, 0u) << "the budget should force evictions on this path";
        std::printf("[ hygiene  ] %d frames, %d switches, %d bakes, %llu evictions, max cache %zu "
                    "B, RSS %.1f -> %.1f MiB\n",
                    frames, switches, bakes, (unsigned long long)c.evictions, maxCache, rssWarm,
                    rssEnd);
    }
    EXPECT_GT(switches, 20);
    EXPECT_LE(maxCache, o.cacheBudgetBytes);
    // Everything Vulkan created was destroyed: leaks are reported by the validation layer while
    // the device and instance are destroyed, into the shared log.
    EXPECT_EQ(o.vulkanLog->count(), 0u) << o.vulkanLog->joined();
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
    std::printf(
        "[ hygiene  ] sanitizer build: RSS includes the sanitizer's quarantine, not compared\n");
#else
    // After warm-up (atlas, caches, pools at their working size) memory stays flat: 1200 more
    // frames with 48 edits may not grow the process by more than a few MiB.
    EXPECT_LT(rssEnd - rssWarm, 16.0) << "RSS grew from " << rssWarm << " to " << rssEnd << " MiB";
#endif
}

} // namespace
} // namespace voxtier
