// Tumour segmentation (issue 5): Dice, detection of each tumour and time, automatic (K-means
// layers, and with the CDSG refinement) and semi-automatic (one seed per tumour), on lphantom volumes
// with the truth liver and vessels given.
//   tumour_bench [--inputs default,fine,coarse,spXxYxZsN] [--variants full,cdsg,cdsg-unshrunk,seeds,no-vessels]
//                [--csv FILE]
#include "common/args.h"
#include "lphantom/phantom.h"

#include "lobe/seg/tumours.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

using namespace lobe;

namespace {

phantom::PhantomParams input(const std::string& name)
{
    phantom::PhantomParams p;
    auto grid = [&](std::array<double, 3> spacing, std::uint64_t seed) {
        p.spacing = spacing;
        p.size = phantom::size_for_spacing(spacing);
        p.seed = seed;
    };
    if (name == "default") {
    } else if (name == "fine") {
        grid({0.8, 0.8, 1.5}, 5);
    } else if (name == "coarse") {
        grid({1.4, 1.4, 2.5}, 3);
    } else if (name == "noisy") {
        p.noise_sigma_hu = 25;
        p.seed = 11;
    } else if (name == "notumours") {
        p.tumours = false;
    } else if (name.rfind("sp", 0) == 0) {
        double x = 0, y = 0, z = 0;
        unsigned long long seed = 1;
        if (std::sscanf(name.c_str(), "sp%lfx%lfx%lfs%llu", &x, &y, &z, &seed) != 4)
            throw std::runtime_error("bad input " + name);
        grid({x, y, z}, seed);
    } else {
        throw std::runtime_error("unknown input " + name);
    }
    return p;
}

} // namespace

int main(int argc, char** argv)
{
    std::vector<std::string> inputs{"default"}, variants{"full"};
    std::string csv;
    for (int a = 1; a + 1 < argc; a += 2) {
        const std::string s = argv[a];
        if (s == "--inputs")
            inputs = bench::split(argv[a + 1]);
        else if (s == "--variants")
            variants = bench::split(argv[a + 1]);
        else if (s == "--csv")
            csv = argv[a + 1];
        else {
            std::cerr << "usage: tumour_bench [--inputs ...] [--variants full,cdsg,cdsg-unshrunk,seeds,no-vessels] [--csv FILE]\n";
            return 1;
        }
    }
    std::ofstream out;
    if (!csv.empty()) {
        out.open(csv);
        out << "input,variant,seconds,dice,found,false_positives,dice_lobular,dice_satellite,dice_boundary\n";
    }
    for (const auto& name : inputs) {
        const auto pp = input(name);
        const auto ph = phantom::generate_phantom(pp);
        core::ImageF hu(ph.ct.geometry());
        for (std::size_t u = 0; u < hu.data.size(); ++u)
            hu.data[u] = ph.ct.data[u];
        core::LabelImage3D liver(ph.labels.geometry(), 0), vessels(ph.labels.geometry(), 0);
        for (std::size_t u = 0; u < liver.data.size(); ++u) {
            liver.data[u] = ph.labels.data[u] >= 1 && ph.labels.data[u] <= 4 ? 1 : 0;
            vessels.data[u] = ph.labels.data[u] == 2 || ph.labels.data[u] == 3 ? 1 : 0;
        }
        // The truth tumours: voxels of label 4 nearest each truth centroid (they do not touch).
        std::vector<int> owner(ph.labels.data.size(), -1);
        for (int k = 0; k < ph.labels.size[2]; ++k)
            for (int j = 0; j < ph.labels.size[1]; ++j)
                for (int i = 0; i < ph.labels.size[0]; ++i) {
                    const std::size_t u = ph.labels.index(i, j, k);
                    if (ph.labels.data[u] != 4)
                        continue;
                    const core::Vec3 p = ph.labels.index_to_physical(i, j, k);
                    double best = 1e300;
                    for (std::size_t t = 0; t < ph.truth.tumours.size(); ++t) {
                        const double d = core::distance(p, ph.truth.tumours[t].centroid);
                        if (d < best) {
                            best = d;
                            owner[u] = int(t);
                        }
                    }
                }
        for (const auto& v : variants) {
            seg::TumourParams tp;
            std::vector<core::Vec3> seeds;
            const core::LabelImage3D* vp = &vessels;
            if (v == "cdsg")
                tp.use_cdsg = true;
            else if (v == "seeds")
                for (const auto& t : ph.truth.tumours)
                    seeds.push_back(t.centroid);
            else if (v == "cdsg-unshrunk") {
                tp.use_cdsg = true;
                tp.init_erosion_mm = 0;
            }
            else if (v == "no-vessels")
                vp = nullptr;
            else if (v != "full")
                throw std::runtime_error("unknown variant " + v);
            const auto t0 = std::chrono::steady_clock::now();
            const auto r = seg::segment_tumours(hu, liver, vp, tp, seeds);
            const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
            std::size_t s = 0, t = 0, both = 0;
            std::vector<std::size_t> ts(ph.truth.tumours.size(), 0), ss(ph.truth.tumours.size(), 0), bs(ph.truth.tumours.size(), 0);
            for (std::size_t u = 0; u < r.mask.data.size(); ++u) {
                const bool a = r.mask.data[u] != 0, b = ph.labels.data[u] == 4;
                s += a;
                t += b;
                both += a && b;
                if (b) {
                    ++ts[std::size_t(owner[u])];
                    bs[std::size_t(owner[u])] += a;
                }
            }
            // Per truth tumour: Dice against the segmented voxels nearest that tumour's centroid.
            for (std::size_t u = 0; u < r.mask.data.size(); ++u)
                if (r.mask.data[u]) {
                    const core::Vec3 p = r.mask.index_to_physical(int(u % std::size_t(r.mask.size[0])),
                                                                  int((u / std::size_t(r.mask.size[0])) % std::size_t(r.mask.size[1])),
                                                                  int(u / (std::size_t(r.mask.size[0]) * std::size_t(r.mask.size[1]))));
                    double best = 1e300;
                    int o = -1;
                    for (std::size_t k = 0; k < ph.truth.tumours.size(); ++k) {
                        const double d = core::distance(p, ph.truth.tumours[k].centroid);
                        if (d < best) {
                            best = d;
                            o = int(k);
                        }
                    }
                    ++ss[std::size_t(o)];
                }
            int found = 0, fp = 0;
            for (const auto& rep : r.tumours) {
                bool hit = false;
                for (const auto& tt : ph.truth.tumours)
                    hit = hit || core::distance(rep.centroid, tt.centroid) < tt.equivalent_radius_mm + 5;
                fp += !hit;
            }
            std::vector<double> dk(3, 0.0);
            for (std::size_t k = 0; k < ph.truth.tumours.size() && k < 3; ++k) {
                dk[k] = ts[k] + ss[k] ? 2.0 * double(bs[k]) / double(ts[k] + ss[k]) : 0.0;
                found += dk[k] >= 0.5;
            }
            char line[256];
            std::snprintf(line, sizeof line, "%s,%s,%.3f,%.4f,%d,%d,%.4f,%.4f,%.4f", name.c_str(), v.c_str(), secs,
                          s + t ? 2.0 * double(both) / double(s + t) : 1.0, found, fp, dk[0], dk[1], dk[2]);
            std::cout << line << std::endl;
            if (out.is_open())
                out << line << "\n" << std::flush;
            std::cerr << "  " << r.message << "; layers";
            for (double c : r.layer_centres)
                std::cerr << " " << c;
            std::cerr << "\n   ";
            for (const auto& [k, sec] : r.timings)
                std::cerr << " " << k << " " << sec;
            std::cerr << "\n";
        }
    }
    return 0;
}
