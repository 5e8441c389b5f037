// Error metrics of CONTRACT.md §8. The distance transform follows Felzenszwalb & Huttenlocher,
// "Distance Transforms of Sampled Functions" (Theory of Computing 8, 2012): a 1D lower
// envelope of parabolas per row, then per column, exact and linear in the pixel count.
#include "compose/error_metrics.hpp"

#include "core/color_compare.hpp"
#include "core/sprite_kernel.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <unordered_map>

namespace voxtier {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

/// 1D squared distance transform of f (values may be +inf) into d.
void dt1d(const double* f, int n, double* d, int* v, double* z) {
    int k = -1;
    for (int q = 0; q < n; ++q) {
        if (f[q] == kInf) continue;
        if (k < 0) {
            k = 0;
            v[0] = q;
            z[0] = -kInf;
            z[1] = kInf;
            continue;
        }
        // Pop parabolas hidden by the new one; z[0] = -inf stops the loop at k = 0.
        double s = 0.0;
        while (true) {
            const int p = v[k];
            s = ((f[q] + double(q) * q) - (f[p] + double(p) * p)) / (2.0 * (q - p));
            if (s > z[k]) break;
            --k;
        }
        ++k;
        v[k] = q;
        z[k] = s;
        z[k + 1] = kInf;
    }
    if (k < 0) {
        std::fill(d, d + n, kInf);
        return;
    }
    int j = 0;
    for (int q = 0; q < n; ++q) {
        while (z[j + 1] < q) ++j;
        const double dq = q - v[j];
        d[q] = dq * dq + f[v[j]];
    }
}

struct Box {
    int x0 = std::numeric_limits<int>::max(), y0 = std::numeric_limits<int>::max(), x1 = -1,
        y1 = -1;
    void add(int x, int y) {
        x0 = std::min(x0, x), y0 = std::min(y0, y), x1 = std::max(x1, x), y1 = std::max(y1, y);
    }
    bool empty() const { return x1 < x0; }
};

/// Silhouette displacement within a box: max over pixels owned by exactly one image of the
/// distance to the other image's footprint.
double displacement(const Image& a, const Image& b, std::uint32_t e, const Box& box) {
    const int w = box.x1 - box.x0 + 1, h = box.y1 - box.y0 + 1;
    std::vector<std::uint8_t> ma(std::size_t(w) * std::size_t(h)), mb(ma.size());
    bool anyA = false, anyB = false;
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const std::size_t p = a.index(box.x0 + x, box.y0 + y);
            ma[std::size_t(y * w + x)] = a.id[p] == e;
            mb[std::size_t(y * w + x)] = b.id[p] == e;
            anyA |= a.id[p] == e;
            anyB |= b.id[p] == e;
        }
    if (anyA != anyB) return kInf;
    if (!anyA) return 0.0;
    const auto da = squaredDistanceTransform(ma, w, h), db = squaredDistanceTransform(mb, w, h);
    double worst = 0.0;
    for (std::size_t i = 0; i < ma.size(); ++i) {
        if (ma[i] && !mb[i]) worst = std::max(worst, db[i]);
        if (mb[i] && !ma[i]) worst = std::max(worst, da[i]);
    }
    return std::sqrt(worst);
}

} // namespace

std::vector<double> squaredDistanceTransform(const std::vector<std::uint8_t>& mask, int w, int h) {
    std::vector<double> g(mask.size());
    for (std::size_t i = 0; i < mask.size(); ++i) g[i] = mask[i] ? 0.0 : kInf;
    const std::size_t n = std::size_t(std::max(w, h));
    std::vector<double> f(n), d(n), z(n + 1);
    std::vector<int> v(n);
    for (int x = 0; x < w; ++x) { // columns
        for (int y = 0; y < h; ++y) f[std::size_t(y)] = g[std::size_t(y * w + x)];
        dt1d(f.data(), h, d.data(), v.data(), z.data());
        for (int y = 0; y < h; ++y) g[std::size_t(y * w + x)] = d[std::size_t(y)];
    }
    for (int y = 0; y < h; ++y) { // rows
        dt1d(&g[std::size_t(y * w)], w, d.data(), v.data(), z.data());
        std::copy(d.begin(), d.begin() + w, g.begin() + std::ptrdiff_t(y * w));
    }
    return g;
}

std::vector<EntityError> entityErrors(const Image& truth, const Image& test,
                                      const std::vector<std::uint32_t>& entities,
                                      std::optional<glm::ivec4> rect) {
    const glm::ivec4 r = rect.value_or(glm::ivec4(0, 0, truth.width, truth.height));
    std::unordered_map<std::uint32_t, std::size_t> slot;
    std::vector<EntityError> out(entities.size());
    std::vector<Box> boxes(entities.size());
    for (std::size_t i = 0; i < entities.size(); ++i) {
        slot[entities[i]] = i;
        out[i].entity = entities[i];
    }
    for (int y = std::max(0, r.y); y < std::min(truth.height, r.w); ++y)
        for (int x = std::max(0, r.x); x < std::min(truth.width, r.z); ++x) {
            const std::size_t p = truth.index(x, y);
            const std::uint32_t a = truth.id[p], b = test.id[p];
            auto visit = [&](std::uint32_t e) {
                const auto it = slot.find(e);
                if (it == slot.end()) return;
                EntityError& r = out[it->second];
                const bool inA = a == e, inB = b == e;
                r.footprintTruth += inA;
                r.footprintTest += inB;
                ++r.unionPixels;
                if (inA != inB || truth.color[p] != test.color[p]) ++r.mismatched;
                r.coverageMismatched += inA != inB;
                boxes[it->second].add(x, y);
            };
            if (a != kernel::VT_NO_ENTITY) visit(a);
            if (b != kernel::VT_NO_ENTITY && b != a) visit(b);
        }
    std::vector<EntityError> present;
    for (std::size_t i = 0; i < out.size(); ++i) {
        if (boxes[i].empty()) continue;
        out[i].silhouetteDisplacementPx = displacement(truth, test, out[i].entity, boxes[i]);
        present.push_back(out[i]);
    }
    return present;
}

EntityError entityError(const Image& truth, const Image& test, std::uint32_t entity) {
    const auto v = entityErrors(truth, test, {entity});
    if (v.empty()) {
        EntityError e;
        e.entity = entity;
        return e;
    }
    return v.front();
}

FrameError summarize(const std::vector<EntityError>& perEntity, const Image& truth,
                     const Image& test) {
    FrameError f;
    f.entities = perEntity.size();
    for (const EntityError& e : perEntity) {
        f.meanMismatch += e.mismatchFraction();
        f.meanDisplacementPx +=
            std::isfinite(e.silhouetteDisplacementPx) ? e.silhouetteDisplacementPx : 0.0;
        if (e.mismatchFraction() > f.worstMismatch) {
            f.worstMismatch = e.mismatchFraction();
            f.worstEntity = e.entity;
        }
        f.worstDisplacementPx = std::max(f.worstDisplacementPx, e.silhouetteDisplacementPx);
    }
    if (f.entities) {
        f.meanMismatch /= double(f.entities);
        f.meanDisplacementPx /= double(f.entities);
    }
    const ColorCompare c = compareColor(truth, test);
    f.rmse = c.rmse;
    f.psnr = c.psnr;
    for (std::size_t p = 0; p < truth.pixelCount(); ++p)
        f.changedPixels += truth.color[p] != test.color[p];
    return f;
}

} // namespace voxtier
