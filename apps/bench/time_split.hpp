#pragma once
// "Where the time goes" in the bench report: each mode's warm frame split into its time steps,
// and the frames drawn on Vulkan split into the host's part and the device's passes, every
// column a figure of the frame figure table (compose/frame_figures.hpp) under its own name.
#include "apps/bench/suite.hpp"

#include <nlohmann/json.hpp>

namespace voxtier::bench {

/// The template's context of the tables: "time_steps" and "time_split" (every mode of every
/// scene), "device_steps" and "device_split" (the modes that drew a tier on Vulkan), each of the
/// warm frame; "motion_time_split" and "motion_device_split" the same columns for the frames in
/// motion (means; the modes timed in motion).
nlohmann::json timeSplitContext(const SuiteResults& results);

} // namespace voxtier::bench
