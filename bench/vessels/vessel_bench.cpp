// Vessel segmentation: time against accuracy with and without each stage (issue 5).
// Generates lphantom volumes in-process, runs seg::segment_vessels inside the truth liver
// ({1,2,3,4}), and scores vessel Dice, centre-line recall by branch level and precision.
//   vessel_bench [--inputs default,fine,large] [--variants full,no-vesselness,...] [--reps N] [--csv FILE]
#include "lphantom/phantom.h"

#include "lobe/seg/metrics.h"
#include "lobe/seg/vessels.h"

#include <algorithm>
#include <cstdlib>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

using namespace lobe;

namespace {

std::vector<std::string> split(const std::string& s)
{
    std::vector<std::string> out;
    std::stringstream ss(s);
    std::string t;
    while (std::getline(ss, t, ','))
        if (!t.empty())
            out.push_back(t);
    return out;
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
    if (name == "default") {
        // the demo's phantom: 512 x 512 x 80, 0.7 x 0.7 x 2.5 mm
    } else if (name == "fine") {
        in.params.spacing = {0.8, 0.8, 1.5};
        in.params.size = phantom::size_for_spacing(in.params.spacing);
        in.params.seed = 5;
    } else if (name == "large") {
        // the timing case: 512 x 512 x 200 (0.7 x 0.7 x 1 mm)
        in.params.size = {512, 512, 200};
        in.params.spacing = {0.7, 0.7, 1.0};
    } else if (name == "coarse") {
        in.params.spacing = {1.4, 1.4, 2.5};
        in.params.size = phantom::size_for_spacing(in.params.spacing);
        in.params.seed = 3;
    } else if (name.rfind("gap", 0) == 0) {
        // gapNN: a 5 mm stretch of a level-3 portal branch with NN % contrast
        in.gap_fraction = std::stod(name.substr(3)) / 100.0;
    } else if (name == "invisible") {
        // no contrast: vessels at the liver's HU
        in.params.hu.portal_vein = in.params.hu.hepatic_vein = in.params.hu.liver;
    } else if (name == "novessels") {
        in.params.vessels = false;
    } else if (name == "noisy") {
        // a low-dose scan: twice the noise
        in.params.noise_sigma_hu = 25;
        in.params.seed = 11;
    } else if (name.rfind("sp", 0) == 0) {
        // sp<x>x<y>x<z>s<seed>, e.g. sp1.2x1.2x2s21: another grid and noise seed
        double x = 0, y = 0, z = 0;
        unsigned long long seed = 1;
        if (std::sscanf(name.c_str(), "sp%lfx%lfx%lfs%llu", &x, &y, &z, &seed) != 4)
            throw std::runtime_error("bad input " + name);
        in.params.spacing = {x, y, z};
        in.params.size = phantom::size_for_spacing(in.params.spacing);
        in.params.seed = seed;
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
        p.sharpening.sharpen_max = 0.75;
    } else if (v == "axial-3") {
        p.sharpening.half_length_mm = 3;
    } else if (v == "no-fc-no-bridging") {
        p.use_fuzzy_connectedness = false;
        p.bridge_gaps = false;
    } else if (v == "no-fc") {
        p.use_fuzzy_connectedness = false;
    } else if (v == "no-lut") {
        p.lookup_table = false;
    } else if (v == "no-pruning") {
        p.use_pruning = false;
    } else if (v == "no-bridging") {
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
    std::string csv;
    for (int a = 1; a < argc; ++a) {
        const std::string s = argv[a];
        auto next = [&]() -> std::string {
            if (a + 1 >= argc)
                throw std::runtime_error(s + " needs a value");
            return argv[++a];
        };
        if (s == "--inputs")
            inputs = split(next());
        else if (s == "--variants")
            variants = split(next());
        else if (s == "--reps")
            reps = std::stoi(next());
        else if (s == "--csv")
            csv = next();
        else {
            std::cerr << "usage: vessel_bench [--inputs default,fine,large,coarse] [--variants full,no-vesselness,"
                         "no-sharpening,no-fc,no-lut,no-pruning,no-bridging] [--reps N] [--csv FILE]\n";
            return 1;
        }
    }
    std::ofstream out;
    if (!csv.empty()) {
        out.open(csv);
        out << "input,variant,seconds,seconds_fc,dice,dice_portal,dice_hepatic,recall_l1,recall_l2,recall_l3,recall_l4,"
               "recall,precision,label_accuracy,level_agreement,trees,edges,max_level\n";
    }
    for (const auto& name : inputs) {
        Input in = make_input(name);
        const auto t0 = std::chrono::steady_clock::now();
        phantom::PhantomResult ph = phantom::generate_phantom(in.params);
        if (std::getenv("VB_GAP"))
            in.gap_fraction = std::atof(std::getenv("VB_GAP"));
        if (in.gap_fraction >= 0) {
            const auto& e = ph.truth.vessel_edges[6];
            phantom::add_vessel_gap(ph, in.params, 6, 0.5 * e.length_mm - 2.5, 5.0, in.gap_fraction);
        }
        std::cerr << name << ": phantom " << ph.ct.size[0] << "x" << ph.ct.size[1] << "x" << ph.ct.size[2] << " in "
                  << std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() << " s\n";
        const core::ImageF hu = [&] {
            core::ImageF f(ph.ct.geometry());
            for (std::size_t u = 0; u < f.data.size(); ++u)
                f.data[u] = ph.ct.data[u];
            return f;
        }();
        core::LabelImage3D liver(ph.labels.geometry(), 0);
        for (std::size_t u = 0; u < liver.data.size(); ++u)
            liver.data[u] = ph.labels.data[u] >= 1 && ph.labels.data[u] <= 4 ? 1 : 0;
        const core::CentrelineGraph truth = phantom::truth_graph(ph.truth);
        for (const auto& v : variants) {
            for (int r = 0; r < reps; ++r) {
                seg::VesselParams p = variant(v);
                p.keep_images = std::getenv("VB_DEBUG") != nullptr;
                const auto t1 = std::chrono::steady_clock::now();
                const seg::VesselResult res = seg::segment_vessels(hu, liver, p);
                const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t1).count();
                double fc_secs = 0;
                for (const auto& [k, s] : res.timings)
                    if (k == "fuzzy connectedness" || k == "region growing")
                        fc_secs = s;
                const double d = dice(res.labels, ph.labels, 2, 3);
                const double dp = dice(res.labels, ph.labels, 2, 2);
                const double dh = dice(res.labels, ph.labels, 3, 3);
                const auto ev = seg::evaluate_centrelines(res.graph, truth, &liver);
                std::map<int, double> rec;
                for (const auto& l : ev.by_level)
                    rec[l.level] = l.recall();
                int max_level = 0;
                for (const auto& e : res.graph.edges)
                    max_level = std::max(max_level, static_cast<int>(e.level));
                const double label_acc =
                    ev.overall.found ? double(ev.overall.labelled_right) / double(ev.overall.found) : 0.0;
                char line[512];
                std::snprintf(line, sizeof line, "%s,%s,%.3f,%.3f,%.4f,%.4f,%.4f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%zu,%zu,%d",
                              name.c_str(), v.c_str(), secs, fc_secs, d, dp, dh, rec[1], rec[2], rec[3], rec[4],
                              ev.overall.recall(), ev.precision, label_acc, ev.level_agreement, res.trees.size(),
                              res.graph.edges.size(), max_level);
                std::cout << line << std::endl;
                if (out)
                    out << line << "\n";
                std::cerr << "  " << res.message << "\n  timings:";
                for (const auto& [k, s] : res.timings)
                    std::cerr << " " << k << "=" << s;
                std::cerr << "\n  centreline: skeleton " << res.centreline.skeleton_voxels << " spurs "
                          << res.centreline.spurs_pruned << " merged " << res.centreline.junctions_merged
                          << " dropped " << res.centreline.components_dropped << " cycles " << res.centreline.cycles_broken
                          << "; parenchyma " << res.parenchyma << " sigma " << res.parenchyma_sigma << " vessel "
                          << res.vessel_intensity << "\n";
                for (const auto& t : res.trees)
                    std::cerr << "  tree label " << t.label << " " << t.name << " length " << t.centreline_mm << " edges "
                              << t.edges << " levels " << t.max_level << " I " << t.mean_intensity << "\n";
                if (p.keep_images) {
                    // distributions inside truth vessels (by label) and parenchyma
                    for (int lab : {1, 2, 3, 4}) {
                        std::vector<float> vv, ff;
                        for (std::size_t u = 0; u < ph.labels.data.size(); ++u)
                            if (ph.labels.data[u] == lab) {
                                vv.push_back(res.vesselness.data[u]);
                                ff.push_back(hu.data[u]);
                            }
                        std::sort(vv.begin(), vv.end());
                        std::sort(ff.begin(), ff.end());
                        auto qq = [](const std::vector<float>& x, double q) { return x.empty() ? 0.f : x[std::size_t(q * double(x.size() - 1))]; };
                        std::cerr << "  label " << lab << " n=" << vv.size() << " V q10/50/90 " << qq(vv, .1) << " " << qq(vv, .5) << " " << qq(vv, .9)
                                  << "  HU q10/50/90 " << qq(ff, .1) << " " << qq(ff, .5) << " " << qq(ff, .9) << "\n";
                    }
                }
                if (std::getenv("VB_EDGES"))
                    for (const auto& e : res.graph.edges) {
                        const auto& a = res.graph.nodes[std::size_t(e.from)].position;
                        const auto& b = res.graph.nodes[std::size_t(e.to)].position;
                        std::fprintf(stderr, "  edge %d->%d L%d lab%d %s r=%.1f len=%.1f (%.0f,%.0f,%.0f)->(%.0f,%.0f,%.0f)\n", e.from, e.to,
                                     e.level, e.label, e.name.c_str(), e.radius_mm, e.length_mm, a.x, a.y, a.z, b.x, b.y, b.z);
                    }
                if (in.gap_fraction >= 0) {
                    // the subtree beyond the gap: edge 6's distal half and its children 16, 17
                    core::CentrelineGraph distal = truth;
                    distal.edges.clear();
                    for (int id : {6, 16, 17}) {
                        auto ed = truth.edges[std::size_t(id)];
                        if (id == 6) {
                            const auto a = ed.points[0], b = ed.points[1];
                            ed.points[0] = a + (b - a) * (0.5 + 3.0 / ed.length_mm);
                        }
                        distal.edges.push_back(ed);
                    }
                    const auto dv = seg::evaluate_centrelines(res.graph, distal, &liver);
                    int lv16 = -1;
                    std::cerr << "  distal recall " << dv.overall.recall() << " level agreement " << dv.level_agreement << "\n";
                    (void)lv16;
                }
                for (const auto& l : ev.by_tree_level)
                    std::cerr << "  truth label " << l.label << " level " << l.level << ": " << l.found << "/" << l.samples
                              << " labelled right " << l.labelled_right << "\n";
            }
        }
    }
    return 0;
}
