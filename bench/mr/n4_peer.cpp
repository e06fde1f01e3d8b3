// The ITK peer of the bias-field benchmark (see n4_peer.h). Only this file includes ITK.
#include "n4_peer.h"

#include "common/itk_image.h"

#include <itkBSplineControlPointImageFilter.h>
#include <itkCommand.h>
#include <itkImage.h>
#include <itkMultiThreaderBase.h>
#include <itkN4BiasFieldCorrectionImageFilter.h>
#include <itkShrinkImageFilter.h>

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

using FImage = itk::Image<float, 3>;
using UImage = itk::Image<unsigned char, 3>;
using N4 = itk::N4BiasFieldCorrectionImageFilter<FImage, UImage, FImage>;

// libseg's tissue rule (bias_field.cpp): above `fraction` of the 99th percentile of a strided
// sample of at most about a million voxels, and above 0 (N4 takes the log).
double tissue_threshold(const core::ImageF& image, double fraction)
{
    const std::size_t n = image.data.size();
    const std::size_t stride = std::max<std::size_t>(1, n / (std::size_t(1) << 20));
    std::vector<float> sample;
    sample.reserve(n / stride + 1);
    for (std::size_t i = 0; i < n; i += stride)
        sample.push_back(image.data[i]);
    const auto k = static_cast<std::ptrdiff_t>(0.99 * static_cast<double>(sample.size() - 1));
    std::nth_element(sample.begin(), sample.begin() + k, sample.end());
    return std::max(0.0, fraction * static_cast<double>(sample[static_cast<std::size_t>(k)]));
}

// Records how many iterations N4 ran at each level (N4 resets its counter per level, and its
// ElapsedIterations after Update() is one past the last level's count).
class LevelCounter : public itk::Command {
public:
    using Self = LevelCounter;
    using Pointer = itk::SmartPointer<Self>;
    itkNewMacro(Self)
    std::vector<int> iterations;
    double convergence = 0.0;

    void Execute(itk::Object* caller, const itk::EventObject& event) override
    {
        Execute(static_cast<const itk::Object*>(caller), event);
    }
    void Execute(const itk::Object* caller, const itk::EventObject& event) override
    {
        if (!itk::IterationEvent().CheckEvent(&event))
            return;
        const auto* n4 = dynamic_cast<const N4*>(caller);
        if (!n4)
            return;
        const auto level = static_cast<std::size_t>(n4->GetCurrentLevel());
        if (iterations.size() <= level)
            iterations.resize(level + 1, 0);
        iterations[level] = static_cast<int>(n4->GetElapsedIterations());
        convergence = static_cast<double>(n4->GetCurrentConvergenceMeasurement());
    }
};

} // namespace

void n4_set_threads(int n)
{
    itk::MultiThreaderBase::SetGlobalMaximumNumberOfThreads(static_cast<itk::ThreadIdType>(std::max(n, 2)));
    itk::MultiThreaderBase::SetGlobalDefaultNumberOfThreads(static_cast<itk::ThreadIdType>(n));
}

N4Run n4_correct(const core::ImageF& image, const N4Params& p)
{
    if (image.data.empty() || p.iterations.empty() || p.shrink < 1)
        throw std::runtime_error("n4_correct: empty image or bad parameters");
    N4Run run;
    const auto t0 = Clock::now();
    const double threshold = tissue_threshold(image, p.tissue_fraction);
    auto input = to_itk<FImage>(image, [](float v) { return v; });
    auto mask = to_itk<UImage>(image, [threshold](float v) {
        return static_cast<unsigned char>(static_cast<double>(v) > threshold && v > 0.0f ? 1 : 0);
    });
    const unsigned char* in_mask = mask->GetBufferPointer();
    for (std::size_t i = 0; i < image.data.size(); ++i)
        run.mask_voxels += in_mask[i];

    // Fit on the shrunk grid, as ITK's N4 example and ANTs do (N4's cost is per voxel).
    using ShrinkF = itk::ShrinkImageFilter<FImage, FImage>;
    using ShrinkU = itk::ShrinkImageFilter<UImage, UImage>;
    auto shrink_input = ShrinkF::New();
    shrink_input->SetInput(input);
    shrink_input->SetShrinkFactors(static_cast<unsigned>(p.shrink));
    auto shrink_mask = ShrinkU::New();
    shrink_mask->SetInput(mask);
    shrink_mask->SetShrinkFactors(static_cast<unsigned>(p.shrink));
    shrink_input->Update();
    shrink_mask->Update();

    auto n4 = N4::New();
    n4->SetInput(shrink_input->GetOutput());
    n4->SetMaskImage(shrink_mask->GetOutput());
    n4->SetNumberOfFittingLevels(static_cast<unsigned>(p.iterations.size()));
    N4::VariableSizeArrayType iterations(static_cast<unsigned>(p.iterations.size()));
    for (std::size_t l = 0; l < p.iterations.size(); ++l)
        iterations[static_cast<unsigned>(l)] = p.iterations[l];
    n4->SetMaximumNumberOfIterations(iterations);
    n4->SetConvergenceThreshold(static_cast<N4::RealType>(p.convergence));
    auto counter = LevelCounter::New();
    n4->AddObserver(itk::IterationEvent(), counter);
    const auto t_fit = Clock::now();
    try {
        n4->Update();
    } catch (const itk::ExceptionObject& e) {
        throw std::runtime_error(std::string("N4: ") + e.GetDescription());
    }
    run.fit_seconds = seconds_since(t_fit);

    // The log field on the full grid from N4's control-point lattice, as ITK's N4 example does.
    // The lattice spans the shrunk grid's extent, which is up to (shrink - 1) / 2 voxels short of
    // the full grid at each end; evaluating it over the full extent stretches it by that much
    // (a negligible change of a field smooth over the lattice's 8 spans per axis).
    using BSpliner = itk::BSplineControlPointImageFilter<N4::BiasFieldControlPointLatticeType, N4::ScalarImageType>;
    auto bspliner = BSpliner::New();
    bspliner->SetInput(n4->GetLogBiasFieldControlPointLattice());
    bspliner->SetSplineOrder(n4->GetSplineOrder());
    bspliner->SetSize(input->GetLargestPossibleRegion().GetSize());
    bspliner->SetOrigin(input->GetOrigin());
    bspliner->SetSpacing(input->GetSpacing());
    bspliner->SetDirection(input->GetDirection());
    bspliner->Update();

    run.field = core::ImageF(image.geometry(), 1.0f);
    run.corrected = image;
    const N4::ScalarType* log_b = bspliner->GetOutput()->GetBufferPointer();
    for (std::size_t i = 0; i < image.data.size(); ++i) {
        const double b = std::exp(static_cast<double>(log_b[i][0]));
        run.field.data[i] = static_cast<float>(b);
        run.corrected.data[i] = static_cast<float>(static_cast<double>(image.data[i]) / b);
    }
    run.seconds = seconds_since(t0);

    // Cross-check of the reconstruction (not timed): unshrunk, N4's own output is input / b on
    // the same grid, so the two fields must agree on the mask.
    double worst = 0.0;
    if (p.shrink == 1) {
        const float* corrected = n4->GetOutput()->GetBufferPointer();
        for (std::size_t i = 0; i < image.data.size(); ++i)
            if (in_mask[i] && corrected[i] > 0.0f) {
                const double ratio = static_cast<double>(image.data[i]) / static_cast<double>(corrected[i]);
                worst = std::max(worst, std::abs(std::log(ratio) - std::log(static_cast<double>(run.field.data[i]))));
            }
    }
    run.level_iterations = counter->iterations;
    run.last_convergence = counter->convergence;
    const auto lattice = n4->GetLogBiasFieldControlPointLattice()->GetLargestPossibleRegion().GetSize();
    char buf[160];
    std::snprintf(buf, sizeof buf, "shrink %d, mask %zu voxels, fit %.3f s, lattice %lux%lux%lu", p.shrink,
                  run.mask_voxels, run.fit_seconds, static_cast<unsigned long>(lattice[0]),
                  static_cast<unsigned long>(lattice[1]), static_cast<unsigned long>(lattice[2]));
    run.notes = buf;
    if (p.shrink == 1)
        run.notes += ", max |log b - log(input / N4 output)| " + std::to_string(worst);
    return run;
}

} // namespace lobe::bench
