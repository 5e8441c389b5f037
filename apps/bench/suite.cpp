// `voxtier bench`: the measurement side (apps/bench/suite.hpp says how it measures).
#include "apps/bench/suite.hpp"

#include "apps/bench/harness.hpp"
#include "core/error.hpp"
#include "core/scene_loader.hpp"
#include "volumetric/near_renderer.hpp"

#include <nlohmann/json.hpp>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <memory>
#include <numeric>
#include <sstream>
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

std::string fmt(double v) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%g", v);
    return buf;
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
// Configurations and sets.

struct Config {
    std::string name; ///< for the progress line and the "truth" column
    BenchMode mode = BenchMode::NearVulkan;
    bool isTruth = false;
    int truth = -1; ///< index (in the set) of the all-near image the errors are measured against
    Scene scene;    ///< this configuration's copy (the FrameRenderer keeps a reference to it)
    std::unique_ptr<FrameRenderer> renderer;
    std::vector<std::vector<FrameStats>> samples; ///< [frame][timed pass]
    FrameStats cold;
    double coldFirstMs = 0.0;
    std::vector<FrameErrorReport> errors;
    std::vector<char> hasError;
    std::vector<std::uint64_t> countedSteps, countedFragments;
    struct MotionFrame {
        FrameStats stats;
        double psnr = 0.0, differingShare = 0.0;
        std::size_t differingPixels = 0;
    };
    std::vector<MotionFrame> motion; ///< the in-motion run, frame by frame
};

struct Row {
    int config = 0;
    Measurement meta; ///< labels; the numbers are filled in from the configuration
};

struct Set {
    std::string label;
    std::vector<int> frames;
    std::vector<double> times;
    int repeats = 1;
    std::vector<std::unique_ptr<Config>> configs; ///< truths first; stable addresses
    std::vector<Row> rows;
    bool inMotion = false; ///< also the in-motion run (runMotion): the scenes' own sets
};

std::string sceneName(const std::string& file) {
    return fs::path(file).stem().string();
}

std::string selectorSummary(const Scene& s) {
    const SelectorConfig& c = s.selector;
    return std::string(toString(c.metric)) + " near_at " + fmt(c.nearAt) + " far_at " +
           fmt(c.farAt) + ", " + std::to_string(c.viewSetSize) + " views, sigma " +
           fmt(s.render.sigma) + ", fade " + std::to_string(c.crossfadeFrames) +
           (c.viewHysteresisDeg > 0 ? ", view hysteresis " + fmt(c.viewHysteresisDeg) : "");
}

/// Adds a configuration; the truth of a truth configuration is itself.
int addConfig(Set& set, const Scene& scene, BenchMode mode, const std::string& name) {
    auto c = std::make_unique<Config>();
    c->name = name;
    c->mode = mode;
    c->scene = scene;
    c->isTruth = info(mode).isTruth;
    set.configs.push_back(std::move(c));
    return int(set.configs.size()) - 1;
}

Measurement label(const std::string& group, const std::string& scene, BenchMode mode,
                  const std::string& family = "", const std::string& setting = "",
                  double param = 0.0) {
    Measurement m;
    m.group = group;
    m.scene = scene;
    m.mode = mode;
    m.family = family;
    m.setting = setting;
    m.param = param;
    return m;
}

void linkTruths(Set& set) {
    // Each approximate configuration is compared with the near_vulkan configuration of the same
    // sigma (the sprites' lattice depends on it; nothing else in a scene copy differs).
    for (auto& c : set.configs) {
        if (c->isTruth) continue;
        for (std::size_t t = 0; t < set.configs.size(); ++t)
            if (set.configs[t]->isTruth &&
                set.configs[t]->scene.render.sigma == c->scene.render.sigma) {
                c->truth = int(t);
                break;
            }
    }
    // Truths render first in every frame, so their images exist when the others are compared.
    for (std::size_t i = 0; i < set.configs.size(); ++i)
        if (!set.configs[i]->isTruth)
            for (std::size_t j = i + 1; j < set.configs.size(); ++j)
                if (set.configs[j]->isTruth)
                    throw std::logic_error("bench: truth configurations must come first");
}

std::pair<std::vector<int>, std::vector<double>> pathSamples(const Scene& s, int count) {
    std::vector<int> frames;
    if (s.path && count > 1) {
        const int n = s.path->frameCount();
        const int k = std::min(count, n);
        for (int i = 0; i < k; ++i)
            frames.push_back(k == 1 ? 0 : int(std::lround(double(i) * (n - 1) / (k - 1))));
    } else {
        frames.push_back(0);
    }
    std::vector<double> times;
    for (int f : frames) times.push_back(s.path ? s.timeOfFrame(f) : 0.0);
    return {frames, times};
}

// ---------------------------------------------------------------------------------------------
// Scenes: loading, overrides, and the JSON edits behind the scaling curves.

struct SceneSource {
    std::string file;
    json doc; ///< the file's JSON (already validated by loadScene)
    Scene scene;
};

SceneSource loadSource(const std::string& file) {
    SceneSource s;
    s.file = file;
    s.scene = loadScene(file); // validates, with the loader's one-line errors
    std::ifstream in(file);
    s.doc = json::parse(in);
    return s;
}

Scene fromJson(const SceneSource& src, const json& doc) {
    return loadSceneJson(doc, src.file, fs::path(src.file).parent_path());
}

void applyOverrides(Scene& s, const Plan& plan, bool capEntities) {
    if (plan.width) s.camera.width = *plan.width, s.camera.height = *plan.height;
    if (plan.budgetVpx) {
        SelectorConfig c = defaultSelectorFor(SelectorMetric::ErrorBudget);
        c.budgetVpx = *plan.budgetVpx;
        c.viewSetSize = s.selector.viewSetSize;
        c.viewHysteresisDeg = s.selector.viewHysteresisDeg;
        c.crossfadeFrames = s.selector.crossfadeFrames;
        c.snapshotScale = s.selector.snapshotScale;
        s.selector = c;
    }
    if (capEntities && plan.entityCap && int(s.entities.size()) > *plan.entityCap)
        s.entities.resize(std::size_t(*plan.entityCap));
}

/// The document with its crowds resized so that the scene has `total` entities (plain entities
/// kept, crowds scaled in proportion). nullopt when the scene has no crowd to resize.
std::optional<json> withEntityCount(json doc, int total) {
    if (!doc.contains("crowds") || doc["crowds"].empty()) return std::nullopt;
    const int plain = doc.contains("entities") ? int(doc["entities"].size()) : 0;
    long long crowd = 0;
    for (const json& c : doc["crowds"]) crowd += c.value("count", 0);
    if (crowd <= 0) return std::nullopt;
    const int want = std::max(0, total - plain);
    int assigned = 0;
    for (std::size_t i = 0; i < doc["crowds"].size(); ++i) {
        json& c = doc["crowds"][i];
        const bool last = i + 1 == doc["crowds"].size();
        const int n = last ? want - assigned
                           : int(std::lround(double(c.value("count", 0)) * want / double(crowd)));
        c["count"] = std::max(0, n);
        assigned += std::max(0, n);
    }
    return doc;
}

/// The document with every tank generator at `side` x `side` x `side/2` voxels, one animation
/// frame (static: the curve is about the voxel count, not about animation) and the voxel size
/// scaled so the tanks keep their size in metres. nullopt when the scene has no tank.
std::optional<json> withTankSide(json doc, int side) {
    double baseSide = 0.0;
    for (json& m : doc["models"]) {
        if (m.value("generator", "") != "tank") continue;
        if (baseSide == 0.0) baseSide = m.contains("size") ? m["size"][0].get<double>() : 32.0;
        m["size"] = {side, side, std::max(8, side / 2)};
        m["frames"] = 1;
    }
    if (baseSide == 0.0) return std::nullopt;
    doc["voxel_size"] = doc.value("voxel_size", 0.1) * baseSide / side;
    for (json& c : doc["crowds"]) c.erase("fps");
    return doc;
}

// ---------------------------------------------------------------------------------------------
// Measuring.

/// Time of a memcpy of `bytes`, split over the TBB workers like the blit (median of 5 after one
/// untimed copy): the bandwidth limit a blit of that many bytes cannot beat.
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

/// How every configuration renders, warm re-render and in motion alike: its near backend, the
/// per-pixel rate for the per-pixel rows, the plan's rate otherwise, the plan's cache directory.
FrameOptions frameOptions(const Config& c, const Plan& plan,
                          const std::shared_ptr<NearRenderer>& near) {
    FrameOptions o;
    o.sharedNear = near;
    o.nearBackend = info(c.mode).nearBackend;
    o.farBackend =
        info(c.mode).farBackend == FarBackend::Auto ? plan.farBackend : info(c.mode).farBackend;
    o.cacheDir = plan.cacheDir;
    o.cacheDirBytes = plan.cacheDirBytes;
    o.nearRate = info(c.mode).perPixel ? NearRate::Fragment : plan.nearRate;
    o.farBlit.kernel = plan.farBlit;
    o.occlusionCull = plan.occlusionCull;
    o.earlyDepthTest = plan.earlyDepthTest;
    o.costAwareBakes = plan.costBound;
    return o;
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
                    c.cold.farBakes += r.stats.farBakes;
                    c.cold.bakeMs += r.stats.bakeMs;
                    c.cold.raysTraced += r.stats.raysTraced;
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
            c->countedSteps[fi] = r.stats.voxelFetches;
            c->countedFragments[fi] = r.stats.nearKernelFragments;
        }
        c->renderer->options().nearCountSteps = false;
    }
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
    m.motionMs = median(ms);
    m.motionMeanMs = std::accumulate(ms.begin(), ms.end(), 0.0) / double(ms.size());
    m.motionP90Ms = quantile(ms, 0.9);
    m.motionWorstMs = quantile(ms, 1.0);
    if (truth) m.motionBaselineMs = median(timedMs(*truth));
    if (m.motionMs > 0 && m.motionBaselineMs > 0) m.motionSpeedup = m.motionBaselineMs / m.motionMs;
    if (reference && reference->motion.size() > std::size_t(plan.motionWarmup))
        m.motionReferenceMs = median(timedMs(*reference));
    if (m.motionMs > 0 && m.motionReferenceMs > 0)
        m.motionSpeedupVsReference = m.motionReferenceMs / m.motionMs;
    m.motionFastestExactMs = m.motionReferenceMs > 0 && m.motionBaselineMs > 0
                                 ? std::min(m.motionReferenceMs, m.motionBaselineMs)
                                 : std::max(m.motionReferenceMs, m.motionBaselineMs);
    if (m.motionMs > 0 && m.motionFastestExactMs > 0)
        m.motionSpeedupVsFastestExact = m.motionFastestExactMs / m.motionMs;
    m.motionPsnrMin = std::numeric_limits<double>::infinity();
    double timed = 0;
    for (std::size_t f = 0; f < c.motion.size(); ++f) {
        const Config::MotionFrame& mf = c.motion[f];
        m.motionPredictedWorstVpx =
            std::max(m.motionPredictedWorstVpx, mf.stats.farPredictedWorstVpx);
        m.motionCacheBytes = std::max(m.motionCacheBytes, double(mf.stats.cacheBytes));
        if (mf.psnr < m.motionPsnrMin) {
            m.motionPsnrMin = mf.psnr;
            m.motionPsnrMinShare = mf.differingShare;
            m.motionPsnrMinPixels = double(mf.differingPixels);
            m.motionPsnrMinFar = double(mf.stats.farDrawn);
        }
        if (f < std::size_t(plan.motionWarmup)) {
            m.motionColdMs += mf.stats.totalMs / plan.motionWarmup;
            continue;
        }
        ++timed;
        m.motionBakes += mf.stats.farBakes;
        m.motionBakeMs += mf.stats.bakeMs;
        m.motionNearMs += mf.stats.nearMs;
        m.motionNearEntities += mf.stats.nearDrawn;
        m.motionFarEntities += mf.stats.farDrawn;
        m.motionDifferingShare += mf.differingShare;
    }
    m.motionBakes /= timed, m.motionBakeMs /= timed, m.motionDifferingShare /= timed;
    m.motionNearMs /= timed, m.motionNearEntities /= timed, m.motionFarEntities /= timed;
    if (c.isTruth) m.motionPsnrMin = 0;
}

/// Each sampled frame's figures: the medians over the timed passes, with the voxel reads of
/// the counting frame where the mode counts them apart.
std::vector<FrameStats> frameMedians(const Config& c) {
    std::vector<FrameStats> out;
    for (std::size_t fi = 0; fi < c.samples.size(); ++fi) {
        FrameStats s = medianOf(c.samples[fi]);
        if (info(c.mode).countsStepsApart) {
            s.voxelFetches = c.countedSteps[fi];
            s.nearKernelFragments = c.countedFragments[fi];
        }
        out.push_back(s);
    }
    return out;
}

/// Voxel steps, blit pixels and memcpy pixels per second, from the path's figures.
void addThroughput(Measurement& m) {
    const PathFigures& f = m.figures;
    const double steps = f.of(&FrameStats::voxelFetches);
    // On Vulkan the reads are the draw's (the counting shader's), over the device's own time of
    // the draw where it has timestamps; on the CPU reference, over the near tier's time.
    const double gpuDrawMs = f.of(&FrameStats::gpuDrawMs);
    const double stepMs =
        info(m.mode).countsStepsApart && gpuDrawMs > 0 ? gpuDrawMs : f.of(&FrameStats::nearMs);
    if (stepMs > 0 && steps > 0) m.voxelStepsPerS = steps / stepMs * 1e3;
    const double blitPx = f.of(&FrameStats::farPixelsTested), blitMs = f.of(&FrameStats::blitMs);
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
        m.mismatchMean += e.all.meanMismatch;
        m.coverageMismatchMean += e.all.meanCoverageMismatch;
        m.farAloneEntities += double(e.farIsolated.entities);
        m.farOverOneCell += double(e.farIsolated.overOneCell);
        m.mismatchWorst = std::max(m.mismatchWorst, e.all.worstMismatch);
        if (e.far.entities) {
            ++farFrames;
            m.farMismatchMean += e.far.meanMismatch;
            m.farIsolatedMismatchMean += e.farIsolated.meanMismatch;
        }
        m.farVisibleDisplacementWorstPx =
            std::max(m.farVisibleDisplacementWorstPx, e.far.worstDisplacementPx);
        m.displacementWorstPx = std::max(m.displacementWorstPx, e.farIsolated.worstDisplacementPx);
        m.displacementWorstCells =
            std::max(m.displacementWorstCells, e.farIsolated.worstDisplacementCells);
        m.rmseMean += e.rmse;
        psnrMin = std::min(psnrMin, e.psnr);
        m.differingPixels += double(e.differingPixels);
        m.missing += e.all.missing;
    }
    if (!errorFrames) return;
    m.hasError = true;
    m.mismatchMean /= errorFrames;
    m.coverageMismatchMean /= errorFrames;
    m.farAloneEntities /= errorFrames;
    m.farOverOneCell /= errorFrames;
    m.rmseMean /= errorFrames;
    m.differingPixels /= errorFrames;
    m.psnrMin = psnrMin;
    if (farFrames) m.farMismatchMean /= farFrames, m.farIsolatedMismatchMean /= farFrames;
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
    const std::vector<FrameStats> medians = frameMedians(c);
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
        m.worstFrameMs = std::max(m.worstFrameMs, fr.median.totalMs);
        m.frames.push_back(fr);
    }
    m.figures = acrossFrames(medians);
    m.visible = m.figures.of(&FrameStats::entities) - m.figures.of(&FrameStats::culled);
    if (truth) {
        const PathFigures t = acrossFrames(frameMedians(*truth));
        m.baselineMs = t.of(&FrameStats::totalMs);
        m.baselineFragments = t.of(&FrameStats::nearPixelsTested);
    }
    if (m.frameMs() > 0 && m.baselineMs > 0) m.speedup = m.baselineMs / m.frameMs();
    if (const Config* fragment = sameSigma(set, c, BenchMode::NearVulkanFragment)) {
        m.fragmentMs = acrossFrames(frameMedians(*fragment)).of(&FrameStats::totalMs);
        if (m.frameMs() > 0 && m.fragmentMs > 0) m.speedupVsFragment = m.fragmentMs / m.frameMs();
    }
    const Config* reference = sameSigma(set, c, BenchMode::NearReference);
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
    m.coldMs = c.coldFirstMs;
    m.coldBakeMs = c.cold.bakeMs;
    m.coldBakes = c.cold.farBakes;
    m.coldRays = double(c.cold.raysTraced);
    if (c.cold.bakeMs > 0 && c.cold.raysTraced)
        m.raysPerS = double(c.cold.raysTraced) / c.cold.bakeMs * 1e3;
    return m;
}

// ---------------------------------------------------------------------------------------------
// The sets.

struct SweepPoint {
    std::string family, setting;
    double param = 0.0;
    SelectorConfig selector;
    double sigma = 1.0;
};

std::string configKey(const SelectorConfig& c, double sigma) {
    return std::string(toString(c.metric)) + "/" + fmt(c.nearAt) + "/" + fmt(c.farAt) + "/" +
           std::to_string(c.viewSetSize) + "/" + std::to_string(c.crossfadeFrames) + "/" +
           fmt(c.viewHysteresisDeg) + "/" + fmt(sigma) + "/" + fmt(c.budgetVpx) + "/" +
           std::to_string(c.ladderCap) + "/" + std::to_string(c.snapshotScale);
}

std::vector<SweepPoint> sweepPoints(const Plan& plan, const Scene& base) {
    std::vector<SweepPoint> pts;
    const SelectorConfig s0 = base.selector;
    const double sigma0 = base.render.sigma;
    auto farAt = [&](SelectorMetric metric, const std::vector<double>& values, double nearFactor) {
        for (double v : values) {
            SweepPoint p;
            p.family = std::string("far_at (") + toString(metric) + ")";
            p.selector = s0;
            p.selector.metric = metric;
            p.selector.farAt = v;
            p.selector.nearAt = v * nearFactor;
            p.sigma = sigma0;
            p.param = v;
            p.setting = std::string(toString(metric)) + " far_at=" + fmt(v) +
                        " near_at=" + fmt(v * nearFactor);
            pts.push_back(p);
        }
    };
    farAt(SelectorMetric::Distance, plan.distanceFarAt, 0.8);
    farAt(SelectorMetric::RadiusPx, plan.radiusFarAt, 1.5);
    farAt(SelectorMetric::ErrorPx, plan.errorFarAt, 2.0);
    // The error budget (issue 13): each budget with each snapshot scale (the speed–error
    // frontier, issue 29), then the ladder cap at the scene's budget.
    for (int k : plan.snapshotScales)
        for (double b : plan.budgets) {
            SweepPoint p{kBudgetFamily, "error_budget " + fmt(b) + " vpx, " + scaleName(k), b, s0,
                         sigma0};
            p.selector = defaultSelectorFor(SelectorMetric::ErrorBudget);
            p.selector.budgetVpx = b;
            p.selector.snapshotScale = k;
            pts.push_back(p);
        }
    for (int cap : plan.ladderCaps) {
        SweepPoint p{"ladder cap (error_budget)",
                     "error_budget 1 vpx, ladder cap " + std::to_string(cap), double(cap), s0,
                     sigma0};
        p.selector = defaultSelectorFor(SelectorMetric::ErrorBudget);
        p.selector.ladderCap = cap;
        pts.push_back(p);
    }
    for (int v : plan.viewSets) {
        SweepPoint p{"view set", std::to_string(v) + " views", double(v), s0, sigma0};
        p.selector.viewSetSize = v;
        pts.push_back(p);
    }
    for (double s : plan.sigmas) pts.push_back({"sigma", "sigma=" + fmt(s), s, s0, s});
    for (int n : plan.crossfades) {
        SweepPoint p{"cross-fade",
                     n ? "cross-fade " + std::to_string(n) + " frames" : "no cross-fade", double(n),
                     s0, sigma0};
        p.selector.crossfadeFrames = n;
        pts.push_back(p);
    }
    return pts;
}

/// A scene's set: every mode and, for the first scene, every sweep point (hybrid). The
/// truths (all near on Vulkan, one per sigma in use) come first and are shared.
Set modesSet(const SceneSource& src, const Plan& plan, bool withSweeps,
             std::vector<std::string>& notes) {
    Set set;
    const std::string name = sceneName(src.file);
    set.label = name;
    set.inMotion = true;
    Scene base = src.scene;
    applyOverrides(base, plan, /*capEntities=*/true);
    std::tie(set.frames, set.times) = pathSamples(base, plan.pathFrames);
    set.repeats = plan.repeats;
    if (!base.edits.empty())
        notes.push_back(name +
                        ": its scripted edits are not applied (`bench edits` measures edits).");
    const std::vector<SweepPoint> pts =
        withSweeps ? sweepPoints(plan, base) : std::vector<SweepPoint>{};

    std::map<BenchMode, int> byMode;
    auto addModes = [&](bool truths) {
        for (const BenchModeInfo& mode : kBenchModes)
            if (mode.isTruth == truths) {
                byMode[mode.mode] = addConfig(set, base, mode.mode, mode.name);
                set.rows.push_back({byMode[mode.mode], label("modes", name, mode.mode)});
            }
    };
    addModes(/*truths=*/true);
    // The sweeps change sigma: the truths of the other sigmas, all near on Vulkan too.
    std::map<double, int> truthBySigma{{base.render.sigma, byMode.at(BenchMode::NearVulkan)}};
    for (const SweepPoint& p : pts) {
        if (truthBySigma.count(p.sigma)) continue;
        Scene sc = base;
        sc.render.sigma = p.sigma;
        const int t =
            addConfig(set, sc, BenchMode::NearVulkan, "near_vulkan sigma=" + fmt(p.sigma));
        truthBySigma[p.sigma] = t;
        set.rows.push_back({t, label("sweep", name, BenchMode::NearVulkan, "sigma (all near)",
                                     "all near, sigma=" + fmt(p.sigma), p.sigma)});
    }
    addModes(/*truths=*/false);

    std::map<std::string, int> byKey{
        {configKey(base.selector, base.render.sigma), byMode.at(BenchMode::Hybrid)}};
    for (const SweepPoint& p : pts) {
        const std::string key = configKey(p.selector, p.sigma);
        if (!byKey.count(key)) {
            Scene sc = base;
            sc.selector = p.selector;
            sc.render.sigma = p.sigma;
            byKey[key] = addConfig(set, sc, BenchMode::Hybrid, "hybrid " + p.setting);
        }
        set.rows.push_back(
            {byKey[key], label("sweep", name, BenchMode::Hybrid, p.family, p.setting, p.param)});
    }
    linkTruths(set);
    return set;
}

/// One point of a scaling curve: every mode on one frame (the camera at t = 0).
Set scalingSet(const SceneSource& src, const json& doc, const Plan& plan, const std::string& group,
               double param, const std::string& what) {
    Set set;
    const std::string name = sceneName(src.file);
    set.label = name + " " + what;
    Scene s = fromJson(src, doc);
    applyOverrides(s, plan, /*capEntities=*/false);
    set.frames = {0};
    set.times = {0.0};
    set.repeats = plan.scalingRepeats;
    for (const bool truths : {true, false})
        for (const BenchModeInfo& mode : kBenchModes)
            if (mode.isTruth == truths)
                set.rows.push_back({addConfig(set, s, mode.mode, mode.name),
                                    label(group, name, mode.mode, group, what, param)});
    linkTruths(set);
    return set;
}

/// The Vulkan frame's fixed cost (no sprite: clear, one submission, readback) at the scene's
/// image size, with the three planes read back (colour, depth, ids: every frame before the far
/// pass moved to the GPU) and with colour alone (what a PNG frame drawn wholly on Vulkan reads
/// back). Interleaved, median of 21 each.
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

Plan makePlan(const SuiteOptions& o) {
    Plan p;
    p.cacheDir = o.cacheDir;
    p.cacheDirBytes = o.cacheDirBytes;
    p.nearRate = o.nearRate;
    // The same bounds as the command line's (cmd_bench.cpp), for other callers.
    if (o.budgetVpx && !(*o.budgetVpx >= 0.01 && *o.budgetVpx <= 64.0))
        throw InputError("", "--budget", "must be in [0.01, 64] virtual pixels");
    p.budgetVpx = o.budgetVpx;
    p.farBlit = o.farBlit;
    p.farBackend = o.farBackend;
    p.occlusionCull = o.occlusionCull;
    p.earlyDepthTest = o.earlyDepthTest;
    p.costBound = o.costBound;
    if (o.smoke) {
        p.preset = "smoke";
        p.repeats = 1;
        p.pathFrames = 1;
        p.width = 240, p.height = 136;
        p.entityCap = 24;
        p.errorFarAt = {1.0};
        p.entityCounts = {4, 12};
        p.modelSides = {16, 32};
        p.sizeEntities = 6;
        p.scalingRepeats = 1;
        p.motionFrames = 3, p.motionWarmup = 1;
        p.budgets = {1};
        p.snapshotScales = {1};
    } else if (o.quick) {
        p.preset = "quick";
        p.repeats = 3;
        p.pathFrames = 2;
        p.distanceFarAt = {15, 40};
        p.radiusFarAt = {24, 8};
        p.errorFarAt = {2, 1, 0.5, 0.25};
        p.budgets = {0.25, 0.5, 1, 2, 4};
        p.snapshotScales = {1, 3};
        p.ladderCaps = {4, 16};
        p.motionFrames = 16, p.motionWarmup = 4;
        p.viewSets = {26, 98};
        p.sigmas = {1, 2};
        p.crossfades = {0, 8};
        p.entityCounts = {10, 100, 1000, 10000};
        p.modelSides = {16, 32, 64, 128};
        p.sizeEntities = 300;
        p.scalingRepeats = 1;
    } else {
        p.preset = "full";
        p.repeats = 7;
        p.pathFrames = 6;
        p.distanceFarAt = {10, 20, 40, 80};
        p.radiusFarAt = {32, 16, 8, 4};
        p.errorFarAt = {4, 2, 1, 0.5, 0.25};
        p.budgets = {0.25, 0.5, 1, 2, 4};
        p.snapshotScales = {1, 2, 3, 4};
        p.ladderCaps = {4, 16, 64};
        p.viewSets = {26, 98, 218};
        p.sigmas = {0.5, 1, 2};
        p.crossfades = {0, 4, 8};
        p.entityCounts = {10, 100, 300, 1000, 3000, 10000, 30000, 100000};
        p.modelSides = {16, 32, 64, 128};
        p.sizeEntities = 500;
        p.scalingRepeats = 5;
    }
    if (o.repeats != -1) {
        if (o.repeats < 1) throw InputError("", "--repeats", "must be >= 1");
        p.repeats = o.repeats;
    }
    if (o.warmup != -1) {
        if (o.warmup < 1)
            throw InputError(
                "", "--warmup",
                "must be >= 1 (the cold bakes are measured in the first warm-up pass)");
        p.warmup = o.warmup;
    }
    if (o.pathFrames != -1) {
        if (o.pathFrames < 1) throw InputError("", "--frames", "must be >= 1");
        p.pathFrames = o.pathFrames;
    }
    if (o.motionFrames != -1) {
        if (o.motionFrames < 2) throw InputError("", "--motion-frames", "must be >= 2");
        p.motionFrames = o.motionFrames;
    }
    if (o.motionWarmup != -1) {
        if (o.motionWarmup < 1) throw InputError("", "--motion-warmup", "must be >= 1");
        p.motionWarmup = o.motionWarmup;
    }
    if (p.motionWarmup >= p.motionFrames)
        throw InputError("", "--motion-warmup",
                         "must be less than --motion-frames (" + std::to_string(p.motionFrames) +
                             "): no frame would be timed in motion");
    if (!o.size.empty()) {
        int w = 0, h = 0;
        char tail = 0;
        if (std::sscanf(o.size.c_str(), "%dx%d%c", &w, &h, &tail) != 2 || w < 1 || h < 1 ||
            w > Limits::kMaxImageDim || h > Limits::kMaxImageDim)
            throw InputError("", "--size",
                             "expected WxH with integers 1.." +
                                 std::to_string(Limits::kMaxImageDim) + ", got '" + o.size + "'");
        p.width = w, p.height = h;
    }
    if (!o.entityCounts.empty())
        p.entityCounts = parseList<int>(o.entityCounts, "--entity-counts", 1, 100000);
    if (!o.modelSides.empty())
        p.modelSides = parseList<int>(o.modelSides, "--model-sides", 8, Limits::kMaxModelDim);
    if (!o.snapshotScales.empty()) {
        p.snapshotScales.clear();
        // A scale named twice would be measured once and drawn twice.
        for (int k : parseList<int>(o.snapshotScales, "--snapshot-scales", 1, kMaxSnapshotScale))
            if (std::find(p.snapshotScales.begin(), p.snapshotScales.end(), k) ==
                p.snapshotScales.end())
                p.snapshotScales.push_back(k);
    }
    p.sweeps = o.sweeps;
    p.scaling = o.scaling;
    return p;
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
        if (s.inMotion) total += std::size_t(plan.motionFrames) * s.configs.size();
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
