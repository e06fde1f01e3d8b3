// Tests of lobe/seg/shape_memory.h: trained on phantoms at two spacings, checked on a third
// phantom (another spacing and noise seed) with true, leaking and collapsed slices.
#include "lobe/core/any_image.h"
#include "lobe/seg/shape_memory.h"

#include "common/expect_error.h"
#include "common/masks.h"
#include "common/orientation.h"
#include "common/timing.h"
#include "lphantom/phantom.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>

using namespace lobe;

namespace {

core::LabelImage3D mask_of(const core::LabelImage3D& labels, std::initializer_list<int> values)
{
    core::LabelImage3D m(labels.geometry(), 0);
    for (std::size_t i = 0; i < m.data.size(); ++i)
        for (int v : values)
            if (labels.data[i] == v)
                m.data[i] = 1;
    return m;
}

phantom::PhantomResult make_phantom(std::array<double, 3> spacing, std::uint64_t seed)
{
    phantom::PhantomParams pp;
    pp.spacing = spacing;
    pp.size = phantom::size_for_spacing(spacing);
    pp.seed = seed;
    return phantom::generate_phantom(pp);
}

using test::count;

core::LabelImage3D unite(const core::LabelImage3D& a, const core::LabelImage3D& b)
{
    core::LabelImage3D u(a.geometry(), 0);
    for (std::size_t i = 0; i < u.data.size(); ++i)
        u.data[i] = (a.data[i] || b.data[i]) ? 1 : 0;
    return u;
}

double radius_mm(const core::LabelImage3D& s)
{
    return std::sqrt(static_cast<double>(count(s)) * s.spacing[0] * s.spacing[1] / M_PI);
}

//! Training on two spacings, checking on a third: generated once for the suite.
struct Data {
    phantom::PhantomResult train_a, train_b, check;
    core::ImageF hu_a, hu_b;
    core::LabelImage3D liver_a, liver_b, liver_c, heart_c, kidney_c;
    seg::ShapeMemory memory;
};

const Data& data()
{
    static const std::unique_ptr<Data> d = [] {
        auto p = std::make_unique<Data>();
        p->train_a = make_phantom({1.4, 1.4, 5.0}, 3);
        p->train_b = make_phantom({2.0, 2.0, 2.5}, 4);
        p->check = make_phantom({1.2, 1.2, 4.0}, 9);
        p->hu_a = core::convert_image<float>(p->train_a.ct);
        p->hu_b = core::convert_image<float>(p->train_b.ct);
        p->liver_a = mask_of(p->train_a.labels, {1, 2, 3, 4});
        p->liver_b = mask_of(p->train_b.labels, {1, 2, 3, 4});
        p->liver_c = mask_of(p->check.labels, {1, 2, 3, 4});
        p->heart_c = mask_of(p->check.labels, {13, 25});
        p->kidney_c = mask_of(p->check.labels, {14});
        p->memory = seg::train_shape_memory({&p->hu_a, &p->hu_b}, {&p->liver_a, &p->liver_b});
        return p;
    }();
    return *d;
}

//! Liver slices k of the check phantom whose next slice k+1 is also liver.
std::vector<int> liver_pairs(const core::LabelImage3D& liver)
{
    std::vector<int> ks;
    for (int k = 0; k + 1 < liver.size[2]; ++k)
        if (count(core::axial_slice(liver, k)) > 0 && count(core::axial_slice(liver, k + 1)) > 0)
            ks.push_back(k);
    return ks;
}

//! `s` shifted by (di, dj) pixels, united with itself: grown on one side.
core::LabelImage3D grow_one_side(const core::LabelImage3D& s, int di, int dj)
{
    core::LabelImage3D g = s;
    for (int j = 0; j < s.size[1]; ++j)
        for (int i = 0; i < s.size[0]; ++i)
            if (s.at(i, j, 0)) {
                // fill the segment from (i, j) to (i + di, j + dj)
                const int n = std::max(std::abs(di), std::abs(dj));
                for (int t = 1; t <= n; ++t) {
                    const int ii = i + di * t / n, jj = j + dj * t / n;
                    if (s.contains(ii, jj, 0))
                        g.at(ii, jj, 0) = 1;
                }
            }
    return g;
}

//! `s` shrunk about its centroid by `f` linearly (area * f^2).
core::LabelImage3D shrink(const core::LabelImage3D& s, double f)
{
    double ci = 0, cj = 0;
    std::size_t n = 0;
    for (int j = 0; j < s.size[1]; ++j)
        for (int i = 0; i < s.size[0]; ++i)
            if (s.at(i, j, 0)) {
                ci += i;
                cj += j;
                ++n;
            }
    ci /= static_cast<double>(n);
    cj /= static_cast<double>(n);
    core::LabelImage3D out(s.geometry(), 0);
    for (int j = 0; j < s.size[1]; ++j)
        for (int i = 0; i < s.size[0]; ++i) {
            const int si = static_cast<int>(std::lround(ci + (i - ci) / f));
            const int sj = static_cast<int>(std::lround(cj + (j - cj) / f));
            if (s.contains(si, sj, 0) && s.at(si, sj, 0))
                out.at(i, j, 0) = 1;
        }
    return out;
}

} // namespace

TEST(ShapeMemory, TrainingCountsAndIntensity)
{
    const Data& d = data();
    const seg::ShapeMemory& m = d.memory;
    EXPECT_EQ(m.volumes, 2);
    const std::size_t pairs = liver_pairs(d.liver_a).size() + liver_pairs(d.liver_b).size();
    EXPECT_EQ(m.transitions, 2 * pairs); // both directions of every consecutive pair
    EXPECT_GT(m.slices, pairs);
    ASSERT_EQ(m.steps.size(), 10u * 4u); // default radius x phase bins
    std::size_t sum = 0;
    for (std::size_t b = 0; b < m.steps.size(); ++b) {
        const auto& s = m.steps[b];
        sum += s.transitions;
        EXPECT_TRUE(std::isfinite(s.outward_per_mm) && s.outward_per_mm >= 0);
        if (b % 10 != 9) { // non-increasing with the radius
            EXPECT_GE(s.outward_per_mm, m.steps[b + 1].outward_per_mm);
            EXPECT_GE(s.growth_per_mm, m.steps[b + 1].growth_per_mm);
        }
        if (b >= 10) { // non-decreasing with the phase
            EXPECT_GE(s.inward_per_mm, m.steps[b - 10].inward_per_mm);
            EXPECT_GE(s.shrink_per_mm, m.steps[b - 10].shrink_per_mm);
        }
    }
    EXPECT_EQ(sum, m.transitions);
    // Intensity: the phantom's parenchyma is 105 HU with 12 HU noise; vessels (160-175 HU) and
    // tumours (75-85 HU) inside the eroded mask widen the tails, but the median and quartiles
    // stay within a few HU of 105.
    EXPECT_EQ(m.intensity.modality, "CT");
    EXPECT_NEAR(m.intensity.quantiles[2], 105.0, 3.0);
    EXPECT_NEAR(m.intensity.mean, 105.0, 6.0);
    EXPECT_GT(m.intensity.sd, 10.0);
    EXPECT_LT(m.intensity.sd, 30.0);
    EXPECT_LT(m.intensity.quantiles[1], m.intensity.quantiles[2]);
    EXPECT_LT(m.intensity.quantiles[2], m.intensity.quantiles[3]);
    // Both phantoms hold the same analytic liver (about 1.4 L).
    EXPECT_NEAR(m.volume_ml_min, 1400.0, 50.0);
    EXPECT_NEAR(m.volume_ml_max, 1400.0, 50.0);
    std::printf("intensity mean %.1f sd %.1f q %.1f %.1f %.1f %.1f %.1f n=%zu\n", m.intensity.mean, m.intensity.sd,
                m.intensity.quantiles[0], m.intensity.quantiles[1], m.intensity.quantiles[2], m.intensity.quantiles[3],
                m.intensity.quantiles[4], m.intensity.voxels);
    std::printf("volume %.0f-%.0f mL extent %.0f-%.0f mm max area %.0f-%.0f\n", m.volume_ml_min, m.volume_ml_max,
                m.extent_mm_min, m.extent_mm_max, m.max_area_mm2_min, m.max_area_mm2_max);
}

TEST(ShapeMemory, ACoronalStackTeachesTheSameMemory)
{
    // The training pairs stored as coronal stacks (a coronal series) hold the same axial slices;
    // training reads them on the axial grid, so every learnt number is the same to the bit. Read
    // along the stored third axis instead, the transitions would be coronal (the counts differ).
    const Data& d = data();
    const core::AxisOrder order = test::coronal_storage();
    const core::ImageF hu_a = core::reorder_axes(d.hu_a, order), hu_b = core::reorder_axes(d.hu_b, order);
    const core::LabelImage3D liver_a = core::reorder_axes(d.liver_a, order), liver_b = core::reorder_axes(d.liver_b, order);
    const seg::ShapeMemory m = seg::train_shape_memory({&hu_a, &hu_b}, {&liver_a, &liver_b});
    EXPECT_EQ(m.slices, d.memory.slices);
    EXPECT_EQ(m.transitions, d.memory.transitions);
    EXPECT_EQ(m.volume_ml_min, d.memory.volume_ml_min);
    EXPECT_EQ(m.extent_mm_max, d.memory.extent_mm_max);
    EXPECT_EQ(m.max_area_mm2_max, d.memory.max_area_mm2_max);
    EXPECT_EQ(m.intensity.voxels, d.memory.intensity.voxels);
    EXPECT_EQ(m.intensity.quantiles, d.memory.intensity.quantiles);
    std::printf("coronal stacks: %zu liver slices, %zu transitions (axial copies %zu, %zu)\n", m.slices, m.transitions,
                d.memory.slices, d.memory.transitions);
    ASSERT_EQ(m.steps.size(), d.memory.steps.size());
    for (std::size_t b = 0; b < m.steps.size(); ++b) {
        const seg::ShapeStep &s = m.steps[b], &t = d.memory.steps[b];
        EXPECT_EQ(s.transitions, t.transitions) << "bin " << b;
        EXPECT_EQ(s.outward_per_mm, t.outward_per_mm) << "bin " << b;
        EXPECT_EQ(s.envelope_per_mm, t.envelope_per_mm) << "bin " << b;
        EXPECT_EQ(s.inward_per_mm, t.inward_per_mm) << "bin " << b;
        EXPECT_EQ(s.growth_per_mm, t.growth_per_mm) << "bin " << b;
        EXPECT_EQ(s.shrink_per_mm, t.shrink_per_mm) << "bin " << b;
        EXPECT_EQ(s.centroid_per_mm, t.centroid_per_mm) << "bin " << b;
    }
}

//! One step of a propagation over the check phantom: previous slice, next slice index, the
//! largest area met so far in that direction.
struct Step {
    int prev = 0, next = 0;
    double largest = 0.0;
};

//! Every step of propagations up (k -> k+1) and down (k+1 -> k) over the liver's slices.
std::vector<Step> propagation(const core::LabelImage3D& liver)
{
    std::vector<Step> steps;
    const auto ks = liver_pairs(liver);
    const double px2 = liver.spacing[0] * liver.spacing[1];
    double largest = 0.0;
    for (int k : ks) {
        largest = std::max(largest, static_cast<double>(count(core::axial_slice(liver, k))) * px2);
        steps.push_back({k, k + 1, largest});
    }
    largest = 0.0;
    for (auto it = ks.rbegin(); it != ks.rend(); ++it) {
        largest = std::max(largest, static_cast<double>(count(core::axial_slice(liver, *it + 1))) * px2);
        steps.push_back({*it + 1, *it, largest});
    }
    return steps;
}

TEST(ShapeMemory, TrueSlicesOfAnotherPhantomArePlausible)
{
    // Trained at 1.4 x 1.4 x 5 and 2 x 2 x 2.5 mm, checked at 1.2 x 1.2 x 4 mm, another noise
    // seed: the anatomy is the same analytic liver, so every true step is within the learnt
    // limits scaled to dz = 4 mm plus the 1.5-pixel allowance (worst score measured 0.78).
    const Data& d = data();
    const double dz = d.liver_c.spacing[2];
    int n = 0, ok = 0;
    double worst = 0;
    for (const Step& st : propagation(d.liver_c)) {
        const auto a = core::axial_slice(d.liver_c, st.prev), b = core::axial_slice(d.liver_c, st.next);
        const seg::ShapeCheck c = seg::check_slice(d.memory, a, b, dz, st.largest);
        ++n;
        ok += c.plausible;
        worst = std::max(worst, c.score);
        EXPECT_TRUE(c.plausible) << st.prev << " -> " << st.next << ": " << c.reason;
        EXPECT_TRUE(std::isfinite(c.score));
        // Without the phase (largest unknown) the check is more permissive, never stricter.
        EXPECT_TRUE(seg::check_slice(d.memory, a, b, dz).plausible);
    }
    EXPECT_EQ(n, 2 * static_cast<int>(liver_pairs(d.liver_c).size()));
    std::printf("%d of %d true steps plausible, worst score %.2f\n", ok, n, worst);
}

TEST(ShapeMemory, LeaksAndCollapsesAreRejected)
{
    const Data& d = data();
    const double dz = d.liver_c.spacing[2];
    const double px = d.liver_c.spacing[0];
    const int g = static_cast<int>(std::lround(15.0 / px));
    int heart_n = 0, heart_rej = 0, kidney_n = 0, kidney_rej = 0, grow_n = 0, grow_rej = 0, col_n = 0, col_rej = 0;
    for (const Step& st : propagation(d.liver_c)) {
        const auto a = core::axial_slice(d.liver_c, st.prev), b = core::axial_slice(d.liver_c, st.next);
        const bool up = st.next > st.prev;
        const double r = radius_mm(a);
        const double area_b = static_cast<double>(count(b));
        // The heart above the liver is met going up, the kidney below it going down: the
        // directions the driver propagates in from its start slice near the top (it reaches
        // the dome going up). Leaks that add less than 10 % of the area are not counted.
        const auto heart = core::axial_slice(d.heart_c, st.next), kidney = core::axial_slice(d.kidney_c, st.next);
        if (up && static_cast<double>(count(heart)) > 0.1 * area_b) {
            ++heart_n;
            const auto c = seg::check_slice(d.memory, a, unite(b, heart), dz, st.largest);
            heart_rej += !c.plausible;
            EXPECT_FALSE(c.plausible) << "heart leak " << st.prev << " -> " << st.next << " score " << c.score;
        }
        if (!up && static_cast<double>(count(kidney)) > 0.1 * area_b) {
            ++kidney_n;
            const auto c = seg::check_slice(d.memory, a, unite(b, kidney), dz, st.largest);
            kidney_rej += !c.plausible;
            EXPECT_FALSE(c.plausible) << "kidney leak " << st.prev << " -> " << st.next << " score " << c.score;
        }
        // 15 mm on the patient's right (the ribs' side: subcostal leak), and a collapse to a
        // quarter of the area, on slices past the widest one (rho < 0.95) of radius >= 30 mm.
        const seg::ShapeCheck truth = seg::check_slice(d.memory, a, b, dz, st.largest);
        if (truth.rho < 0.95 && r >= 30) {
            ++grow_n;
            const auto cg = seg::check_slice(d.memory, a, grow_one_side(b, -g, 0), dz, st.largest);
            grow_rej += !cg.plausible;
            if (!cg.plausible) {
                EXPECT_NE(cg.reason, "");
            }
        }
        if (r >= 30) {
            ++col_n;
            const auto cc = seg::check_slice(d.memory, a, shrink(b, 0.5), dz, st.largest);
            col_rej += !cc.plausible;
            EXPECT_FALSE(cc.plausible) << "collapse " << st.prev << " -> " << st.next << " score " << cc.score;
        }
    }
    std::printf("rejected: heart %d/%d kidney %d/%d grown %d/%d collapsed %d/%d\n", heart_rej, heart_n, kidney_rej,
                kidney_n, grow_rej, grow_n, col_rej, col_n);
    // Enough cases that the loop above means something.
    EXPECT_GE(heart_n, 3);
    EXPECT_GE(kidney_n, 3);
    EXPECT_GE(grow_n, 10);
    // A one-sided 15 mm bulge is judged against the previous slice: near the dome the true
    // contour retreats 5-10 mm per 4 mm slice on that side, so the bulge is only 5-10 mm beyond
    // the previous contour and within the learnt motion; measured 20 of 27 rejected (all the
    // misses are above the widest slice going up, 36 -> 42, and 10 -> 9 at the tip).
    EXPECT_GE(grow_rej, static_cast<int>(0.7 * grow_n));
    EXPECT_EQ(heart_rej, heart_n);
    EXPECT_EQ(kidney_rej, kidney_n);
    EXPECT_EQ(col_rej, col_n);
    EXPECT_GE(col_n, 20);
}

TEST(ShapeMemory, EnvelopeHoldsTheNextSliceAndCutsALeak)
{
    const Data& d = data();
    const double dz = d.liver_c.spacing[2];
    const int g = static_cast<int>(std::lround(15.0 / d.liver_c.spacing[0]));
    std::size_t truth_n = 0, truth_in = 0, leak_n = 0, leak_out = 0, bad_core = 0, bad_env = 0;
    std::size_t organ_n = 0, organ_out = 0;
    double seconds = 0;
    const auto steps = propagation(d.liver_c);
    for (const Step& st : steps) {
        const auto a = core::axial_slice(d.liver_c, st.prev), b = core::axial_slice(d.liver_c, st.next);
        const auto t0 = std::chrono::steady_clock::now();
        const auto env = seg::plausible_envelope(d.memory, a, dz, st.largest);
        seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        const auto core_mask = seg::plausible_core(d.memory, a, dz, st.largest);
        const auto grown = grow_one_side(b, -g, 0);
        const bool up = st.next > st.prev;
        const auto organ = core::axial_slice(up ? d.heart_c : d.kidney_c, st.next);
        for (std::size_t i = 0; i < b.data.size(); ++i) {
            if (organ.data[i]) {
                ++organ_n;
                organ_out += !env.data[i];
            }
            if (b.data[i]) {
                ++truth_n;
                truth_in += env.data[i];
            } else if (grown.data[i]) {
                ++leak_n;
                leak_out += !env.data[i];
            }
            bad_core += core_mask.data[i] > a.data[i]; // the core lies inside the previous slice
            bad_env += env.data[i] < a.data[i];        // the envelope contains it
        }
    }
    EXPECT_EQ(bad_core, 0u);
    EXPECT_EQ(bad_env, 0u);
    const double recall = static_cast<double>(truth_in) / static_cast<double>(truth_n);
    const double cut = static_cast<double>(leak_out) / static_cast<double>(leak_n);
    const double organ_cut = static_cast<double>(organ_out) / static_cast<double>(organ_n);
    std::printf("envelope: recall of the true next slice %.4f, heart/kidney leak excluded %.3f, 15 mm bulge "
                "excluded %.3f, %.2f ms per slice\n",
                recall, organ_cut, cut, 1e3 * seconds / static_cast<double>(steps.size()));
    // The envelope is the dilation by the 90th percentile (over steps) of the 95th-percentile
    // boundary motion, with margin: it holds >= 99 % of the true next slices' pixels. A leak
    // into the heart or kidney lies mostly beyond it (measured 0.98 ... see the docs). A 15 mm
    // bulge is only partly cut: at 4 mm slices the learnt motion near the liver's ends is
    // 10-13 mm, so only the outer few mm go (measured 0.13); the check, not the envelope, is
    // what rejects it.
    EXPECT_GE(recall, 0.99);
    EXPECT_GE(organ_cut, 0.7);
    EXPECT_GE(cut, 0.08);
}

TEST(ShapeMemory, CheckOnAFullSizeSliceIsFast)
{
    const Data& d = data();
    // A check-phantom slice resampled onto a 512 x 512 grid of 0.7 mm (the default phantom).
    core::ImageGeometry g;
    g.size = {512, 512, 1};
    g.spacing = {0.7, 0.7, 2.5};
    const int k = d.liver_c.size[2] / 2;
    core::LabelImage3D a(g, 0), b(g, 0);
    for (int j = 0; j < 512; ++j)
        for (int i = 0; i < 512; ++i) {
            const int si = i * d.liver_c.size[0] / 512, sj = j * d.liver_c.size[1] / 512;
            a.at(i, j, 0) = d.liver_c.at(si, sj, k);
            b.at(i, j, 0) = d.liver_c.at(si, sj, k + 1);
        }
    const auto t0 = std::chrono::steady_clock::now();
    const auto c = seg::check_slice(d.memory, a, b, 4.0);
    const auto env = seg::plausible_envelope(d.memory, a, 4.0);
    const double ms = 1e3 * std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::printf("check + envelope on 512 x 512: %.1f ms\n", ms);
    EXPECT_TRUE(c.plausible) << c.reason;
    EXPECT_GT(count(env), count(a));
    EXPECT_LT(ms, test::time_bound(200.0)); // generous: a loaded 2-core machine
}

TEST(ShapeMemory, EmptyCandidateIsImplausibleNotNaN)
{
    const Data& d = data();
    const int k = d.liver_c.size[2] / 2;
    const auto a = core::axial_slice(d.liver_c, k);
    core::LabelImage3D empty(a.geometry(), 0);
    const auto c = seg::check_slice(d.memory, a, empty, 4.0);
    EXPECT_FALSE(c.plausible);
    EXPECT_EQ(c.reason, "empty");
    EXPECT_TRUE(std::isinf(c.score));
    EXPECT_EQ(c.area_mm2, 0.0);
}

TEST(ShapeMemory, ErrorsAreClear)
{
    const Data& d = data();
    using core::InvalidInputError;
    EXPECT_LOBE_ERROR(InvalidInputError, seg::train_shape_memory({}, {}), "no training volumes");
    EXPECT_LOBE_ERROR(InvalidInputError, seg::train_shape_memory({&d.hu_a}, {}), "1 images but 0");
    core::LabelImage3D empty(d.liver_a.geometry(), 0);
    EXPECT_LOBE_ERROR(InvalidInputError, seg::train_shape_memory({&d.hu_a, &d.hu_b}, {&d.liver_a, &empty}),
                      "volume 2", "grid");
    EXPECT_LOBE_ERROR(InvalidInputError, seg::train_shape_memory({&d.hu_a}, {&empty}), "volume 1", "empty");
    // One liver slice: no transition to learn from.
    core::LabelImage3D one = empty;
    one.at(50, 50, 10) = 1;
    EXPECT_LOBE_ERROR(InvalidInputError, seg::train_shape_memory({&d.hu_a}, {&one}), "no two consecutive");

    const int k = d.liver_c.size[2] / 2;
    const auto a = core::axial_slice(d.liver_c, k);
    core::LabelImage3D none(a.geometry(), 0);
    EXPECT_LOBE_ERROR(InvalidInputError, seg::check_slice(d.memory, none, a, 4.0), "previous slice is empty");
    EXPECT_LOBE_ERROR(InvalidInputError, seg::check_slice(d.memory, a, a, 0.0), "dz");
    EXPECT_LOBE_ERROR(InvalidInputError, seg::check_slice(d.memory, a, a, std::nan("")), "dz");
    EXPECT_LOBE_ERROR(InvalidInputError, seg::check_slice(d.memory, d.liver_c, a, 4.0), "one slice");
    EXPECT_LOBE_ERROR(InvalidInputError, seg::check_slice(d.memory, a, core::axial_slice(d.liver_a, 10), 4.0),
                      "grid");
    EXPECT_LOBE_ERROR(InvalidInputError, seg::check_slice(seg::ShapeMemory{}, a, a, 4.0), "train it first");
    EXPECT_LOBE_ERROR(InvalidInputError, seg::plausible_envelope(d.memory, none, 4.0), "empty");
}
