// The ITK peer of the active-contour benchmark (see itk_peer.h). Only this file includes ITK.
#include "itk_peer.h"

#include "common/itk_image.h"

#include <itkCurvatureAnisotropicDiffusionImageFilter.h>
#include <itkGeodesicActiveContourLevelSetImageFilter.h>
#include <itkGradientImageFilter.h>
#include <itkGradientMagnitudeRecursiveGaussianImageFilter.h>
#include <itkGradientVectorFlowImageFilter.h>
#include <itkImage.h>
#include <itkMultiThreaderBase.h>
#include <itkSigmoidImageFilter.h>
#include <itkSignedMaurerDistanceMapImageFilter.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <vector>

namespace lobe::bench {
namespace {

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

template <unsigned D> using FImage = itk::Image<float, D>;
template <unsigned D> using UImage = itk::Image<unsigned char, D>;

std::string num(double a)
{
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.4g", a);
    return buf;
}

template <unsigned D>
typename FImage<D>::Pointer windowed(const core::ImageF& image, double level, double width)
{
    const float lo = static_cast<float>(level - width / 2), w = static_cast<float>(width);
    return to_itk<FImage<D>>(image, [lo, w](float v) { return std::clamp((v - lo) / w, 0.0f, 1.0f); });
}

template <unsigned D>
typename UImage<D>::Pointer binary(const core::LabelImage3D& mask, bool complement = false)
{
    return to_itk<UImage<D>>(mask, [complement](std::uint8_t v) {
        return static_cast<unsigned char>((v != 0) != complement ? 1 : 0);
    });
}

// SignedMaurerDistanceMap (exact EDT, mm): <= 0 on the object (0 on its border voxels),
// the distance to the nearest object voxel outside it.
template <unsigned D>
typename FImage<D>::Pointer maurer(typename UImage<D>::Pointer object)
{
    using Filter = itk::SignedMaurerDistanceMapImageFilter<UImage<D>, FImage<D>>;
    auto f = Filter::New();
    f->SetInput(object);
    f->SetUseImageSpacing(true);
    f->SetSquaredDistance(false);
    f->SetInsideIsPositive(false);
    f->SetBackgroundValue(0);
    f->Update();
    return f->GetOutput();
}

template <unsigned D>
core::LabelImage3D mask_from(const FImage<D>* phi, const core::ImageGeometry& grid)
{
    core::LabelImage3D out(grid, 0);
    const float* p = phi->GetBufferPointer();
    for (std::size_t i = 0; i < out.data.size(); ++i)
        out.data[i] = p[i] < 0 ? 1 : 0;
    return out;
}

double min_spacing(const core::ImageGeometry& g, unsigned D)
{
    double h = g.spacing[0];
    for (unsigned a = 1; a < D; ++a)
        h = std::min(h, g.spacing[a]);
    return h;
}

// The initial level set from the mask: the Maurer distance shifted by half the smallest
// spacing, so that the zero level lies half a voxel outside the mask's border voxels and
// phi < 0 reproduces the mask exactly (libseg's initial_level_set convention).
template <unsigned D>
typename FImage<D>::Pointer initial_phi(const core::LabelImage3D& init, int* mismatches)
{
    auto phi = maurer<D>(binary<D>(init));
    const float half = static_cast<float>(0.5 * min_spacing(init, D));
    float* p = phi->GetBufferPointer();
    int bad = 0;
    for (std::size_t i = 0; i < init.data.size(); ++i) {
        p[i] -= half;
        if ((p[i] < 0) != (init.data[i] != 0))
            ++bad;
    }
    if (mismatches)
        *mismatches = bad;
    return phi;
}

// Sigmoid alpha and beta from gradient statistics, without the reference (see ItkGacParams).
template <unsigned D>
std::pair<double, double> sigmoid_parameters(const FImage<D>* grad, const FImage<D>* phi0, const ItkGacParams& p)
{
    const float* g = grad->GetBufferPointer();
    const float* f = phi0->GetBufferPointer();
    const std::size_t n = grad->GetBufferedRegion().GetNumberOfPixels();
    double inside = 0;
    std::size_t n_inside = 0;
    std::vector<float> shell;
    for (std::size_t i = 0; i < n; ++i) {
        if (f[i] < 0) {
            inside += double(g[i]);
            ++n_inside;
        } else if (double(f[i]) <= p.shell_mm) {
            shell.push_back(g[i]);
        }
    }
    if (shell.empty())
        shell.assign(g, g + n);
    const double k2 = n_inside ? inside / static_cast<double>(n_inside) : 0.0;
    const auto k = static_cast<std::ptrdiff_t>(p.k1_percentile * static_cast<double>(shell.size() - 1));
    std::nth_element(shell.begin(), shell.begin() + k, shell.end());
    const double k1 = shell[static_cast<std::size_t>(k)];
    return {(k2 - k1) / 6.0, (k1 + k2) / 2.0};
}

template <unsigned D>
ItkRun itk_gac_d(const core::ImageF& image, const core::LabelImage3D& init, const ItkGacParams& p)
{
    ItkRun run;
    const auto t0 = Clock::now();
    auto input = windowed<D>(image, p.window_level, p.window_width);

    using Diffusion = itk::CurvatureAnisotropicDiffusionImageFilter<FImage<D>, FImage<D>>;
    auto diffusion = Diffusion::New();
    // ITK's two stability bounds: (min spacing, or 1 in index units) / 2^(dim+1) from
    // AnisotropicDiffusionImageFilter, and 0.5 / 2^dim from the curvature variant.
    const double unit = diffusion->GetUseImageSpacing() ? min_spacing(image, D) : 1.0;
    const double dt = std::min({p.diffusion_time_step, unit / double(1u << (D + 1)), 0.5 / double(1u << D)});
    diffusion->SetInput(input);
    diffusion->SetTimeStep(dt);
    diffusion->SetNumberOfIterations(static_cast<unsigned>(p.diffusion_iterations));
    diffusion->SetConductanceParameter(p.diffusion_conductance);
    diffusion->Update();

    using GradMag = itk::GradientMagnitudeRecursiveGaussianImageFilter<FImage<D>, FImage<D>>;
    auto gradmag = GradMag::New();
    gradmag->SetInput(diffusion->GetOutput());
    gradmag->SetSigma(p.sigma_mm);
    gradmag->Update();
    const double field_part1 = seconds_since(t0);

    // The initial level set is needed for the shell statistics: time it as evolution (it is
    // the level-set initialisation), not as field.
    const auto t_phi = Clock::now();
    int mismatches = 0;
    auto phi0 = initial_phi<D>(init, &mismatches);
    const double phi_seconds = seconds_since(t_phi);

    const auto t1 = Clock::now();
    const auto [alpha, beta] =
        p.statistics_mask
            ? sigmoid_parameters<D>(gradmag->GetOutput(), initial_phi<D>(*p.statistics_mask, nullptr).GetPointer(), p)
            : sigmoid_parameters<D>(gradmag->GetOutput(), phi0.GetPointer(), p);
    using Sigmoid = itk::SigmoidImageFilter<FImage<D>, FImage<D>>;
    auto sigmoid = Sigmoid::New();
    sigmoid->SetInput(gradmag->GetOutput());
    sigmoid->SetOutputMinimum(0.0f);
    sigmoid->SetOutputMaximum(1.0f);
    sigmoid->SetAlpha(alpha);
    sigmoid->SetBeta(beta);
    sigmoid->Update();
    run.field_seconds = field_part1 + seconds_since(t1);

    const auto t2 = Clock::now();
    using Gac = itk::GeodesicActiveContourLevelSetImageFilter<FImage<D>, FImage<D>, float>;
    auto gac = Gac::New();
    gac->SetInput(phi0);
    gac->SetFeatureImage(sigmoid->GetOutput());
    gac->SetPropagationScaling(static_cast<float>(p.propagation_scaling));
    gac->SetCurvatureScaling(static_cast<float>(p.curvature_scaling));
    gac->SetAdvectionScaling(static_cast<float>(p.advection_scaling));
    gac->SetMaximumRMSError(p.max_rms_error);
    gac->SetNumberOfIterations(static_cast<itk::IdentifierType>(p.iterations));
    gac->Update();
    run.evolve_seconds = phi_seconds + seconds_since(t2);

    run.mask = mask_from<D>(gac->GetOutput(), image);
    run.iterations = static_cast<int>(gac->GetElapsedIterations());
    run.converged = run.iterations < p.iterations;
    run.total_seconds = seconds_since(t0);
    run.notes = "diffusion dt " + num(dt) + " x" + std::to_string(p.diffusion_iterations) + " cond " +
                num(p.diffusion_conductance) + "; sigma " + num(p.sigma_mm) + " mm; sigmoid alpha " +
                num(alpha) + " beta " + num(beta) + (p.statistics_mask ? " (statistics from the eroded reference)" : "") +
                "; prop/curv/adv " +
                num(p.propagation_scaling) + "/" + num(p.curvature_scaling) + "/" +
                num(p.advection_scaling) + "; rms " + num(gac->GetRMSChange()) + " (max " +
                num(p.max_rms_error) + ")";
    if (mismatches)
        run.notes += "; WARNING init phi sign mismatches " + std::to_string(mismatches);
    return run;
}

template <unsigned D>
ItkRun itk_gvf_d(const core::ImageF& image, const core::LabelImage3D& init, const ItkGvfParams& p)
{
    ItkRun run;
    const auto t0 = Clock::now();
    auto input = windowed<D>(image, p.window_level, p.window_width);

    using GradMag = itk::GradientMagnitudeRecursiveGaussianImageFilter<FImage<D>, FImage<D>>;
    auto gradmag = GradMag::New();
    gradmag->SetInput(input);
    gradmag->SetSigma(p.sigma_mm);
    gradmag->Update();

    // edge map f = |grad| / max |grad| in [0, 1]
    auto edge = FImage<D>::New();
    edge->CopyInformation(gradmag->GetOutput());
    edge->SetRegions(gradmag->GetOutput()->GetBufferedRegion());
    edge->Allocate();
    {
        const float* g = gradmag->GetOutput()->GetBufferPointer();
        const std::size_t n = edge->GetBufferedRegion().GetNumberOfPixels();
        const float mx = std::max(*std::max_element(g, g + n), 1e-12f);
        float* o = edge->GetBufferPointer();
        for (std::size_t i = 0; i < n; ++i)
            o[i] = g[i] / mx;
    }

    using Gradient = itk::GradientImageFilter<FImage<D>, float, float>;
    auto gradient = Gradient::New();
    gradient->SetInput(edge);
    gradient->SetUseImageSpacing(false); // index units, as Xu & Prince and libseg's GVF
    gradient->SetUseImageDirection(false);
    gradient->Update();

    using CovImage = typename Gradient::OutputImageType;
    using Gvf = itk::GradientVectorFlowImageFilter<CovImage, CovImage, float>;
    auto gvf = Gvf::New();
    gvf->SetInput(gradient->GetOutput());
    gvf->SetIterationNum(p.iterations);
    gvf->SetNoiseLevel(p.mu);
    gvf->GetLaplacianFilter()->SetUseImageSpacing(false);
    gvf->Update();
    run.field_seconds = seconds_since(t0);
    run.iterations = p.iterations;
    run.notes = "GVF mu " + num(p.mu) + " x" + std::to_string(p.iterations) + " (dt = 1/(2^dim mu), index units); sigma " +
                num(p.sigma_mm) + " mm";
    if (!p.snake) {
        run.total_seconds = run.field_seconds;
        run.notes += "; field only";
        return run;
    }

    // The snake: normalised GVF as the advection image, sigmoid speed (from the same
    // gradient magnitude, alpha/beta as itk_gac) weighting the curvature, no propagation.
    const auto t1 = Clock::now();
    int mismatches = 0;
    auto phi0 = initial_phi<D>(init, &mismatches);
    const double phi_seconds = seconds_since(t1);

    const auto t2 = Clock::now();
    const auto [alpha, beta] = sigmoid_parameters<D>(gradmag->GetOutput(), phi0.GetPointer(), p.speed);
    using Sigmoid = itk::SigmoidImageFilter<FImage<D>, FImage<D>>;
    auto sigmoid = Sigmoid::New();
    sigmoid->SetInput(gradmag->GetOutput());
    sigmoid->SetOutputMinimum(0.0f);
    sigmoid->SetOutputMaximum(1.0f);
    sigmoid->SetAlpha(alpha);
    sigmoid->SetBeta(beta);
    sigmoid->Update();

    using Gac = itk::GeodesicActiveContourLevelSetImageFilter<FImage<D>, FImage<D>, float>;
    using VecImage = typename Gac::VectorImageType;
    auto advection = VecImage::New();
    advection->CopyInformation(input);
    advection->SetRegions(input->GetBufferedRegion());
    advection->Allocate();
    {
        const auto* v = gvf->GetOutput()->GetBufferPointer();
        auto* a = advection->GetBufferPointer();
        const std::size_t n = input->GetBufferedRegion().GetNumberOfPixels();
        for (std::size_t i = 0; i < n; ++i) {
            double m = 0;
            for (unsigned c = 0; c < D; ++c)
                m += double(v[i][c]) * double(v[i][c]);
            m = std::sqrt(m);
            for (unsigned c = 0; c < D; ++c)
                a[i][c] = m > 1e-9 ? static_cast<float>(double(v[i][c]) / m) : 0.0f;
        }
    }
    run.field_seconds += seconds_since(t2);

    const auto t3 = Clock::now();
    auto gac = Gac::New();
    gac->SetAutoGenerateSpeedAdvection(false);
    gac->SetInput(phi0);
    gac->SetFeatureImage(sigmoid->GetOutput());
    gac->SetSpeedImage(sigmoid->GetOutput());
    gac->SetAdvectionImage(advection);
    gac->SetPropagationScaling(0.0);
    gac->SetCurvatureScaling(static_cast<float>(p.curvature_scaling));
    gac->SetAdvectionScaling(static_cast<float>(p.advection_scaling));
    gac->SetMaximumRMSError(p.max_rms_error);
    gac->SetNumberOfIterations(static_cast<itk::IdentifierType>(p.snake_iterations));
    gac->Update();
    run.evolve_seconds = phi_seconds + seconds_since(t3);
    run.mask = mask_from<D>(gac->GetOutput(), image);
    run.iterations = static_cast<int>(gac->GetElapsedIterations());
    run.converged = run.iterations < p.snake_iterations;
    run.total_seconds = seconds_since(t0);
    run.notes += "; snake: normalised GVF advection " + num(p.advection_scaling) + ", curvature " +
                 num(p.curvature_scaling) + " x sigmoid(alpha " + num(alpha) + " beta " +
                 num(beta) + "), no propagation; rms " + num(gac->GetRMSChange());
    if (mismatches)
        run.notes += "; WARNING init phi sign mismatches " + std::to_string(mismatches);
    return run;
}

bool is_2d(const core::ImageGeometry& g) { return g.size[2] == 1; }

void check_grids(const core::ImageGeometry& a, const core::ImageGeometry& b, const char* what)
{
    if (!core::same_grid(a, b))
        throw std::invalid_argument(std::string(what) + ": the image and the mask are on different grids");
}

// Border voxels: object voxels with an 8- (2-D) or 26- (3-D) neighbour outside the object;
// outside the grid counts as outside, except along z for a one-slice image.
core::LabelImage3D border(const core::LabelImage3D& m)
{
    core::LabelImage3D b(m.geometry(), 0);
    const int nx = m.size[0], ny = m.size[1], nz = m.size[2];
    const int dk = nz == 1 ? 0 : 1;
    for (int k = 0; k < nz; ++k)
        for (int j = 0; j < ny; ++j)
            for (int i = 0; i < nx; ++i) {
                if (!m.data[m.index(i, j, k)])
                    continue;
                bool edge = false;
                for (int c = -dk; c <= dk && !edge; ++c)
                    for (int bb = -1; bb <= 1 && !edge; ++bb)
                        for (int a = -1; a <= 1 && !edge; ++a) {
                            const int x = i + a, y = j + bb, z = k + c;
                            if (!m.contains(x, y, z) || !m.data[m.index(x, y, z)])
                                edge = true;
                        }
                b.data[m.index(i, j, k)] = edge ? 1 : 0;
            }
    return b;
}

template <unsigned D>
CrossCheck cross_check_d(const core::LabelImage3D& seg, const core::LabelImage3D& ref)
{
    CrossCheck c;
    std::size_t ns = 0, nr = 0, both = 0;
    for (std::size_t i = 0; i < seg.data.size(); ++i) {
        const bool s = seg.data[i] != 0, r = ref.data[i] != 0;
        ns += s;
        nr += r;
        both += s && r;
    }
    c.dice = ns + nr ? 2.0 * double(both) / double(ns + nr) : 1.0;
    if (!ns || !nr)
        return c;
    const auto bs = border(seg), br = border(ref);
    const auto ds = maurer<D>(binary<D>(bs)), dr = maurer<D>(binary<D>(br));
    const float* ps = ds->GetBufferPointer();
    const float* pr = dr->GetBufferPointer();
    double sum = 0;
    for (std::size_t i = 0; i < bs.data.size(); ++i) {
        if (bs.data[i]) {
            sum += double(std::max(0.0f, pr[i]));
            ++c.border_seg;
        }
        if (br.data[i]) {
            sum += double(std::max(0.0f, ps[i]));
            ++c.border_ref;
        }
    }
    c.asd_mm = sum / double(c.border_seg + c.border_ref);
    return c;
}

} // namespace

void itk_set_threads(int n)
{
    itk::MultiThreaderBase::SetGlobalMaximumNumberOfThreads(static_cast<itk::ThreadIdType>(std::max(n, 2)));
    itk::MultiThreaderBase::SetGlobalDefaultNumberOfThreads(static_cast<itk::ThreadIdType>(n));
}

core::LabelImage3D erode_by_distance(const core::LabelImage3D& mask, double distance_mm)
{
    core::LabelImage3D out(mask.geometry(), 0);
    auto apply = [&](const float* d) {
        for (std::size_t i = 0; i < out.data.size(); ++i)
            out.data[i] = (mask.data[i] && double(d[i]) > distance_mm) ? 1 : 0;
    };
    // distance to the nearest voxel outside the mask: the Maurer map of the complement
    if (is_2d(mask))
        apply(maurer<2>(binary<2>(mask, true))->GetBufferPointer());
    else
        apply(maurer<3>(binary<3>(mask, true))->GetBufferPointer());
    return out;
}

ItkRun itk_gac(const core::ImageF& image, const core::LabelImage3D& init, const ItkGacParams& params)
{
    check_grids(image, init, "itk_gac");
    return is_2d(image) ? itk_gac_d<2>(image, init, params) : itk_gac_d<3>(image, init, params);
}

ItkRun itk_gvf(const core::ImageF& image, const core::LabelImage3D& init, const ItkGvfParams& params)
{
    check_grids(image, init, "itk_gvf");
    return is_2d(image) ? itk_gvf_d<2>(image, init, params) : itk_gvf_d<3>(image, init, params);
}

CrossCheck cross_check(const core::LabelImage3D& seg, const core::LabelImage3D& ref)
{
    check_grids(seg, ref, "cross_check");
    return is_2d(seg) ? cross_check_d<2>(seg, ref) : cross_check_d<3>(seg, ref);
}

} // namespace lobe::bench
