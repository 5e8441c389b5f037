// `voxtier bench near`: the Vulkan near tier against the CPU reference on the same frames, side
// by side in one run (CONTRACT.md §8: speed next to the error it costs). For each entity count it
// builds a crowd of near entities (characters, props, a few vehicles), warms up, and reports
// medians over the repeats of: Vulkan draw (record + submit + wait) and readback ms, the CPU
// reference ms (TBB), their ratio, fragments shaded, DDA steps per fragment, and how many pixels
// differ from the reference. Besides the default (hull proxy, one instanced draw) it measures
// the alternatives one change at a time: one draw per entity, the quad proxy, the rasterised
// proxy box (NearProxy in volumetric/near_renderer.hpp).
#include "apps/bench/harness.hpp"
#include "apps/cli_options.hpp"
#include "apps/commands.hpp"
#include "core/error.hpp"
#include "core/procedural.hpp"
#include "core/scene.hpp"
#include "core/sprite.hpp"
#include "core/vox_reader.hpp"
#include "volumetric/near_renderer.hpp"
#include "volumetric/reference_renderer.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <random>
#include <sstream>
#include <string>
#include <time.h>
#include <vector>

namespace voxtier::cli {

namespace {

/// Where the bench models come from: the bundled .vox files, or procedural stand-ins.
enum class ModelSource { Vox, Procedural };
const std::pair<const char*, ModelSource> kModelSourceNames[] = {
    {"vox", ModelSource::Vox}, {"procedural", ModelSource::Procedural}};

struct BenchArgs {
    std::vector<int> entities = {10, 100, 1000};
    int repeats = 5;
    int warmup = 2;
    std::string out;
    ModelSource models = ModelSource::Vox;
    std::string voxDir = "scenes/vox";
    std::string size = "960x540"; ///< WxH (checked by imageSize())
    bool alternatives = true;
};

std::shared_ptr<VoxelModel> voxModel(const std::filesystem::path& file, int index = 0) {
    const VoxFile vox = readVoxFile(file);
    return std::make_shared<VoxelModel>(file.stem().string(), vox.palette,
                                        std::vector<VoxelGrid>{vox.models.at(std::size_t(index))});
}

/// The bench models, entity-sized: a character (weight 5), four 8^3 props (weight 4) and a fire
/// truck (weight 1), from the bundled .vox files, or procedural stand-ins of similar sizes.
struct BenchModels {
    std::vector<std::shared_ptr<VoxelModel>> models;
    std::vector<int> pick; ///< model index per slot of a 10-slot wheel
};

BenchModels benchModels(const BenchArgs& a) {
    BenchModels m;
    if (a.models == ModelSource::Procedural) {
        m.models = {makeBox({8, 6, 11}, proc_index::kOrange),
                    makeSphere(4, proc_index::kCyan),
                    makeArrow(8),
                    makeShell({8, 8, 8}, 1, proc_index::kViolet),
                    makeSingleVoxel(5),
                    makeBox({24, 58, 20})};
    } else {
        const std::filesystem::path dir(a.voxDir);
        if (!std::filesystem::exists(dir / "mmmm"))
            throw InputError(
                a.voxDir, "--vox-dir",
                "bundled models not found (run from the repository root, pass --vox-dir, or use "
                "--models procedural)");
        const auto props = dir / "opengametools/test_multiple_model_scene.vox";
        m.models = {voxModel(dir / "mmmm/chr_cop1.vox"),
                    voxModel(props, 0),
                    voxModel(props, 1),
                    voxModel(props, 2),
                    voxModel(props, 3),
                    voxModel(dir / "mmmm/veh_fire.vox")};
    }
    m.pick = {0, 0, 0, 0, 0, 1, 2, 3, 4, 5};
    return m;
}

/// A seeded crowd of `n` entities standing on the ground in front of the camera at 6..26 m (the
/// near band of the default selector), random model and yaw. Raw mt19937 words, so the layout
/// is the same with every standard library.
Scene benchScene(const BenchModels& models, int n, int width, int height) {
    Scene s;
    s.source = "bench near";
    s.models = models.models;
    s.camera.position = {0.0, 3.0, 6.0};
    s.camera.target = {0.0, 0.5, -10.0};
    s.camera.fovYDeg = 50.0;
    s.camera.width = width;
    s.camera.height = height;
    std::mt19937 rng(1234567u);
    auto uniform = [&](double lo, double hi) {
        return lo + (hi - lo) * (double(rng()) / 4294967296.0);
    };
    for (int i = 0; i < n; ++i) {
        Entity e;
        e.model = models.pick[rng() % models.pick.size()];
        const double z = uniform(-20.0, 0.0);
        const double halfWidth = 0.55 * (6.0 - z); // stay inside the horizontal field of view
        e.position = {uniform(-halfWidth, halfWidth), 0.0, z};
        e.rotation = glm::angleAxis(uniform(0.0, 6.283185307179586), glm::dvec3(0.0, 1.0, 0.0));
        s.entities.push_back(e);
    }
    return s;
}

/// CPU time of the whole process, every thread (lavapipe's rasteriser threads and TBB's workers
/// included): on a shared machine wall-clock ms move with the neighbours' load, CPU ms much less.
double processCpuMs() {
    timespec ts{};
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return double(ts.tv_sec) * 1e3 + double(ts.tv_nsec) * 1e-6;
}

struct Row {
    int entities = 0;
    int visible = 0;
    std::string variant;
    double vkDrawMs = 0, vkReadbackMs = 0, refMs = 0;
    double vkCpuMs = 0, refCpuMs = 0; ///< process CPU time (all threads): work, whatever the load
    std::uint64_t fragments = 0, kernelFragments = 0, fetches = 0;
    std::size_t differing = 0, drawn = 0;
    double vkFrameMs() const { return vkDrawMs + vkReadbackMs; }
    double ratio() const { return vkFrameMs() > 0 ? refMs / vkFrameMs() : 0.0; }
    double stepsPerFragment() const {
        return kernelFragments ? double(fetches) / double(kernelFragments) : 0.0;
    }
};

/// The CSV (--out): one line per column, header and rows alike.
std::vector<CsvColumn<Row>> csvColumns() {
    // clang-format off
    return {
        {"entities",               [](const Row& r) { return r.entities; }},
        {"visible",                [](const Row& r) { return r.visible; }},
        {"variant",                [](const Row& r) { return r.variant; }},
        {"vk_draw_ms",             [](const Row& r) { return r.vkDrawMs; }},
        {"vk_readback_ms",         [](const Row& r) { return r.vkReadbackMs; }},
        {"vk_frame_ms",            [](const Row& r) { return r.vkFrameMs(); }},
        {"reference_ms",           [](const Row& r) { return r.refMs; }},
        {"reference_over_vk",      [](const Row& r) { return r.ratio(); }},
        {"vk_cpu_ms",              [](const Row& r) { return r.vkCpuMs; }},
        {"reference_cpu_ms",       [](const Row& r) { return r.refCpuMs; }},
        {"fragments_shaded",       [](const Row& r) { return r.fragments; }},
        {"kernel_fragments",       [](const Row& r) { return r.kernelFragments; }},
        {"dda_steps_per_fragment", [](const Row& r) { return r.stepsPerFragment(); }},
        {"differing_pixels",       [](const Row& r) { return r.differing; }},
        {"drawn_pixels",           [](const Row& r) { return r.drawn; }},
    };
    // clang-format on
}

struct Variant {
    const char* name;
    NearOptions options;
};

/// One variant on one frame: the counting run, the warm-ups, then the timed repeats of the
/// Vulkan draw and the CPU reference side by side; the error columns against `reference`.
Row measureVariant(NearRenderer& near, const Scene& scene, const CameraFrame& cam,
                   const std::vector<SpriteSetup>& sprites, const Image& reference,
                   const Variant& v, const BenchArgs& a) {
    Row row;
    row.variant = v.name;
    // Steps and fragments come from the counting shader, in a run of its own (its atomics would
    // distort the timed runs).
    NearOptions counting = v.options;
    counting.countSteps = true;
    NearStats cs;
    const Image counted =
        near.render(cam, scene.models, sprites, scene.render.background, counting, &cs);
    row.kernelFragments = cs.kernelFragments;
    row.fetches = cs.voxelFetches;
    for (int w = 0; w < a.warmup; ++w)
        near.render(cam, scene.models, sprites, scene.render.background, v.options);
    std::vector<double> draw, readback, ref, vkCpu, refCpu;
    Image img;
    for (int r = 0; r < a.repeats; ++r) {
        NearStats ns;
        GpuFrameReport report;
        const double c0 = processCpuMs();
        img = near.render(cam, scene.models, sprites, scene.render.background, v.options, &ns,
                          &report);
        vkCpu.push_back(processCpuMs() - c0);
        // The device's own time of the draw where it has timestamps, else the host's wait.
        // (The per-pixel sprites are drawn, or traced in compute: NearOptions::pixels.)
        const std::optional<double> device =
            ns.pixelsInCompute ? report.ms("near_trace") : report.ms("near_draw");
        draw.push_back(device.value_or(report.host.waitMs));
        readback.push_back(report.host.readbackMs + report.ms("copy_planes").value_or(0.0) +
                           report.ms("readback_copy").value_or(0.0));
        row.fragments = ns.fragmentInvocations;
        Image cpu(cam.width, cam.height, scene.render.background);
        ReferenceStats rs;
        const double c1 = processCpuMs();
        renderReference(scene.models, sprites, cpu, &rs);
        refCpu.push_back(processCpuMs() - c1);
        ref.push_back(rs.milliseconds);
    }
    row.vkDrawMs = median(draw);
    row.vkReadbackMs = median(readback);
    row.refMs = median(ref);
    row.vkCpuMs = median(vkCpu);
    row.refCpuMs = median(refCpu);
    row.differing = diffImages(img, reference).pixelDiffs;
    if (diffImages(counted, img).pixelDiffs != 0)
        throw InputError("", "bench", "the step-counting shader drew a different image (a bug)");
    for (auto id : img.id) row.drawn += id != kernel::VT_NO_ENTITY;
    return row;
}

void run(const BenchArgs& a) {
    const glm::ivec2 size = *readImageSize(a.size);
    const int width = size.x, height = size.y;
    CsvWriter<Row> csv(csvColumns());
    if (!a.out.empty()) csv.open(a.out);

    const BenchModels models = benchModels(a);
    NearRenderer near; // validation follows VOXTIER_VALIDATION (off for honest timings)
    std::printf("Vulkan device: %s%s; CPU reference: TBB; %dx%d, %d repeats (median), %d warm-up\n",
                near.deviceName().c_str(),
                near.validationEnabled() ? " (validation ON: timings inflated)" : "", width, height,
                a.repeats, a.warmup);
    std::printf("%8s %7s %-16s %8s %7s %8s %8s %6s %8s %8s %6s %10s %10s %7s %8s\n", "entities",
                "visible", "variant", "vk_draw", "vk_read", "vk_frame", "ref_ms", "ref/vk",
                "vk_cpu", "ref_cpu", "cpu_r", "fragments", "kernel_frg", "steps/f", "mismatch");

    auto variant = [](const char* name, NearProxy proxy, NearDraws draws) {
        NearOptions o;
        o.pixels = NearPixels::Raster;
        o.proxy = proxy;
        o.draws = draws;
        return Variant{name, o};
    };
    // The GPUs' default first (per-pixel sprites traced in compute; NearPixels::Auto draws them
    // on a CPU device), then the draw (hull proxy, one instanced draw), then one change of the
    // draw at a time.
    NearOptions compute;
    compute.pixels = NearPixels::Compute;
    std::vector<Variant> variants = {
        Variant{"compute", compute},
        variant("hull-instanced", NearProxy::Hull, NearDraws::Instanced)};
    if (a.alternatives) {
        variants.push_back(variant("hull-per-entity", NearProxy::Hull, NearDraws::PerEntity));
        variants.push_back(variant("quad-instanced", NearProxy::Quad, NearDraws::Instanced));
        variants.push_back(variant("box-instanced", NearProxy::Box, NearDraws::Instanced));
    }

    for (int n : a.entities) {
        const Scene scene = benchScene(models, n, width, height);
        const CameraFrame cam = makeCameraFrame(scene.camera);
        const std::vector<SpriteSetup> sprites = setupSprites(scene, cam, 0.0);
        int visible = 0;
        for (const auto& s : sprites) visible += s.visible();

        // The reference image of this frame (also the ground truth for the error columns).
        Image reference(cam.width, cam.height, scene.render.background);
        renderReference(scene.models, sprites, reference);

        for (const Variant& v : variants) {
            Row row = measureVariant(near, scene, cam, sprites, reference, v, a);
            row.entities = n;
            row.visible = visible;
            std::printf(
                "%8d %7d %-16s %8.1f %7.1f %8.1f %8.1f %6.2f %8.1f %8.1f %6.2f %10llu %10llu "
                "%7.2f %8zu\n",
                row.entities, row.visible, row.variant.c_str(), row.vkDrawMs, row.vkReadbackMs,
                row.vkFrameMs(), row.refMs, row.ratio(), row.vkCpuMs, row.refCpuMs,
                row.vkCpuMs > 0 ? row.refCpuMs / row.vkCpuMs : 0.0,
                (unsigned long long)row.fragments, (unsigned long long)row.kernelFragments,
                row.stepsPerFragment(), row.differing);
            std::fflush(stdout);
            csv.write(row);
        }
    }
    std::printf(
        "vk_draw: record + submit + wait of the draw; vk_read: copy of colour/id/depth to host + "
        "unpack;\n"
        "ref/vk = reference_ms / vk_frame_ms; vk_cpu, ref_cpu: process CPU ms (all threads) of the "
        "whole\n"
        "near render call and of the reference, cpu_r = ref_cpu / vk_cpu (robust to other load);\n"
        "fragments: pipeline statistics (FRAGMENT_SHADER_INVOCATIONS);\n"
        "kernel_frg: fragments that ran the kernel; steps/f: voxel reads (DDA steps incl. outline "
        "rays) per\n"
        "kernel fragment; mismatch: pixels differing from the reference (colour, depth or id).\n");
    if (csv) {
        csv.save();
        std::printf("-> %s\n", a.out.c_str());
    }
}

} // namespace

void addBenchNearCommand(CLI::App& bench) {
    auto args = std::make_shared<BenchArgs>();
    CLI::App* cmd = bench.add_subcommand(
        "near", "Vulkan near tier vs the CPU reference, same frames, side by side");
    cmd->add_option("--entities", args->entities, "Entity counts, comma-separated")
        ->delimiter(',')
        ->check(intIn(1, Limits::kMaxEntities))
        ->capture_default_str();
    cmd->add_option("--repeats", args->repeats,
                    "Timed frames per count and variant (median reported)")
        ->check(atLeast(1))
        ->capture_default_str();
    cmd->add_option("--warmup", args->warmup, "Untimed frames first (pipeline compile, uploads)")
        ->check(atLeast(0))
        ->capture_default_str();
    cmd->add_option("-o,--out", args->out, "Also write the table as CSV");
    cmd->add_option("--models", args->models, "vox (bundled .vox models) or procedural")
        ->type_name("TEXT")
        ->transform(oneOf(kModelSourceNames, "model source"))
        ->default_str(nameOf(kModelSourceNames, args->models));
    cmd->add_option("--vox-dir", args->voxDir, "Where the bundled models are")
        ->capture_default_str();
    cmd->add_option("--size", args->size, "Image size")
        ->type_name("WxH")
        ->check(imageSize())
        ->capture_default_str();
    cmd->add_flag("!--no-alternatives", args->alternatives,
                  "Only the default variant (hull proxy, one instanced draw)");
    cmd->callback([args] { run(*args); });
}

} // namespace voxtier::cli
