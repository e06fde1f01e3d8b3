// Tests of lobe/seg/postprocess.h: the 3-D pass on a jagged stack of the phantom's liver.
#include "lobe/seg/postprocess.h"

#include "common/expect_error.h"
#include "common/masks.h"
#include "lobe/seg/metrics.h"
#include "lphantom/phantom.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>
#include <random>

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

using test::count;

//! Fraction of the voxels of `part` that `m` holds.
double covered(const core::LabelImage3D& m, const core::LabelImage3D& part)
{
    std::size_t n = 0, in = 0;
    for (std::size_t i = 0; i < m.data.size(); ++i)
        if (part.data[i]) {
            ++n;
            in += m.data[i] != 0;
        }
    return n ? static_cast<double>(in) / static_cast<double>(n) : 0.0;
}

//! Each slice grown or shrunk by a random 0-2 pixels (4-neighbour steps): the jagged stack a
//! slice-by-slice segmentation gives.
core::LabelImage3D jitter(const core::LabelImage3D& m, std::uint64_t seed)
{
    std::mt19937_64 rng(seed);
    std::uniform_int_distribution<int> step(-2, 2);
    core::LabelImage3D out = m;
    const int nx = m.size[0], ny = m.size[1];
    for (int k = 0; k < m.size[2]; ++k) {
        const int s = step(rng);
        for (int it = 0; it < std::abs(s); ++it) {
            const core::LabelImage3D prev = out;
            for (int j = 1; j + 1 < ny; ++j)
                for (int i = 1; i + 1 < nx; ++i) {
                    const auto nb = prev.at(i - 1, j, k) + prev.at(i + 1, j, k) + prev.at(i, j - 1, k) +
                                    prev.at(i, j + 1, k);
                    if (s > 0 && nb > 0)
                        out.at(i, j, k) = 1;
                    if (s < 0 && nb < 4)
                        out.at(i, j, k) = 0;
                }
        }
    }
    return out;
}

struct Data {
    phantom::PhantomResult ph;
    core::LabelImage3D liver, parenchyma, inner, ivc, jagged;
};

const Data& data()
{
    static const std::unique_ptr<Data> d = [] {
        auto p = std::make_unique<Data>();
        phantom::PhantomParams pp;
        pp.spacing = {1.2, 1.2, 2.5};
        pp.size = phantom::size_for_spacing(pp.spacing);
        pp.seed = 5;
        p->ph = phantom::generate_phantom(pp);
        p->liver = mask_of(p->ph.labels, {1, 2, 3, 4});
        p->parenchyma = mask_of(p->ph.labels, {1});
        p->inner = mask_of(p->ph.labels, {2, 3, 4});
        p->ivc = mask_of(p->ph.labels, {15});
        // The IVC only lies in the Omega concavity where the neck is (z in -22..56 mm, see
        // tools/lphantom/phantom.cpp); elsewhere it runs outside the liver.
        for (int k = 0; k < p->ivc.size[2]; ++k) {
            const double z = p->ivc.index_to_physical(0, 0, k).z;
            if (z < -20 || z > 54)
                for (int j = 0; j < p->ivc.size[1]; ++j)
                    for (int i = 0; i < p->ivc.size[0]; ++i)
                        p->ivc.at(i, j, k) = 0;
        }
        p->jagged = jitter(p->parenchyma, 11);
        return p;
    }();
    return *d;
}

} // namespace

TEST(Postprocess, Sliver07BringsAJaggedParenchymaStackCloserToTheLiver)
{
    const Data& d = data();
    const auto r = seg::postprocess_liver_full(d.jagged);
    const auto before = seg::evaluate_segmentation(d.jagged, d.liver);
    const auto after = seg::evaluate_segmentation(r.mask, d.liver);
    std::printf("vs liver {1,2,3,4}: Dice %.4f -> %.4f, ASD %.3f -> %.3f mm, RVD %.2f -> %.2f %%; "
                "filled holes %zu, concavities %zu, removed %zu, t = %.3f, %.3f s\n",
                before.dice, after.dice, before.surface.average, after.surface.average, before.rvd, after.rvd,
                r.filled_holes, r.filled_concavities, r.removed_components, r.threshold, r.seconds);
    std::printf("inner structures covered %.3f -> %.3f, IVC covered %.3f -> %.3f\n", covered(d.jagged, d.inner),
                covered(r.mask, d.inner), covered(d.jagged, d.ivc), covered(r.mask, d.ivc));
    // Filling the vessels and tumours and the IVC concavity, and smoothing the +-2 px jitter:
    // measured Dice 0.934 -> 0.960 and ASD 3.2 -> 0.9 mm (margins for another seed's jitter).
    EXPECT_GT(after.dice, before.dice + 0.015);
    EXPECT_GT(after.dice, 0.95);
    EXPECT_LT(after.surface.average, 0.5 * before.surface.average);
    EXPECT_LT(after.surface.average, 1.2);
    // Internal vessels and tumours: measured 0.89 covered (the rest are the trunks leaving the
    // liver at the hilum, which are not enclosed in any slice).
    EXPECT_GT(covered(r.mask, d.inner), 0.8);
    EXPECT_GT(covered(r.mask, d.ivc), 0.9);
    EXPECT_GT(r.filled_holes, 0u);
    EXPECT_GT(r.filled_concavities, 0u);
    EXPECT_LT(r.seconds, 3.0);
}

TEST(Postprocess, ParenchymaKeepsHolesAndTheIvcOut)
{
    const Data& d = data();
    seg::PostprocessParams p;
    p.convention = seg::LiverConvention::Parenchyma;
    const auto r = seg::postprocess_liver_full(d.jagged, p);
    const auto before = seg::evaluate_segmentation(d.jagged, d.parenchyma);
    const auto after = seg::evaluate_segmentation(r.mask, d.parenchyma);
    std::printf("vs parenchyma {1}: Dice %.4f -> %.4f, ASD %.3f -> %.3f mm, volume %.1f -> %.1f mL\n", before.dice,
                after.dice, before.surface.average, after.surface.average, before.volume_seg_ml, after.volume_seg_ml);
    std::printf("inner covered %.3f IVC covered %.3f\n", covered(r.mask, d.inner), covered(r.mask, d.ivc));
    // Holes restored: the vessels and tumours the jagged stack left out stay out (the 0-2 px
    // jitter grows some slices over their rims: measured 0.16, as in the input).
    EXPECT_LT(covered(r.mask, d.inner), covered(d.jagged, d.inner) + 0.05);
    EXPECT_LT(covered(r.mask, d.ivc), 0.1);
    EXPECT_EQ(r.filled_concavities, 0u);
    // Smoothing keeps the volume (volume-preserving threshold; holes cut out again afterwards):
    // measured -0.01 %; stated bound 2 %.
    EXPECT_NEAR(after.volume_seg_ml, before.volume_seg_ml, 0.02 * before.volume_seg_ml);
    EXPECT_GT(after.dice, before.dice);
    EXPECT_LT(after.surface.average, before.surface.average);
}

TEST(Postprocess, SmoothingAloneKeepsTheVolume)
{
    const Data& d = data();
    seg::PostprocessParams p;
    p.fill_holes = false;
    p.concavity_closing_mm = 0;
    const auto r = seg::postprocess_liver_full(d.jagged, p);
    const double change = (static_cast<double>(count(r.mask)) - static_cast<double>(count(d.jagged))) /
                          static_cast<double>(count(d.jagged));
    p.preserve_volume = false;
    const auto half = seg::postprocess_liver_full(d.jagged, p);
    const double change_half = (static_cast<double>(count(half.mask)) - static_cast<double>(count(d.jagged))) /
                               static_cast<double>(count(d.jagged));
    std::printf("volume change: preserving %.3f %% (t = %.3f), at 0.5 %.3f %%\n", 100 * change, r.threshold,
                100 * change_half);
    // The level is found on a 4096-bin histogram: the count above it is within one bin of the
    // input's; stated bound 0.5 %.
    EXPECT_LT(std::abs(change), 0.005);
    EXPECT_EQ(r.filled_holes, 0u);
}

TEST(Postprocess, EmptyAndSingleSliceInputsAreSafe)
{
    const Data& d = data();
    core::LabelImage3D empty(d.jagged.geometry(), 0);
    const auto r = seg::postprocess_liver_full(empty);
    EXPECT_EQ(count(r.mask), 0u);
    EXPECT_TRUE(core::same_grid(r.mask, empty));

    const int k = d.liver.size[2] / 2;
    const auto one = core::axial_slice(d.liver, k);
    const auto s = seg::postprocess_liver(one);
    ASSERT_EQ(s.data.size(), one.data.size());
    const double ratio = static_cast<double>(count(s)) / static_cast<double>(count(one));
    // One slice: the z smoothing is the identity (mirrored border), only in-plane smoothing and
    // the 2-D filling act; the area changes by the filled vessels only (measured ratio below).
    std::printf("single slice: area ratio %.3f\n", ratio);
    EXPECT_GT(ratio, 0.95);
    EXPECT_LT(ratio, 1.15);

    // A single voxel: smoothing would erase it; it is kept rather than lost.
    core::LabelImage3D dot(d.jagged.geometry(), 0);
    dot.at(100, 100, 20) = 1;
    EXPECT_EQ(count(seg::postprocess_liver(dot)), 1u);

    core::LabelImage3D bad = empty;
    bad.data.resize(10);
    EXPECT_LOBE_ERROR(core::InvalidInputError, seg::postprocess_liver(bad), "values for");
    seg::PostprocessParams p;
    p.smoothing_mm = std::nan("");
    EXPECT_LOBE_ERROR(core::InvalidInputError, seg::postprocess_liver(one, p), "NaN");
}

TEST(Postprocess, LargestComponentIsKept)
{
    const Data& d = data();
    core::LabelImage3D m = d.liver;
    // A stray blob far from the liver (a leak that the driver left on a few slices).
    for (int k = 5; k < 9; ++k)
        for (int j = 10; j < 20; ++j)
            for (int i = m.size[0] - 20; i < m.size[0] - 10; ++i)
                m.at(i, j, k) = 1;
    const auto r = seg::postprocess_liver_full(m);
    EXPECT_EQ(r.removed_components, 400u);
    for (int k = 5; k < 9; ++k)
        EXPECT_EQ(r.mask.at(m.size[0] - 15, 15, k), 0);
    seg::PostprocessParams p;
    p.keep_largest_component = false;
    EXPECT_EQ(seg::postprocess_liver_full(m, p).removed_components, 0u);
}

// The run-based labelling against a plain voxel-by-voxel 26-connected flood fill on random
// volumes full of small components (density 0.08-0.2, around and above 26-connected percolation,
// about 0.1): the same voxels are kept, to the voxel, with ties going to the component met first
// in raster order (k, j, i). Smoothing and the Parenchyma convention are off/on so that the
// output is exactly the largest component.
TEST(Postprocess, LargestComponentMatchesAVoxelFloodFill)
{
    core::ImageGeometry g;
    g.size = {37, 29, 17};
    g.spacing = {1, 1, 1};
    seg::PostprocessParams p;
    p.smoothing_mm = 0;
    p.convention = seg::LiverConvention::Parenchyma;
    for (const double density : {0.08, 0.12, 0.2}) {
        std::mt19937_64 rng(static_cast<unsigned>(density * 100));
        std::bernoulli_distribution on(density);
        core::LabelImage3D m(g, 0);
        for (auto& v : m.data)
            v = on(rng) ? 1 : 0;
        // Reference: label by BFS in raster order, keep the first largest.
        std::vector<int> label(m.data.size(), 0);
        std::vector<std::size_t> size{0};
        for (int k = 0; k < g.size[2]; ++k)
            for (int j = 0; j < g.size[1]; ++j)
                for (int i = 0; i < g.size[0]; ++i) {
                    if (!m.at(i, j, k) || label[m.index(i, j, k)])
                        continue;
                    const int id = static_cast<int>(size.size());
                    size.push_back(0);
                    std::vector<std::array<int, 3>> stack{{i, j, k}};
                    label[m.index(i, j, k)] = id;
                    while (!stack.empty()) {
                        const auto [a, b, c] = stack.back();
                        stack.pop_back();
                        ++size.back();
                        for (int dk = -1; dk <= 1; ++dk)
                            for (int dj = -1; dj <= 1; ++dj)
                                for (int di = -1; di <= 1; ++di) {
                                    const int x = a + di, y = b + dj, z = c + dk;
                                    if (x < 0 || y < 0 || z < 0 || x >= g.size[0] || y >= g.size[1] || z >= g.size[2])
                                        continue;
                                    if (m.at(x, y, z) && !label[m.index(x, y, z)]) {
                                        label[m.index(x, y, z)] = id;
                                        stack.push_back({x, y, z});
                                    }
                                }
                    }
                }
        ASSERT_GT(size.size(), 3u) << "density " << density << ": the volume should hold several components";
        const int best = static_cast<int>(std::max_element(size.begin(), size.end()) - size.begin());
        const auto r = seg::postprocess_liver_full(m, p);
        std::size_t differ = 0, kept = 0;
        for (std::size_t v = 0; v < m.data.size(); ++v) {
            const bool want = label[v] == best;
            kept += want;
            differ += (r.mask.data[v] != 0) != want;
        }
        EXPECT_EQ(differ, 0u) << "density " << density << ": " << size.size() - 1 << " components";
        EXPECT_EQ(r.removed_components, count(m) - kept) << "density " << density;
    }
}

TEST(Postprocess, FullSizeVolumeUnderASecond)
{
    // A liver-sized ellipsoid with jagged slices on the default 512 x 512 x 80 grid.
    core::ImageGeometry g;
    g.size = {512, 512, 80};
    g.spacing = {0.7, 0.7, 2.5};
    core::LabelImage3D m(g, 0);
    std::mt19937_64 rng(3);
    std::uniform_real_distribution<double> u(-1.4, 1.4);
    for (int k = 5; k < 75; ++k) {
        const double dz = (k - 40) * 2.5 / 85.0, jag = u(rng);
        for (int j = 0; j < 512; ++j)
            for (int i = 0; i < 512; ++i) {
                const double dx = (i - 200) * 0.7 / (100.0 + jag), dy = (j - 256) * 0.7 / (75.0 + jag);
                if (dx * dx + dy * dy + dz * dz <= 1.0)
                    m.at(i, j, k) = 1;
            }
    }
    const auto r = seg::postprocess_liver_full(m);
    std::printf("512 x 512 x 80: %.3f s\n", r.seconds);
    EXPECT_GT(count(r.mask), 0u);
    EXPECT_LT(r.seconds, 3.0); // measured below 1 s on the idle machine; margin for load
}
