// MR bias-field correction, speed against accuracy: libseg's correct_bias_field (K-means classes
// and a polynomial log field) against ITK's N4 (bench/mr/README.md).
//
//   bias_bench [--out DIR] [--data DIR] [--reps N] [--threads N] [--inputs SUBSTR,..] [--methods SUBSTR,..] [--quick]
//
// Inputs: T1-like lphantom volumes (the CT mapped to T1 grey levels) multiplied by a KNOWN field
// b_true (none, linear across x, smooth 3-D), at 1.4 x 1.4 x 5 mm and 1.2 x 1.2 x 4 mm; and the
// real MR of ../shared/data/mr-small (no true field). Methods: none, lobe (defaults), lobe-deg1,
// lobe-k3 (3 classes), lobe-deg3, itk-n4. Measures: wall time; on the phantoms the field error (RMS over the liver of
// log b_est - log b_true less its liver mean, in %); on every input the liver's robust CV and
// block spread of the corrected image. Writes OUT/bias_field.csv (rows go to a .partial file as
// they come, renamed at the end) and prints each row with the methods' own diagnostics.
#include "common/args.h"
#include "n4_peer.h"

#include "lobe/core/any_image.h"
#include "lobe/io/image_io.h"
#include "lobe/seg/bias_field.h"
#include "lphantom/phantom.h"

#include <omp.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <fstream>
#include <functional>
#include <optional>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

namespace fs = std::filesystem;
using namespace lobe;

namespace {

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

// A run that takes longer than this is not repeated: its time is far above the timer's noise.
constexpr double kCheapSeconds = 5.0;

struct Options {
    fs::path out = fs::path(LOBE_SOURCE_DIR) / "docs" / "benchmarks";
    fs::path data;
    int reps = 3;    // repetitions of a cheap run (the fastest is reported)
    int threads = 2; // OpenMP (lobe's field evaluation) and ITK
    bool quick = false;
    fs::path volumes; // non-empty: write each shaded phantom and its liver here (bench/mr/liver_shaded.sh)
    std::vector<std::string> inputs, methods; // substring filters (empty = all)
};

bool selected(const std::vector<std::string>& filters, const std::string& name)
{
    if (filters.empty())
        return true;
    return std::any_of(filters.begin(), filters.end(),
                       [&](const std::string& f) { return name.find(f) != std::string::npos; });
}

std::string num(double v, int decimals)
{
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
    return buf;
}

// ---- inputs -------------------------------------------------------------------------------

// A known multiplicative field, of the index coordinates normalised to [0, 1].
struct Shading {
    std::string name;
    std::function<double(double, double, double)> b; // empty: no field
};

std::vector<Shading> shadings()
{
    std::vector<Shading> out{{"none", {}}};
    // A coil's falloff across the body: linear in x, mean 1.
    for (double a : {0.15, 0.30, 0.45})
        out.push_back({"linear-" + num(a, 2), [a](double x, double, double) { return (1 + a) - 2 * a * x; }});
    // Smooth 3-D: a tilt in x and y, a bend in z and a saddle in x-y (log b is a degree-2
    // polynomial, so lobe's default model can represent it exactly).
    for (double a : {0.2, 0.4})
        out.push_back({"smooth-" + num(a, 1), [a](double x, double y, double z) {
                           return std::exp(a * (1.2 * (0.5 - x) + 0.8 * (y - 0.5) - 3.6 * (z - 0.5) * (z - 0.5) +
                                                2.4 * (x - 0.5) * (y - 0.5)));
                       }});
    return out;
}

core::ImageF field_image(const core::ImageGeometry& g, const Shading& s)
{
    core::ImageF b(g, 1.0f);
    if (!s.b)
        return b;
    const auto norm = [](int i, int n) { return n > 1 ? double(i) / double(n - 1) : 0.0; };
    for (int k = 0; k < g.size[2]; ++k)
        for (int j = 0; j < g.size[1]; ++j)
            for (int i = 0; i < g.size[0]; ++i)
                b.data[g.index(i, j, k)] =
                    static_cast<float>(s.b(norm(i, g.size[0]), norm(j, g.size[1]), norm(k, g.size[2])));
    return b;
}

struct Base {
    std::string name;
    core::ImageF image; // T1-like, unshaded (the MR: as read)
    core::LabelImage3D liver;
    bool known_field = true;
};

core::LabelImage3D labels_in(const core::LabelImage3D& labels, int lo, int hi)
{
    core::LabelImage3D m(labels.geometry(), 0);
    for (std::size_t i = 0; i < m.data.size(); ++i)
        m.data[i] = labels.data[i] >= lo && labels.data[i] <= hi ? 1 : 0;
    return m;
}

Base phantom_base(const std::array<double, 3>& spacing, std::uint64_t seed)
{
    const auto t0 = Clock::now();
    phantom::PhantomParams pp;
    pp.spacing = spacing;
    pp.size = phantom::size_for_spacing(spacing);
    pp.seed = seed;
    const auto ph = phantom::generate_phantom(pp);
    Base b;
    b.name = "phantom-" + num(spacing[0], 1) + "x" + num(spacing[2], 0);
    b.image = phantom::t1_weighted(core::convert_image<float>(ph.ct));
    b.liver = labels_in(ph.labels, 1, 4); // SLIVER07's liver: parenchyma, vessels, tumours
    std::fprintf(stderr, "%s: %d x %d x %d, noise seed %llu, generated in %.1f s\n", b.name.c_str(), pp.size[0],
                 pp.size[1], pp.size[2], static_cast<unsigned long long>(seed), seconds_since(t0));
    return b;
}

std::optional<Base> mr_small(const fs::path& data)
{
    const fs::path dir = data / "mr-small";
    if (!fs::exists(dir / "mr.mhd") || !fs::exists(dir / "labels.mhd")) {
        std::fprintf(stderr, "no %s/{mr,labels}.mhd: the mr-small input is skipped\n", dir.string().c_str());
        return std::nullopt;
    }
    Base b;
    b.name = "mr-small";
    b.known_field = false;
    b.image = core::convert_image<float>(io::read_image(dir / "mr.mhd"));
    const auto labels = core::convert_image<std::uint8_t>(io::read_image(dir / "labels.mhd"));
    if (labels.size != b.image.size) {
        std::fprintf(stderr, "mr-small: mr.mhd and labels.mhd differ in size: skipped\n");
        return std::nullopt;
    }
    b.liver = labels_in(labels, 5, 5);
    b.liver.ImageGeometry::operator=(b.image.geometry());
    return b;
}

// ---- measures -----------------------------------------------------------------------------

double quantile(std::vector<float> v, double q)
{
    const auto k = static_cast<std::ptrdiff_t>(q * static_cast<double>(v.size() - 1));
    std::nth_element(v.begin(), v.begin() + k, v.end());
    return v[static_cast<std::size_t>(k)];
}

// Robust CV of the corrected image over the liver: IQR / 1.349 (the sd of a normal sample) over
// the median. Vessels and tumours are in the liver mask, which is why the spread is robust.
double robust_cv(const core::ImageF& img, const core::LabelImage3D& liver)
{
    std::vector<float> v;
    for (std::size_t i = 0; i < img.data.size(); ++i)
        if (liver.data[i])
            v.push_back(img.data[i]);
    return (quantile(v, 0.75) - quantile(v, 0.25)) / 1.349 / quantile(v, 0.5);
}

// Block spread: the liver's bounding box cut into 4 x 4 x 3 blocks (x, y by index quarters, z by
// thirds); the medians of the blocks with more than 200 liver voxels, (max - min) over the liver
// median. Shading left in the image shows as a spread of the block medians, which noise (the
// median of > 200 voxels) and the liver's own texture barely move.
double block_spread(const core::ImageF& img, const core::LabelImage3D& liver)
{
    std::array<int, 3> lo{img.size}, hi{-1, -1, -1};
    for (int k = 0; k < img.size[2]; ++k)
        for (int j = 0; j < img.size[1]; ++j)
            for (int i = 0; i < img.size[0]; ++i)
                if (liver.data[img.index(i, j, k)]) {
                    const std::array<int, 3> ijk{i, j, k};
                    for (int a = 0; a < 3; ++a) {
                        lo[a] = std::min(lo[a], ijk[a]);
                        hi[a] = std::max(hi[a], ijk[a]);
                    }
                }
    constexpr std::array<int, 3> cuts{4, 4, 3};
    std::vector<std::vector<float>> blocks(4 * 4 * 3);
    std::vector<float> all;
    for (int k = lo[2]; k <= hi[2]; ++k)
        for (int j = lo[1]; j <= hi[1]; ++j)
            for (int i = lo[0]; i <= hi[0]; ++i) {
                const std::size_t v = img.index(i, j, k);
                if (!liver.data[v])
                    continue;
                const std::array<int, 3> ijk{i, j, k};
                std::array<int, 3> b{};
                for (int a = 0; a < 3; ++a)
                    b[a] = (ijk[a] - lo[a]) * cuts[a] / (hi[a] - lo[a] + 1);
                blocks[static_cast<std::size_t>(b[0] + 4 * (b[1] + 4 * b[2]))].push_back(img.data[v]);
                all.push_back(img.data[v]);
            }
    double mn = HUGE_VAL, mx = -HUGE_VAL;
    for (auto& blk : blocks)
        if (blk.size() > 200) {
            const double m = quantile(std::move(blk), 0.5);
            mn = std::min(mn, m);
            mx = std::max(mx, m);
        }
    return mx >= mn ? (mx - mn) / quantile(std::move(all), 0.5) : 0.0;
}

// RMS over the liver of log b_est - log b_true after removing its liver mean (a field is known
// only up to a scale), in percent.
double field_rms_percent(const core::ImageF& est, const core::ImageF& truth, const core::LabelImage3D& liver)
{
    double sum = 0, sum2 = 0;
    std::size_t n = 0;
    for (std::size_t i = 0; i < est.data.size(); ++i)
        if (liver.data[i]) {
            const double d = std::log(double(est.data[i])) - std::log(double(truth.data[i]));
            sum += d;
            sum2 += d * d;
            ++n;
        }
    const double mean = sum / double(n);
    return 100.0 * std::sqrt(std::max(0.0, sum2 / double(n) - mean * mean));
}

// The range of a field over the liver, relative to its geometric mean there.
std::pair<double, double> liver_range(const core::ImageF& field, const core::LabelImage3D& liver)
{
    double sum = 0, lo = HUGE_VAL, hi = -HUGE_VAL;
    std::size_t n = 0;
    for (std::size_t i = 0; i < field.data.size(); ++i)
        if (liver.data[i]) {
            const double l = std::log(double(field.data[i]));
            sum += l;
            lo = std::min(lo, l);
            hi = std::max(hi, l);
            ++n;
        }
    const double mean = n ? sum / double(n) : 0.0;
    return n ? std::pair{std::exp(lo - mean), std::exp(hi - mean)} : std::pair{1.0, 1.0};
}

// ---- methods ------------------------------------------------------------------------------

struct Correction {
    core::ImageF corrected, field;
    double seconds = 0.0;
    std::string notes;
};

// Runs `fn` once, and when that was cheap up to `reps` times, keeping the fastest time (the
// machine is shared: the minimum is the best estimate of the cost itself). The methods are
// deterministic, so the images of any run are the result.
Correction timed(int reps, const std::function<Correction()>& fn)
{
    Correction best = fn();
    std::vector<double> times{best.seconds};
    for (int r = 1; r < reps && best.seconds < kCheapSeconds; ++r) {
        Correction c = fn();
        times.push_back(c.seconds);
        if (c.seconds < best.seconds)
            best = std::move(c);
    }
    std::sort(times.begin(), times.end());
    best.notes += "; " + std::to_string(times.size()) + " run(s), median " + num(times[times.size() / 2], 3) + " s";
    return best;
}

Correction run_lobe(const core::ImageF& image, int degree, int classes = seg::BiasFieldParams{}.classes)
{
    seg::BiasFieldParams p;
    p.degree = degree;
    p.classes = classes;
    const auto t0 = Clock::now();
    seg::BiasFieldResult r = seg::correct_bias_field(image, p);
    Correction c;
    c.seconds = seconds_since(t0);
    c.corrected = std::move(r.corrected);
    c.field = std::move(r.field);
    c.notes = "degree " + std::to_string(degree) + ", " + std::to_string(classes) + " classes, " + std::to_string(r.iterations) + " iterations" +
              (r.converged ? "" : " (NOT converged)") + ", " + std::to_string(r.samples) + " samples, gain " +
              num(r.min_gain, 3) + ".." + num(r.max_gain, 3);
    return c;
}

Correction run_n4(const core::ImageF& image, int shrink)
{
    bench::N4Params p;
    p.shrink = shrink;
    bench::N4Run r = bench::n4_correct(image, p);
    Correction c;
    c.seconds = r.seconds;
    c.corrected = std::move(r.corrected);
    c.field = std::move(r.field);
    std::string levels;
    for (std::size_t l = 0; l < r.level_iterations.size(); ++l)
        levels += (l ? "/" : "") + std::to_string(r.level_iterations[l]);
    c.notes = r.notes + ", iterations per level " + levels + ", last convergence " + num(r.last_convergence, 5);
    return c;
}

struct Method {
    std::string name;
    std::function<Correction(const core::ImageF&, const Base&)> run;
};

std::vector<Method> methods(const Options& opt)
{
    std::vector<Method> out;
    out.push_back({"none", [](const core::ImageF& img, const Base&) {
                       return Correction{img, core::ImageF(img.geometry(), 1.0f), 0.0, "uncorrected"};
                   }});
    const int reps = opt.reps;
    out.push_back({"lobe", [reps](const core::ImageF& img, const Base&) {
                       return timed(reps, [&] { return run_lobe(img, seg::BiasFieldParams{}.degree); });
                   }});
    out.push_back({"lobe-deg1", [reps](const core::ImageF& img, const Base&) {
                       return timed(reps, [&] { return run_lobe(img, 1); });
                   }});
    out.push_back({"lobe-k3", [reps](const core::ImageF& img, const Base&) {
                       return timed(reps, [&] { return run_lobe(img, seg::BiasFieldParams{}.degree, 3); });
                   }});
    out.push_back({"lobe-deg3", [reps](const core::ImageF& img, const Base&) {
                       return timed(reps, [&] { return run_lobe(img, 3); });
                   }});
    // Shrink 2 is N4's usual setting; the 117 x 91 x 20 MR is small enough to fit at full size.
    out.push_back({"itk-n4", [reps](const core::ImageF& img, const Base& base) {
                       const int shrink = base.known_field ? 2 : 1;
                       return timed(reps, [&] { return run_n4(img, shrink); });
                   }});
    out.erase(std::remove_if(out.begin(), out.end(), [&](const Method& m) { return !selected(opt.methods, m.name); }),
              out.end());
    return out;
}

// ---- driver -------------------------------------------------------------------------------

void usage()
{
    std::fprintf(stderr, "usage: bias_bench [--out DIR] [--data DIR] [--reps N] [--threads N] [--inputs SUBSTR,..] "
                         "[--methods SUBSTR,..] [--quick] [--volumes DIR]\n");
}

std::optional<Options> parse(int argc, char** argv)
{
    Options opt;
    if (const char* d = std::getenv("LOBE_DATA_DIR"))
        opt.data = d;
    else
        opt.data = fs::path(LOBE_SOURCE_DIR) / ".." / "shared" / "data";
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        const bool has_value = i + 1 < argc;
        if (a == "--out" && has_value)
            opt.out = argv[++i];
        else if (a == "--data" && has_value)
            opt.data = argv[++i];
        else if (a == "--reps" && has_value)
            opt.reps = std::max(1, std::atoi(argv[++i]));
        else if (a == "--threads" && has_value)
            opt.threads = std::max(1, std::atoi(argv[++i]));
        else if (a == "--inputs" && has_value)
            opt.inputs = bench::split(argv[++i]);
        else if (a == "--methods" && has_value)
            opt.methods = bench::split(argv[++i]);
        else if (a == "--quick")
            opt.quick = true;
        else if (a == "--volumes" && has_value)
            opt.volumes = argv[++i];
        else
            return std::nullopt;
    }
    if (opt.quick) { // a smoke run: the coarse phantom, one field of each kind, one repetition
        opt.reps = 1;
        if (opt.inputs.empty())
            opt.inputs = {"phantom-1.4x5/none", "phantom-1.4x5/linear-0.30", "phantom-1.4x5/smooth-0.4", "mr-small"};
    }
    return opt;
}

} // namespace

int main(int argc, char** argv)
{
    const auto parsed = parse(argc, argv);
    if (!parsed) {
        usage();
        return 2;
    }
    const Options opt = *parsed;
    omp_set_num_threads(opt.threads);
    bench::n4_set_threads(opt.threads);
    const std::vector<Method> ms = methods(opt);

    fs::create_directories(opt.out);
    const fs::path csv = opt.out / "bias_field.csv";
    const fs::path partial = opt.out / "bias_field.csv.partial";
    std::ofstream out(partial);
    out << "input,method,seconds,field_rms_percent,liver_robust_cv,block_spread\n";
    std::fprintf(stderr, "threads: %d (OpenMP for lobe's field evaluation, ITK's global default)\n", opt.threads);

    const auto run_input = [&](const std::string& name, const core::ImageF& image, const Base& base,
                               const core::ImageF* truth) {
        std::vector<std::pair<std::string, core::ImageF>> fields; // to compare the methods' fields
        for (const Method& m : ms) {
            Correction c;
            try {
                c = m.run(image, base);
            } catch (const std::exception& e) {
                std::fprintf(stderr, "%s / %s: FAILED: %s\n", name.c_str(), m.name.c_str(), e.what());
                continue;
            }
            const std::string rms = truth ? num(field_rms_percent(c.field, *truth, base.liver), 3) : "";
            const std::string row = name + "," + m.name + "," + num(c.seconds, 4) + "," + rms + "," +
                                    num(robust_cv(c.corrected, base.liver), 4) + "," +
                                    num(block_spread(c.corrected, base.liver), 4);
            out << row << "\n" << std::flush;
            const auto [lo, hi] = liver_range(c.field, base.liver);
            std::printf("%s  [%s; field over the liver %.3f..%.3f of its mean]\n", row.c_str(), c.notes.c_str(), lo,
                        hi);
            std::fflush(stdout);
            if (m.name != "none")
                fields.emplace_back(m.name, std::move(c.field));
        }
        // Without a true field (mr-small) the methods can only be compared with each other.
        for (std::size_t a = 0; a < fields.size(); ++a)
            for (std::size_t b = a + 1; b < fields.size(); ++b)
                std::printf("  %s: %s against %s: field difference %.3f %% RMS over the liver\n", name.c_str(),
                            fields[a].first.c_str(), fields[b].first.c_str(),
                            field_rms_percent(fields[a].second, fields[b].second, base.liver));
        std::fflush(stdout);
    };

    // Noise seeds 3 and 5: the ones tests/seg/liver_test.cpp uses at these spacings' neighbours.
    const std::vector<std::pair<std::array<double, 3>, std::uint64_t>> grids{{{1.4, 1.4, 5.0}, 3},
                                                                            {{1.2, 1.2, 4.0}, 5}};
    const std::vector<Shading> fields = shadings();
    for (const auto& [spacing, seed] : grids) {
        const std::string prefix = "phantom-" + num(spacing[0], 1) + "x" + num(spacing[2], 0) + "/";
        if (std::none_of(fields.begin(), fields.end(),
                         [&](const Shading& s) { return selected(opt.inputs, prefix + s.name); }))
            continue;
        const Base base = phantom_base(spacing, seed);
        const std::string stem = prefix.substr(0, prefix.size() - 1);
        if (!opt.volumes.empty()) {
            fs::create_directories(opt.volumes);
            io::write_image(opt.volumes / (stem + "_liver.mhd"), base.liver);
        }
        for (const Shading& s : fields) {
            const std::string name = prefix + s.name;
            if (!selected(opt.inputs, name))
                continue;
            const core::ImageF truth = field_image(base.image.geometry(), s);
            core::ImageF image = base.image;
            for (std::size_t i = 0; i < image.data.size(); ++i)
                image.data[i] *= truth.data[i];
            if (!opt.volumes.empty())
                io::write_image(opt.volumes / (stem + "_" + s.name + ".mhd"), image);
            run_input(name, image, base, &truth);
        }
    }
    if (selected(opt.inputs, "mr-small")) {
        try {
            if (const auto mr = mr_small(opt.data))
                run_input(mr->name, mr->image, *mr, nullptr);
        } catch (const std::exception& e) {
            std::fprintf(stderr, "mr-small: %s: skipped\n", e.what());
        }
    }
    out.close();
    fs::rename(partial, csv);
    std::fprintf(stderr, "wrote %s\n", csv.string().c_str());
    return 0;
}
