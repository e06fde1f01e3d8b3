#include "lobe/seg/metrics.h"

#include "lobe/seg/distance_transform.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <string>
#include <vector>

// Definitions and reference values: docs/algorithms/metrics.md.
namespace lobe::seg {
namespace {

std::string size_text(const core::ImageGeometry& g)
{
    return std::to_string(g.size[0]) + " x " + std::to_string(g.size[1]) + " x " + std::to_string(g.size[2]);
}

void check_mask(const core::LabelImage3D& m, const char* what)
{
    if (m.data.size() != m.voxel_count())
        throw core::InvalidInputError(std::string("evaluate_segmentation: the ") + what + " holds " +
                                      std::to_string(m.data.size()) + " values for a grid of " + size_text(m) +
                                      " voxels");
}

// Smallest box holding every non-zero voxel of a and b: the surface distances only involve
// their voxels, so the distance transforms can run on it alone.
struct Box {
    std::array<int, 3> lo{}, hi{}; // inclusive
};

Box union_box(const core::LabelImage3D& a, const core::LabelImage3D& b)
{
    Box box;
    box.lo = a.size;
    box.hi = {-1, -1, -1};
    for (int k = 0; k < a.size[2]; ++k)
        for (int j = 0; j < a.size[1]; ++j) {
            const std::size_t row = a.index(0, j, k);
            for (int i = 0; i < a.size[0]; ++i)
                if (a.data[row + static_cast<std::size_t>(i)] || b.data[row + static_cast<std::size_t>(i)]) {
                    const std::array<int, 3> p{i, j, k};
                    for (int c = 0; c < 3; ++c) {
                        box.lo[c] = std::min(box.lo[c], p[c]);
                        box.hi[c] = std::max(box.hi[c], p[c]);
                    }
                }
        }
    return box;
}

// The border of mask m inside `box`, on a grid of the box's size: object voxels with one of
// their 26 neighbours outside the object or outside the full grid.
core::LabelImage3D border(const core::LabelImage3D& m, const Box& box)
{
    core::ImageGeometry g = m.geometry();
    const core::Vec3 origin = m.index_to_physical(box.lo[0], box.lo[1], box.lo[2]);
    for (int c = 0; c < 3; ++c) {
        g.size[c] = box.hi[c] - box.lo[c] + 1;
        g.origin[c] = origin[c];
    }
    core::LabelImage3D out(g, 0);
    const auto inside = [&m](int i, int j, int k) { return m.contains(i, j, k) && m.at(i, j, k) != 0; };
    // A 2-D image (one slice) has no neighbours across its plane: its border is 8-connected.
    std::array<int, 3> r{};
    for (int c = 0; c < 3; ++c)
        r[c] = m.size[c] > 1 ? 1 : 0;
#pragma omp parallel for schedule(static) if (out.data.size() >= (std::size_t(1) << 16))
    for (int k = box.lo[2]; k <= box.hi[2]; ++k)
        for (int j = box.lo[1]; j <= box.hi[1]; ++j)
            for (int i = box.lo[0]; i <= box.hi[0]; ++i) {
                if (!m.at(i, j, k))
                    continue;
                bool edge = false;
                for (int dk = -r[2]; dk <= r[2] && !edge; ++dk)
                    for (int dj = -r[1]; dj <= r[1] && !edge; ++dj)
                        for (int di = -r[0]; di <= r[0] && !edge; ++di)
                            edge = !inside(i + di, j + dj, k + dk);
                if (edge)
                    out.at(i - box.lo[0], j - box.lo[1], k - box.lo[2]) = 1;
            }
    return out;
}

struct Pooled {
    double sum = 0, sum_sq = 0, max = 0;
    std::size_t count = 0;
};

// Adds the distance of every voxel of `from` to the nearest voxel of `to` (both borders).
void pool(const core::LabelImage3D& from, const core::LabelImage3D& to, Pooled& p)
{
    const core::ImageF d = euclidean_distance(to);
    for (std::size_t i = 0; i < from.data.size(); ++i)
        if (from.data[i]) {
            const auto v = static_cast<double>(d.data[i]);
            p.sum += v;
            p.sum_sq += v * v;
            p.max = std::max(p.max, v);
            ++p.count;
        }
}

double score(double value, double reference, const char* what)
{
    if (!(reference > 0) || !std::isfinite(reference))
        throw core::InvalidInputError(std::string("sliver_score: the reference value for ") + what + " is " +
                                      std::to_string(reference) + " (must be finite and positive)");
    return std::max(0.0, 100.0 - 25.0 * value / reference);
}

} // namespace

SegmentationMeasures evaluate_segmentation(const core::LabelImage3D& seg, const core::LabelImage3D& ref)
{
    check_mask(seg, "segmentation");
    check_mask(ref, "reference");
    if (!core::same_grid(seg, ref))
        throw core::InvalidInputError("evaluate_segmentation: the segmentation (" + size_text(seg) +
                                      " voxels) and the reference (" + size_text(ref) +
                                      " voxels) are not on the same grid (size, spacing, origin and direction "
                                      "must agree)");
    std::size_t n_seg = 0, n_ref = 0, n_both = 0;
    for (std::size_t i = 0; i < seg.data.size(); ++i) {
        const bool s = seg.data[i] != 0, r = ref.data[i] != 0;
        n_seg += s;
        n_ref += r;
        n_both += s && r;
    }
    if (n_seg == 0 || n_ref == 0)
        throw core::InvalidInputError(std::string("evaluate_segmentation: the ") +
                                      (n_seg == 0 ? "segmentation" : "reference") +
                                      " mask is empty (no non-zero voxel): its measures are undefined");

    SegmentationMeasures m;
    const double s = double(n_seg), r = double(n_ref), both = double(n_both);
    m.dice = 2.0 * both / (s + r);
    m.jaccard = both / (s + r - both);
    m.voe = (1.0 - m.jaccard) * 100.0;
    m.rvd = (s - r) / r * 100.0;
    m.abs_rvd = std::abs(m.rvd);
    const double voxel_ml = seg.spacing[0] * seg.spacing[1] * seg.spacing[2] / 1000.0;
    m.volume_seg_ml = s * voxel_ml;
    m.volume_ref_ml = r * voxel_ml;

    const Box box = union_box(seg, ref);
    const core::LabelImage3D border_seg = border(seg, box), border_ref = border(ref, box);
    Pooled p;
    pool(border_seg, border_ref, p);
    m.surface.border_voxels_seg = p.count;
    pool(border_ref, border_seg, p);
    m.surface.border_voxels_ref = p.count - m.surface.border_voxels_seg;
    m.surface.average = p.sum / double(p.count);
    m.surface.rms = std::sqrt(p.sum_sq / double(p.count));
    m.surface.maximum = p.max;
    return m;
}

SliverScore sliver_score(const SegmentationMeasures& m, const SliverReference& reference)
{
    SliverScore s;
    s.voe = score(m.voe, reference.voe, "VOE");
    s.abs_rvd = score(m.abs_rvd, reference.abs_rvd, "|RVD|");
    s.asd = score(m.surface.average, reference.asd, "ASD");
    s.rmsd = score(m.surface.rms, reference.rmsd, "RMSD");
    s.maxd = score(m.surface.maximum, reference.maxd, "MaxD");
    s.total = (s.voe + s.abs_rvd + s.asd + s.rmsd + s.maxd) / 5.0;
    return s;
}

} // namespace lobe::seg
