#pragma once
// The machine's own figures the bench sets its measurements beside: a memcpy's time (the
// bandwidth limit of the far blit), the Vulkan frame's fixed cost, the CPU's name.
#include "core/scene.hpp"
#include "volumetric/near_renderer.hpp"

#include <cstddef>
#include <string>

namespace voxtier::bench {

/// Time of a memcpy of `bytes`, split over the TBB workers like the blit (median of 5 after one
/// untimed copy): the bandwidth limit a blit of that many bytes cannot beat.
double memcpyMs(std::size_t bytes);

/// The Vulkan frame's fixed cost (no sprite: clear, one submission, readback) at the scene's
/// image size, with the three planes read back (colour, depth, ids) and with colour alone, as a
/// line for the report's notes. Interleaved, median of 21 each.
std::string fixedFrameCost(NearRenderer& near, const Scene& scene);

/// The CPU's model name ("unknown CPU" where /proc/cpuinfo does not say).
std::string cpuName();

} // namespace voxtier::bench
