#include "core/color_compare.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>

namespace voxtier {

ColorCompare compareColor(const Image& truth, const Image& test) {
    assert(truth.width == test.width && truth.height == test.height);
    // Summed in batches of 4096 pixels, so that the running total never dwarfs one batch's.
    constexpr std::size_t kBatch = 4096;
    double total = 0.0, maxError = 0.0;
    const std::size_t n = truth.pixelCount();
    for (std::size_t begin = 0; begin < n; begin += kBatch) {
        double batch = 0.0;
        for (std::size_t i = begin; i < std::min(n, begin + kBatch); ++i) {
            if (truth.color[i] == test.color[i]) continue;
            for (int c = 0; c < 4; ++c) {
                const double e = std::abs(double(channel(truth.color[i], c)) -
                                          double(channel(test.color[i], c))) /
                                 255.0;
                batch += e * e;
                maxError = std::max(maxError, e);
            }
        }
        total += batch;
    }
    ColorCompare r;
    r.maxError = maxError;
    r.rmse = n ? std::sqrt(total / double(n * 4)) : 0.0;
    r.psnr =
        r.rmse > 0.0 ? 20.0 * std::log10(1.0 / r.rmse) : std::numeric_limits<double>::infinity();
    return r;
}

} // namespace voxtier
