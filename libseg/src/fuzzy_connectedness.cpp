#include "lobe/seg/fuzzy_connectedness.h"

#include "detail/volume.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

namespace lobe::seg {
namespace {

void check_affinity(const AffinityParams& a)
{
    if (!std::isfinite(a.object_mean))
        throw core::InvalidInputError("fuzzy_connectedness: object_mean must be finite");
    if (!(a.object_sigma > 0) || !std::isfinite(a.object_sigma))
        throw core::InvalidInputError("fuzzy_connectedness: object_sigma must be finite and > 0");
    if (!(a.gradient_sigma > 0))
        throw core::InvalidInputError("fuzzy_connectedness: gradient_sigma must be > 0 (infinity: no gradient term)");
}

double h1(const AffinityParams& a, double m)
{
    const double d = m - a.object_mean;
    if (a.one_sided && d >= 0)
        return 1.0;
    return std::exp(-d * d / (2 * a.object_sigma * a.object_sigma));
}

double h2(const AffinityParams& a, double g)
{
    if (std::isinf(a.gradient_sigma))
        return 1.0;
    return std::exp(-g * g / (2 * a.gradient_sigma * a.gradient_sigma));
}

struct Neighbour {
    std::ptrdiff_t offset; // in the padded index space
    double distance_mm;
    int table;             // which h2 table (one per distinct distance)
};

} // namespace

double affinity(const AffinityParams& a, double fc, double fd, double distance_mm)
{
    check_affinity(a);
    if (!(distance_mm > 0))
        throw core::InvalidInputError("affinity: the distance must be > 0");
    return h1(a, 0.5 * (fc + fd)) * h2(a, std::abs(fc - fd) / distance_mm);
}

FuzzyConnectednessResult fuzzy_connectedness(const core::ImageF& feature, const core::LabelImage3D& seeds,
                                             const FuzzyConnectednessParams& params, const core::LabelImage3D* roi)
{
    detail::check_image(feature, "fuzzy_connectedness: feature image");
    detail::check_same_grid(feature, seeds, "fuzzy_connectedness: the seed mask");
    if (roi)
        detail::check_same_grid(feature, *roi, "fuzzy_connectedness: the ROI");
    check_affinity(params.affinity);
    if (params.connectivity != 6 && params.connectivity != 26)
        throw core::InvalidInputError("fuzzy_connectedness: connectivity must be 6 or 26, got " +
                                      std::to_string(params.connectivity));
    if (params.levels < 16 || params.levels > 65535)
        throw core::InvalidInputError("fuzzy_connectedness: levels must be in [16, 65535]");
    if (!(params.lut_step > 0) || !std::isfinite(params.lut_step))
        throw core::InvalidInputError("fuzzy_connectedness: lut_step must be finite and > 0");
    if (!(params.min_connectedness >= 0 && params.min_connectedness <= 1))
        throw core::InvalidInputError("fuzzy_connectedness: min_connectedness must be in [0, 1]");

    FuzzyConnectednessResult res;
    res.connectedness = core::ImageF(feature.geometry(), 0.f);
    const detail::Box box = roi ? detail::bounding_box(*roi)
                                : detail::Box{{0, 0, 0}, {feature.size[0] - 1, feature.size[1] - 1, feature.size[2] - 1}};
    if (box.empty())
        throw core::InvalidInputError("fuzzy_connectedness: the ROI is empty");

    // A copy of the ROI's box padded by one voxel of "outside" on every side, so that neighbours
    // of ROI voxels never need a bounds check.
    const auto bs = box.size();
    const std::array<std::size_t, 3> pn{std::size_t(bs[0]) + 2, std::size_t(bs[1]) + 2, std::size_t(bs[2]) + 2};
    const std::size_t total = pn[0] * pn[1] * pn[2];
    if (total >= std::numeric_limits<std::uint32_t>::max())
        throw core::InvalidInputError("fuzzy_connectedness: the ROI's box is too large");
    std::vector<std::uint8_t> in(total, 0);
    std::vector<float> f(total, 0.f);
    std::vector<std::uint32_t> queue_seeds;
    auto pidx = [&](int i, int j, int k) {
        return (std::size_t(i) + 1) + pn[0] * ((std::size_t(j) + 1) + pn[1] * (std::size_t(k) + 1));
    };
    float fmin = std::numeric_limits<float>::max(), fmax = std::numeric_limits<float>::lowest();
    for (int k = 0; k < bs[2]; ++k)
        for (int j = 0; j < bs[1]; ++j)
            for (int i = 0; i < bs[0]; ++i) {
                const std::size_t g = feature.index(box.lo[0] + i, box.lo[1] + j, box.lo[2] + k);
                if (roi && !roi->data[g])
                    continue;
                const float v = feature.data[g];
                if (!std::isfinite(v))
                    throw core::InvalidInputError("fuzzy_connectedness: the feature image holds non-finite values in the ROI");
                const std::size_t p = pidx(i, j, k);
                in[p] = 1;
                f[p] = v;
                fmin = std::min(fmin, v);
                fmax = std::max(fmax, v);
                if (seeds.data[g])
                    queue_seeds.push_back(static_cast<std::uint32_t>(p));
            }
    if (queue_seeds.empty())
        throw core::InvalidInputError("fuzzy_connectedness: no seed lies in the ROI");

    std::vector<Neighbour> nbrs;
    std::vector<double> distances;
    for (int dk = -1; dk <= 1; ++dk)
        for (int dj = -1; dj <= 1; ++dj)
            for (int di = -1; di <= 1; ++di) {
                const int m = std::abs(di) + std::abs(dj) + std::abs(dk);
                if (m == 0 || (params.connectivity == 6 && m > 1))
                    continue;
                const double d = std::sqrt(std::pow(di * feature.spacing[0], 2) + std::pow(dj * feature.spacing[1], 2) +
                                           std::pow(dk * feature.spacing[2], 2));
                int t = 0;
                while (t < static_cast<int>(distances.size()) && std::abs(distances[std::size_t(t)] - d) > 1e-9)
                    ++t;
                if (t == static_cast<int>(distances.size()))
                    distances.push_back(d);
                nbrs.push_back({static_cast<std::ptrdiff_t>(di) +
                                    static_cast<std::ptrdiff_t>(pn[0]) * (dj + static_cast<std::ptrdiff_t>(pn[1]) * dk),
                                d, t});
            }

    const int top = params.levels - 1;
    const int min_level = static_cast<int>(std::ceil(params.min_connectedness * top - 1e-9));
    const AffinityParams& ap = params.affinity;

    // The lookup tables: h1 by the sum of two quantised values, h2 by their difference, one h2
    // table per neighbour distance.
    std::vector<std::uint16_t> q;
    std::vector<float> t1;
    std::vector<std::vector<float>> t2;
    if (params.lookup_table) {
        const double range = static_cast<double>(fmax) - static_cast<double>(fmin);
        const double nq = std::floor(range / params.lut_step) + 1;
        if (nq > 65535)
            throw core::InvalidInputError("fuzzy_connectedness: lut_step " + std::to_string(params.lut_step) +
                                          " is too fine for the feature's range " + std::to_string(range) +
                                          " (at most 65535 steps)");
        const std::size_t nqs = static_cast<std::size_t>(nq);
        q.assign(total, 0);
        for (std::size_t p = 0; p < total; ++p)
            if (in[p])
                q[p] = static_cast<std::uint16_t>(
                    std::min(nq - 1, std::round((static_cast<double>(f[p]) - static_cast<double>(fmin)) / params.lut_step)));
        t1.resize(2 * nqs - 1);
        for (std::size_t s = 0; s < t1.size(); ++s)
            t1[s] = static_cast<float>(h1(ap, static_cast<double>(fmin) + 0.5 * static_cast<double>(s) * params.lut_step));
        t2.resize(distances.size());
        for (std::size_t t = 0; t < distances.size(); ++t) {
            t2[t].resize(nqs);
            for (std::size_t d = 0; d < nqs; ++d)
                t2[t][d] = static_cast<float>(h2(ap, static_cast<double>(d) * params.lut_step / distances[t]));
        }
    }

    // Max-min propagation on a monotone bucket queue: a voxel's candidate strength is never more
    // than the strength of the voxel being expanded, so buckets are only filled at or below the
    // current one, and each voxel is expanded once, at its final strength.
    std::vector<std::uint16_t> K(total, 0);
    std::vector<std::uint8_t> done(total, 0);
    std::vector<std::vector<std::uint32_t>> buckets(static_cast<std::size_t>(params.levels));
    for (std::uint32_t s : queue_seeds) {
        K[s] = static_cast<std::uint16_t>(top);
        buckets[static_cast<std::size_t>(top)].push_back(s);
    }
    for (int cur = top; cur >= std::max(min_level, 1); --cur) {
        auto& bucket = buckets[static_cast<std::size_t>(cur)];
        while (!bucket.empty()) {
            const std::uint32_t v = bucket.back();
            bucket.pop_back();
            if (done[v] || K[v] != cur)
                continue;
            done[v] = 1;
            ++res.expanded;
            for (const Neighbour& nb : nbrs) {
                const std::size_t w = static_cast<std::size_t>(static_cast<std::ptrdiff_t>(v) + nb.offset);
                if (!in[w] || done[w] || K[w] >= cur)
                    continue;
                double mu;
                if (params.lookup_table) {
                    const int a = q[v], b = q[w];
                    mu = static_cast<double>(t1[static_cast<std::size_t>(a + b)]) *
                         static_cast<double>(t2[static_cast<std::size_t>(nb.table)][static_cast<std::size_t>(std::abs(a - b))]);
                } else {
                    const double fv = static_cast<double>(f[v]), fw = static_cast<double>(f[w]);
                    mu = h1(ap, 0.5 * (fv + fw)) * h2(ap, std::abs(fv - fw) / nb.distance_mm);
                }
                const int lv = std::min(cur, static_cast<int>(mu * top));
                if (lv > K[w] && lv >= min_level && lv > 0) {
                    K[w] = static_cast<std::uint16_t>(lv);
                    buckets[static_cast<std::size_t>(lv)].push_back(static_cast<std::uint32_t>(w));
                }
            }
        }
        std::vector<std::uint32_t>().swap(bucket);
    }

    const float inv = 1.0f / static_cast<float>(top);
    for (int k = 0; k < bs[2]; ++k)
        for (int j = 0; j < bs[1]; ++j)
            for (int i = 0; i < bs[0]; ++i) {
                const std::size_t p = pidx(i, j, k);
                if (K[p])
                    res.connectedness.at(box.lo[0] + i, box.lo[1] + j, box.lo[2] + k) = static_cast<float>(K[p]) * inv;
            }
    return res;
}

} // namespace lobe::seg
