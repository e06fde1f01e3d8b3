// Speed against accuracy of libseg's active contours (issue 3), with ITK as the outside peer.
//
//   seg_bench [--out DIR] [--quick] [--data DIR] [--inputs SUBSTR,..] [--methods SUBSTR,..] [--reps N] [--dump DIR]
//             [--name STEM]
//
// For every input (lphantom axial slices and the phantom volume; ct-small's liver, one slice and
// the volume; the 512 x 512 ct-dicom-jpeg2000 series when present) it runs, from ONE shared
// initial mask (the reference eroded by 10 mm, see bench/seg/README.md):
//   lobe CDSG, lobe CDSG with a template (2-D: the neighbouring slice's reference), lobe GGVF,
//   lobe GAC, ITK GAC, ITK GVF snake; and, time only, the GVF/GGVF fields of libseg and ITK's
//   GradientVectorFlowImageFilter at the same iteration count.
// Asked for by name (--inputs seed), each 2-D slice also runs from a seeded start (input name +
// "-seed": a 5 mm ball at the reference's deepest voxel, one click in the liver's middle), with
// GGVF's field iterations swept from the default to 8000 (methods GGVF-f<N>).
// Accuracy: Dice and ASD from lobe::seg::evaluate_segmentation against the reference, each
// cross-checked by an independent computation (bench/seg/itk_peer.cpp); a disagreement is
// written into the notes. Writes OUT/seg_speed_accuracy.csv (rows appended to a .partial file
// as they come, renamed at the end) and prints each row.
#include "common/args.h"
#include "itk_peer.h"

#include "lobe/core/any_image.h"
#include "lobe/io/image_io.h"
#include "lobe/seg/distance_transform.h"
#include "lobe/seg/edge_map.h"
#include "lobe/seg/gvf.h"
#include "lobe/seg/metrics.h"
#include "lobe/seg/snake.h"
#include "lphantom/phantom.h"

#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iomanip>
#include <iostream>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

namespace fs = std::filesystem;
using namespace lobe;

namespace {

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

constexpr double kErosionMm = 10.0; // the shared initialisation: reference eroded by this distance
constexpr double kSeedRadiusMm = 5.0; // the seeded start: a ball of lseg snake's default --seed-radius
// The seeded start's GGVF field iterations: the default (a third of the row) cannot carry the
// edges' pull from the liver's middle to a seed 40-70 mm away; these chart what more would buy.
const std::vector<int> kSeededGgvfIterations = {500, 1000, 2000, 4000, 8000};

struct Options {
    fs::path out = fs::path(LOBE_SOURCE_DIR) / "docs" / "benchmarks";
    fs::path data;
    bool quick = false;
    int reps = 3; // repetitions of each 2-D run (the median time is reported); 3-D runs once
    std::vector<std::string> inputs, methods; // substring filters (empty = all)
    fs::path dump;                            // when set: every result mask (and input) as .mha here
    std::string name = "seg_speed_accuracy";  // the CSV's file name without .csv
    seg::SnakeParams lobe;                    // libseg's snakes' parameters (--lobe KEY=VALUE,...)
    std::string lobe_spec;                    // ... as given, for the notes
    bench::ItkGacParams itk_gac;              // the ITK peer's parameters (--itk KEY=VALUE,...)
    bench::ItkGvfParams itk_gvf;
};

// Calls set(key, value) for each KEY=VALUE of a comma-separated spec; false at the first item
// without '=' or that set refuses (an unknown key).
template <class Set> bool parse_key_values(const std::string& spec, Set&& set)
{
    std::stringstream ss(spec);
    std::string item;
    while (std::getline(ss, item, ',')) {
        const auto eq = item.find('=');
        if (eq == std::string::npos || !set(item.substr(0, eq), std::atof(item.substr(eq + 1).c_str())))
            return false;
    }
    return true;
}

// --itk KEY=VALUE,...: k1 (percentile), shell (mm), prop, curv, adv, rms, iters (GAC);
// gvfcurv, gvfadv (the GVF snake's curvature and advection scaling).
bool parse_itk(const std::string& spec, Options& opt)
{
    const bool ok = parse_key_values(spec, [&](const std::string& key, double v) {
        auto& g = opt.itk_gac;
        if (key == "k1") g.k1_percentile = v;
        else if (key == "shell") g.shell_mm = v;
        else if (key == "prop") g.propagation_scaling = v;
        else if (key == "curv") g.curvature_scaling = v;
        else if (key == "adv") g.advection_scaling = v;
        else if (key == "rms") g.max_rms_error = v;
        else if (key == "iters") g.iterations = int(v);
        else if (key == "gvfcurv") opt.itk_gvf.curvature_scaling = v;
        else if (key == "gvfadv") opt.itk_gvf.advection_scaling = v;
        else return false;
        return true;
    });
    if (!ok)
        return false;
    opt.itk_gvf.speed = opt.itk_gac;
    opt.itk_gvf.max_rms_error = opt.itk_gac.max_rms_error;
    opt.itk_gvf.snake_iterations = opt.itk_gac.iterations;
    return true;
}

// --lobe KEY=VALUE,...: libseg's snake parameters other than the defaults (for experiments; the
// recorded runs use the defaults). Keys: curv (ε), sigma (edge σ, mm), gk (g's k), bandgvf (CDSG's
// band GGVF iterations), delta1, pk and power (CDSG's pressure stopping k and exponent), low and
// high (CDSG's binary edges), band, cfl, tol, checks (convergence), leak (leak checks), iters.
bool parse_lobe(const std::string& spec, Options& opt)
{
    const bool ok = parse_key_values(spec, [&](const std::string& key, double v) {
        auto& p = opt.lobe;
        if (key == "curv") p.curvature_weight = v;
        else if (key == "sigma") p.edge.sigma_mm = v;
        else if (key == "gk") p.edge.stopping_k = v;
        else if (key == "bandgvf") p.band_gvf_iterations = int(v);
        else if (key == "delta1") p.cdsg.edge_band = int(v);
        else if (key == "pk") p.cdsg.pressure_stopping_k = v;
        else if (key == "power") p.cdsg.pressure_stopping_power = v;
        else if (key == "low") p.cdsg.edges.low = v;
        else if (key == "high") p.cdsg.edges.high = v;
        else if (key == "band") p.level_set.band_voxels = int(v);
        else if (key == "cfl") p.level_set.cfl = v;
        else if (key == "tol") p.level_set.convergence_tolerance = v;
        else if (key == "checks") p.level_set.convergence_checks = int(v);
        else if (key == "leak") p.level_set.leak_checks = int(v);
        else if (key == "iters") p.level_set.max_iterations = int(v);
        else return false;
        return true;
    });
    opt.lobe_spec = spec;
    return ok;
}

struct Input {
    std::string name;
    core::ImageF image;
    core::LabelImage3D ref;
    core::LabelImage3D init;
    std::optional<core::LabelImage3D> templ; // the neighbouring slice's reference (2-D only)
    bool scaling = false;                      // also run the methods on one thread
    bool itk_gvf_snake = true;                 // ITK GVF snake (2-D, or small 3-D)
    bool gvf_fields = false;                   // time the GVF fields alone
    bool seeded = false;                       // init = a ball around the reference's deepest point
    core::LabelImage3D eroded;                 // seeded: the unseeded init (ITK's sigmoid statistics)
    std::string init_note;                     // how the init was made (seeded inputs)
};

struct Row {
    std::string input, dims, method;
    int threads = 0;
    double field = 0, evolve = 0, total = 0;
    int iterations = 0;
    std::string converged; // "true", "false" or "" (not applicable)
    std::string dice, asd; // empty when not applicable
    std::string notes;
};

// v with `digits` significant digits, or with `digits` decimals when fixed
std::string num(double v, int digits = 4, bool fixed = false)
{
    std::ostringstream s;
    if (fixed)
        s << std::fixed;
    s << std::setprecision(digits) << v;
    return s.str();
}

std::string dims_of(const core::ImageGeometry& g)
{
    std::string d = std::to_string(g.size[0]) + "x" + std::to_string(g.size[1]);
    if (g.size[2] > 1)
        d += "x" + std::to_string(g.size[2]);
    return d;
}

std::string csv_field(const std::string& s)
{
    if (s.find_first_of(",\"\n") == std::string::npos)
        return s;
    std::string q = "\"";
    for (char c : s)
        q += c == '"' ? std::string("\"\"") : std::string(1, c);
    return q + "\"";
}

class CsvWriter {
public:
    explicit CsvWriter(fs::path final_path) : final_(std::move(final_path)), partial_(final_.string() + ".partial")
    {
        fs::create_directories(final_.parent_path());
        out_.open(partial_);
        if (!out_)
            throw std::runtime_error("cannot write " + partial_.string());
        out_ << "input,dims,method,threads,field_seconds,evolve_seconds,total_seconds,iterations,converged,dice,"
                "asd_mm,notes\n";
        out_.flush();
    }
    void add(const Row& r)
    {
        out_ << csv_field(r.input) << ',' << r.dims << ',' << csv_field(r.method) << ',' << r.threads << ','
             << num(r.field, 4, true) << ',' << num(r.evolve, 4, true) << ',' << num(r.total, 4, true) << ','
             << r.iterations << ',' << r.converged << ',' << r.dice << ',' << r.asd << ',' << csv_field(r.notes)
             << '\n';
        out_.flush();
        std::fprintf(stderr, "  %-24s %-14s %-18s t%d  field %8.3f  evolve %8.3f  total %8.3f  it %5d  conv %-5s  dice %-6s  asd %-6s  %s\n",
                     r.input.c_str(), r.dims.c_str(), r.method.c_str(), r.threads, r.field, r.evolve, r.total,
                     r.iterations, r.converged.c_str(), r.dice.c_str(), r.asd.c_str(), r.notes.c_str());
    }
    void finish()
    {
        out_.close();
        fs::rename(partial_, final_);
    }

private:
    fs::path final_, partial_;
    std::ofstream out_;
};

std::string load_average()
{
    std::ifstream f("/proc/loadavg");
    std::string a, b, c;
    f >> a >> b >> c;
    return a + " " + b + " " + c;
}

// ---- inputs ------------------------------------------------------------------------------

template <class T>
core::Image3D<T> slice(const core::Image3D<T>& v, int k)
{
    core::ImageGeometry g = v.geometry();
    const core::Vec3 o = g.index_to_physical(0, 0, k);
    g.origin = {o.x, o.y, o.z};
    g.size[2] = 1;
    core::Image3D<T> s(g);
    const std::size_t n = std::size_t(g.size[0]) * std::size_t(g.size[1]);
    std::copy(v.data.begin() + std::ptrdiff_t(n * std::size_t(k)), v.data.begin() + std::ptrdiff_t(n * std::size_t(k + 1)),
              s.data.begin());
    return s;
}

std::size_t count(const core::LabelImage3D& m)
{
    return std::size_t(std::count_if(m.data.begin(), m.data.end(), [](std::uint8_t v) { return v != 0; }));
}

int largest_slice(const core::LabelImage3D& m)
{
    const std::size_t n = std::size_t(m.size[0]) * std::size_t(m.size[1]);
    int best = 0;
    std::size_t best_count = 0;
    for (int k = 0; k < m.size[2]; ++k) {
        const auto c = std::size_t(std::count_if(m.data.begin() + std::ptrdiff_t(n * std::size_t(k)),
                                                 m.data.begin() + std::ptrdiff_t(n * std::size_t(k + 1)),
                                                 [](std::uint8_t v) { return v != 0; }));
        if (c > best_count) {
            best_count = c;
            best = k;
        }
    }
    return best;
}

core::ImageF to_float(const core::ImageI16& ct)
{
    core::ImageF f(ct.geometry());
    std::transform(ct.data.begin(), ct.data.end(), f.data.begin(), [](std::int16_t v) { return float(v); });
    return f;
}

// Liver = {1, 2, 3, 4} (parenchyma, portal and hepatic veins, tumours: the SLIVER07 convention)
core::LabelImage3D phantom_liver(const core::LabelImage3D& labels)
{
    core::LabelImage3D m(labels.geometry(), 0);
    for (std::size_t i = 0; i < m.data.size(); ++i) {
        const auto l = labels.data[i];
        m.data[i] = (l == phantom::kLiver || l == phantom::kPortalVein || l == phantom::kHepaticVein ||
                     l == phantom::kTumour)
                        ? 1
                        : 0;
    }
    return m;
}

// The seeded start: a ball of kSeedRadiusMm around the reference's deepest voxel (the largest
// distance to the outside, spacing-aware), i.e. one click in the middle of the liver. The ball
// keeps the reference's geometry; only its voxels inside the reference count (a thin liver).
core::LabelImage3D seed_ball(const core::LabelImage3D& ref, std::string& note)
{
    core::LabelImage3D outside(ref.geometry(), 0);
    for (std::size_t i = 0; i < ref.data.size(); ++i)
        outside.data[i] = ref.data[i] ? 0 : 1;
    const core::ImageF depth = seg::euclidean_distance(outside);
    std::size_t best = 0;
    for (std::size_t i = 0; i < depth.data.size(); ++i)
        if (ref.data[i] && depth.data[i] > depth.data[best])
            best = i;
    const int nx = ref.size[0], ny = ref.size[1];
    const int ci = int(best % std::size_t(nx)), cj = int((best / std::size_t(nx)) % std::size_t(ny)),
              ck = int(best / (std::size_t(nx) * std::size_t(ny)));
    core::LabelImage3D ball(ref.geometry(), 0);
    for (int k = 0; k < ref.size[2]; ++k)
        for (int j = 0; j < ny; ++j)
            for (int i = 0; i < nx; ++i) {
                const double dx = (i - ci) * ref.spacing[0], dy = (j - cj) * ref.spacing[1], dz = (k - ck) * ref.spacing[2];
                if (dx * dx + dy * dy + dz * dz <= kSeedRadiusMm * kSeedRadiusMm && ref.at(i, j, k))
                    ball.at(i, j, k) = 1;
            }
    note = "seed (" + std::to_string(ci) + "," + std::to_string(cj) + "," + std::to_string(ck) + "), " +
           num(depth.data[best], 3) + " mm deep, ball " + num(kSeedRadiusMm, 2) + " mm";
    return ball;
}

bool wanted(const std::vector<std::string>& filters, const std::string& name)
{
    if (filters.empty())
        return true;
    return std::any_of(filters.begin(), filters.end(),
                       [&](const std::string& f) { return name.find(f) != std::string::npos; });
}

// Adds an input after making its initial mask; false (with a message) if the erosion is empty.
bool finish_input(Input& in)
{
    in.init = bench::erode_by_distance(in.ref, kErosionMm);
    if (in.seeded) {
        in.eroded = std::move(in.init);
        in.init = seed_ball(in.ref, in.init_note);
    }
    const std::size_t ni = count(in.init), nr = count(in.ref);
    std::fprintf(stderr, "input %s: %s, spacing %.3g x %.3g x %.3g mm, reference %zu voxels, init %zu voxels (%.1f%%)%s%s\n",
                 in.name.c_str(), dims_of(in.image).c_str(), in.image.spacing[0], in.image.spacing[1],
                 in.image.spacing[2], nr, ni, nr ? 100.0 * double(ni) / double(nr) : 0.0,
                 in.init_note.empty() ? "" : ", ", in.init_note.c_str());
    if (ni == 0) {
        std::fprintf(stderr, "  skipped: the reference eroded by %.0f mm is empty\n", kErosionMm);
        return false;
    }
    return true;
}

void add_slices_and_volume(std::vector<Input>& inputs, const Options& opt, const std::string& prefix,
                           const core::ImageF& ct, const core::LabelImage3D& liver,
                           const std::vector<std::pair<int, std::string>>& slices, bool volume, bool volume_scaling)
{
    bool first = true;
    for (const auto& [k, what] : slices) {
        Input in;
        in.name = prefix + "-k" + std::to_string(k) + (what.empty() ? "" : "-" + what);
        const bool plain = wanted(opt.inputs, in.name);
        // The seeded start runs only when asked for by name (a filter holding "seed"), so that the
        // default run and its chart stay the eroded start's.
        const bool seeded_wanted =
            !opt.quick && std::any_of(opt.inputs.begin(), opt.inputs.end(), [&](const std::string& f) {
                return f.find("seed") != std::string::npos && (in.name + "-seed").find(f) != std::string::npos;
            });
        if (!plain && !seeded_wanted)
            continue;
        in.image = slice(ct, k);
        in.ref = slice(liver, k);
        const int kt = k + 1 < liver.size[2] ? k + 1 : k - 1;
        if (kt >= 0) { // the neighbouring slice's reference, placed on this slice's grid
            in.templ = slice(liver, kt);
            static_cast<core::ImageGeometry&>(*in.templ) = in.ref.geometry();
        }
        in.scaling = first && !opt.quick;
        in.gvf_fields = true;
        first = false;
        // The same slice from one click in the liver's middle (the seeded start): the field must
        // reach the front from the edges, which is where the thesis says CDSG beats GGVF.
        Input seeded;
        seeded.name = in.name + "-seed";
        seeded.image = in.image;
        seeded.ref = in.ref;
        seeded.templ = in.templ;
        seeded.seeded = true;
        seeded.itk_gvf_snake = false; // ITK's GVF at the default count fails like libseg's GGVF there
        if (plain && finish_input(in))
            inputs.push_back(std::move(in));
        if (seeded_wanted && finish_input(seeded))
            inputs.push_back(std::move(seeded));
    }
    if (volume) {
        Input in;
        in.name = prefix + "-volume";
        if (!wanted(opt.inputs, in.name))
            return;
        in.image = ct;
        in.ref = liver;
        in.scaling = volume_scaling;
        in.itk_gvf_snake = ct.voxel_count() <= 2'000'000; // ITK's GVF is single-threaded: small 3-D only
        if (finish_input(in))
            inputs.push_back(std::move(in));
    }
}

std::vector<Input> make_inputs(const Options& opt)
{
    std::vector<Input> inputs;
    // (1) the synthetic patient, docs/phantom.md: k = 59 heart contact, 27 kidney contact,
    // 48 IVC Omega, 50 both fissures (default grid 512 x 512 x 80, 0.7 x 0.7 x 2.5 mm).
    {
        const auto t0 = Clock::now();
        phantom::PhantomParams pp;
        const auto ph = phantom::generate_phantom(pp);
        std::fprintf(stderr, "phantom 512x512x80 generated in %.1f s\n", seconds_since(t0));
        const auto ct = to_float(ph.ct);
        const auto liver = phantom_liver(ph.labels);
        std::vector<std::pair<int, std::string>> slices = {{59, "heart"}, {27, "kidney"}, {48, "omega"}, {50, "fissures"}};
        if (opt.quick)
            slices.resize(1);
        // No 1-thread rows for this volume: one libseg 3-D run takes minutes (the scaling of the
        // 3-D runs is measured on the 512 x 512 x 20 ct-dicom volume instead).
        add_slices_and_volume(inputs, opt, "phantom", ct, liver, slices, !opt.quick, false);
    }
    // (2) real CT from ../shared/data (TotalSegmentator's test scan; its liver label as reference)
    const fs::path small = opt.data / "ct-small";
    if (fs::exists(small / "ct.mhd") && fs::exists(small / "liver.mhd")) {
        const auto ct = core::convert_image<float>(io::read_image(small / "ct.mhd"));
        auto liver = core::convert_image<std::uint8_t>(io::read_image(small / "liver.mhd"));
        for (auto& v : liver.data)
            v = v ? 1 : 0;
        if (!core::same_grid(ct, liver)) {
            std::fprintf(stderr, "ct-small: ct.mhd and liver.mhd are on different grids: skipped\n");
        } else {
            const int k = largest_slice(liver);
            add_slices_and_volume(inputs, opt, "ct-small", ct, liver, {{k, "maxliver"}}, true, !opt.quick);
        }
    } else {
        std::fprintf(stderr, "no %s (ct.mhd, liver.mhd): the ct-small inputs are skipped (--data DIR)\n",
                     small.string().c_str());
    }
    const fs::path dicom = opt.data / "ct-dicom-jpeg2000";
    if (!opt.quick && fs::exists(dicom / "dicom") && fs::exists(dicom / "liver.mhd")) {
        try {
            const auto ct = core::convert_image<float>(io::read_image(dicom / "dicom"));
            auto liver = core::convert_image<std::uint8_t>(io::read_image(dicom / "liver.mhd"));
            for (auto& v : liver.data)
                v = v ? 1 : 0;
            if (!core::same_grid(ct, liver, 1e-2)) {
                std::fprintf(stderr, "ct-dicom: the series and liver.mhd are on different grids: skipped\n");
            } else {
                liver.ImageGeometry::operator=(ct.geometry());
                const int k = largest_slice(liver);
                add_slices_and_volume(inputs, opt, "ct-dicom", ct, liver, {{k, "maxliver"}}, true, true);
            }
        } catch (const std::exception& e) {
            std::fprintf(stderr, "ct-dicom: %s: skipped\n", e.what());
        }
    } else if (!opt.quick) {
        std::fprintf(stderr, "no %s: the ct-dicom inputs are skipped\n", dicom.string().c_str());
    }
    return inputs;
}

// ---- runs --------------------------------------------------------------------------------

void set_threads(int n)
{
    omp_set_num_threads(n);
    bench::itk_set_threads(n);
}

// Accuracy by libseg, cross-checked independently.
void evaluate(Row& row, const core::LabelImage3D& seg, const core::LabelImage3D& ref)
{
    const std::size_t n = count(seg);
    if (n == 0) {
        row.dice = "0";
        row.notes += "; empty result";
        return;
    }
    const auto xc = bench::cross_check(seg, ref);
    try {
        const auto m = seg::evaluate_segmentation(seg, ref);
        row.dice = num(m.dice, 4, true);
        row.asd = num(m.surface.average, 3, true);
        if (!std::isfinite(m.dice) || std::abs(m.dice - xc.dice) > 1e-6)
            row.notes += "; CHECK dice: libseg " + num(m.dice, 6, true) + " vs independent " + num(xc.dice, 6, true);
        if (!std::isfinite(m.surface.average) ||
            std::abs(m.surface.average - xc.asd_mm) > std::max(0.02, 0.01 * xc.asd_mm))
            row.notes += "; CHECK asd: libseg " + num(m.surface.average, 4, true) + " (borders " +
                         std::to_string(m.surface.border_voxels_seg) + "/" + std::to_string(m.surface.border_voxels_ref) +
                         ") vs independent " + num(xc.asd_mm, 4, true) + " (borders " + std::to_string(xc.border_seg) +
                         "/" + std::to_string(xc.border_ref) + ")";
    } catch (const std::exception& e) {
        row.dice = num(xc.dice, 4, true);
        row.asd = num(xc.asd_mm, 3, true);
        row.notes += std::string("; evaluate_segmentation threw (") + e.what() + "), independent values shown";
    }
}

struct Timed {
    core::LabelImage3D mask;
    double field = 0, evolve = 0, total = 0;
    int iterations = 0;
    bool converged = false;
    bool has_mask = true;
    std::string notes;
};

// Runs `fn` reps times and keeps the fastest run (the machine is shared: the minimum is the best
// estimate of the cost itself); the notes give the median and say when the masks differ.
Timed repeat(int reps, const std::function<Timed()>& fn)
{
    std::vector<Timed> runs;
    for (int r = 0; r < reps; ++r)
        runs.push_back(fn());
    bool same = true;
    for (std::size_t r = 1; r < runs.size(); ++r)
        same = same && runs[r].mask.data == runs[0].mask.data;
    std::sort(runs.begin(), runs.end(), [](const Timed& a, const Timed& b) { return a.total < b.total; });
    const double median = runs[runs.size() / 2].total;
    Timed t = std::move(runs.front());
    if (reps > 1)
        t.notes += (t.notes.empty() ? "" : "; ") + std::string("fastest of ") + std::to_string(reps) + ", median " +
                   num(median, 3) + " s";
    if (!same)
        t.notes += "; NOTE masks differ between repetitions";
    return t;
}

void run_input(const Input& in, const Options& opt, CsvWriter& csv)
{
    const bool is2d = in.image.size[2] == 1;
    const int reps = is2d ? opt.reps : 1;
    const std::string dims = dims_of(in.image);
    if (!opt.dump.empty()) {
        fs::create_directories(opt.dump);
        io::write_image(opt.dump / (in.name + "_image.mha"), in.image);
        io::write_image(opt.dump / (in.name + "_ref.mha"), in.ref);
        io::write_image(opt.dump / (in.name + "_init.mha"), in.init);
    }
    std::vector<int> thread_counts = {2};
    if (in.scaling)
        thread_counts.push_back(1);

    auto emit = [&](const std::string& method, int threads, Timed t) {
        Row row;
        row.input = in.name;
        row.dims = dims;
        row.method = method;
        row.threads = threads;
        row.field = t.field;
        row.evolve = t.evolve;
        row.total = t.total;
        row.iterations = t.iterations;
        row.notes = t.notes;
        if (in.seeded)
            row.notes += "; " + in.init_note;
        if (t.has_mask) {
            row.converged = t.converged ? "true" : "false";
            evaluate(row, t.mask, in.ref);
            if (!opt.dump.empty())
                io::write_image(opt.dump / (in.name + "_" + method + "_t" + std::to_string(threads) + ".mha"), t.mask);
        }
        if (!row.notes.empty() && row.notes.rfind("; ", 0) == 0)
            row.notes.erase(0, 2);
        csv.add(row);
    };
    auto failed = [&](const std::string& method, int threads, const std::string& what) {
        Row row;
        row.input = in.name;
        row.dims = dims;
        row.method = method;
        row.threads = threads;
        row.converged = "false";
        row.notes = "FAILED: " + what;
        csv.add(row);
    };

    // libseg's three snakes (and CDSG with a template on slices)
    struct LobeCase {
        std::string name;
        seg::SnakeMethod method;
        const core::LabelImage3D* templ;
        int gvf_iterations = 0; // 0: the default (GGVF: a third of the longest row)
    };
    std::vector<LobeCase> lobe_cases = {{"CDSG", seg::SnakeMethod::Cdsg, nullptr}};
    if (in.templ)
        lobe_cases.push_back({"CDSG+template", seg::SnakeMethod::Cdsg, &*in.templ});
    lobe_cases.push_back({"GGVF", seg::SnakeMethod::Ggvf, nullptr});
    if (in.seeded)
        for (int n : kSeededGgvfIterations)
            lobe_cases.push_back({"GGVF-f" + std::to_string(n), seg::SnakeMethod::Ggvf, nullptr, n});
    lobe_cases.push_back({"GAC", seg::SnakeMethod::Gac, nullptr});

    for (int threads : thread_counts) {
        for (const auto& lc : lobe_cases) {
            if (!wanted(opt.methods, lc.name) || (threads == 1 && lc.templ))
                continue;
            set_threads(threads);
            try {
                auto t = repeat(reps, [&] {
                    seg::SnakeParams p = opt.lobe;
                    p.method = lc.method;
                    p.gvf.iterations = lc.gvf_iterations;
                    const auto t0 = Clock::now();
                    auto r = seg::segment_snake(in.image, in.init, p, lc.templ);
                    Timed out;
                    out.total = seconds_since(t0);
                    out.field = r.field_seconds;
                    out.evolve = r.evolve_seconds;
                    out.iterations = r.iterations;
                    out.converged = r.converged;
                    out.mask = std::move(r.mask);
                    if (lc.templ)
                        out.notes = "template = reference of the neighbouring slice";
                    if (!opt.lobe_spec.empty())
                        out.notes += std::string(out.notes.empty() ? "" : "; ") + "lobe " + opt.lobe_spec;
                    if (lc.gvf_iterations > 0)
                        out.notes += std::string(out.notes.empty() ? "" : "; ") + "GGVF field iterations " +
                                     std::to_string(lc.gvf_iterations);

                    if (r.runs > 1 || r.competition_used)
                        out.notes += std::string(out.notes.empty() ? "" : "; ") + "runs " + std::to_string(r.runs) +
                                     (r.competition_used ? ", competition G=0.3" : "");
                    return out;
                });
                emit(lc.name, threads, std::move(t));
            } catch (const std::exception& e) {
                failed(lc.name, threads, e.what());
            }
        }
        // ITK's geodesic active contour (2-D per slice, or 3-D)
        if (wanted(opt.methods, "ITK-GAC")) {
            set_threads(threads);
            try {
                auto t = repeat(reps, [&] {
                    bench::ItkGacParams gp = opt.itk_gac;
                    if (in.seeded)
                        gp.statistics_mask = &in.eroded;
                    auto r = bench::itk_gac(in.image, in.init, gp);
                    return Timed{std::move(r.mask), r.field_seconds, r.evolve_seconds, r.total_seconds,
                                 r.iterations,      r.converged,     true,             r.notes};
                });
                emit("ITK-GAC", threads, std::move(t));
            } catch (const std::exception& e) {
                failed("ITK-GAC", threads, e.what());
            }
        }
        // The same with the ITK example's own settings (propagation 2, K1 = 90th percentile), to
        // show what the tuning of ITK-GAC bought; 2-D and small 3-D only (it leaks, and a leak
        // runs all 800 iterations).
        if (threads == 2 && in.itk_gvf_snake && wanted(opt.methods, "ITK-GAC-example")) {
            set_threads(threads);
            try {
                auto t = repeat(reps, [&] {
                    bench::ItkGacParams gp = opt.itk_gac;
                    gp.k1_percentile = 0.9;
                    gp.propagation_scaling = 2.0;
                    auto r = bench::itk_gac(in.image, in.init, gp);
                    return Timed{std::move(r.mask), r.field_seconds, r.evolve_seconds, r.total_seconds,
                                 r.iterations,      r.converged,     true,             r.notes};
                });
                emit("ITK-GAC-example", threads, std::move(t));
            } catch (const std::exception& e) {
                failed("ITK-GAC-example", threads, e.what());
            }
        }
    }

    // GVF: the fields alone at the same iteration count (time only), then ITK's GVF snake.
    int gvf_iterations = 0;
    {
        seg::GvfParams gp; // libseg's default: the GGVF baseline's count
        gvf_iterations = gp.iterations > 0 ? gp.iterations : (std::max(in.image.size[0], in.image.size[1]) + 2) / 3;
    }
    if (in.gvf_fields) {
        for (int threads : thread_counts) {
            set_threads(threads);
            for (auto model : {seg::GvfModel::Ggvf, seg::GvfModel::Gvf}) {
                const std::string name = model == seg::GvfModel::Ggvf ? "lobe-GGVF-field" : "lobe-GVF-field";
                if (!wanted(opt.methods, name))
                    continue;
                try {
                    auto t = repeat(reps, [&] {
                        const auto t0 = Clock::now();
                        seg::SnakeParams sp;
                        const auto em = seg::edge_map(in.image, sp.edge);
                        seg::GvfParams gp = sp.gvf;
                        gp.model = model;
                        gp.iterations = gvf_iterations;
                        const auto r = seg::gradient_vector_flow(em.edge, gp);
                        Timed out;
                        out.total = out.field = seconds_since(t0);
                        out.iterations = r.iterations;
                        out.has_mask = false;
                        out.notes = "edge map + field only (time), mu " + num(gp.mu) +
                                    (model == seg::GvfModel::Ggvf ? ", K " + num(gp.k) : std::string());
                        return out;
                    });
                    emit(name, threads, std::move(t));
                } catch (const std::exception& e) {
                    failed(name, threads, e.what());
                }
            }
            if (wanted(opt.methods, "ITK-GVF-field")) {
                try {
                    auto t = repeat(reps, [&] {
                        bench::ItkGvfParams gp = opt.itk_gvf;
                        gp.iterations = gvf_iterations;
                        gp.snake = false;
                        auto r = bench::itk_gvf(in.image, in.init, gp);
                        Timed out;
                        out.total = out.field = r.field_seconds;
                        out.iterations = r.iterations;
                        out.has_mask = false;
                        out.notes = r.notes;
                        return out;
                    });
                    emit("ITK-GVF-field", threads, std::move(t));
                } catch (const std::exception& e) {
                    failed("ITK-GVF-field", threads, e.what());
                }
            }
        }
    }
    if (in.itk_gvf_snake && wanted(opt.methods, "ITK-GVF-snake")) {
        set_threads(2);
        try {
            auto t = repeat(reps, [&] {
                bench::ItkGvfParams gp = opt.itk_gvf;
                gp.iterations = gvf_iterations;
                auto r = bench::itk_gvf(in.image, in.init, gp);
                return Timed{std::move(r.mask), r.field_seconds, r.evolve_seconds, r.total_seconds,
                             r.iterations,      r.converged,     true,             r.notes};
            });
            emit("ITK-GVF-snake", 2, std::move(t));
        } catch (const std::exception& e) {
            failed("ITK-GVF-snake", 2, e.what());
        }
    }
}

int usage(const char* argv0, int code)
{
    std::fprintf(code ? stderr : stdout,
                 "usage: %s [--out DIR] [--quick] [--data DIR] [--inputs SUBSTR,..] [--methods SUBSTR,..] [--reps N] [--lobe K=V,..] [--itk K=V,..] [--dump DIR] [--name STEM]\n"
                 "  --out DIR      where seg_speed_accuracy.csv goes (default: docs/benchmarks of the source tree)\n"
                 "  --quick        phantom slice k = 59 and ct-small (slice and volume) only; one repetition\n"
                 "  --data DIR     the shared data folder holding ct-small/ (default: $LOBE_DATA_DIR or ../shared/data)\n"
                 "  --inputs LIST  only inputs whose name contains one of these (e.g. phantom-k59,ct-small)\n"
                 "  --methods LIST only methods whose name contains one of these (CDSG, GGVF, GAC, ITK-GAC, ...)\n"
                 "  --reps N       repetitions of each 2-D run, the fastest reported (default 3; 1 with --quick)\n"
                 "  --itk K=V,..   ITK peer parameters: k1 (sigmoid K1 percentile), shell (mm), prop, curv, adv, rms,\n"
                 "                 iters (GAC), gvfcurv, gvfadv (GVF snake); defaults in bench/seg/itk_peer.h\n"
                 "  --lobe K=V,..  libseg snake parameters (experiments): curv, sigma, gk, bandgvf, delta1, pk, power,\n"
                 "                 low, high, band, cfl, tol, checks, leak, iters (see parse_lobe)\n"
                 "  --dump DIR     also write every input, reference, init and result mask as .mha into DIR\n"
                 "  --name STEM    the CSV's file name without .csv (default seg_speed_accuracy)\n",
                 argv0);
    return code;
}

} // namespace

int main(int argc, char** argv)
{
    Options opt;
    if (const char* env = std::getenv("LOBE_DATA_DIR"))
        opt.data = env;
    else
        opt.data = fs::path(LOBE_SOURCE_DIR).parent_path() / "shared" / "data";
    bool reps_given = false;
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        auto value = [&]() -> std::string {
            if (i + 1 >= argc) {
                std::fprintf(stderr, "%s needs a value\n", a.c_str());
                std::exit(usage(argv[0], 1));
            }
            return argv[++i];
        };
        if (a == "--out")
            opt.out = value();
        else if (a == "--data")
            opt.data = value();
        else if (a == "--lobe") {
            if (!parse_lobe(value(), opt))
                return usage(argv[0], 1);
        } else if (a == "--itk") {
            if (!parse_itk(value(), opt))
                return usage(argv[0], 1);
        } else if (a == "--dump")
            opt.dump = value();
        else if (a == "--name")
            opt.name = value();
        else if (a == "--quick")
            opt.quick = true;
        else if (a == "--inputs")
            opt.inputs = bench::split(value());
        else if (a == "--methods")
            opt.methods = bench::split(value());
        else if (a == "--reps") {
            opt.reps = std::atoi(value().c_str());
            reps_given = true;
            if (opt.reps < 1)
                return usage(argv[0], 1);
        } else if (a == "--help" || a == "-h")
            return usage(argv[0], 0);
        else {
            std::fprintf(stderr, "unknown option %s\n", a.c_str());
            return usage(argv[0], 1);
        }
    }
    if (opt.quick && !reps_given)
        opt.reps = 1;

    try {
        std::fprintf(stderr, "seg_bench: load average %s; OpenMP max threads %d; ITK and OpenMP set to 2 threads "
                             "(1 for the scaling rows)\n",
                     load_average().c_str(), omp_get_max_threads());
        const auto t0 = Clock::now();
        const auto inputs = make_inputs(opt);
        CsvWriter csv(opt.out / (opt.name + ".csv"));
        for (const auto& in : inputs) {
            std::fprintf(stderr, "== %s (%s), load average %s\n", in.name.c_str(), dims_of(in.image).c_str(),
                         load_average().c_str());
            run_input(in, opt, csv);
        }
        csv.finish();
        std::fprintf(stderr, "seg_bench: done in %.0f s, load average %s; wrote %s\n", seconds_since(t0),
                     load_average().c_str(), (opt.out / (opt.name + ".csv")).string().c_str());
    } catch (const std::exception& e) {
        std::fprintf(stderr, "seg_bench: %s\n", e.what());
        return 2;
    }
    return 0;
}
