#include "core/image.hpp"

#include "core/sprite_kernel.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cassert>
#include <cstring>

namespace voxtier {

Image::Image(int w, int h, Rgba8 background) : width(w), height(h) {
    clear(background);
}

void Image::clear(Rgba8 background) {
    const std::size_t n = pixelCount();
    color.resize(n);
    depth.resize(n);
    id.resize(n);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, std::size_t(1) << 15),
                      [&](const tbb::blocked_range<std::size_t>& r) {
                          std::fill(color.begin() + std::ptrdiff_t(r.begin()),
                                    color.begin() + std::ptrdiff_t(r.end()), background);
                          std::fill(depth.begin() + std::ptrdiff_t(r.begin()),
                                    depth.begin() + std::ptrdiff_t(r.end()), 0.0f);
                          std::fill(id.begin() + std::ptrdiff_t(r.begin()),
                                    id.begin() + std::ptrdiff_t(r.end()), kernel::VT_NO_ENTITY);
                      });
}

std::size_t Image::countEntity(std::uint32_t entity) const {
    return std::size_t(std::count(id.begin(), id.end(), entity));
}

ImageDiff diffImages(const Image& a, const Image& b) {
    assert(a.width == b.width && a.height == b.height);
    ImageDiff d;
    bool first = true;
    for (std::size_t i = 0; i < a.pixelCount(); ++i) {
        const bool c = a.color[i] != b.color[i];
        const bool z = std::memcmp(&a.depth[i], &b.depth[i], sizeof(float)) != 0;
        const bool e = a.id[i] != b.id[i];
        d.colorDiffs += c;
        d.depthDiffs += z;
        d.idDiffs += e;
        d.pixelDiffs += c || z || e;
        if ((c || z || e) && first) {
            first = false;
            d.firstX = i % std::size_t(a.width);
            d.firstY = i / std::size_t(a.width);
        }
    }
    return d;
}

} // namespace voxtier
