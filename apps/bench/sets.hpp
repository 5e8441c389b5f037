#pragma once
// The bench's configurations and sets (apps/bench/suite.hpp says how a set is measured): a
// configuration is a scene copy drawn in one mode by its own renderer, with what its passes
// measured; a set is the configurations run interleaved, frame by frame, and the rows
// (Measurements) read from them.
#include "apps/bench/scene_edits.hpp"
#include "apps/bench/suite.hpp"

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace voxtier::bench {

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
    /// [frame][pass]: FrameStats::totalMs of the frame drawn on the device without a readback
    /// (timeDeviceFrames); empty where not measured.
    std::vector<std::vector<double>> deviceMs;
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

/// "tank_army" for "scenes/bench/tank_army.json".
std::string sceneName(const std::string& file);
/// The selector in a few words, for the results' "selector" column.
std::string selectorSummary(const Scene& s);

/// A scene's set: every mode and, with `withSweeps`, every sweep point of the plan (hybrid).
/// The truths (all near on Vulkan, one per sigma in use) come first and are shared. Notes what
/// the bench leaves out of the scene.
Set modesSet(const SceneSource& src, const Plan& plan, bool withSweeps,
             std::vector<std::string>& notes);

/// One point of a scaling curve (`doc`, an edit of src's JSON): every mode on one frame (the
/// camera at t = 0).
Set scalingSet(const SceneSource& src, const nlohmann::json& doc, const Plan& plan,
               const std::string& group, double param, const std::string& what);

} // namespace voxtier::bench
