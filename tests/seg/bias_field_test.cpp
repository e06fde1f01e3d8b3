// MR shading correction (lobe/seg/bias_field.h) on volumes built here: four tissues in a body,
// times a known smooth field, plus noise. The model (piecewise-constant tissues, log b a
// polynomial of degree 2) is exact here, so what is left after the fit is noise.
#include "lobe/seg/bias_field.h"

#include "lobe/core/errors.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <random>
#include <vector>

using namespace lobe;

namespace {

// A 96 x 80 x 24 body at 2 x 2 x 4 mm: air outside an ellipse, a fat rim (400, T1-bright),
// muscle (40) and fluid (20) blobs and a liver (100) inside the rest. Returns the tissue image
// (without field) and writes each voxel's tissue label (0 = air) to `labels`.
core::ImageF body(std::vector<int>& labels)
{
    core::ImageGeometry g;
    g.size = {96, 80, 24};
    g.spacing = {2.0, 2.0, 4.0};
    core::ImageF img(g, 0.0f);
    labels.assign(img.data.size(), 0);
    for (int k = 0; k < g.size[2]; ++k)
        for (int j = 0; j < g.size[1]; ++j)
            for (int i = 0; i < g.size[0]; ++i) {
                const double x = (i - 47.5) / 44.0, y = (j - 39.5) / 36.0;
                const double r = x * x + y * y;
                int t = 0;
                if (r < 1.0)
                    t = r > 0.75 ? 4 : 3; // fat rim, liver inside
                if (t == 3 && std::hypot(x - 0.35, y + 0.2) < 0.25)
                    t = 2; // muscle
                if (t == 3 && std::hypot(x + 0.4, y - 0.25) < 0.2)
                    t = 1; // fluid
                const std::size_t v = g.index(i, j, k);
                labels[v] = t;
                img.data[v] = static_cast<float>(std::array<double, 5>{0, 20, 40, 100, 400}[static_cast<std::size_t>(t)]);
            }
    return img;
}

// `tissue` times `field(x, y, z)` (x, y, z in [-1, 1] across the grid), plus Gaussian noise of sd
// `noise` (additive, as an MR magnitude's is in tissue).
core::ImageF shaded(const core::ImageF& tissue, const std::function<double(double, double, double)>& field,
                    double noise, std::vector<double>& truth)
{
    core::ImageF out = tissue;
    truth.assign(out.data.size(), 1.0);
    std::mt19937 rng(7);
    std::normal_distribution<double> n(0.0, noise);
    for (int k = 0; k < out.size[2]; ++k)
        for (int j = 0; j < out.size[1]; ++j)
            for (int i = 0; i < out.size[0]; ++i) {
                const std::size_t v = out.index(i, j, k);
                const double b = field(2.0 * i / (out.size[0] - 1) - 1, 2.0 * j / (out.size[1] - 1) - 1,
                                       2.0 * k / (out.size[2] - 1) - 1);
                truth[v] = b;
                out.data[v] = static_cast<float>(std::max(0.0, double(tissue.data[v]) * b + (tissue.data[v] > 0 ? n(rng) : 0.0)));
            }
    return out;
}

// RMS of log(estimated / true) over the tissue, after removing its mean (a field is only known up
// to a scale: the tissue's grey levels absorb it), in percent.
double field_error_percent(const core::ImageF& estimate, const std::vector<double>& truth, const std::vector<int>& labels)
{
    std::vector<double> d;
    for (std::size_t v = 0; v < truth.size(); ++v)
        if (labels[v] > 0)
            d.push_back(std::log(double(estimate.data[v]) / truth[v]));
    double mean = 0;
    for (double x : d)
        mean += x;
    mean /= double(d.size());
    double ss = 0;
    for (double x : d)
        ss += (x - mean) * (x - mean);
    return 100.0 * std::sqrt(ss / double(d.size()));
}

// The coefficient of variation of one tissue in `img`.
double cv_of(const core::ImageF& img, const std::vector<int>& labels, int tissue)
{
    double s = 0, ss = 0, n = 0;
    for (std::size_t v = 0; v < labels.size(); ++v)
        if (labels[v] == tissue) {
            const double x = img.data[v];
            s += x;
            ss += x * x;
            ++n;
        }
    const double mean = s / n;
    return std::sqrt(std::max(0.0, ss / n - mean * mean)) / mean;
}

} // namespace

// A coil's falloff across the body (±30 % in x, a bend in y, a z tilt): degree 2 holds it
// exactly, so the estimate is limited by the noise (sd 3 on the liver's 100: a 3 % CV). Measured:
// 0.54 % field error, liver CV 14.3 % → 3.1 % in 24 iterations. Bounds: 1.5 % error (3× the measured), liver CV
// under 3.5 % (the noise's 3 % plus the field error).
TEST(BiasField, RecoversAKnownSmoothField)
{
    std::vector<int> labels;
    const core::ImageF tissue = body(labels);
    std::vector<double> truth;
    const core::ImageF img =
        shaded(tissue, [](double x, double y, double z) { return std::exp(-0.3 * x - 0.15 * y * y + 0.1 * z); }, 3.0, truth);
    const seg::BiasFieldResult r = seg::correct_bias_field(img);
    EXPECT_TRUE(r.converged);
    EXPECT_GT(r.samples, 100000u);
    const double err = field_error_percent(r.field, truth, labels);
    std::cerr << "field error " << err << " %, liver CV " << cv_of(img, labels, 3) << " -> "
              << cv_of(r.corrected, labels, 3) << ", " << r.iterations << " iterations, gain " << r.min_gain << ".."
              << r.max_gain << "\n";
    EXPECT_LT(err, 1.5);
    EXPECT_GT(cv_of(img, labels, 3), 0.10); // the shading is there to remove
    EXPECT_LT(cv_of(r.corrected, labels, 3), 0.035);
    EXPECT_LT(cv_of(r.corrected, labels, 4), 0.035); // the fat rim too (noise 3 on 400: under 1 %)
    // The gains span the true field's range (exp(±0.3 ± ...)), to within the error above.
    EXPECT_LT(r.min_gain, 0.8);
    EXPECT_GT(r.max_gain, 1.2);
}

// Without shading the fit must not invent one: the gain stays within ±1 % (noise only).
TEST(BiasField, LeavesAnUnshadedVolumeAlone)
{
    std::vector<int> labels;
    const core::ImageF tissue = body(labels);
    std::vector<double> truth;
    const core::ImageF img = shaded(tissue, [](double, double, double) { return 1.0; }, 3.0, truth);
    const seg::BiasFieldResult r = seg::correct_bias_field(img);
    EXPECT_TRUE(r.converged);
    EXPECT_GT(r.min_gain, 0.99);
    EXPECT_LT(r.max_gain, 1.01);
}

// A field the polynomial cannot hold (a step of 0.8 to 1.2 across x) breaks the model: the K-means
// classes split the liver at the step and the fit has nothing smooth to find. It must fail safely:
// a finite, positive field within the step's own range, and the liver's spread not made worse by
// more than 10 % (measured: CV 20.7 % → 21.5 %).
TEST(BiasField, AFieldOutsideTheModelFailsSafely)
{
    std::vector<int> labels;
    const core::ImageF tissue = body(labels);
    std::vector<double> truth;
    const core::ImageF img = shaded(tissue, [](double x, double, double) { return x < 0.1 ? 0.8 : 1.2; }, 3.0, truth);
    const seg::BiasFieldResult r = seg::correct_bias_field(img);
    for (float b : r.field.data)
        ASSERT_TRUE(std::isfinite(b) && b > 0.0f);
    EXPECT_GT(r.min_gain, 0.8 / 1.2);
    EXPECT_LT(r.max_gain, 1.2 / 0.8);
    std::cerr << "step: liver CV " << cv_of(img, labels, 3) << " -> " << cv_of(r.corrected, labels, 3) << ", gain "
              << r.min_gain << ".." << r.max_gain << "\n";
    EXPECT_LT(cv_of(r.corrected, labels, 3), 1.1 * cv_of(img, labels, 3));
}

// Where nothing can be fitted the image comes back unchanged, b = 1, not converged; bad input and
// parameters are refused with an error that names them.
TEST(BiasField, FailsSafely)
{
    core::ImageGeometry g;
    g.size = {20, 20, 4};
    const core::ImageF dark(g, 0.0f); // no tissue at all
    seg::BiasFieldResult r = seg::correct_bias_field(dark);
    EXPECT_FALSE(r.converged);
    EXPECT_EQ(r.samples, 0u);
    EXPECT_EQ(r.corrected.data, dark.data);
    EXPECT_TRUE(std::all_of(r.field.data.begin(), r.field.data.end(), [](float b) { return b == 1.0f; }));

    // A constant body has one grey level: no class contrast, no field.
    r = seg::correct_bias_field(core::ImageF(g, 50.0f));
    EXPECT_NEAR(r.min_gain, 1.0, 1e-6);
    EXPECT_NEAR(r.max_gain, 1.0, 1e-6);

    // One slice: the z powers are dropped, the fit still runs.
    core::ImageGeometry g2 = g;
    g2.size = {40, 40, 1};
    core::ImageF slice(g2, 0.0f);
    for (int j = 0; j < 40; ++j)
        for (int i = 0; i < 40; ++i)
            slice.data[slice.index(i, j, 0)] = static_cast<float>((i < 20 ? 100.0 : 300.0) * (1.0 + 0.005 * j));
    seg::BiasFieldParams quartic;
    quartic.degree = 4;
    r = seg::correct_bias_field(slice, quartic);
    EXPECT_TRUE(r.converged);
    EXPECT_NEAR(r.max_gain / r.min_gain, 1.0 + 0.005 * 39, 0.02);

    core::ImageF bad(g, 50.0f);
    bad.data[3] = std::numeric_limits<float>::quiet_NaN();
    EXPECT_THROW(seg::correct_bias_field(bad), core::InvalidInputError);
    EXPECT_THROW(seg::correct_bias_field(core::ImageF{}), core::InvalidInputError);
    const auto refused = [&](const std::function<void(seg::BiasFieldParams&)>& set) {
        seg::BiasFieldParams p;
        set(p);
        EXPECT_THROW(seg::correct_bias_field(dark, p), core::InvalidInputError);
    };
    refused([](seg::BiasFieldParams& p) { p.degree = 5; });
    refused([](seg::BiasFieldParams& p) { p.classes = 0; });
    refused([](seg::BiasFieldParams& p) { p.tissue_fraction = 1.0; });
    refused([](seg::BiasFieldParams& p) { p.tolerance = 0.0; });
    refused([](seg::BiasFieldParams& p) { p.max_samples = 10; });
}
