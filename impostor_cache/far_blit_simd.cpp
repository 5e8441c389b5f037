// The far blit's vectorised band kernel (CONTRACT.md §4, Blit): the scalar reference of
// far_blit.cpp, N pixels of a row at once (N = 4 on SSE4, 8 on AVX2, 16 on AVX-512), compiled
// for every SIMD target Highway knows and dispatched to the best one the CPU has at run time.
//
// It writes the same bits as the reference because it performs the same IEEE operations in the
// same order on every lane: vtPixelCell's products, sums, reciprocal and floors in float (the
// project builds with -ffp-contract=off, so nothing is fused), SnapshotCellMap's affine form
// and floor in double, vtLit's integer arithmetic, and writeIfNearer's depth/id rule. What
// changes is only how: range tests on the floored floats, table lookups by gather, and a masked
// store of the three target planes in place of a branch per pixel.
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "impostor_cache/far_blit_simd.cpp"
#include "impostor_cache/detail/far_blit_band.hpp"

#include <hwy/cache_control.h>
#include <hwy/foreach_target.h> // IWYU pragma: keep
#include <hwy/highway.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <vector>

HWY_BEFORE_NAMESPACE();
namespace voxtier::detail {
namespace HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

static_assert(std::endian::native == std::endian::little,
              "the snapshot gather reads two SnapshotCells as one little-endian word");

#if HWY_HAVE_FLOAT64 && HWY_TARGET != HWY_SCALAR
using DF = hn::ScalableTag<float>;
using DI = hn::RebindToSigned<DF>;
using DU = hn::RebindToUnsigned<DF>;
using VI = hn::Vec<DI>;
using VF = hn::Vec<DF>;
using VU = hn::Vec<DU>;
using MI = hn::Mask<DI>;

/// Rows of pixels a chunk of a sprite takes together: its cell table holds the cell rows they
/// reach. A chunk of 16 rows of a sprite magnified k times reaches about 16 / k + 3 cell rows.
constexpr int kChunkRows = 16;
/// Entries after a cell table that its building may overwrite: a vector's spill past the last
/// row (the widest Highway target has 64 lanes of 32 bits).
constexpr std::size_t kCellTablePadding = 64;
/// A chunk gets a cell table when the cells of the rows it reaches, times this, are fewer than
/// its pixels (measured in docs/decisions/simd-far-blit.md).
constexpr std::uint64_t kCellTableCost = 1;

/// Near cell -> what the sprite shows there, N cells at once: SnapshotCellMap in double
/// (floor((u0 + ui i) + uj j)), Snapshot::at, then vtLit of the palette colour by the face's
/// light, or the outline. The colour, or 0 where nothing is drawn (a drawn colour always has
/// alpha 255).
class CellShader {
  public:
    explicit CellShader(const BlitSprite& s)
        : u0_(hn::Set(dd_, s.map.u0)), ui_(hn::Set(dd_, s.map.ui)), uj_(hn::Set(dd_, s.map.uj)),
          v0_(hn::Set(dd_, s.map.v0)), vi_(hn::Set(dd_, s.map.vi)), vj_(hn::Set(dd_, s.map.vj)),
          snapU0_(hn::Set(di_, s.snapshot->lattice.cellRange.x)),
          snapU1_(hn::Set(di_, s.snapshot->lattice.cellRange.y)),
          snapV0_(hn::Set(di_, s.snapshot->lattice.cellRange.z)),
          snapV1_(hn::Set(di_, s.snapshot->lattice.cellRange.w)),
          snapWidth_(hn::Set(di_, s.snapshot->width())),
          cellWords_(reinterpret_cast<const std::uint32_t*>(s.snapshot->cells.data())),
          palette_(s.palette), lights_(s.lightByCode.data()) {
        // The float shortcut's error bound per axis: the float form below is within
        // 6 * 2^-24 * (|c0| + |cI| max|i| + |cJ| max|j|) of the double one (coefficients rounded
        // once, a product and two sums each rounded once); 16 leaves room for rounding u +- e.
        const glm::ivec4 r = s.gpu->cellRange;
        const double mi = std::max(std::abs(r.x), std::abs(r.y));
        const double mj = std::max(std::abs(r.z), std::abs(r.w));
        const auto bound = [&](double c0, double cI, double cJ) {
            return hn::Set(df_, float(16.0 * 0x1p-24 *
                                      (std::abs(c0) + std::abs(cI) * mi + std::abs(cJ) * mj)));
        };
        if (hn::Lanes(du_) >= 8) lightTable_ = hn::LoadU(du_, lightsWide(s).data());
        fu_ = {hn::Set(df_, float(s.map.u0)), hn::Set(df_, float(s.map.ui)),
               hn::Set(df_, float(s.map.uj)), bound(s.map.u0, s.map.ui, s.map.uj)};
        fv_ = {hn::Set(df_, float(s.map.v0)), hn::Set(df_, float(s.map.vi)),
               hn::Set(df_, float(s.map.vj)), bound(s.map.v0, s.map.vi, s.map.vj)};
    }

    /// Cells (ci, cj) where `keep`; other lanes give 0.
    VU operator()(VI ci, VI cj, MI keep) const {
        ci = hn::IfThenElseZero(keep, ci);
        cj = hn::IfThenElseZero(keep, cj);
        // SnapshotCellMap in float first: where every lane's value lies farther than the error
        // bound from an integer, its floor is the double form's; otherwise (a snapshot cell
        // boundary within rounding) the vector is mapped in double, exactly as the reference.
        const auto fi = hn::ConvertTo(df_, ci), fj = hn::ConvertTo(df_, cj);
        const auto nearFloor = [&](const FloatAxis& a, VI& out) {
            const auto u = hn::Add(hn::Add(a.c0, hn::Mul(a.cI, fi)), hn::Mul(a.cJ, fj));
            const auto lo = hn::Floor(hn::Sub(u, a.error));
            out = hn::ConvertTo(di_, lo);
            return hn::RebindMask(di_, hn::Ne(lo, hn::Floor(hn::Add(u, a.error))));
        };
        VI su, sv;
        const auto unsure = hn::Or(nearFloor(fu_, su), nearFloor(fv_, sv));
        if (!hn::AllFalse(di_, hn::And(keep, unsure))) {
            const auto ciLo = hn::PromoteTo(dd_, hn::LowerHalf(dih_, ci));
            const auto ciHi = hn::PromoteTo(dd_, hn::UpperHalf(dih_, ci));
            const auto cjLo = hn::PromoteTo(dd_, hn::LowerHalf(dih_, cj));
            const auto cjHi = hn::PromoteTo(dd_, hn::UpperHalf(dih_, cj));
            const auto affine = [&](auto c0, auto cI, auto cJ) {
                return hn::Combine(
                    di_,
                    hn::DemoteTo(dih_, hn::Floor(hn::Add(hn::Add(c0, hn::Mul(cI, ciHi)),
                                                         hn::Mul(cJ, cjHi)))),
                    hn::DemoteTo(dih_, hn::Floor(hn::Add(hn::Add(c0, hn::Mul(cI, ciLo)),
                                                         hn::Mul(cJ, cjLo)))));
            };
            su = affine(u0_, ui_, uj_);
            sv = affine(v0_, vi_, vj_);
        }
        // Snapshot::at: empty outside the stored range.
        const auto outside = hn::Or(hn::Or(hn::Lt(su, snapU0_), hn::Gt(su, snapU1_)),
                                    hn::Or(hn::Lt(sv, snapV0_), hn::Gt(sv, snapV1_)));
        const auto look = hn::AndNot(outside, keep);
        if (hn::AllFalse(di_, look)) return hn::Zero(du_);
        const auto zeroI = hn::Zero(di_);
        const auto slot = hn::IfThenElseZero(
            look, hn::Add(hn::Mul(hn::Sub(sv, snapV0_), snapWidth_), hn::Sub(su, snapU0_)));
        // Two-byte cells, gathered as the 32-bit word that ends with the cell (so no read
        // passes the end of the payload), or starts with it for the first cell.
        const auto offset = hn::Max(hn::Sub(hn::ShiftLeft<1>(slot), hn::Set(di_, 2)), zeroI);
        const auto word = hn::GatherOffset(du_, cellWords_, offset);
        const auto cell =
            hn::IfThenElse(hn::RebindMask(du_, hn::Eq(slot, zeroI)),
                           hn::And(word, hn::Set(du_, 0xFFFFu)), hn::ShiftRight<16>(word));
        const auto byteMask = hn::Set(du_, 255u);
        const auto index = hn::And(cell, byteMask);
        const auto code = hn::And(hn::ShiftRight<8>(cell), byteMask);
        const auto drawn = hn::AndNot(hn::Eq(code, hn::Zero(du_)), hn::RebindMask(du_, look));
        if (hn::AllFalse(du_, drawn)) return hn::Zero(du_);
        // Solid codes are kSolid0 .. kSolid0 + 5; anything else drawn is outline.
        const auto solid = hn::And(hn::Gt(code, hn::Zero(du_)),
                                   hn::Lt(code, hn::Set(du_, snapshot_code::kSolid0 + 6u)));
        const auto lightIndex = hn::BitCast(di_, hn::IfThenElseZero(solid, code));
        // Where the eight codes fit one vector, a lane permute instead of a gather.
        const VU light =
            hn::Lanes(du_) >= 8
                ? hn::TableLookupLanes(lightTable_,
                                       hn::IndicesFromVec(du_, hn::BitCast(du_, lightIndex)))
                : hn::GatherIndex(du_, lights_, lightIndex);
        const auto rgba = hn::GatherIndex(du_, palette_, hn::BitCast(di_, index));
        // vtLit: min(255, (c * factor + 2^15) >> 16) per channel, in uint32 like the kernel.
        const auto round = hn::Set(du_, 32768u);
        const auto lit = [&](auto c) {
            return hn::Min(byteMask, hn::ShiftRight<16>(hn::Add(hn::Mul(c, light), round)));
        };
        const auto shaded =
            hn::Or(hn::Or(lit(hn::And(rgba, byteMask)),
                          hn::ShiftLeft<8>(lit(hn::And(hn::ShiftRight<8>(rgba), byteMask)))),
                   hn::Or(hn::ShiftLeft<16>(lit(hn::And(hn::ShiftRight<16>(rgba), byteMask))),
                          hn::Set(du_, 255u << 24)));
        return hn::IfThenElseZero(
            drawn, hn::IfThenElse(solid, shaded, hn::Set(du_, kernel::VT_OUTLINE_RGBA)));
    }

  private:
    /// One axis of SnapshotCellMap in float: c0 + cI i + cJ j, within `error` of the double.
    struct FloatAxis {
        hn::Vec<DF> c0, cI, cJ, error;
    };
    /// lightByCode repeated to fill a vector of up to 64 lanes (TableLookupLanes reads lanes
    /// 0..7 of it).
    static std::array<std::uint32_t, 64> lightsWide(const BlitSprite& s) {
        std::array<std::uint32_t, 64> w{};
        for (std::size_t k = 0; k < w.size(); ++k) w[k] = s.lightByCode[k % 8];
        return w;
    }
    DF df_;
    DI di_;
    DU du_;
    FloatAxis fu_, fv_;
    VU lightTable_;
    hn::Half<DI> dih_;
    hn::Repartition<double, DF> dd_; // N/2 doubles
    hn::Vec<hn::Repartition<double, DF>> u0_, ui_, uj_, v0_, vi_, vj_;
    VI snapU0_, snapU1_, snapV0_, snapV1_, snapWidth_;
    const std::uint32_t* cellWords_;
    const Rgba8* palette_;
    const std::uint32_t* lights_;
};

/// candidateColumns for Lanes(double) consecutive rows at once, one row per lane, with the
/// reference's double operations in its order. A constraint's x coefficient is the same on every
/// row, so its sign test is decided once per sprite; the row's own term, the division, the
/// bounds, floor, ceil and clamp run per lane.
class RowColumns {
  public:
    RowColumns(const kernel::SpriteGpu& g, int rx0, int rx1) : lowest_(rx0), highest_(rx1) {
        const double d = g.mapDen.x;
        constraints_[count_++] = {d, 0.0, 1.0, true, g.mapDen}; // denominator >= 0 (first)
        const auto axis = [&](const glm::vec3& m, int first, int last) {
            const double a = m.x;
            const double qlo = first - 1.0, qhi = last + 2.0;
            constraints_[count_++] = {a - qlo * d, qlo, 1.0, false, m};     // q >= qlo
            constraints_[count_++] = {-(a - qhi * d), qhi, -1.0, false, m}; // q <= qhi
        };
        axis(g.mapI, g.cellRange.x, g.cellRange.y);
        axis(g.mapJ, g.cellRange.z, g.cellRange.w);
    }
    static int rows() { return int(hn::Lanes(hn::ScalableTag<double>())); }

    /// x0[k], x1[k] of row y0 + k, for k < rows().
    void operator()(int y0, int* x0, int* x1) const {
        const hn::ScalableTag<double> dd;
        const hn::Rebind<float, decltype(dd)> df;
        const hn::Rebind<std::int32_t, decltype(dd)> di;
        // The pixel centre's y, rounded to float as the kernel has it, then widened.
        const auto py =
            hn::PromoteTo(dd, hn::Add(hn::ConvertTo(df, hn::Add(hn::Iota(di, 0), hn::Set(di, y0))),
                                      hn::Set(df, 0.5f)));
        const auto rowTerm = [&](const glm::vec3& m) { // double(m.y) * py + double(m.z)
            return hn::Add(hn::Mul(hn::Set(dd, double(m.y)), py), hn::Set(dd, double(m.z)));
        };
        const auto e = rowTerm(constraints_[0].form); // the denominator's row term
        auto lo = hn::Set(dd, -std::numeric_limits<double>::infinity());
        auto hi = hn::Set(dd, std::numeric_limits<double>::infinity());
        auto empty = hn::Lt(e, e); // all false
        for (int k = 0; k < count_; ++k) {
            const Constraint& c = constraints_[k];
            auto b = c.denominator ? e : hn::Sub(rowTerm(c.form), hn::Mul(hn::Set(dd, c.q), e));
            if (c.sign < 0.0) b = hn::Neg(b);
            if (c.a > 0.0) {
                const auto v = hn::Div(hn::Neg(b), hn::Set(dd, c.a));
                lo = hn::IfThenElse(hn::Lt(lo, v), v, lo); // std::max(lo, v)
            } else if (c.a < 0.0) {
                const auto v = hn::Div(hn::Neg(b), hn::Set(dd, c.a));
                hi = hn::IfThenElse(hn::Lt(v, hi), v, hi); // std::min(hi, v)
            } else {
                empty = hn::Or(empty, hn::Lt(b, hn::Zero(dd)));
            }
        }
        const auto half = hn::Set(dd, 0.5);
        const auto lowest = hn::Set(dd, double(lowest_)), highest = hn::Set(dd, double(highest_));
        const auto clamp = [&](auto v) { // std::clamp(v, lowest, highest)
            return hn::IfThenElse(hn::Lt(v, lowest), lowest,
                                  hn::IfThenElse(hn::Lt(highest, v), highest, v));
        };
        const auto first = clamp(hn::Sub(hn::Floor(hn::Sub(lo, half)), hn::Set(dd, 1.0)));
        const auto last = clamp(hn::Add(hn::Ceil(hn::Sub(hi, half)), hn::Set(dd, 2.0)));
        const auto none = hn::Or(empty, hn::Not(hn::Le(lo, hi)));
        const auto i0 = hn::DemoteTo(di, hn::IfThenElse(none, lowest, first));
        const auto i1 = hn::DemoteTo(di, hn::IfThenElse(none, lowest, last));
        hn::StoreU(i0, di, x0);
        hn::StoreU(hn::Max(i0, i1), di, x1);
    }

  private:
    struct Constraint {
        double a = 0.0;           ///< coefficient of x
        double q = 0.0;           ///< the cell bound (axis constraints)
        double sign = 1.0;        ///< -1: the constraint is negated (q <= qhi)
        bool denominator = false; ///< the denominator's own constraint
        glm::vec3 form{0.0f};     ///< the axis' (or denominator's) pixel form
    };
    Constraint constraints_[5];
    int count_ = 0;
    int lowest_, highest_;
};

/// Whether this target can shade the sprite (else the scalar reference does): a vector fits the
/// image's width, and the snapshot holds the two cells the gather reads at least.
bool Vectorisable(const BlitSprite& s, const Image& img) {
    return img.width >= int(hn::Lanes(DF())) && s.snapshot->cells.size() >= 2;
}

/// Rows of near cells [j0, j1] that the pixels of spans x0[k] .. x1[k] of rows y0 + k can map
/// to: along a row vtPixelCell's q_j is a ratio of affine forms with a positive denominator, so
/// monotone, and its extremes lie at the spans' ends; found in double, grown by one cell for
/// the float kernel's rounding, clamped to cellRange. Where a denominator is not positive there
/// (the candidate columns are widened by a pixel or two) the whole cellRange.
glm::ivec2 CellRowsReached(const kernel::SpriteGpu& g, int y0, int rows, const int* x0,
                           const int* x1) {
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (int k = 0; k < rows; ++k) {
        if (x0[k] >= x1[k]) continue;
        const double py = double(float(y0 + k) + 0.5f);
        for (const double px : {double(x0[k]) + 0.5, double(x1[k]) - 0.5}) {
            const double den =
                double(g.mapDen.x) * px + double(g.mapDen.y) * py + double(g.mapDen.z);
            if (!(den > 0.0)) return {g.cellRange.z, g.cellRange.w};
            const double q =
                (double(g.mapJ.x) * px + double(g.mapJ.y) * py + double(g.mapJ.z)) / den;
            lo = std::min(lo, q);
            hi = std::max(hi, q);
        }
    }
    if (!(lo <= hi)) return {g.cellRange.z, g.cellRange.z - 1};
    const double first = std::max(std::floor(lo) - 1.0, double(g.cellRange.z));
    const double last = std::min(std::floor(hi) + 1.0, double(g.cellRange.w));
    return {int(first), int(last)};
}

/// Cell rows [j0, j1] of the sprite's cellRange shaded into `table`, row by row
/// (CellShader, one vector of cells at a time). A row's last vector may run past the row into
/// the next one (rewritten right after) or, after the last row, into kCellTablePadding entries.
void BuildCellTable(const BlitSprite& s, const CellShader& shade, int j0, int j1, Rgba8* table) {
    const DI di;
    const DU du;
    const int n = int(hn::Lanes(di));
    const glm::ivec4 r = s.gpu->cellRange;
    const auto iota = hn::Iota(di, 0);
    const auto last = hn::Set(di, r.y);
    Rgba8* out = table;
    for (int j = j0; j <= j1; ++j) {
        const auto cj = hn::Set(di, j);
        for (int i = r.x; i <= r.y; i += n, out += n) {
            const auto ci = hn::Add(iota, hn::Set(di, i));
            hn::StoreU(shade(ci, cj, hn::Not(hn::Gt(ci, last))), du, out);
        }
        out -= (n - 1) - (r.y - r.x) % n; // back to the end of the row
    }
}

/// One sprite's rows [y0, y1), in chunks of kChunkRows rows. Per chunk: the candidate columns of
/// its rows (as the reference), then, where the chunk has more pixels than the cell rows they can
/// reach hold cells (a magnified sprite), a cell table of those rows, so each cell is shaded once
/// and each pixel looks its cell's colour up; elsewhere each pixel's cell is shaded (CellShader).
/// Pixels go N at a time; the last vector of a row that would pass the image's right edge is
/// moved left to end there, its lanes before the span masked off, so every load and store stays
/// inside the row. The table is the task's own and small, so it stays in this core's cache.
/// The lanes of the vector at `start` (pixels start .. start + lanes - 1 of a row) that lie in
/// the span [x, x1) and that a sprite at `depth` with id `entity` may still write: writeIfNearer's
/// condition, nearer (greater reversed-Z depth) or as near with a lower id.
hn::Mask<DU> OpenLanes(VI xi, int x, int x1, const float* depthRow, const std::uint32_t* idRow,
                       int start, VF depth, VU entity) {
    const DF df;
    const DI di;
    const DU du;
    const auto inSpan = hn::AndNot(hn::Lt(xi, hn::Set(di, x)), hn::Lt(xi, hn::Set(di, x1)));
    const auto oldDepth = hn::LoadU(df, depthRow + start);
    const auto oldId = hn::LoadU(du, idRow + start);
    const auto wins =
        hn::Or(hn::RebindMask(du, hn::Gt(depth, oldDepth)),
               hn::And(hn::RebindMask(du, hn::Eq(depth, oldDepth)), hn::Lt(entity, oldId)));
    return hn::And(wins, hn::RebindMask(du, inSpan));
}

/// Whether some pixel of the spans [x0[k], x1[k]) of rows y0 + k (k < rows) may still take a
/// sprite at `depth` with id `entity`, a vector at a time.
bool AnyPixelOpen(int y0, int rows, const int* x0, const int* x1, const Image& img, VF depth,
                  VU entity) {
    const DI di;
    const int n = int(hn::Lanes(di));
    const auto iota = hn::Iota(di, 0);
    for (int k = 0; k < rows; ++k) {
        const std::size_t rowBase = img.index(0, y0 + k);
        for (int x = x0[k]; x < x1[k]; x += n) {
            const int start = std::min(x, img.width - n);
            const auto xi = hn::Add(iota, hn::Set(di, start));
            if (!hn::AllFalse(DU(), OpenLanes(xi, x, x1[k], img.depth.data() + rowBase,
                                              img.id.data() + rowBase, start, depth, entity)))
                return true;
        }
    }
    return false;
}

void BlitSpriteRows(const BlitSprite& s, int y0, int y1, Image& img, BlitCounters& counters) {
    const DF df;
    const DI di;
    const DU du;
    const int n = int(hn::Lanes(df));
    if (!Vectorisable(s, img)) {
        blitSpriteScalar(s, y0, y1, img, counters);
        return;
    }
    const kernel::SpriteGpu& g = *s.gpu;
    // Built on the first chunk with a pixel the sprite may still take: in a crowd most sprites'
    // rows are covered already, and the shader's per-sprite set-up was most of their cost.
    std::optional<CellShader> shade;

    const auto iota = hn::Iota(di, 0);
    const auto zeroF = hn::Zero(df);
    const auto oneF = hn::Set(df, 1.0f);
    const auto halfF = hn::Set(df, 0.5f);
    // vtPixelCell's per-sprite terms.
    const auto denX = hn::Set(df, g.mapDen.x), denZ = hn::Set(df, g.mapDen.z);
    const auto iX = hn::Set(df, g.mapI.x), iZ = hn::Set(df, g.mapI.z);
    const auto jX = hn::Set(df, g.mapJ.x), jZ = hn::Set(df, g.mapJ.z);
    const auto denMax = hn::Set(df, g.denMax);
    const auto cellI0 = hn::Set(df, float(g.cellRange.x)),
               cellI1 = hn::Set(df, float(g.cellRange.y));
    const auto cellJ0 = hn::Set(df, float(g.cellRange.z)),
               cellJ1 = hn::Set(df, float(g.cellRange.w));
    const int tableWidth = g.cellRange.y - g.cellRange.x + 1;
    const bool fading = g.fade > 0.0f;
    const auto fade = hn::Set(df, g.fade);
    // writeIfNearer's operands.
    const auto depth = hn::Set(df, g.depth);
    const auto entity = hn::Set(du, s.entity);

    const RowColumns columns(g, s.rect.x, s.rect.z);
    const bool minified =
        std::uint64_t(tableWidth) * std::uint64_t(g.cellRange.w - g.cellRange.z + 1) >=
        std::uint64_t(std::max(0, s.rect.z - s.rect.x)) *
            std::uint64_t(std::max(0, s.rect.w - s.rect.y));
    constexpr int kMaxRowLanes = HWY_MAX_BYTES / 8;
    int spanFirst[kChunkRows + kMaxRowLanes], spanLast[kChunkRows + kMaxRowLanes];
    thread_local std::vector<Rgba8> table;
    for (int yc = y0; yc < y1; yc += kChunkRows) {
        const int rows = std::min(kChunkRows, y1 - yc);
        std::uint64_t pixels = 0;
        for (int k = 0; k < rows; k += RowColumns::rows())
            columns(yc + k, spanFirst + k, spanLast + k);
        for (int k = 0; k < rows; ++k) pixels += std::uint64_t(spanLast[k] - spanFirst[k]);
        counters.tested += pixels;
        if (pixels == 0) continue;
        // The depth test alone first: a chunk whose every span pixel already holds what beats
        // the sprite (writeIfNearer's rule) needs no cell rows, no table and no shading.
        if (!AnyPixelOpen(yc, rows, spanFirst, spanLast, img, depth, entity)) continue;
        if (!shade) shade.emplace(s);
        // A minified sprite (more cells than rectangle pixels) never gains from a table.
        const glm::ivec2 reach =
            minified ? glm::ivec2(0, -1) : CellRowsReached(g, yc, rows, spanFirst, spanLast);
        const std::uint64_t cells =
            std::uint64_t(std::max(0, reach.y - reach.x + 1)) * std::uint64_t(tableWidth);
        const bool tabled = cells > 0 && cells * kCellTableCost < pixels;
        if (tabled) {
            if (table.size() < cells + kCellTablePadding) table.resize(cells + kCellTablePadding);
            BuildCellTable(s, *shade, reach.x, reach.y, table.data());
        }
        const auto tableI0 = hn::Set(di, g.cellRange.x), tableJ0 = hn::Set(di, reach.x);
        const auto tableJ1 = hn::Set(di, reach.y), tableStride = hn::Set(di, tableWidth);

        for (int y = yc; y < yc + rows; ++y) {
            const int x0 = spanFirst[y - yc], x1 = spanLast[y - yc];
            if (x0 >= x1) continue;
            const float py = float(y) + 0.5f;
            // vtPixelCell evaluates m.x * px + m.y * py + m.z left to right: the py product is the
            // same float on every pixel of the row.
            const auto denY = hn::Set(df, g.mapDen.y * py);
            const auto iY = hn::Set(df, g.mapI.y * py), jY = hn::Set(df, g.mapJ.y * py);
            const auto rowY = hn::Set(di, y & 3);
            const std::size_t rowBase = img.index(0, y);
            float* depthRow = img.depth.data() + rowBase;
            std::uint32_t* colorRow = img.color.data() + rowBase;
            std::uint32_t* idRow = img.id.data() + rowBase;
            for (int x = x0; x < x1; x += n) {
                const int start = std::min(x, img.width - n);
                const auto xi = hn::Add(iota, hn::Set(di, start));
                const auto px = hn::Add(hn::ConvertTo(df, xi), halfF);
                // writeIfNearer's test first: a pixel a nearer sprite already holds is neither
                // mapped nor looked up (most of a crowd's pixels).
                auto keep =
                    hn::RebindMask(df, OpenLanes(xi, x, x1, depthRow, idRow, start, depth, entity));
                if (hn::AllFalse(df, keep)) continue;
                if (fading) {
                    // vtDitherThreshold: the 4x4 Bayer index from the bits of x ^ y and y.
                    const auto a = hn::Xor(hn::And(xi, hn::Set(di, 3)), rowY);
                    const auto v = hn::Or(
                        hn::Or(hn::ShiftLeft<3>(hn::And(a, hn::Set(di, 1))),
                               hn::ShiftLeft<2>(hn::And(rowY, hn::Set(di, 1)))),
                        hn::Or(hn::ShiftLeft<1>(hn::ShiftRight<1>(a)), hn::ShiftRight<1>(rowY)));
                    const auto threshold =
                        hn::Div(hn::Add(hn::ConvertTo(df, v), halfF), hn::Set(df, 16.0f));
                    const auto below = hn::Lt(threshold, fade);
                    keep = hn::And(keep, g.fadeSide > 0.0f ? below : hn::Not(below));
                }
                const auto den = hn::Add(hn::Add(hn::Mul(denX, px), denY), denZ);
                keep = hn::And(keep, hn::AndNot(hn::Gt(den, denMax), hn::Gt(den, zeroF)));
                if (hn::AllFalse(df, keep)) continue;
                const auto inv = hn::Div(oneF, den);
                const auto qi = hn::Mul(hn::Add(hn::Add(hn::Mul(iX, px), iY), iZ), inv);
                const auto qj = hn::Mul(hn::Add(hn::Add(hn::Mul(jX, px), jY), jZ), inv);
                const auto fi = hn::Floor(qi), fj = hn::Floor(qj);
                const auto outside = hn::Or(hn::Or(hn::Lt(fi, cellI0), hn::Gt(fi, cellI1)),
                                            hn::Or(hn::Lt(fj, cellJ0), hn::Gt(fj, cellJ1)));
                keep = hn::AndNot(outside, keep);
                if (hn::AllFalse(df, keep)) continue;
                // Lanes not kept take cell (0, 0), never read.
                const auto keepI = hn::RebindMask(di, keep);
                const auto ci = hn::ConvertTo(di, hn::IfThenElseZero(keep, fi));
                const auto cj = hn::ConvertTo(di, hn::IfThenElseZero(keep, fj));
                VU color;
                // A cell row outside the table's (never, unless the double estimate of the reach
                // was off by more than its cell of margin) is shaded in place.
                if (tabled && hn::AllFalse(di, hn::And(keepI, hn::Or(hn::Lt(cj, tableJ0),
                                                                     hn::Gt(cj, tableJ1))))) {
                    const auto slot = hn::IfThenElseZero(
                        keepI,
                        hn::Add(hn::Mul(hn::Sub(cj, tableJ0), tableStride), hn::Sub(ci, tableI0)));
                    color = hn::IfThenElseZero(hn::RebindMask(du, keepI),
                                               hn::GatherIndex(du, table.data(), slot));
                } else {
                    color = (*shade)(ci, cj, keepI);
                }
                // Lanes not kept (outside the span, lost the depth test) have colour 0.
                const auto write = hn::Not(hn::Eq(color, hn::Zero(du)));
                if (hn::AllFalse(du, write)) continue;
                counters.written += hn::CountTrue(du, write);
                hn::BlendedStore(color, write, du, colorRow + start);
                hn::BlendedStore(depth, hn::RebindMask(df, write), df, depthRow + start);
                hn::BlendedStore(entity, write, du, idRow + start);
            }
        }
    }
}
#else
bool Vectorisable(const BlitSprite&, const Image&) {
    return false;
}
void BlitSpriteRows(const BlitSprite& s, int y0, int y1, Image& img, BlitCounters& counters) {
    blitSpriteScalar(s, y0, y1, img, counters);
}
#endif

void BlitBand(const BlitBand& band, BlitCounters& counters) {
    // A sprite reads its snapshot at scattered cells (per pixel, or per cell into a table), and
    // waits for each vector's gather; the snapshot of the sprite two places ahead is fetched
    // while this one is drawn (measured in docs/decisions/simd-far-blit.md).
    constexpr std::size_t kAhead = 2;
    for (std::size_t k = 0; k < band.count; ++k) {
        const BlitSprite& s = band.sprites[band.list[k]];
        if (k + kAhead < band.count) {
            const BlitSprite& next = band.sprites[band.list[k + kAhead]];
            const char* p = reinterpret_cast<const char*>(next.snapshot->cells.data());
            const std::size_t bytes = next.snapshot->cells.size() * 2;
            for (std::size_t b = 0; b < bytes; b += 64) hwy::Prefetch(p + b);
        }
        drawInBand(band, s, counters, [&](const BlitSprite& part, int y0, int y1) {
            BlitSpriteRows(part, y0, y1, *band.target, counters);
        });
    }
}

const char* TargetName() {
    return hwy::TargetName(HWY_TARGET);
}

} // namespace HWY_NAMESPACE
} // namespace voxtier::detail
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace voxtier {
namespace detail {
HWY_EXPORT(BlitBand);
HWY_EXPORT(TargetName);

void blitBandSimd(const BlitBand& band, BlitCounters& counters) {
    HWY_DYNAMIC_DISPATCH(BlitBand)(band, counters);
}
const char* blitSimdTargetName() {
    return HWY_DYNAMIC_DISPATCH(TargetName)();
}
} // namespace detail

const char* farBlitSimdTarget() {
    return detail::blitSimdTargetName();
}
} // namespace voxtier
#endif
