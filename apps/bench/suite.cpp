// `voxtier bench`: the measurement side (apps/bench/suite.hpp says how it measures).
#include "apps/bench/suite.hpp"

#include "apps/bench/harness.hpp"
#include "apps/bench/machine.hpp"
#include "apps/bench/presets.hpp"
#include "apps/bench/scene_edits.hpp"
#include "apps/bench/sets.hpp"
#include "core/error.hpp"
#include "core/scene_loader.hpp"
#include "volumetric/near_renderer.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <map>
#include <memory>
#include <numeric>
#include <thread>
#include <unistd.h>

namespace voxtier::bench {

using cli::median;
using cli::parseList;
using cli::quantile;

namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;
using nlohmann::json;

double secondsSince(Clock::time_point t0) {
    return std::chrono::duration<double>(Clock::now() - t0).count();
}

// ---------------------------------------------------------------------------------------------
// Progress: one line on stderr, rewritten in place on a terminal, a line every few seconds
// otherwise (logs and tests).

class Progress {
  public:
    explicit Progress(std::size_t total)
        : total_(std::max<std::size_t>(total, 1)), t0_(Clock::now()), tty_(isatty(2)) {}
    void step(const std::string& what) {
        ++done_;
        const double t = secondsSince(t0_);
        if (!tty_ && t - lastPrint_ < 5.0 && done_ < total_) return;
        lastPrint_ = t;
        const int pct = int(100.0 * double(done_) / double(total_));
        std::fprintf(stderr, "%s[%3d%%] %5.0f s  %s%s", tty_ ? "\r\033[K" : "", std::min(pct, 100),
                     t, what.c_str(), tty_ ? "" : "\n");
        std::fflush(stderr);
    }
    /// Counts `n` steps as done without a line: work planned but not needed.
    void skip(std::size_t n) { done_ += n; }
    void finish() {
        if (tty_) std::fprintf(stderr, "\n");
    }

  private:
    std::size_t total_, done_ = 0;
    Clock::time_point t0_;
    bool tty_;
    double lastPrint_ = -1e9;
};

// ---------------------------------------------------------------------------------------------
// Measuring.

/// How a configuration renders, warm re-render and in motion alike: the plan's base options with
/// what its mode's line in kBenchModes sets (its near backend, its far backend unless Auto, the
/// per-pixel rate for the per-pixel rows), on the run's one Vulkan device.
FrameOptions frameOptions(const Config& c, const Plan& plan,
                          const std::shared_ptr<NearRenderer>& near) {
    FrameOptions o = plan.frame;
    o.sharedNear = near;
    o.nearBackend = info(c.mode).nearBackend;
    if (info(c.mode).farBackend != FarBackend::Auto) o.farBackend = info(c.mode).farBackend;
    if (info(c.mode).perPixel) o.nearRate = NearRate::Fragment;
    return o;
}

/// The device frame (issue 35): the set's frames drawn again, `set.repeats` passes, each timed
/// without reading the image back (FrameOptions::readBack): set-up, selection, recording and
/// the device's work, what a frame shown on the GPU costs (FrameStats::totalMs). Only a frame
/// drawn wholly on Vulkan can skip its readback; whether one was is seen in its result (an
/// empty image), since which tier draws what depends on the frame. Left empty where a frame
/// came back read (a CPU tier drew part of it): the first such frame ends the measurement.
void timeDeviceFrames(Config& c, const Set& set, Progress& progress) {
    const std::size_t frames = set.frames.size(), steps = frames * std::size_t(set.repeats);
    c.deviceMs.clear();
    if (info(c.mode).renderMode == RenderMode::Reference) {
        progress.skip(steps);
        return;
    }
    std::vector<std::vector<double>> ms(frames);
    c.renderer->options().readBack = false;
    bool readBack = false;
    std::size_t done = 0;
    for (int pass = 0; pass < set.repeats && !readBack; ++pass) {
        c.renderer->selector().reset(); // a pass is the path from its start
        for (std::size_t fi = 0; fi < frames && !readBack; ++fi) {
            progress.step(set.label + ": " + c.name + ", device frame " +
                          std::to_string(set.frames[fi]) + ", pass " + std::to_string(pass + 1));
            const FrameResult r =
                c.renderer->render(set.times[fi], info(c.mode).renderMode, set.frames[fi]);
            readBack = r.image.pixelCount() > 0;
            ms[fi].push_back(r.stats.totalMs);
            ++done;
        }
    }
    progress.skip(steps - done);
    c.renderer->options().readBack = true;
    if (!readBack) c.deviceMs = std::move(ms);
}

void runSet(Set& set, const Plan& plan, const std::shared_ptr<NearRenderer>& near,
            Progress& progress) {
    const std::size_t F = set.frames.size();
    for (auto& c : set.configs) {
        c->renderer = std::make_unique<FrameRenderer>(c->scene, frameOptions(*c, plan, near));
        c->samples.assign(F, {});
        c->errors.assign(F, {});
        c->hasError.assign(F, 0);
        c->countedSteps.assign(F, 0);
        c->countedFragments.assign(F, 0);
    }
    const int passes = plan.warmup + set.repeats;
    std::size_t truths = 0;
    while (truths < set.configs.size() && set.configs[truths]->isTruth) ++truths;
    for (int pass = 0; pass < passes; ++pass) {
        // Truths first (their images are compared with in the last pass), the others rotated by
        // one place per pass, so no configuration always runs right after the same neighbour.
        std::vector<std::size_t> order;
        for (std::size_t i = 0; i < set.configs.size(); ++i)
            order.push_back(i < truths ? i
                                       : truths + (i - truths + std::size_t(pass)) %
                                                      (set.configs.size() - truths));
        const bool timed = pass >= plan.warmup, last = pass == passes - 1;
        for (auto& c : set.configs)
            c->renderer->selector().reset(); // a pass is the path from its start
        for (std::size_t fi = 0; fi < F; ++fi) {
            std::vector<Image> truthImages(set.configs.size());
            for (const std::size_t ci : order) {
                Config& c = *set.configs[ci];
                progress.step(set.label + ": " + c.name + ", frame " +
                              std::to_string(set.frames[fi]) +
                              (timed ? ", pass " + std::to_string(pass - plan.warmup + 1) + "/" +
                                           std::to_string(set.repeats)
                                     : ", warm-up"));
                FrameResult r =
                    c.renderer->render(set.times[fi], info(c.mode).renderMode, set.frames[fi]);
                if (pass == 0) {
                    if (fi == 0) c.coldFirstMs = r.stats.totalMs;
                    c.cold.far.bakes += r.stats.far.bakes;
                    c.cold.far.ensureMs += r.stats.far.ensureMs;
                    c.cold.far.raysTraced += r.stats.far.raysTraced;
                    c.cold.totalMs += r.stats.totalMs;
                }
                if (timed) c.samples[fi].push_back(r.stats);
                if (!last) continue;
                if (c.isTruth) {
                    truthImages[ci] = std::move(r.image);
                } else if (c.truth >= 0) {
                    c.errors[fi] = measureFrameError(truthImages[std::size_t(c.truth)], r.image,
                                                     r.sprites, r.plan);
                    if (r.stats.farDrawn > 0)
                        c.errors[fi].farIsolated = summarizeEntities(
                            isolatedFarErrors(c.scene,
                                              makeCameraFrame(c.scene.cameraAt(set.times[fi])),
                                              r.sprites, r.plan, c.renderer->snapshotCache()),
                            r.sprites);
                    c.hasError[fi] = 1;
                }
            }
        }
    }
    // Voxel reads of the Vulkan near tier: one more, untimed frame with the counting shader.
    for (auto& c : set.configs) {
        if (!info(c->mode).countsStepsApart) continue;
        c->renderer->options().nearCountSteps = true;
        for (std::size_t fi = 0; fi < F; ++fi) {
            progress.step(set.label + ": " + c->name + ", counting voxel steps");
            const FrameResult r =
                c->renderer->render(set.times[fi], info(c->mode).renderMode, set.frames[fi]);
            const Figures counted = figuresOf(r.stats);
            c->countedSteps[fi] = std::uint64_t(counted["voxel_steps"]);
            c->countedFragments[fi] = std::uint64_t(counted["near_kernel_fragments"]);
        }
        c->renderer->options().nearCountSteps = false;
    }
    // The scenes' own sets: the device frame beside the file frame.
    if (set.inMotion)
        for (auto& c : set.configs) timeDeviceFrames(*c, set, progress);
}

/// In motion (issue 13): the path's first plan.motionFrames frames, consecutive and in order,
/// each rendered and timed once with the bakes it causes, every configuration starting from a
/// fresh renderer (empty snapshot cache, selector from the path's start). The configurations
/// interleave frame by frame, truths first (the others' images are compared with theirs), the
/// others rotated by one place per frame.
void runMotion(Set& set, const Plan& plan, const std::shared_ptr<NearRenderer>& near,
               Progress& progress) {
    const Scene& first = set.configs.front()->scene;
    if (!first.path || plan.motionFrames <= 0) return;
    const int frames = std::min(plan.motionFrames, first.path->frameCount());
    std::size_t truths = 0;
    while (truths < set.configs.size() && set.configs[truths]->isTruth) ++truths;
    for (auto& c : set.configs) {
        c->renderer = std::make_unique<FrameRenderer>(c->scene, frameOptions(*c, plan, near));
        c->motion.clear();
    }
    const std::size_t others = set.configs.size() - truths;
    for (int f = 0; f < frames; ++f) {
        std::vector<Image> truthImages(set.configs.size());
        for (std::size_t k = 0; k < set.configs.size(); ++k) {
            const std::size_t ci = k < truths ? k : truths + (k - truths + std::size_t(f)) % others;
            Config& c = *set.configs[ci];
            progress.step(set.label + ": " + c.name + ", in motion, frame " + std::to_string(f));
            FrameResult r = c.renderer->render(c.scene.timeOfFrame(f), info(c.mode).renderMode, f);
            Config::MotionFrame m{r.stats};
            if (c.isTruth) {
                truthImages[ci] = std::move(r.image);
            } else if (c.truth >= 0) {
                const FrameErrorReport e = measureFrameError(truthImages[std::size_t(c.truth)],
                                                             r.image, r.sprites, r.plan);
                m.psnr = e.psnr;
                m.differingShare = double(e.differingPixels) / double(r.image.pixelCount());
                m.differingPixels = e.differingPixels;
            }
            c.motion.push_back(m);
        }
    }
}

/// The in-motion figures of a configuration (Measurement::motion*), after the cold start.
void addMotion(Measurement& m, const Config& c, const Config* truth, const Config* reference,
               const Plan& plan) {
    const auto timedMs = [&](const Config& of) {
        std::vector<double> ms;
        for (std::size_t f = std::size_t(plan.motionWarmup); f < of.motion.size(); ++f)
            ms.push_back(of.motion[f].stats.totalMs);
        return ms;
    };
    if (c.motion.size() <= std::size_t(plan.motionWarmup)) return;
    const std::vector<double> ms = timedMs(c);
    m.motion.ms = median(ms);
    m.motion.meanMs = std::accumulate(ms.begin(), ms.end(), 0.0) / double(ms.size());
    m.motion.p90Ms = quantile(ms, 0.9);
    m.motion.worstMs = quantile(ms, 1.0);
    if (truth) m.motion.allNearVulkanMs = median(timedMs(*truth));
    if (m.motion.ms > 0 && m.motion.allNearVulkanMs > 0)
        m.motion.speedupVsAllNearVulkan = m.motion.allNearVulkanMs / m.motion.ms;
    if (reference && reference->motion.size() > std::size_t(plan.motionWarmup))
        m.motion.allNearReferenceMs = median(timedMs(*reference));
    if (m.motion.ms > 0 && m.motion.allNearReferenceMs > 0)
        m.motion.speedupVsAllNearReference = m.motion.allNearReferenceMs / m.motion.ms;
    m.motion.fastestExactMs = m.motion.allNearReferenceMs > 0 && m.motion.allNearVulkanMs > 0
                                  ? std::min(m.motion.allNearReferenceMs, m.motion.allNearVulkanMs)
                                  : std::max(m.motion.allNearReferenceMs, m.motion.allNearVulkanMs);
    if (m.motion.ms > 0 && m.motion.fastestExactMs > 0)
        m.motion.speedupVsFastestExact = m.motion.fastestExactMs / m.motion.ms;
    m.motion.psnrMin = std::numeric_limits<double>::infinity();
    double timed = 0;
    std::vector<Figures> timedFigures; // InMotion::split's
    for (std::size_t f = 0; f < c.motion.size(); ++f) {
        const Config::MotionFrame& mf = c.motion[f];
        m.motion.predictedWorstVpx = std::max(m.motion.predictedWorstVpx, mf.stats.plan.worstVpx);
        m.motion.cacheBytes = std::max(m.motion.cacheBytes, double(mf.stats.cacheBytes));
        if (mf.psnr < m.motion.psnrMin) {
            m.motion.psnrMin = mf.psnr;
            m.motion.psnrMinShare = mf.differingShare;
            m.motion.psnrMinDifferingPixels = double(mf.differingPixels);
            m.motion.psnrMinFarEntities = double(mf.stats.farDrawn);
        }
        if (f < std::size_t(plan.motionWarmup)) {
            m.motion.coldMs += mf.stats.totalMs / plan.motionWarmup;
            continue;
        }
        ++timed;
        timedFigures.push_back(figuresOf(mf.stats));
        m.motion.bakes += double(mf.stats.far.bakes);
        m.motion.bakeMs += mf.stats.far.ensureMs;
        m.motion.nearMs += mf.stats.nearMs;
        m.motion.nearEntities += mf.stats.nearDrawn;
        m.motion.farEntities += mf.stats.farDrawn;
        m.motion.differingShare += mf.differingShare;
    }
    m.motion.split = acrossFrames(timedFigures);
    m.motion.bakes /= timed, m.motion.bakeMs /= timed, m.motion.differingShare /= timed;
    m.motion.nearMs /= timed, m.motion.nearEntities /= timed, m.motion.farEntities /= timed;
    if (c.isTruth) m.motion.psnrMin = 0;
}

/// Each sampled frame's figures: the medians over the timed passes, with the voxel reads of
/// the counting frame where the mode counts them apart.
std::vector<Figures> frameMedians(const Config& c) {
    std::vector<Figures> out;
    for (std::size_t fi = 0; fi < c.samples.size(); ++fi) {
        Figures s = medianOf(c.samples[fi]);
        if (info(c.mode).countsStepsApart) {
            s["voxel_steps"] = double(c.countedSteps[fi]);
            s["near_kernel_fragments"] = double(c.countedFragments[fi]);
        }
        out.push_back(s);
    }
    return out;
}

/// Voxel steps, blit pixels and memcpy pixels per second, from the path's figures.
void addThroughput(Measurement& m) {
    const Figures& f = m.figures;
    const double steps = f["voxel_steps"];
    // On Vulkan the reads are the draw's (the counting shader's), over the device's own time of
    // the draw where it has timestamps; on the CPU reference, over the near tier's time.
    const double gpuDrawMs = f["gpu_draw_ms"];
    const double stepMs = info(m.mode).countsStepsApart && gpuDrawMs > 0 ? gpuDrawMs : f["near_ms"];
    if (stepMs > 0 && steps > 0) m.voxelStepsPerS = steps / stepMs * 1e3;
    const double blitPx = f["blit_pixels"], blitMs = f["far_blit_ms"];
    if (blitMs > 0 && blitPx > 0) {
        m.blitPixelsPerS = blitPx / blitMs * 1e3;
        const double ms = memcpyMs(std::size_t(blitPx * kBlitBytesPerPixel));
        if (ms > 0) m.memcpyPixelsPerS = blitPx / ms * 1e3;
    }
}

/// The errors of the frames (FrameRow::error) as means and worsts over the path.
void addErrors(Measurement& m) {
    double psnrMin = std::numeric_limits<double>::infinity();
    int errorFrames = 0, farFrames = 0;
    for (const FrameRow& fr : m.frames) {
        if (!fr.hasError) continue;
        const FrameErrorReport& e = fr.error;
        ++errorFrames;
        m.error.mismatchMean += e.all.meanMismatch;
        m.error.coverageMismatchMean += e.all.meanCoverageMismatch;
        m.error.farAloneEntities += double(e.farIsolated.entities);
        m.error.farDisplacedOver1Vpx += double(e.farIsolated.overOneCell);
        m.error.mismatchWorst = std::max(m.error.mismatchWorst, e.all.worstMismatch);
        if (e.far.entities) {
            ++farFrames;
            m.error.farMismatchMean += e.far.meanMismatch;
            m.error.farAloneMismatchMean += e.farIsolated.meanMismatch;
        }
        m.error.farVisibleDisplacementWorstPx =
            std::max(m.error.farVisibleDisplacementWorstPx, e.far.worstDisplacementPx);
        m.error.farDisplacementWorstPx =
            std::max(m.error.farDisplacementWorstPx, e.farIsolated.worstDisplacementPx);
        m.error.farDisplacementWorstVpx =
            std::max(m.error.farDisplacementWorstVpx, e.farIsolated.worstDisplacementCells);
        m.error.rmseMean += e.rmse;
        psnrMin = std::min(psnrMin, e.psnr);
        m.error.differingPixels += double(e.differingPixels);
        m.error.missingEntities += e.all.missing;
    }
    if (!errorFrames) return;
    m.hasError = true;
    m.error.mismatchMean /= errorFrames;
    m.error.coverageMismatchMean /= errorFrames;
    m.error.farAloneEntities /= errorFrames;
    m.error.farDisplacedOver1Vpx /= errorFrames;
    m.error.rmseMean /= errorFrames;
    m.error.differingPixels /= errorFrames;
    m.error.psnrMin = psnrMin;
    if (farFrames) m.error.farMismatchMean /= farFrames, m.error.farAloneMismatchMean /= farFrames;
}

/// The configuration of `mode` in `set` at `c`'s sigma (the baselines a measurement is set
/// against), or null.
const Config* sameSigma(const Set& set, const Config& c, BenchMode mode) {
    for (const auto& other : set.configs)
        if (other->mode == mode && other->scene.render.sigma == c.scene.render.sigma)
            return other.get();
    return nullptr;
}

Measurement aggregate(const Set& set, const Row& row, const Plan& plan) {
    const Config& c = *set.configs[std::size_t(row.config)];
    Measurement m = row.meta;
    const Config* truth = c.isTruth      ? &c
                          : c.truth >= 0 ? set.configs[std::size_t(c.truth)].get()
                                         : nullptr;
    m.selector = selectorSummary(c.scene);
    m.truth = c.isTruth ? "itself" : c.truth >= 0 ? set.configs[std::size_t(c.truth)]->name : "";
    const std::vector<Figures> medians = frameMedians(c);
    for (std::size_t fi = 0; fi < medians.size(); ++fi) {
        FrameRow fr;
        fr.frame = set.frames[fi];
        fr.time = set.times[fi];
        fr.median = medians[fi];
        fr.minMs = 1e300;
        for (const FrameStats& s : c.samples[fi])
            fr.minMs = std::min(fr.minMs, s.totalMs), fr.maxMs = std::max(fr.maxMs, s.totalMs);
        fr.hasError = c.hasError[fi];
        fr.error = c.errors[fi];
        m.worstFrameMs = std::max(m.worstFrameMs, fr.median["frame_ms"]);
        m.frames.push_back(fr);
    }
    m.figures = acrossFrames(medians);
    m.visible = m.figures["entities"] - m.figures["culled"];
    const auto pathOf = [](const Config& of) { return acrossFrames(frameMedians(of)); };
    const auto ratio = [](double baseline, double ms) { return ms > 0 ? baseline / ms : 0.0; };
    if (truth) {
        const Figures t = pathOf(*truth);
        m.allNearVulkanMs = t["frame_ms"];
        m.allNearVulkanFragments = t["near_fragments"];
    }
    m.speedupVsAllNearVulkan = ratio(m.allNearVulkanMs, m.frameMs());
    if (const Config* fragment = sameSigma(set, c, BenchMode::NearVulkanFragment))
        m.nearVulkanFragmentMs = pathOf(*fragment)["frame_ms"];
    m.speedupVsNearVulkanFragment = ratio(m.nearVulkanFragmentMs, m.frameMs());
    // The fastest exact path: the faster of all-near on Vulkan and on the CPU reference, where
    // both were measured at this sigma (the sigma sweep's truths are on Vulkan alone), as in
    // motion (addMotion).
    const Config* reference = sameSigma(set, c, BenchMode::NearReference);
    m.fastestExact = truth ? toString(BenchMode::NearVulkan) : "";
    m.fastestExactMs = m.allNearVulkanMs;
    if (reference) {
        const double referenceMs = pathOf(*reference)["frame_ms"];
        if (m.fastestExactMs <= 0 || referenceMs < m.fastestExactMs)
            m.fastestExact = toString(BenchMode::NearReference), m.fastestExactMs = referenceMs;
    }
    m.speedupVsFastestExact = ratio(m.fastestExactMs, m.frameMs());
    if (!c.deviceMs.empty()) {
        for (const std::vector<double>& passes : c.deviceMs) m.deviceFrameMs += median(passes);
        m.deviceFrameMs /= double(c.deviceMs.size());
    }
    addThroughput(m);
    addErrors(m);
    addMotion(m, c, truth, reference, plan);
    const RenderMode renderMode = info(c.mode).renderMode;
    m.nearBackend = renderMode == RenderMode::Reference ? "reference"
                    : renderMode == RenderMode::Near    ? "vulkan"
                                                        : toString(c.renderer->nearBackend());
    if (renderMode == RenderMode::Hybrid || renderMode == RenderMode::Far) {
        m.farBackend = toString(c.renderer->farBackend());
        m.snapshotScale = c.scene.selector.snapshotScale;
    }
    // The all-near frames drawn the way this configuration draws its near tier: near fragments
    // count different things on each backend and rate (Vulkan: fragment shader invocations,
    // the CPU reference: pixels traced), so only those share a unit.
    const BenchMode sameWay = m.nearBackend == "reference" ? BenchMode::NearReference
                              : info(c.mode).perPixel      ? BenchMode::NearVulkanFragment
                                                           : BenchMode::NearVulkan;
    if (const Config* same = sameSigma(set, c, sameWay))
        m.allNearSameBackendFragments = pathOf(*same)["near_fragments"];
    m.imagePixels = double(c.scene.camera.width) * double(c.scene.camera.height);
    m.cold.firstFrameMs = c.coldFirstMs;
    m.cold.bakeMs = c.cold.far.ensureMs;
    m.cold.bakes = double(c.cold.far.bakes);
    m.cold.rays = double(c.cold.far.raysTraced);
    if (c.cold.far.ensureMs > 0 && c.cold.far.raysTraced)
        m.cold.raysPerS = double(c.cold.far.raysTraced) / c.cold.far.ensureMs * 1e3;
    return m;
}

} // namespace

const BenchModeInfo& info(BenchMode mode) {
    for (const BenchModeInfo& i : kBenchModes)
        if (i.mode == mode) return i;
    throw std::logic_error("a BenchMode without a line in kBenchModes");
}

const char* toString(BenchMode mode) {
    return info(mode).name;
}

std::string scaleName(int snapshotScale) {
    return "x" + std::to_string(snapshotScale);
}

SuiteResults runSuite(const SuiteOptions& options) {
    const auto t0 = Clock::now();
    SuiteResults res;
    res.plan = makePlan(options);
    const Plan& plan = res.plan;
    res.scenes = options.scenes;
    res.cpu = cpuName();
    res.threads = std::thread::hardware_concurrency();

    // Everything that can fail on input fails here, before anything is measured.
    std::vector<SceneSource> sources;
    for (const std::string& f : options.scenes) sources.push_back(loadSource(f));
    if (sources.empty()) throw InputError("", "SCENES", "no scene to measure");

    std::vector<Set> sets;
    for (std::size_t i = 0; i < sources.size(); ++i)
        sets.push_back(modesSet(sources[i], plan, i == 0 && plan.sweeps, res.notes));
    if (plan.scaling) {
        const SceneSource& src = sources.front();
        const std::string name = sceneName(src.file);
        bool ok = true;
        for (int n : plan.entityCounts) {
            const auto doc = withEntityCount(src.doc, n);
            if (!doc) {
                res.notes.push_back("Entity-count curve skipped: " + name +
                                    " has no crowd to resize.");
                ok = false;
                break;
            }
            sets.push_back(scalingSet(src, *doc, plan, "scaling_entities", n,
                                      std::to_string(n) + " entities"));
        }
        (void)ok;
        for (int side : plan.modelSides) {
            const auto counted = withEntityCount(src.doc, plan.sizeEntities);
            const auto doc = withTankSide(counted ? *counted : src.doc, side);
            if (!doc) {
                res.notes.push_back("Model-size curve skipped: " + name +
                                    " has no tank generator to resize.");
                break;
            }
            sets.push_back(scalingSet(src, *doc, plan, "scaling_size", side,
                                      std::to_string(side) + "x" + std::to_string(side) + "x" +
                                          std::to_string(std::max(8, side / 2)) + " tanks"));
        }
    }

    std::size_t total = 0;
    for (const Set& s : sets) {
        std::size_t counting = 0; // configurations with an extra step-counting frame
        for (const auto& c : s.configs) counting += info(c->mode).countsStepsApart;
        total +=
            s.frames.size() * (std::size_t(plan.warmup + s.repeats) * s.configs.size() + counting);
        if (s.inMotion) // the in-motion run and the device frames (or their skip)
            total += (std::size_t(plan.motionFrames) + s.frames.size() * std::size_t(s.repeats)) *
                     s.configs.size();
    }
    // One Vulkan device for the whole run; validation (VOXTIER_VALIDATION=1) inflates timings.
    auto near = std::make_shared<NearRenderer>();
    res.vulkanDevice = near->deviceName();
    if (near->validationEnabled())
        res.notes.push_back("Vulkan validation was ON: every Vulkan timing is inflated.");
    Progress progress(total);
    for (Set& set : sets) {
        runSet(set, plan, near, progress);
        if (set.inMotion) runMotion(set, plan, near, progress);
        for (const Row& row : set.rows) res.rows.push_back(aggregate(set, row, plan));
        set.configs.clear(); // frees the caches and images of this set
    }
    progress.finish();
    res.notes.push_back(fixedFrameCost(*near, sources.front().scene));
    constexpr std::size_t kBig = std::size_t(64) << 20;
    res.memcpyGBps = double(kBig) / (memcpyMs(kBig) * 1e-3) / 1e9;
    res.wallSeconds = secondsSince(t0);
    return res;
}

} // namespace voxtier::bench
