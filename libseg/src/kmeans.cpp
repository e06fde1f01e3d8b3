#include "lobe/seg/kmeans.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <numeric>
#include <string>
#include <vector>

namespace lobe::seg {
namespace {

using Index = std::ptrdiff_t;

//! Passes over fewer voxels run on one thread (as in edge_map.cpp): a 512 x 512 slice takes
//! ~0.3 ms per pass, less than a fork/join costs on a loaded machine.
constexpr Index kParallelMin = Index(1) << 19;

//! One non-empty histogram bin: how many values fell in it, their sum and sum of squares. The
//! bin's mean (not its centre) represents it, so a bin of one distinct level is exact.
struct Bin {
    double count = 0.0;
    double sum = 0.0;
    double sumsq = 0.0;
    double mean() const { return sum / count; }
};

//! The non-empty bins of a histogram over [lo, hi] of values[i] for the i where keep(i), in
//! ascending order.
template <class Keep>
std::vector<Bin> histogram(const float* values, std::size_t n, Keep keep, double lo, double hi, int bins)
{
    std::vector<Bin> h(static_cast<std::size_t>(bins));
    const double scale = hi > lo ? bins / (hi - lo) : 0.0;
    for (std::size_t i = 0; i < n; ++i) {
        if (!keep(i))
            continue;
        const double v = values[i];
        const int b = std::min(bins - 1, static_cast<int>((v - lo) * scale));
        Bin& bin = h[static_cast<std::size_t>(b)];
        bin.count += 1.0;
        bin.sum += v;
        bin.sumsq += v * v;
    }
    h.erase(std::remove_if(h.begin(), h.end(), [](const Bin& b) { return b.count == 0.0; }), h.end());
    return h;
}

std::vector<Bin> histogram(const std::vector<float>& values, double lo, double hi, int bins)
{
    return histogram(values.data(), values.size(), [](std::size_t) { return true; }, lo, hi, bins);
}

struct Lloyd {
    std::vector<double> centres; //!< ascending, every cluster non-empty
    int iterations = 0;
    bool converged = false;
};

//! The value at quantile q of the binned values (the mean of the bin holding that rank).
double quantile(const std::vector<Bin>& bins, double total, double q)
{
    const double rank = q * total;
    double below = 0.0;
    for (const Bin& b : bins) {
        if (below + b.count > rank)
            return b.mean();
        below += b.count;
    }
    return bins.back().mean();
}

//! Lloyd's algorithm on 1-D binned data. In 1-D the nearest-centre assignment of sorted data is
//! monotone: with sorted centres, cluster j holds the values in [t_{j-1}, t_j) where t_j is the
//! midpoint of centres j and j+1, so one sweep over the bins assigns them all (O(bins + K)).
//! An empty cluster is re-seeded at the bin contributing most to J (deterministic); when no bin
//! contributes (fewer distinct levels than clusters) it is dropped.
Lloyd lloyd_1d(const std::vector<Bin>& bins, std::vector<double> centres, int max_iterations, double tolerance)
{
    Lloyd r;
    std::vector<double> sum, cnt;
    std::vector<int> owner(bins.size());
    for (int it = 0; it < max_iterations; ++it) {
        std::sort(centres.begin(), centres.end());
        const std::size_t k = centres.size();
        sum.assign(k, 0.0);
        cnt.assign(k, 0.0);
        std::size_t c = 0;
        for (std::size_t b = 0; b < bins.size(); ++b) {
            const double v = bins[b].mean();
            while (c + 1 < k && v >= 0.5 * (centres[c] + centres[c + 1]))
                ++c;
            owner[b] = static_cast<int>(c);
            sum[c] += bins[b].sum;
            cnt[c] += bins[b].count;
        }
        r.iterations = it + 1;
        double moved = 0.0;
        bool reseeded = false;
        std::vector<double> next(k);
        for (std::size_t j = 0; j < k; ++j)
            next[j] = cnt[j] > 0.0 ? sum[j] / cnt[j] : std::numeric_limits<double>::quiet_NaN();
        // Empty clusters: move each to the worst-represented bin (largest count * squared error).
        std::vector<char> taken(bins.size(), 0);
        for (std::size_t j = 0; j < k; ++j) {
            if (cnt[j] > 0.0)
                continue;
            double best = 0.0;
            std::size_t arg = bins.size();
            for (std::size_t b = 0; b < bins.size(); ++b) {
                if (taken[b])
                    continue;
                const double e = bins[b].mean() - next[static_cast<std::size_t>(owner[b])];
                const double w = bins[b].count * e * e;
                if (w > best) {
                    best = w;
                    arg = b;
                }
            }
            if (arg < bins.size()) {
                taken[arg] = 1;
                next[j] = bins[arg].mean();
                reseeded = true;
            }
        }
        std::vector<double> kept;
        for (std::size_t j = 0; j < k; ++j)
            if (std::isfinite(next[j]))
                kept.push_back(next[j]);
        if (kept.size() != k) {
            centres = kept; // dropped: nothing left to re-seed with
            continue;
        }
        for (std::size_t j = 0; j < k; ++j)
            moved = std::max(moved, std::abs(next[j] - centres[j]));
        centres = next;
        if (!reseeded && moved <= tolerance) {
            r.converged = true;
            break;
        }
    }
    std::sort(centres.begin(), centres.end());
    centres.erase(std::unique(centres.begin(), centres.end()), centres.end());
    r.centres = centres;
    return r;
}

//! The globally optimal K-means partition of 1-D binned data, by dynamic programming (the
//! Ckmeans.1d.dp recurrence of Wang & Song 2011): in 1-D an optimal cluster is a run of
//! consecutive bins, so with D_k(i) the least J of the first i+1 bins in k clusters,
//!     D_k(i) = min_{k-1 <= j <= i} D_{k-1}(j-1) + SS(j..i),
//! where SS is the within-run sum of squares from prefix sums in O(1). The optimal j is
//! monotone in i, so each row is filled by divide and conquer in O(B log B): O(K B log B) in all
//! (4096 bins, K = 6: ~0.3 M cost evaluations), against O(K N) per Lloyd iteration on pixels.
//! Returns the centres of at most `k` clusters (fewer when there are fewer bins).
std::vector<double> optimal_1d(const std::vector<Bin>& bins, int k)
{
    const std::size_t nb = bins.size();
    const std::size_t kk = std::min<std::size_t>(static_cast<std::size_t>(k), nb);
    // Prefix sums of count, count * (m - ref) and count * (m - ref)^2 with a central reference
    // value: the within-run SS = S2 - S1^2 / S0 then cancels far less than with raw values.
    const double ref = bins[nb / 2].mean();
    std::vector<double> s0(nb + 1, 0.0), s1(nb + 1, 0.0), s2(nb + 1, 0.0);
    for (std::size_t b = 0; b < nb; ++b) {
        const double d = bins[b].mean() - ref;
        s0[b + 1] = s0[b] + bins[b].count;
        s1[b + 1] = s1[b] + bins[b].count * d;
        s2[b + 1] = s2[b] + bins[b].count * d * d;
    }
    auto ss = [&](std::size_t j, std::size_t i) { // bins j..i inclusive
        const double n = s0[i + 1] - s0[j], a = s1[i + 1] - s1[j], q = s2[i + 1] - s2[j];
        return std::max(0.0, q - a * a / n);
    };
    const double inf = std::numeric_limits<double>::infinity();
    std::vector<double> prev(nb), cur(nb);
    std::vector<std::vector<std::uint32_t>> start(kk, std::vector<std::uint32_t>(nb, 0));
    for (std::size_t i = 0; i < nb; ++i)
        prev[i] = ss(0, i);
    for (std::size_t c = 1; c < kk; ++c) {
        std::fill(cur.begin(), cur.end(), inf);
        auto& arg = start[c];
        // Fill cur[ilo..ihi] knowing that the optimal start lies in [jlo, jhi].
        struct Task { std::size_t ilo, ihi, jlo, jhi; };
        std::vector<Task> stack{{c, nb - 1, c, nb - 1}};
        while (!stack.empty()) {
            const Task t = stack.back();
            stack.pop_back();
            if (t.ilo > t.ihi)
                continue;
            const std::size_t i = t.ilo + (t.ihi - t.ilo) / 2;
            double best = inf;
            std::size_t bj = std::max(t.jlo, c);
            for (std::size_t j = std::max(t.jlo, c); j <= std::min(t.jhi, i); ++j) {
                const double v = prev[j - 1] + ss(j, i);
                if (v < best) {
                    best = v;
                    bj = j;
                }
            }
            cur[i] = best;
            arg[i] = static_cast<std::uint32_t>(bj);
            if (i > t.ilo)
                stack.push_back({t.ilo, i - 1, t.jlo, bj});
            stack.push_back({i + 1, t.ihi, bj, t.jhi});
        }
        std::swap(prev, cur);
    }
    // Backtrack the runs and return their means.
    std::vector<double> centres(kk);
    std::size_t end = nb - 1;
    for (std::size_t c = kk; c-- > 0;) {
        const std::size_t j = c > 0 ? start[c][end] : 0;
        centres[c] = ref + (s1[end + 1] - s1[j]) / (s0[end + 1] - s0[j]);
        if (c > 0)
            end = j - 1;
    }
    return centres;
}

//! Layer of value v (0-based) for ascending thresholds t: the number of thresholds <= v.
int layer_of(double v, const std::vector<double>& t)
{
    return static_cast<int>(std::upper_bound(t.begin(), t.end(), v) - t.begin());
}

std::vector<double> midpoints(const std::vector<double>& c)
{
    std::vector<double> t;
    for (std::size_t j = 0; j + 1 < c.size(); ++j)
        t.push_back(0.5 * (c[j] + c[j + 1]));
    return t;
}

//! Mean, standard deviation and count of binned values in one cluster.
struct Stats {
    double count = 0.0, mean = 0.0, sigma = 0.0;
};
Stats stats_of(const std::vector<Bin>& bins, double lo, double hi)
{
    double n = 0, s = 0, s2 = 0;
    for (const Bin& b : bins) {
        const double v = b.mean();
        if (v >= lo && v < hi) {
            n += b.count;
            s += b.sum;
            s2 += b.sumsq;
        }
    }
    Stats st;
    st.count = n;
    if (n > 0) {
        st.mean = s / n;
        st.sigma = std::sqrt(std::max(0.0, s2 / n - st.mean * st.mean));
    }
    return st;
}

void check_params(const KMeansParams& p)
{
    if (p.clusters < 1 || p.clusters > 64)
        throw core::InvalidInputError("kmeans_layers: clusters must be in 1..64, got " + std::to_string(p.clusters));
    if (p.max_iterations < 1)
        throw core::InvalidInputError("kmeans_layers: max_iterations must be >= 1");
    if (!(p.tolerance >= 0.0) || !std::isfinite(p.tolerance))
        throw core::InvalidInputError("kmeans_layers: tolerance must be finite and >= 0");
    if (p.bins < 16 || p.bins > 65536)
        throw core::InvalidInputError("kmeans_layers: bins must be in 16..65536, got " + std::to_string(p.bins));
    if (!p.seeds.empty()) {
        if (static_cast<int>(p.seeds.size()) != p.clusters)
            throw core::InvalidInputError("kmeans_layers: " + std::to_string(p.seeds.size()) +
                                          " seeds given for " + std::to_string(p.clusters) + " clusters");
        for (double s : p.seeds)
            if (!std::isfinite(s))
                throw core::InvalidInputError("kmeans_layers: the seeds must be finite");
    }
}

} // namespace

KMeansResult kmeans_layers(const core::ImageF& image, const KMeansParams& params, const core::LabelImage3D* roi)
{
    core::validate_geometry(image, "kmeans_layers: image");
    if (image.data.size() != image.voxel_count())
        throw core::InvalidInputError("kmeans_layers: the image holds " + std::to_string(image.data.size()) +
                                      " values for " + std::to_string(image.voxel_count()) + " voxels");
    check_params(params);
    if (roi && (!core::same_grid(image, *roi) || roi->data.size() != image.data.size()))
        throw core::InvalidInputError("kmeans_layers: the ROI is not on the image's grid");

    // Range of the clustered values, checking for NaN and infinity on the way.
    const std::size_t n = image.data.size();
    auto in_roi = [roi](std::size_t i) { return !roi || roi->data[i] != 0; };
    std::size_t bad = 0, first_bad = n, used = 0;
    float lo = std::numeric_limits<float>::max(), hi = std::numeric_limits<float>::lowest();
    for (std::size_t i = 0; i < n; ++i) {
        if (!in_roi(i))
            continue;
        const float v = image.data[i];
        if (!std::isfinite(v)) {
            if (bad++ == 0)
                first_bad = i;
            continue;
        }
        lo = std::min(lo, v);
        hi = std::max(hi, v);
        ++used;
    }
    if (bad) {
        const std::size_t nx = static_cast<std::size_t>(image.size[0]), ny = static_cast<std::size_t>(image.size[1]);
        throw core::InvalidInputError("kmeans_layers: " + std::to_string(bad) +
                                      " clustered voxels are NaN or infinite, the first at (" +
                                      std::to_string(first_bad % nx) + ", " + std::to_string((first_bad / nx) % ny) +
                                      ", " + std::to_string(first_bad / (nx * ny)) + ")");
    }
    if (used == 0)
        throw core::InvalidInputError("kmeans_layers: the ROI is empty: no voxel to cluster");

    const std::vector<Bin> bins = histogram(image.data.data(), n, in_roi, lo, hi, params.bins);
    // Without seeds: the global optimum on the bins, which Lloyd then only confirms (one
    // iteration: an optimum is a fixed point). With seeds (the previous slice's centres): Lloyd
    // from them, a local optimum that keeps each layer's identity from slice to slice.
    const std::vector<double> seeds = params.seeds.empty() ? optimal_1d(bins, params.clusters) : params.seeds;
    const Lloyd ll = lloyd_1d(bins, seeds, params.max_iterations, params.tolerance);

    KMeansResult r;
    r.iterations = ll.iterations;
    r.converged = ll.converged;
    std::vector<double> centres = ll.centres;

    // Label the voxels by their own values (not their bins'), so the layers are exactly the
    // midpoint partition of the final centres; a layer emptied by that (a boundary bin that
    // split) is dropped and the labelling redone.
    r.layers = core::LabelImage3D(image.geometry(), 0);
    for (;;) {
        const std::vector<double> t = midpoints(centres);
        const std::size_t k = centres.size();
        std::vector<double> cnt(k, 0.0), sum(k, 0.0), sumsq(k, 0.0);
        const Index ni = static_cast<Index>(n);
#pragma omp parallel if (ni > kParallelMin)
        {
            std::vector<double> c(k, 0.0), s(k, 0.0), s2(k, 0.0);
#pragma omp for schedule(static) nowait
            for (Index i = 0; i < ni; ++i) {
                const auto u = static_cast<std::size_t>(i);
                if (roi && roi->data[u] == 0)
                    continue;
                const double v = image.data[u];
                const int l = layer_of(v, t);
                r.layers.data[u] = static_cast<std::uint8_t>(l + 1);
                c[static_cast<std::size_t>(l)] += 1.0;
                s[static_cast<std::size_t>(l)] += v;
                s2[static_cast<std::size_t>(l)] += v * v;
            }
#pragma omp critical
            for (std::size_t j = 0; j < k; ++j) {
                cnt[j] += c[j];
                sum[j] += s[j];
                sumsq[j] += s2[j];
            }
        }
        std::vector<double> kept;
        for (std::size_t j = 0; j < k; ++j)
            if (cnt[j] > 0.0)
                kept.push_back(centres[j]);
        if (kept.size() != k) {
            centres = kept;
            continue;
        }
        r.thresholds = t;
        r.objective = 0.0;
        for (std::size_t j = 0; j < k; ++j) {
            const double mean = sum[j] / cnt[j];
            const double ss = std::max(0.0, sumsq[j] - cnt[j] * mean * mean);
            r.centres.push_back(mean);
            r.sigmas.push_back(std::sqrt(ss / cnt[j]));
            r.counts.push_back(static_cast<std::size_t>(cnt[j]));
            r.objective += ss;
        }
        break;
    }
    return r;
}

LayerResult layer_mask(const core::ImageF& image, const KMeansResult& km, double target_value,
                       const LayerParams& params)
{
    if (km.centres.empty() || km.sigmas.size() != km.centres.size())
        throw core::InvalidInputError("layer_mask: the K-means result is empty");
    if (!core::same_grid(image, km.layers) || image.data.size() != km.layers.data.size())
        throw core::InvalidInputError("layer_mask: the image and the K-means layers are on different grids");
    if (!std::isfinite(target_value))
        throw core::InvalidInputError("layer_mask: the target value must be finite");
    if (!(params.alpha >= 0.0) || !std::isfinite(params.alpha))
        throw core::InvalidInputError("layer_mask: alpha must be finite and >= 0");
    if (params.max_depth < 0 || !(params.min_sigma >= 0.0) || !std::isfinite(params.split_separation) ||
        !(params.min_split_fraction >= 0.0 && params.min_split_fraction < 0.5))
        throw core::InvalidInputError("layer_mask: max_depth, min_sigma must be >= 0, split_separation finite, "
                                      "min_split_fraction in [0, 0.5)");

    LayerResult r;
    std::size_t best = 0;
    for (std::size_t j = 1; j < km.centres.size(); ++j)
        if (std::abs(km.centres[j] - target_value) < std::abs(km.centres[best] - target_value))
            best = j;
    r.layer = static_cast<int>(best) + 1;
    r.centre = km.centres[best];
    r.sigma = km.sigmas[best];

    // Multi-layer refinement: split the layer by 2-means while the split is clean (Ashman's D)
    // and keep the part nearest the target.
    if (params.max_depth > 0) {
        std::vector<float> vals;
        const auto label = static_cast<std::uint8_t>(r.layer);
        for (std::size_t i = 0; i < image.data.size(); ++i)
            if (km.layers.data[i] == label && std::isfinite(image.data[i]))
                vals.push_back(image.data[i]);
        double lo = -std::numeric_limits<double>::infinity(), hi = std::numeric_limits<double>::infinity();
        for (int depth = 0; depth < params.max_depth && vals.size() >= 2; ++depth) {
            const auto [mn, mx] = std::minmax_element(vals.begin(), vals.end());
            if (!(*mx > *mn))
                break;
            const std::vector<Bin> bins = histogram(vals, *mn, *mx, 1024);
            const double total = static_cast<double>(vals.size());
            const Lloyd two = lloyd_1d(bins, {quantile(bins, total, 0.25), quantile(bins, total, 0.75)}, 100, 0.0);
            if (two.centres.size() != 2)
                break;
            const double t = 0.5 * (two.centres[0] + two.centres[1]);
            const Stats a = stats_of(bins, -std::numeric_limits<double>::infinity(), t);
            const Stats b = stats_of(bins, t, std::numeric_limits<double>::infinity());
            const double spread = std::sqrt(a.sigma * a.sigma + b.sigma * b.sigma);
            const double d = spread > 0 ? std::sqrt(2.0) * std::abs(b.mean - a.mean) / spread
                                        : std::numeric_limits<double>::infinity();
            if (!(d > params.split_separation) || std::min(a.count, b.count) < params.min_split_fraction * total)
                break;
            const bool upper = std::abs(b.mean - target_value) < std::abs(a.mean - target_value);
            const Stats& keep = upper ? b : a;
            (upper ? lo : hi) = t;
            r.centre = keep.mean;
            r.sigma = keep.sigma;
            r.depth = depth + 1;
            vals.erase(std::remove_if(vals.begin(), vals.end(), [&](float v) { return double(v) < lo || double(v) >= hi; }),
                       vals.end());
        }
    }
    r.sigma = std::max(r.sigma, params.min_sigma);
    r.low = r.centre - params.alpha * r.sigma;
    r.high = r.centre + params.alpha * r.sigma;

    r.mask = core::LabelImage3D(image.geometry(), 0);
    const float flo = static_cast<float>(r.low), fhi = static_cast<float>(r.high);
    const Index n = static_cast<Index>(image.data.size());
#pragma omp parallel for if (n > kParallelMin) schedule(static)
    for (Index i = 0; i < n; ++i) {
        const auto u = static_cast<std::size_t>(i);
        const float v = image.data[u];
        r.mask.data[u] = km.layers.data[u] != 0 && v >= flo && v <= fhi ? 1 : 0;
    }
    return r;
}

} // namespace lobe::seg
