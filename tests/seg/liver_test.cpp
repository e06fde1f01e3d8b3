// Tests of the liver pipeline's driver (lobe/seg/liver.h) on phantoms.
#include "lobe/seg/liver.h"

#include "lobe/core/errors.h"
#include "lobe/seg/distance_transform.h"
#include "lobe/seg/metrics.h"
#include "lphantom/phantom.h"

#include <gtest/gtest.h>

#include <fstream>
#include <iostream>

using namespace lobe;

namespace {

core::LabelImage3D liver_truth(const core::LabelImage3D& labels)
{
    core::LabelImage3D m(labels.geometry(), 0);
    for (std::size_t i = 0; i < m.data.size(); ++i)
        m.data[i] = labels.data[i] >= 1 && labels.data[i] <= 4 ? 1 : 0;
    return m;
}

core::ImageF to_float(const core::Image3D<std::int16_t>& ct)
{
    core::ImageF f(ct.geometry());
    for (std::size_t i = 0; i < f.data.size(); ++i)
        f.data[i] = ct.data[i];
    return f;
}

} // namespace

TEST(LiverPropagation, ExperimentTruthSeed)
{
    phantom::PhantomParams pp;
    const auto ph = phantom::generate_phantom(pp);
    const core::LabelImage3D truth = liver_truth(ph.labels);
    const core::ImageF hu = to_float(ph.ct);
    const int k0 = ph.truth.landmark("liver_centroid").index[2];
    core::LabelImage3D sl = core::axial_slice(truth, k0);
    // shrink 10 mm
    core::LabelImage3D out(sl.geometry(), 0);
    for (std::size_t i = 0; i < sl.data.size(); ++i)
        out.data[i] = sl.data[i] ? 0 : 1;
    const auto d = seg::euclidean_distance(out);
    core::LabelImage3D seed(sl.geometry(), 0);
    for (std::size_t i = 0; i < sl.data.size(); ++i)
        seed.data[i] = sl.data[i] && d.data[i] > 10 ? 1 : 0;
    seg::LiverParams lp;
    if (std::getenv("LOBE_NO_RIBS")) lp.use_rib_cage = false;
    if (std::getenv("LOBE_NO_KMEANS")) lp.use_kmeans = false;
    if (std::getenv("LOBE_NO_3D")) lp.use_3d_pass = false;
    if (const char* it = std::getenv("LOBE_ITERS")) lp.propagation_max_iterations = std::atoi(it);
    if (const char* it = std::getenv("LOBE_GROWTH")) lp.max_growth_mm = std::atof(it);
    const auto r = std::getenv("LOBE_FULL") ? seg::segment_liver(hu, lp, nullptr, [](const std::string& s) { std::cerr << s << "\n"; })
                                           : seg::propagate_liver(hu, seed, k0, lp, [](const std::string& s) { std::cerr << s << "\n"; });
    if (r.seed.found) {
        const auto ts = core::axial_slice(truth, r.seed.slice);
        std::size_t in = 0, all = 0;
        for (std::size_t i = 0; i < ts.data.size(); ++i) if (r.seed.mask.data[i]) { ++all; in += ts.data[i]; }
        std::cerr << "seed precision " << double(in) / double(all) << " of " << all << "\n";
    }
    for (const auto& t : r.timings) std::cerr << t.first << " " << t.second << "\n";
    const auto m = seg::evaluate_segmentation(r.mask, truth);
    std::cerr << "Dice " << m.dice << " ASD " << m.surface.average << " slices " << r.first_slice << ".." << r.last_slice
              << " time " << r.timings[0].second << "\n";
    int tk0 = 1000, tk1 = -1;
    for (int k = 0; k < truth.size[2]; ++k)
        for (int j = 0; j < truth.size[1]; ++j)
            for (int i = 0; i < truth.size[0]; ++i)
                if (truth.at(i, j, k)) { tk0 = std::min(tk0, k); tk1 = std::max(tk1, k); }
    if (const char* dump = std::getenv("LOBE_LIVER_DUMP")) {
        std::ofstream(std::string(dump) + "/ct.raw", std::ios::binary).write(reinterpret_cast<const char*>(ph.ct.data.data()), std::streamsize(ph.ct.data.size() * 2));
        std::ofstream(std::string(dump) + "/seg.raw", std::ios::binary).write(reinterpret_cast<const char*>(r.mask.data.data()), std::streamsize(r.mask.data.size()));
        std::ofstream(std::string(dump) + "/labels.raw", std::ios::binary).write(reinterpret_cast<const char*>(ph.labels.data.data()), std::streamsize(ph.labels.data.size()));
    }
    std::cerr << "truth slices " << tk0 << ".." << tk1 << "\n";
}
