// Vessel segmentation (issue 5): time against accuracy with and without each stage.
// Generates lphantom volumes in-process, runs seg::segment_vessels inside the truth liver
// ({1,2,3,4}), and scores vessel Dice, centre-line recall by branch level, precision, tree labels
// and branch levels against the phantom's truth graph; for the gap inputs, the recall and level
// agreement of the subtree beyond the gap. bench/vessels/run.sh runs it and draws the chart.
//
//   vessel_bench [--inputs default,noisy,gap35,large] [--variants full,no-vesselness,...] [--reps N]
//                [--csv FILE] [--lut-csv FILE]
// Inputs: default (512 x 512 x 80, 0.7 x 0.7 x 2.5 mm: the demo's), large (512 x 512 x 200,
// 0.7 x 0.7 x 1 mm: the timing case), fine (0.8 x 0.8 x 1.5), coarse (1.4 x 1.4 x 2.5),
// noisy (default grid, 25 HU noise), gapNN (default grid, 5 mm of a level-3 portal branch at NN %
// contrast), invisible (vessels at the liver's HU), novessels, spXxYxZsN (any spacing and seed).
#include "common/args.h"
#include "lphantom/phantom.h"

#include "lobe/seg/fuzzy_connectedness.h"
#include "lobe/seg/vessels.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <limits>
#include <map>
#include <sstream>
#include <string>
#include <vector>

using namespace lobe;

namespace {

using Clock = std::chrono::steady_clock;

double since(Clock::time_point t0)
{
    return std::chrono::duration<double>(Clock::now() - t0).count();
}

struct Input {
    std::string name;
    phantom::PhantomParams params;
    double gap_fraction = -1; //!< >= 0: a contrast gap on portal edge 6 (level 3)
};

Input make_input(const std::string& name)
{
    Input in;
    in.name = name;
    auto grid = [&](std::array<double, 3> spacing, std::uint64_t seed) {
        in.params.spacing = spacing;
        in.params.size = phantom::size_for_spacing(spacing);
        in.params.seed = seed;
    };
    if (name == "default") {
    } else if (name == "large") {
        in.params.size = {512, 512, 200};
        in.params.spacing = {0.7, 0.7, 1.0};
    } else if (name == "fine") {
        grid({0.8, 0.8, 1.5}, 5);
    } else if (name == "coarse") {
        grid({1.4, 1.4, 2.5}, 3);
    } else if (name == "noisy") {
        in.params.noise_sigma_hu = 25;
        in.params.seed = 11;
    } else if (name.rfind("gap", 0) == 0) {
        in.gap_fraction = std::stod(name.substr(3)) / 100.0;
    } else if (name == "invisible") {
        in.params.hu.portal_vein = in.params.hu.hepatic_vein = in.params.hu.liver;
    } else if (name == "novessels") {
        in.params.vessels = false;
    } else if (name.rfind("sp", 0) == 0) {
        double x = 0, y = 0, z = 0;
        unsigned long long seed = 1;
        if (std::sscanf(name.c_str(), "sp%lfx%lfx%lfs%llu", &x, &y, &z, &seed) != 4)
            throw std::runtime_error("bad input " + name + " (spXxYxZsSEED)");
        grid({x, y, z}, seed);
    } else {
        throw std::runtime_error("unknown input " + name);
    }
    return in;
}

seg::VesselParams variant(const std::string& v)
{
    seg::VesselParams p;
    if (v == "full") {
    } else if (v == "no-vesselness") {
        p.use_vesselness = false;
    } else if (v == "no-sharpening") {
        p.use_directional_sharpening = false;
    } else if (v == "tan-kernel") {
        p.sharpening.sharpen_max = 0.75; // the thesis's DSG sharpening kernel on the vesselness
    } else if (v == "seed3") {
        p.seed_sigmas = 3;
    } else if (v == "no-fc") {
        p.use_fuzzy_connectedness = false;
    } else if (v == "no-lut") {
        p.lookup_table = false;
    } else if (v == "no-pruning") {
        p.use_pruning = false;
    } else if (v == "no-bridging") {
        p.bridge_gaps = false;
    } else if (v == "no-fc-no-bridging") {
        p.use_fuzzy_connectedness = false;
        p.bridge_gaps = false;
    } else {
        throw std::runtime_error("unknown variant " + v);
    }
    return p;
}

double dice(const core::LabelImage3D& seg, const core::LabelImage3D& truth, std::uint8_t a, std::uint8_t b)
{
    std::size_t ns = 0, nt = 0, both = 0;
    for (std::size_t u = 0; u < seg.data.size(); ++u) {
        const bool s = seg.data[u] == a || seg.data[u] == b;
        const bool t = truth.data[u] == a || truth.data[u] == b;
        ns += s;
        nt += t;
        both += s && t;
    }
    return ns + nt ? 2.0 * double(both) / double(ns + nt) : 1.0;
}

} // namespace

int main(int argc, char** argv)
{
    std::vector<std::string> inputs{"default"}, variants{"full"};
    int reps = 1;
    std::string csv, lut_csv;
    try {
        for (int a = 1; a < argc; ++a) {
            const std::string s = argv[a];
            auto next = [&]() -> std::string {
                if (a + 1 >= argc)
                    throw std::runtime_error(s + " needs a value");
                return argv[++a];
            };
            if (s == "--inputs")
                inputs = bench::split(next());
            else if (s == "--variants")
                variants = bench::split(next());
            else if (s == "--reps")
                reps = std::max(1, std::stoi(next()));
            else if (s == "--csv")
                csv = next();
            else if (s == "--lut-csv")
                lut_csv = next();
            else
                throw std::runtime_error("unknown option " + s);
        }
    } catch (const std::exception& e) {
        std::cerr << "vessel_bench: " << e.what() << "\nusage: vessel_bench [--inputs default,large,fine,coarse,noisy,gapNN,"
                     "invisible,novessels,spXxYxZsN] [--variants full,no-vesselness,no-sharpening,tan-kernel,no-fc,no-lut,"
                     "no-pruning,no-bridging,no-fc-no-bridging] [--reps N] [--csv FILE] [--lut-csv FILE]\n";
        return 1;
    }
    std::ofstream out, lut_out;
    if (!csv.empty()) {
        out.open(csv);
        out << "input,variant,seconds,seconds_fc,dice,dice_portal,dice_hepatic,recall_l1,recall_l2,recall_l3,recall_l4,"
               "recall,precision,label_accuracy,level_agreement,trees,segments,max_level,distal_recall,distal_level_agreement,"
               "found\n";
    }
    if (!lut_csv.empty()) {
        lut_out.open(lut_csv);
        lut_out << "input,liver_voxels,seconds_exact,seconds_lut,speedup,max_abs_difference\n";
    }
    for (const auto& name : inputs) {
        const Input in = make_input(name);
        const auto t0 = Clock::now();
        phantom::PhantomResult ph = phantom::generate_phantom(in.params);
        if (in.gap_fraction >= 0) {
            const auto& e = ph.truth.vessel_edges[6];
            phantom::add_vessel_gap(ph, in.params, 6, 0.5 * e.length_mm - 2.5, 5.0, in.gap_fraction);
        }
        std::cerr << name << ": phantom " << ph.ct.size[0] << " x " << ph.ct.size[1] << " x " << ph.ct.size[2] << " in "
                  << since(t0) << " s\n";
        core::ImageF hu(ph.ct.geometry());
        for (std::size_t u = 0; u < hu.data.size(); ++u)
            hu.data[u] = ph.ct.data[u];
        core::LabelImage3D liver(ph.labels.geometry(), 0);
        for (std::size_t u = 0; u < liver.data.size(); ++u)
            liver.data[u] = ph.labels.data[u] >= 1 && ph.labels.data[u] <= 4 ? 1 : 0;
        const core::CentrelineGraph truth = phantom::truth_graph(ph.truth);
        core::CentrelineGraph distal = truth;
        distal.edges.clear();
        if (in.gap_fraction >= 0)
            for (int id : {6, 16, 17}) { // edge 6 beyond the gap and its two children
                auto ed = truth.edges[std::size_t(id)];
                if (id == 6)
                    ed.points[0] = ed.points[0] + (ed.points[1] - ed.points[0]) * (0.5 + 3.0 / ed.length_mm);
                distal.edges.push_back(ed);
            }

        for (const auto& v : variants) {
            seg::VesselResult res;
            double secs = std::numeric_limits<double>::infinity();
            for (int r = 0; r < reps; ++r) {
                const auto t1 = Clock::now();
                res = seg::segment_vessels(hu, liver, variant(v));
                secs = std::min(secs, since(t1));
            }
            double fc_secs = 0;
            for (const auto& [k, s] : res.timings)
                if (k == "fuzzy connectedness" || k == "region growing")
                    fc_secs = s;
            const auto ev = seg::evaluate_centrelines(res.graph, truth, &liver);
            std::map<int, double> rec;
            for (const auto& l : ev.by_level)
                rec[l.level] = l.recall();
            int max_level = 0;
            for (const auto& e : res.graph.edges)
                max_level = std::max(max_level, static_cast<int>(e.level));
            const double label_acc = ev.overall.found ? double(ev.overall.labelled_right) / double(ev.overall.found) : 0.0;
            std::string distal_text = ",";
            if (in.gap_fraction >= 0) {
                const auto dv = seg::evaluate_centrelines(res.graph, distal, &liver);
                char b[64];
                std::snprintf(b, sizeof b, "%.3f,%.3f", dv.overall.recall(), dv.level_agreement);
                distal_text = b;
            }
            char line[640];
            std::snprintf(line, sizeof line, "%s,%s,%.3f,%.3f,%.4f,%.4f,%.4f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%zu,%zu,%d,%s,%d",
                          name.c_str(), v.c_str(), secs, fc_secs, dice(res.labels, ph.labels, 2, 3),
                          dice(res.labels, ph.labels, 2, 2), dice(res.labels, ph.labels, 3, 3), rec[1], rec[2], rec[3],
                          rec[4], ev.overall.recall(), ev.precision, label_acc, ev.level_agreement, res.trees.size(),
                          res.graph.edges.size(), max_level, distal_text.c_str(), res.found ? 1 : 0);
            std::cout << line << std::endl;
            if (out.is_open())
                out << line << "\n" << std::flush;
            std::cerr << "  " << v << ": " << res.message << "\n   ";
            for (const auto& [k, s] : res.timings)
                std::cerr << " " << k << " " << s;
            std::cerr << "\n";
        }

        if (lut_out.is_open()) {
            // The fuzzy-connectedness propagation over the whole liver (no minimum strength, so
            // every liver voxel is expanded), exact affinity against the lookup table, from the
            // pipeline's seeds and affinity.
            seg::VesselParams p;
            p.keep_images = true;
            const auto res = seg::segment_vessels(hu, liver, p);
            if (!res.found)
                continue;
            seg::FuzzyConnectednessParams fc;
            fc.affinity.object_mean = res.vessel_intensity;
            fc.affinity.object_sigma = 0.5 * res.contrast / std::sqrt(2 * std::log(2.0));
            fc.affinity.gradient_sigma = res.contrast / p.gradient_width_mm;
            double best[2] = {1e300, 1e300};
            seg::FuzzyConnectednessResult k[2];
            for (int r = 0; r < std::max(3, reps); ++r)
                for (int lut = 0; lut < 2; ++lut) {
                    fc.lookup_table = lut == 1;
                    const auto t1 = Clock::now();
                    k[lut] = seg::fuzzy_connectedness(res.feature, res.seeds, fc, &liver);
                    best[lut] = std::min(best[lut], since(t1));
                }
            double diff = 0;
            for (std::size_t u = 0; u < liver.data.size(); ++u)
                diff = std::max(diff, std::abs(double(k[0].connectedness.data[u]) - double(k[1].connectedness.data[u])));
            char line[256];
            std::snprintf(line, sizeof line, "%s,%zu,%.3f,%.3f,%.2f,%.4f", name.c_str(), k[0].expanded, best[0], best[1],
                          best[0] / best[1], diff);
            std::cout << "lut: " << line << std::endl;
            lut_out << line << "\n" << std::flush;
        }
    }
    return 0;
}
