#include "lobe/seg/tumours.h"

#include "detail/report.h"
#include "detail/volume.h"
#include "lobe/seg/distance_transform.h"
#include "lobe/seg/edge_map.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <deque>
#include <iomanip>
#include <sstream>
#include <string>
#include <vector>

namespace lobe::seg {
namespace {

using Clock = std::chrono::steady_clock;

void check_params(const TumourParams& p)
{
    auto nonneg = [](double v, const char* name) { detail::require_nonnegative(v, "segment_tumours", name); };
    nonneg(p.smoothing_mm, "smoothing_mm");
    nonneg(p.vessel_margin_mm, "vessel_margin_mm");
    nonneg(p.min_contrast, "min_contrast");
    nonneg(p.contrast_sigmas, "contrast_sigmas");
    nonneg(p.min_volume_ml, "min_volume_ml");
    nonneg(p.max_contrast, "max_contrast");
    nonneg(p.min_thickness_mm, "min_thickness_mm");
    nonneg(p.surface_rim_mm, "surface_rim_mm");
    nonneg(p.box_margin_mm, "box_margin_mm");
    nonneg(p.init_erosion_mm, "init_erosion_mm");
    nonneg(p.max_growth_mm, "max_growth_mm");
    nonneg(p.seed_radius_mm, "seed_radius_mm");
    nonneg(p.max_seed_extent_mm, "max_seed_extent_mm");
    if (p.kmeans.clusters < 2)
        throw core::InvalidInputError("segment_tumours: at least 2 K-means clusters are needed");
}

//! Distance [mm] from every voxel to the nearest non-zero voxel of `m`.
core::ImageF distance_to(const core::LabelImage3D& m)
{
    return euclidean_distance(m);
}

//! Distance [mm] from every voxel of `m` to the nearest voxel outside it.
core::ImageF depth_in(const core::LabelImage3D& m)
{
    core::LabelImage3D out = m;
    for (auto& v : out.data)
        v = v ? 0 : 1;
    return euclidean_distance(out);
}

} // namespace

TumourResult segment_tumours(const core::ImageF& image, const core::LabelImage3D& liver, const core::LabelImage3D* vessels,
                             const TumourParams& params, const std::vector<core::Vec3>& seeds, const TumourProgress& progress)
{
    detail::check_image(image, "segment_tumours: image");
    detail::check_same_grid(image, liver, "segment_tumours: the liver mask");
    if (vessels)
        detail::check_same_grid(image, *vessels, "segment_tumours: the vessel mask");
    check_params(params);
    auto say = [&](const std::string& s) {
        if (progress)
            progress(s);
    };
    const auto t_start = Clock::now();
    auto t0 = t_start;
    TumourResult res;
    auto lap = [&](const std::string& name) {
        const auto t1 = Clock::now();
        res.timings.emplace_back(name, std::chrono::duration<double>(t1 - t0).count());
        t0 = t1;
    };
    res.mask = core::LabelImage3D(image.geometry(), 0);

    const detail::Box lbox = detail::bounding_box(liver);
    if (lbox.empty())
        throw core::InvalidInputError("segment_tumours: the liver mask is empty");
    // Seeds: on the grid and in the liver.
    std::vector<std::array<int, 3>> seed_vox;
    for (const auto& s : seeds) {
        const core::Vec3 c = image.physical_to_index(s);
        const std::array<int, 3> v{static_cast<int>(std::lround(c.x)), static_cast<int>(std::lround(c.y)),
                                   static_cast<int>(std::lround(c.z))};
        if (!image.contains(v[0], v[1], v[2]) || !liver.at(v[0], v[1], v[2]))
            throw core::InvalidInputError("segment_tumours: seed (" + detail::fixed(s.x) + ", " + detail::fixed(s.y) + ", " + detail::fixed(s.z) +
                                          ") mm is not inside the liver");
        seed_vox.push_back(v);
    }
    const detail::Box box = detail::grown(lbox, detail::voxels_for(image, params.box_margin_mm + 3 * params.smoothing_mm), image);
    const core::ImageF I = detail::crop(image, box);
    core::LabelImage3D L = detail::crop(liver, box);
    for (auto& v : L.data)
        v = v ? 1 : 0;
    for (std::size_t u = 0; u < I.data.size(); ++u)
        if (L.data[u] && !std::isfinite(I.data[u]))
            throw core::InvalidInputError("segment_tumours: the image holds non-finite values inside the liver");
    const double voxel_ml = image.spacing[0] * image.spacing[1] * image.spacing[2] / 1000.0;
    const double finest = std::min({image.spacing[0], image.spacing[1], image.spacing[2]});

    // The region searched: the liver without its vessels (bright, and their partial-volume rims)
    // and without its surface rim (voxels that average the liver with fat, bile or air outside it
    // are dark like a tumour); a tumour reaching the rim gets it back at the end.
    const core::ImageF depth = depth_in(L); // mm to the liver's outside
    core::LabelImage3D R = L;
    core::LabelImage3D rim(L.geometry(), 0);
    for (int k = 0; k < L.size[2]; ++k)
        for (int j = 0; j < L.size[1]; ++j)
            for (int i = 0; i < L.size[0]; ++i) {
                const std::size_t u = L.index(i, j, k);
                if (!L.data[u])
                    continue;
                bool edge = static_cast<double>(depth.data[u]) <= params.surface_rim_mm;
                for (int dk = -1; dk <= 1 && !edge; ++dk)
                    for (int dj = -1; dj <= 1 && !edge; ++dj)
                        for (int di = -1; di <= 1 && !edge; ++di)
                            edge = !L.contains(i + di, j + dj, k + dk) || !L.at(i + di, j + dj, k + dk);
                if (edge) {
                    rim.data[u] = 1;
                    R.data[u] = 0;
                }
            }
    if (vessels) {
        const core::LabelImage3D V = detail::crop(*vessels, box);
        const core::ImageF dv = distance_to(V);
        for (std::size_t u = 0; u < R.data.size(); ++u)
            if (static_cast<double>(dv.data[u]) <= params.vessel_margin_mm)
                R.data[u] = 0;
    }
    // Normalised convolution: the mean of the region's own voxels around each voxel, so that the
    // liver's surroundings (fat, the vena cava) and the vessels do not blur into it.
    core::ImageF S(I.geometry(), 0.f);
    {
        core::ImageF num(I.geometry(), 0.f), den(I.geometry(), 0.f);
        for (std::size_t u = 0; u < I.data.size(); ++u)
            if (R.data[u]) {
                num.data[u] = I.data[u];
                den.data[u] = 1.f;
            }
        num = gaussian_smooth(num, params.smoothing_mm);
        den = gaussian_smooth(den, params.smoothing_mm);
        for (std::size_t u = 0; u < S.data.size(); ++u)
            S.data[u] = den.data[u] > 1e-3f ? num.data[u] / den.data[u] : I.data[u];
    }
    lap("smoothing");

    // Multi-layer K-means over the region; the most populous layer is the parenchyma.
    std::size_t n_region = 0;
    for (auto v : R.data)
        n_region += v;
    if (n_region < 64)
        throw core::InvalidInputError("segment_tumours: the liver (without its vessels) has too few voxels");
    const KMeansResult km = kmeans_layers(S, params.kmeans, &R);
    res.layer_centres = km.centres;
    {
        std::vector<float> vals;
        vals.reserve(n_region);
        for (std::size_t u = 0; u < S.data.size(); ++u)
            if (R.data[u])
                vals.push_back(S.data[u]);
        const auto [median, sd] = detail::median_and_robust_sd(std::move(vals));
        res.parenchyma = median;
        res.parenchyma_sigma = std::max(1e-3, sd);
    }
    const double delta = std::max(params.min_contrast, params.contrast_sigmas * res.parenchyma_sigma);
    // The tumour layers: centres below the parenchyma by delta or more; the boundary is half way
    // between their (count-weighted) centre and the parenchyma's (the half-contrast level of a
    // blurred edge).
    double tumour_sum = 0, tumour_count = 0;
    for (std::size_t j = 0; j < km.centres.size(); ++j)
        if (km.centres[j] <= res.parenchyma - delta) {
            tumour_sum += km.centres[j] * static_cast<double>(km.counts[j]);
            tumour_count += static_cast<double>(km.counts[j]);
        }
    const double tumour_centre = tumour_count > 0 ? tumour_sum / tumour_count : res.parenchyma - 2 * delta;
    res.threshold = 0.5 * (tumour_centre + res.parenchyma);
    lap("k-means");
    say("parenchyma " + detail::fixed(res.parenchyma) + " +- " + detail::fixed(res.parenchyma_sigma) + " (smoothed); " +
        (tumour_count > 0 ? "tumour layer at " + detail::fixed(tumour_centre) + ", boundary " + detail::fixed(res.threshold)
                          : "no layer below " + detail::fixed(res.parenchyma - delta)));

    std::vector<core::LabelImage3D> components; // each on the crop's grid
    std::vector<bool> from_seed;
    if (seed_vox.empty()) {
        if (tumour_count == 0) {
            res.message = "no tumours: no K-means layer inside the liver is darker than the parenchyma (" +
                          detail::fixed(res.parenchyma) + ") by " + detail::fixed(delta) + " or more";
            res.timings.emplace_back("total", std::chrono::duration<double>(Clock::now() - t_start).count());
            say(res.message);
            return res;
        }
        core::LabelImage3D cand(R.geometry(), 0);
        for (std::size_t u = 0; u < cand.data.size(); ++u)
            cand.data[u] = R.data[u] && static_cast<double>(S.data[u]) < res.threshold ? 1 : 0;
        const auto comps = detail::connected_components(cand, 26);
        const core::ImageF thick = depth_in(cand);
        std::vector<double> max_depth(comps.sizes.size(), 0.0);
        for (std::size_t u = 0; u < cand.data.size(); ++u)
            if (comps.id[u] >= 0)
                max_depth[std::size_t(comps.id[u])] = std::max(max_depth[std::size_t(comps.id[u])], static_cast<double>(thick.data[u]));
        std::vector<std::vector<float>> values(comps.sizes.size());
        for (std::size_t u = 0; u < cand.data.size(); ++u)
            if (comps.id[u] >= 0)
                values[std::size_t(comps.id[u])].push_back(S.data[u]);
        std::size_t too_dark = 0;
        for (std::size_t c = 0; c < comps.sizes.size(); ++c) {
            if (static_cast<double>(comps.sizes[c]) * voxel_ml < params.min_volume_ml || max_depth[c] < params.min_thickness_mm)
                continue;
            if (detail::quantile(values[c], 0.5) < res.parenchyma - params.max_contrast) {
                ++too_dark;
                continue;
            }
            core::LabelImage3D m(R.geometry(), 0);
            for (std::size_t u = 0; u < m.data.size(); ++u)
                m.data[u] = comps.id[u] == static_cast<std::int32_t>(c) ? 1 : 0;
            components.push_back(std::move(m));
            from_seed.push_back(false);
        }
        if (too_dark)
            res.message = std::to_string(too_dark) + " region" + (too_dark > 1 ? "s" : "") + " darker than parenchyma - " +
                          detail::fixed(params.max_contrast, 0) + " left out as fluid, bile or fat";
    } else {
        // Semi-automatic: each seed's tumour is the region darker than half way between the
        // seed's surroundings and the parenchyma, grown from the seed.
        for (std::size_t s = 0; s < seed_vox.size(); ++s) {
            const std::array<int, 3> v{seed_vox[s][0] - box.lo[0], seed_vox[s][1] - box.lo[1], seed_vox[s][2] - box.lo[2]};
            const core::Vec3 sp = I.index_to_physical(v[0], v[1], v[2]);
            std::vector<float> around;
            const auto reach = detail::voxels_for(I, params.seed_radius_mm);
            for (int k = std::max(0, v[2] - reach[2]); k <= std::min(I.size[2] - 1, v[2] + reach[2]); ++k)
                for (int j = std::max(0, v[1] - reach[1]); j <= std::min(I.size[1] - 1, v[1] + reach[1]); ++j)
                    for (int i = std::max(0, v[0] - reach[0]); i <= std::min(I.size[0] - 1, v[0] + reach[0]); ++i)
                        if (R.at(i, j, k) && core::distance(I.index_to_physical(i, j, k), sp) <= params.seed_radius_mm)
                            around.push_back(S.at(i, j, k));
            const double seed_value = around.empty() ? static_cast<double>(S.at(v[0], v[1], v[2])) : detail::quantile(around, 0.5);
            if (res.parenchyma - seed_value < params.min_contrast) {
                res.message += (res.message.empty() ? "" : "; ") + std::string("seed ") + std::to_string(s + 1) +
                               ": not in a hypodense region (" + detail::fixed(seed_value) + " against parenchyma " +
                               detail::fixed(res.parenchyma) + ")";
                continue;
            }
            const double t = 0.5 * (seed_value + res.parenchyma);
            core::LabelImage3D m(R.geometry(), 0);
            std::deque<std::array<int, 3>> q{v};
            m.at(v[0], v[1], v[2]) = 1;
            while (!q.empty()) {
                const auto c = q.front();
                q.pop_front();
                for (int dk = -1; dk <= 1; ++dk)
                    for (int dj = -1; dj <= 1; ++dj)
                        for (int di = -1; di <= 1; ++di) {
                            const int i = c[0] + di, j = c[1] + dj, k = c[2] + dk;
                            if (!m.contains(i, j, k) || m.at(i, j, k) || !R.at(i, j, k) || static_cast<double>(S.at(i, j, k)) >= t)
                                continue;
                            if (core::distance(m.index_to_physical(i, j, k), sp) > params.max_seed_extent_mm)
                                continue;
                            m.at(i, j, k) = 1;
                            q.push_back({i, j, k});
                        }
            }
            components.push_back(std::move(m));
            from_seed.push_back(true);
        }
    }
    lap("layers to components");

    // CDSG from each component, in its box, on the smoothed image with the liver's outside and
    // the vessels set to the parenchyma's value (no edge pulls the contour out of the liver).
    core::LabelImage3D tum(R.geometry(), 0);
    std::vector<int> iterations(components.size(), 0);
    std::vector<bool> converged(components.size(), true);
    for (std::size_t c = 0; c < components.size(); ++c) {
        const core::LabelImage3D& comp = components[c];
        if (!params.use_cdsg) {
            for (std::size_t u = 0; u < tum.data.size(); ++u)
                tum.data[u] |= comp.data[u];
            continue;
        }
        const detail::Box cb = detail::grown(detail::bounding_box(comp), detail::voxels_for(I, params.box_margin_mm), I);
        core::ImageF sub = detail::crop(S, cb);
        const core::LabelImage3D sub_r = detail::crop(R, cb);
        for (std::size_t u = 0; u < sub.data.size(); ++u)
            if (!sub_r.data[u])
                sub.data[u] = static_cast<float>(res.parenchyma);
        const core::LabelImage3D sub_c = detail::crop(comp, cb);
        const core::ImageF inner = depth_in(sub_c);
        core::LabelImage3D init(sub_c.geometry(), 0);
        std::size_t n_init = 0;
        for (std::size_t u = 0; u < init.data.size(); ++u)
            if (sub_c.data[u] && static_cast<double>(inner.data[u]) > params.init_erosion_mm) {
                init.data[u] = 1;
                ++n_init;
            }
        if (n_init == 0)
            init = sub_c;
        SnakeParams sp = params.snake;
        // The window spans four times the tumour's contrast around the boundary level, so the
        // tumour's edge has the strength of an organ edge in the default W400 window.
        const double contrast = std::max(res.parenchyma - res.threshold, 1.0) * 2.0;
        sp.edge.window.level = res.threshold;
        sp.edge.window.width = 4.0 * contrast;
        sp.competition = CompetitionMode::Off;
        SnakeResult snake;
        try {
            snake = segment_snake(sub, init, sp);
        } catch (const core::InvalidInputError&) {
            // A component filling its whole box (nothing outside to grow into): keep it as it is.
            for (std::size_t u = 0; u < tum.data.size(); ++u)
                tum.data[u] |= comp.data[u];
            continue;
        }
        iterations[c] = snake.iterations;
        converged[c] = snake.converged;
        const core::ImageF from_comp = distance_to(sub_c);
        core::LabelImage3D part(tum.geometry(), 0);
        for (int k = 0; k < sub.size[2]; ++k)
            for (int j = 0; j < sub.size[1]; ++j)
                for (int i = 0; i < sub.size[0]; ++i) {
                    const std::size_t u = sub.index(i, j, k);
                    if ((snake.mask.data[u] && sub_r.data[u] && static_cast<double>(from_comp.data[u]) <= params.max_growth_mm) ||
                        init.data[u])
                        tum.at(i + cb.lo[0], j + cb.lo[1], k + cb.lo[2]) = 1;
                }
    }
    lap("cdsg");

    // The surface rim next to a tumour is tumour (the boundary tumour of the thesis's failure
    // cases reaches the liver's surface): rim voxels touching a tumour voxel (26-neighbours).
    {
        std::vector<std::size_t> grow;
        for (int k = 0; k < tum.size[2]; ++k)
            for (int j = 0; j < tum.size[1]; ++j)
                for (int i = 0; i < tum.size[0]; ++i) {
                    const std::size_t u = tum.index(i, j, k);
                    if (!rim.data[u] || tum.data[u])
                        continue;
                    bool next = false;
                    for (int dk = -1; dk <= 1 && !next; ++dk)
                        for (int dj = -1; dj <= 1 && !next; ++dj)
                            for (int di = -1; di <= 1 && !next; ++di)
                                next = tum.contains(i + di, j + dj, k + dk) && tum.at(i + di, j + dj, k + dk);
                    if (next)
                        grow.push_back(u);
                }
        for (std::size_t u : grow)
            tum.data[u] = 1;
    }

    // Reports per connected tumour.
    const auto comps = detail::connected_components(tum, 26);
    struct Acc {
        core::Vec3 c;
        double n = 0, sum = 0;
        bool surface = false, seeded = false;
        int iters = 0;
        bool conv = true;
    };
    std::vector<Acc> acc(comps.sizes.size());
    for (int k = 0; k < tum.size[2]; ++k)
        for (int j = 0; j < tum.size[1]; ++j)
            for (int i = 0; i < tum.size[0]; ++i) {
                const std::size_t u = tum.index(i, j, k);
                if (comps.id[u] < 0)
                    continue;
                Acc& a = acc[std::size_t(comps.id[u])];
                a.c += tum.index_to_physical(i, j, k);
                a.n += 1;
                a.sum += static_cast<double>(I.data[u]);
                a.surface = a.surface || static_cast<double>(depth.data[u]) <= 1.5 * finest;
                for (std::size_t c = 0; c < components.size(); ++c)
                    if (components[c].data[u]) {
                        a.seeded = a.seeded || from_seed[c];
                        a.iters = std::max(a.iters, iterations[c]);
                        a.conv = a.conv && converged[c];
                    }
            }
    for (const auto& a : acc) {
        TumourReport r;
        r.centroid = a.c / a.n;
        r.volume_ml = a.n * voxel_ml;
        r.mean_intensity = a.sum / a.n;
        r.contrast = r.mean_intensity - res.parenchyma;
        r.touches_surface = a.surface;
        r.from_seed = a.seeded;
        r.snake_iterations = a.iters;
        r.snake_converged = a.conv;
        res.tumours.push_back(r);
    }
    std::sort(res.tumours.begin(), res.tumours.end(), [](const TumourReport& a, const TumourReport& b) { return a.volume_ml > b.volume_ml; });
    for (auto& v : tum.data)
        v = v ? kTumourLabel : 0;
    detail::paste(res.mask, tum, box);
    res.found = !res.tumours.empty();
    std::string list;
    for (const auto& t : res.tumours)
        list += (list.empty() ? "" : ", ") + detail::fixed(t.volume_ml, 2) + " mL" + (t.touches_surface ? " (at the surface)" : "");
    const std::string what = res.found ? std::to_string(res.tumours.size()) + " tumour" + (res.tumours.size() > 1 ? "s: " : ": ") + list
                                       : "no tumours";
    res.message = res.message.empty() ? what : what + "; " + res.message;
    res.timings.emplace_back("total", std::chrono::duration<double>(Clock::now() - t_start).count());
    say(res.message);
    return res;
}

} // namespace lobe::seg
