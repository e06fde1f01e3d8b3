// Fuzzy connectedness (lobe/seg/fuzzy_connectedness.h): the max-min strength on a chain computed
// by hand, the lookup-table affinity against the exact one, a gap that fuzzy connectedness bridges
// and a half-contrast threshold does not, the ROI and the errors.
#include "lobe/seg/fuzzy_connectedness.h"

#include "common/expect_error.h"
#include "common/tubes.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <deque>
#include <vector>

using namespace lobe;

namespace {

//! The affinity the vessel pipeline uses for a vessel of `mean` over a background `mean - c`.
seg::AffinityParams vessel_affinity(double mean, double c)
{
    seg::AffinityParams a;
    a.object_mean = mean;
    a.object_sigma = 0.5 * c / std::sqrt(2 * std::log(2.0)); // h1 = 1/2 at half contrast
    a.gradient_sigma = c / 1.0;
    return a;
}

} // namespace

// On a chain there is one path: the strength of voxel i is the smallest affinity of the links
// before it, quantised down to the 1023 levels (so within 1/1023 of the exact value below it).
TEST(FuzzyConnectedness, MaxMinAlongAChain)
{
    const auto g = test::grid({6, 1, 1}, {1, 1, 1});
    core::ImageF f(g);
    f.data = {160, 150, 130, 155, 120, 165};
    core::LabelImage3D seeds(g, 0);
    seeds.data[0] = 1;
    seg::FuzzyConnectednessParams p;
    p.affinity = vessel_affinity(160, 60);
    p.lookup_table = false;
    const auto r = seg::fuzzy_connectedness(f, seeds, p);
    double expected = 1.0;
    EXPECT_FLOAT_EQ(r.connectedness.data[0], 1.0f);
    for (std::size_t i = 1; i < 6; ++i) {
        expected = std::min(expected, seg::affinity(p.affinity, f.data[i - 1], f.data[i], 1.0));
        EXPECT_LE(r.connectedness.data[i], expected + 1e-6) << i;
        EXPECT_GE(r.connectedness.data[i], expected - 1.0 / 1023 - 1e-6) << i;
    }
    EXPECT_EQ(r.expanded, 6u);
}

// The lookup table quantises the feature to 0.5 units: h1 changes by at most 0.25 x its largest
// slope (1/(σ√e) = 0.024 per unit at σ = 25) = 0.006, well inside 0.02, and the θ-objects agree
// on all but a handful of voxels.
TEST(FuzzyConnectedness, LookupTableMatchesExactAffinity)
{
    const auto g = test::grid({48, 48, 24}, {0.8, 0.8, 1.5});
    const auto img = test::tube_image(g, {{{4, 4, 5}, {34, 34, 30}, 2.5}, {{20, 4, 18}, {20, 34, 18}, 1.5}}, 100, 60, 6.0);
    core::LabelImage3D seeds(g, 0);
    seeds.at(8, 8, 5) = 1; // on the first tube's axis near its start (p = (6.4, 6.4, 7.5))
    seg::FuzzyConnectednessParams p;
    p.affinity = vessel_affinity(160, 60);
    p.lookup_table = false;
    const auto exact = seg::fuzzy_connectedness(img, seeds, p);
    p.lookup_table = true;
    const auto lut = seg::fuzzy_connectedness(img, seeds, p);
    double worst = 0;
    std::size_t differ = 0, object = 0;
    for (std::size_t u = 0; u < img.data.size(); ++u) {
        worst = std::max(worst, std::abs(double(exact.connectedness.data[u]) - double(lut.connectedness.data[u])));
        const bool a = exact.connectedness.data[u] >= 0.25f, b = lut.connectedness.data[u] >= 0.25f;
        object += a;
        differ += a != b;
    }
    EXPECT_LT(worst, 0.02);
    EXPECT_GT(object, 500u);
    EXPECT_LT(differ, object / 200);
}

// A tube (r = 2 mm, 60 over 100, noise 3) with a 5 mm stretch at 40 % contrast: the pair mean in
// the gap is about 124, where h1 = exp(-(36)²/(2·25.5²)) = 0.37, so the far side stays connected
// above θ = 0.25; the half-contrast threshold (130) cuts the tube there; the background (h1 = 0.06)
// stays far below θ.
TEST(FuzzyConnectedness, BridgesAContrastGapThatAThresholdCannot)
{
    const auto g = test::grid({80, 16, 16}, {1, 1, 1});
    const std::vector<test::Tube> tube{{{3, 7.5, 7.5}, {76, 7.5, 7.5}, 2.0}};
    core::ImageF img(g, 0.f);
    std::mt19937 rng(7);
    std::normal_distribution<double> noise(0, 3);
    for (int k = 0; k < 16; ++k)
        for (int j = 0; j < 16; ++j)
            for (int i = 0; i < 80; ++i) {
                const double x = i;
                const double scale = x >= 38 && x <= 43 ? 0.4 : 1.0;
                img.at(i, j, k) = static_cast<float>(100 + 60 * scale * test::tube_fraction(g, i, j, k, tube) + noise(rng));
            }
    core::LabelImage3D seeds(g, 0);
    for (int i = 4; i < 8; ++i)
        seeds.at(i, 7, 7) = 1;
    seg::FuzzyConnectednessParams p;
    p.affinity = vessel_affinity(160, 60);
    p.min_connectedness = 0.25;
    const auto r = seg::fuzzy_connectedness(img, seeds, p);
    for (int i = 50; i < 72; i += 5)
        EXPECT_GE(r.connectedness.at(i, 7, 7), 0.25f) << "x = " << i;
    EXPECT_EQ(r.connectedness.at(40, 1, 1), 0.f); // background: never reached above θ

    // The half-contrast threshold grown from the same seeds stops at the gap.
    std::vector<std::uint8_t> grown(img.data.size(), 0);
    std::deque<std::size_t> q;
    for (std::size_t u = 0; u < img.data.size(); ++u)
        if (seeds.data[u]) {
            grown[u] = 1;
            q.push_back(u);
        }
    while (!q.empty()) {
        const std::size_t u = q.front();
        q.pop_front();
        const int i = int(u % 80), j = int((u / 80) % 16), k = int(u / (80 * 16));
        const int nb[6][3] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
        for (const auto& d : nb) {
            const int ii = i + d[0], jj = j + d[1], kk = k + d[2];
            if (!g.contains(ii, jj, kk))
                continue;
            const std::size_t w = g.index(ii, jj, kk);
            if (!grown[w] && img.data[w] >= 130.f) {
                grown[w] = 1;
                q.push_back(w);
            }
        }
    }
    EXPECT_TRUE(grown[g.index(30, 7, 7)]);
    EXPECT_FALSE(grown[g.index(60, 7, 7)]);
}

// Only the ROI is visited; min_connectedness only removes what lies below it.
TEST(FuzzyConnectedness, RoiAndMinimumStrength)
{
    const auto g = test::grid({40, 20, 20}, {1, 1, 1});
    const auto img = test::tube_image(g, {{{2, 10, 10}, {37, 10, 10}, 3.0}}, 100, 60, 2.0);
    core::LabelImage3D seeds(g, 0), roi(g, 1);
    seeds.at(5, 10, 10) = 1;
    for (int k = 0; k < 20; ++k)
        for (int j = 0; j < 20; ++j)
            for (int i = 25; i < 40; ++i)
                roi.at(i, j, k) = 0;
    seg::FuzzyConnectednessParams p;
    p.affinity = vessel_affinity(160, 60);
    const auto full = seg::fuzzy_connectedness(img, seeds, p, &roi);
    EXPECT_EQ(full.connectedness.at(30, 10, 10), 0.f);
    EXPECT_GT(full.connectedness.at(20, 10, 10), 0.5f);
    p.min_connectedness = 0.3;
    const auto cut = seg::fuzzy_connectedness(img, seeds, p, &roi);
    std::size_t kept = 0;
    for (std::size_t u = 0; u < img.data.size(); ++u) {
        if (full.connectedness.data[u] >= 0.3f) {
            EXPECT_EQ(cut.connectedness.data[u], full.connectedness.data[u]);
            ++kept;
        } else {
            EXPECT_EQ(cut.connectedness.data[u], 0.f);
        }
    }
    EXPECT_GT(kept, 100u);
    EXPECT_LT(cut.expanded, full.expanded);
}

TEST(FuzzyConnectedness, RefusesBadInput)
{
    const auto g = test::grid({8, 8, 8}, {1, 1, 1});
    const core::ImageF img(g, 100.f);
    core::LabelImage3D seeds(g, 0);
    EXPECT_LOBE_ERROR(core::InvalidInputError, seg::fuzzy_connectedness(img, seeds), "no seed");
    seeds.data[0] = 1;
    seg::FuzzyConnectednessParams p;
    p.connectivity = 18;
    EXPECT_LOBE_ERROR(core::InvalidInputError, seg::fuzzy_connectedness(img, seeds, p), "connectivity");
    p = {};
    p.affinity.object_sigma = 0;
    EXPECT_LOBE_ERROR(core::InvalidInputError, seg::fuzzy_connectedness(img, seeds, p), "object_sigma");
    p = {};
    p.lut_step = 1e-6;
    core::ImageF wide = img;
    wide.data[3] = 1000;
    EXPECT_LOBE_ERROR(core::InvalidInputError, seg::fuzzy_connectedness(wide, seeds, p), "lut_step");
    const core::LabelImage3D other(test::grid({8, 8, 7}, {1, 1, 1}), 1);
    EXPECT_LOBE_ERROR(core::InvalidInputError, seg::fuzzy_connectedness(img, other), "seed mask");
    EXPECT_LOBE_ERROR(core::InvalidInputError, seg::affinity(p.affinity, 1, 2, 0), "distance");
}
