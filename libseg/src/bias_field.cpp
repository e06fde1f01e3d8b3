#include "lobe/seg/bias_field.h"

#include "detail/volume.h"
#include "lobe/core/errors.h"
#include "lobe/seg/kmeans.h"

#include <Eigen/Dense>

#include <algorithm>
#include <array>
#include <cmath>
#include <string>
#include <tuple>
#include <vector>

namespace lobe::seg {
namespace {

using Powers = std::array<int, 3>;

// The monomials x^a y^b z^c with a + b + c <= degree, the constant first; an axis one voxel
// long has no extent, so its powers would only repeat the constant and make the fit singular.
std::vector<Powers> monomials(int degree, const std::array<int, 3>& size)
{
    std::vector<Powers> out;
    for (int d = 0; d <= degree; ++d)
        for (int a = d; a >= 0; --a)
            for (int b = d - a; b >= 0; --b) {
                const int c = d - a - b;
                if ((a > 0 && size[0] < 2) || (b > 0 && size[1] < 2) || (c > 0 && size[2] < 2))
                    continue;
                out.push_back({a, b, c});
            }
    return out;
}

// Index coordinates to polynomial coordinates: millimetres from the grid's centre, divided by
// half the longest physical extent, so the field is smooth in mm (a thin slab of slices cannot
// carry a steep z term) and the longest axis spans [-1, 1].
struct Coordinates {
    std::array<double, 3> centre{};
    std::array<double, 3> scale{};

    explicit Coordinates(const core::ImageGeometry& g)
    {
        double half = 0.0;
        for (int a = 0; a < 3; ++a)
            half = std::max(half, 0.5 * (g.size[a] - 1) * g.spacing[a]);
        half = half > 0.0 ? half : 1.0;
        for (int a = 0; a < 3; ++a) {
            centre[a] = 0.5 * (g.size[a] - 1);
            scale[a] = g.spacing[a] / half;
        }
    }
    double operator()(int axis, int index) const { return (index - centre[axis]) * scale[axis]; }
};

// The polynomial's terms at one voxel, from the per-axis powers.
void evaluate_terms(const std::vector<Powers>& terms, const std::array<std::array<double, 5>, 3>& pw, double* out)
{
    for (std::size_t t = 0; t < terms.size(); ++t)
        out[t] = pw[0][terms[t][0]] * pw[1][terms[t][1]] * pw[2][terms[t][2]];
}

std::array<double, 5> powers_of(double x)
{
    return {1.0, x, x * x, x * x * x, x * x * x * x};
}

void validate(const core::ImageF& image, const BiasFieldParams& p)
{
    const auto fail = [](const std::string& what) { throw core::InvalidInputError("correct_bias_field: " + what); };
    if (image.data.empty() || image.data.size() != image.geometry().voxel_count())
        fail("the image is empty or its data does not match its grid");
    if (p.degree < 0 || p.degree > 4)
        fail("degree must be 0..4, is " + std::to_string(p.degree));
    if (p.classes < 1 || p.classes > 16)
        fail("classes must be 1..16, is " + std::to_string(p.classes));
    if (!(p.tissue_fraction > 0.0 && p.tissue_fraction < 1.0))
        fail("tissue_fraction must lie in (0, 1), is " + std::to_string(p.tissue_fraction));
    if (p.max_iterations < 1)
        fail("max_iterations must be at least 1, is " + std::to_string(p.max_iterations));
    if (!(p.tolerance > 0.0) || !std::isfinite(p.tolerance))
        fail("tolerance must be finite and > 0, is " + std::to_string(p.tolerance));
    if (!(p.outlier_sigmas > 0.0) || !std::isfinite(p.outlier_sigmas))
        fail("outlier_sigmas must be finite and > 0, is " + std::to_string(p.outlier_sigmas));
    if (p.max_samples < 100)
        fail("max_samples must be at least 100, is " + std::to_string(p.max_samples));
    for (float v : image.data)
        if (!std::isfinite(v))
            fail("the image has non-finite values");
}

} // namespace

BiasFieldResult correct_bias_field(const core::ImageF& image, const BiasFieldParams& p)
{
    validate(image, p);
    const core::ImageGeometry g = image.geometry();
    BiasFieldResult out;
    out.corrected = image;
    out.field = core::ImageF(g, 1.0f);

    // Tissue: clearly above air and noise. The fit sees a regular subsample of it.
    const double threshold = std::max(0.0, p.tissue_fraction * detail::sampled_quantile(image, 0.99));
    std::size_t tissue = 0;
    for (float v : image.data)
        tissue += static_cast<double>(v) > threshold && v > 0.0f;
    const std::vector<Powers> terms = monomials(p.degree, g.size);
    const auto nt = static_cast<Eigen::Index>(terms.size());
    if (tissue < 20 * terms.size() + 1)
        return out; // nothing to fit: b = 1, not converged
    const std::size_t stride = (tissue + p.max_samples - 1) / p.max_samples;

    const Coordinates xyz(g);
    std::vector<std::size_t> at;
    at.reserve(tissue / stride + 1);
    std::size_t seen = 0;
    for (std::size_t v = 0; v < image.data.size(); ++v)
        if (static_cast<double>(image.data[v]) > threshold && image.data[v] > 0.0f && seen++ % stride == 0)
            at.push_back(v);
    const auto n = static_cast<Eigen::Index>(at.size());
    out.samples = at.size();

    Eigen::MatrixXd design(n, nt);
    Eigen::VectorXd log_v(n);
    const auto nx = static_cast<std::size_t>(g.size[0]);
    const auto nxy = nx * static_cast<std::size_t>(g.size[1]);
    for (Eigen::Index s = 0; s < n; ++s) {
        const std::size_t v = at[static_cast<std::size_t>(s)];
        const int i = static_cast<int>(v % nx), j = static_cast<int>((v % nxy) / nx), k = static_cast<int>(v / nxy);
        const std::array<std::array<double, 5>, 3> pw{powers_of(xyz(0, i)), powers_of(xyz(1, j)), powers_of(xyz(2, k))};
        std::array<double, 35> row{};
        evaluate_terms(terms, pw, row.data());
        for (Eigen::Index t = 0; t < nt; ++t)
            design(s, t) = row[static_cast<std::size_t>(t)];
        log_v(s) = std::log(static_cast<double>(image.data[v]));
    }

    Eigen::VectorXd coef = Eigen::VectorXd::Zero(nt);
    Eigen::VectorXd log_b = Eigen::VectorXd::Zero(n);
    KMeansParams km;
    km.clusters = p.classes;
    core::ImageGeometry line;
    line.size = {static_cast<int>(n), 1, 1};
    core::ImageF values(line);
    std::vector<float> residual(static_cast<std::size_t>(n));
    for (out.iterations = 1; out.iterations <= p.max_iterations; ++out.iterations) {
        // Classify the corrected log intensity; from the second round on Lloyd starts at the last
        // centres, so the classes follow the field instead of being re-chosen.
        for (Eigen::Index s = 0; s < n; ++s)
            values.data[static_cast<std::size_t>(s)] = static_cast<float>(log_v(s) - log_b(s));
        const KMeansResult classes = kmeans_layers(values, km);
        if (classes.centres.size() == static_cast<std::size_t>(p.classes))
            km.seeds = classes.centres;
        const auto layer_of = [&](Eigen::Index s) {
            return static_cast<std::size_t>(std::max<int>(classes.layers.data[static_cast<std::size_t>(s)], 1) - 1);
        };
        Eigen::VectorXd target(n);
        for (Eigen::Index s = 0; s < n; ++s) {
            target(s) = log_v(s) - classes.centres[layer_of(s)];
            residual[static_cast<std::size_t>(s)] = static_cast<float>(target(s) - log_b(s));
        }
        // Weighted robust least squares, the maximum-likelihood fit of Gaussian classes: each
        // voxel weighs 1 / (its class's robust variance), so a tight class (liver, muscle) steers
        // the field more than a broad one (fat, whose T1 grey level varies with its kind), and a
        // voxel far from its class (partial volume at a class boundary, a vessel, a tissue the K
        // classes lack) is left out.
        const std::size_t nk = classes.centres.size();
        std::vector<std::vector<float>> per_class(nk);
        for (Eigen::Index s = 0; s < n; ++s)
            per_class[layer_of(s)].push_back(residual[static_cast<std::size_t>(s)]);
        std::vector<double> centre(nk), spread(nk);
        for (std::size_t k = 0; k < nk; ++k)
            std::tie(centre[k], spread[k]) = detail::median_and_robust_sd(std::move(per_class[k]));
        Eigen::MatrixXd normal = Eigen::MatrixXd::Zero(nt, nt);
        Eigen::VectorXd rhs = Eigen::VectorXd::Zero(nt);
        Eigen::Index used = 0;
        for (Eigen::Index s = 0; s < n; ++s) {
            const std::size_t k = layer_of(s);
            const double sd = std::max(spread[k], 1e-3); // 0.1 %: a constant class is not infinitely sure
            if (std::abs(static_cast<double>(residual[static_cast<std::size_t>(s)]) - centre[k]) > p.outlier_sigmas * sd)
                continue;
            const double w = 1.0 / (sd * sd);
            normal.selfadjointView<Eigen::Lower>().rankUpdate(design.row(s).transpose(), w);
            rhs += design.row(s).transpose() * (w * target(s));
            ++used;
        }
        if (used < 20 * nt)
            break; // too few inliers to trust a fit: keep the last field
        normal.triangularView<Eigen::Upper>() = normal.transpose();
        // A vanishing ridge keeps the solve defined when the tissue spans a thin region.
        normal.diagonal().array() += 1e-9 * normal.diagonal().mean();
        Eigen::VectorXd next = normal.ldlt().solve(rhs);
        Eigen::VectorXd next_log_b = design * next;
        // The field's level trades with the class means: fix its geometric mean at 1.
        const double mean = next_log_b.mean();
        next(0) -= mean;
        next_log_b.array() -= mean;
        const double change = (next_log_b - log_b).cwiseAbs().maxCoeff();
        coef = next;
        log_b = next_log_b;
        if (change < p.tolerance) {
            out.converged = true;
            break;
        }
    }
    out.iterations = std::min(out.iterations, p.max_iterations);
    out.min_gain = std::exp(log_b.minCoeff());
    out.max_gain = std::exp(log_b.maxCoeff());

    // The field on every voxel, slice by slice (the terms' z part is shared by the slice).
#pragma omp parallel for schedule(static)
    for (int k = 0; k < g.size[2]; ++k) {
        std::array<std::array<double, 5>, 3> pw{};
        pw[2] = powers_of(xyz(2, k));
        std::array<double, 35> row{};
        for (int j = 0; j < g.size[1]; ++j) {
            pw[1] = powers_of(xyz(1, j));
            for (int i = 0; i < g.size[0]; ++i) {
                pw[0] = powers_of(xyz(0, i));
                evaluate_terms(terms, pw, row.data());
                double lb = 0.0;
                for (Eigen::Index t = 0; t < nt; ++t)
                    lb += coef(t) * row[static_cast<std::size_t>(t)];
                const std::size_t v = g.index(i, j, k);
                const double b = std::exp(lb);
                out.field.data[v] = static_cast<float>(b);
                out.corrected.data[v] = static_cast<float>(static_cast<double>(image.data[v]) / b);
            }
        }
    }
    return out;
}

} // namespace lobe::seg
