// The automatic liver pipeline (lobe/seg/liver.h) on phantoms it was not tuned on, and where it
// must refuse. The pipeline was developed on the default phantom (0.7 x 0.7 x 2.5 mm, noise seed
// 1); these tests use other spacings and noise seeds. The bounds are the measured values less a
// margin for platform differences in floating point (the propagation is deterministic for a
// given build); docs/algorithms/liver.md lists the measurements and the failure modes that cap
// them (the phantom's heart wall is 5 HU from liver and touches the dome almost horizontally).
#include "lobe/seg/liver.h"

#include "lobe/core/any_image.h"
#include "lobe/core/errors.h"
#include "lobe/seg/distance_transform.h"
#include "lobe/seg/metrics.h"
#include "lobe/seg/shape_memory.h"
#include "lphantom/phantom.h"
#include "common/masks.h"
#include "common/orientation.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <initializer_list>
#include <iostream>
#include <limits>
#include <random>
#include <string>

using namespace lobe;

namespace {

core::LabelImage3D liver_truth(const core::LabelImage3D& labels)
{
    core::LabelImage3D m(labels.geometry(), 0);
    for (std::size_t i = 0; i < m.data.size(); ++i)
        m.data[i] = labels.data[i] >= 1 && labels.data[i] <= 4 ? 1 : 0;
    return m;
}

struct Case {
    core::ImageF hu;
    core::LabelImage3D truth;
    phantom::PhantomTruth info;
    core::LabelImage3D labels;
};

Case phantom_case(std::array<double, 3> spacing, std::uint64_t seed)
{
    phantom::PhantomParams pp;
    pp.spacing = spacing;
    pp.size = phantom::size_for_spacing(spacing);
    pp.seed = seed;
    auto ph = phantom::generate_phantom(pp);
    return {core::convert_image<float>(ph.ct), liver_truth(ph.labels), ph.truth, ph.labels};
}

// The lowest slice with liver in `truth` (its size[2] if none).
int lowest_slice(const core::LabelImage3D& truth)
{
    for (int k = 0; k < truth.size[2]; ++k) {
        const core::LabelImage3D sl = core::axial_slice(truth, k);
        if (std::any_of(sl.data.begin(), sl.data.end(), [](std::uint8_t v) { return v != 0; }))
            return k;
    }
    return truth.size[2];
}

// Voxels of the mask `m` whose phantom label is one of `which`.
std::size_t voxels_on(const core::LabelImage3D& m, const core::LabelImage3D& labels,
                      std::initializer_list<std::uint8_t> which)
{
    std::size_t n = 0;
    for (std::size_t i = 0; i < m.data.size(); ++i)
        n += m.data[i] && std::find(which.begin(), which.end(), labels.data[i]) != which.end();
    return n;
}

// A component switched on and off on one case: both results, and what the tests compare of them.
struct OnOff {
    seg::LiverResult on, off;
    seg::SegmentationMeasures m_on, m_off;
    double score_on = 0, score_off = 0;
    double missed_on = 0, missed_off = 0;   // truth voxels left out
    double outside_on = 0, outside_off = 0; // mask voxels outside the truth

    // "what: missed a -> b, outside c -> d, Dice e -> f, score g -> h"
    void print(const std::string& what) const
    {
        std::cerr << what << ": missed " << missed_off << " -> " << missed_on << ", outside " << outside_off << " -> "
                  << outside_on << ", Dice " << m_off.dice << " -> " << m_on.dice << ", score " << score_off << " -> "
                  << score_on << "\n";
    }
};

// Runs the pipeline with `p` (on) and with `p` as switch_off(p) leaves it (off).
template <class SwitchOff> OnOff on_and_off(const Case& c, seg::LiverParams p, SwitchOff&& switch_off)
{
    OnOff r;
    r.on = seg::segment_liver(c.hu, p);
    switch_off(p);
    r.off = seg::segment_liver(c.hu, p);
    r.m_on = seg::evaluate_segmentation(r.on.mask, c.truth);
    r.m_off = seg::evaluate_segmentation(r.off.mask, c.truth);
    r.score_on = seg::sliver_score(r.m_on).total;
    r.score_off = seg::sliver_score(r.m_off).total;
    r.missed_on = test::voxels_missed(r.on.mask, c.truth);
    r.missed_off = test::voxels_missed(r.off.mask, c.truth);
    r.outside_on = test::voxels_outside(r.on.mask, c.truth);
    r.outside_off = test::voxels_outside(r.off.mask, c.truth);
    return r;
}

// Slices where the vessel-cut rule kept a piece.
int vessel_cut_slices(const seg::LiverResult& r)
{
    int n = 0;
    for (const auto& s : r.slices)
        n += s.vessel_cut_mm2 > 0;
    return n;
}

// The vessel-cut midline (LiverParams::vessel_cut_midline_reach_mm) switched off and on with `p`:
// it must keep pieces on more slices, win back more than `missed` truth voxels, `dice` and
// `score`, and add at most `outside` voxels outside the truth.
void expect_midline_gains(const Case& c, const seg::LiverParams& p, const std::string& what, double missed, double dice,
                          double score, double outside = 3000.0)
{
    const OnOff r = on_and_off(c, p, [](seg::LiverParams& q) { q.vessel_cut_midline_reach_mm = 0.0; });
    r.print(what + ": vessel-cut pieces on " + std::to_string(vessel_cut_slices(r.off)) + " -> " +
            std::to_string(vessel_cut_slices(r.on)) + " slices");
    EXPECT_GT(vessel_cut_slices(r.on), vessel_cut_slices(r.off));
    EXPECT_LT(r.missed_on + missed, r.missed_off);
    EXPECT_LT(r.outside_on, r.outside_off + outside);
    EXPECT_GE(r.m_on.dice, r.m_off.dice + dice);
    EXPECT_GE(r.score_on, r.score_off + score);
}

double precision_in(const core::LabelImage3D& m, const core::LabelImage3D& truth_slice)
{
    std::size_t in = 0, all = 0;
    for (std::size_t i = 0; i < m.data.size(); ++i)
        if (m.data[i]) {
            ++all;
            in += truth_slice.data[i] ? 1 : 0;
        }
    return all ? double(in) / double(all) : 0.0;
}

} // namespace

// 1.4 x 1.4 x 5 mm, noise seed 3: coarse slices make the heart and kidney contacts blurrier.
// Measured: Dice 0.907, ASD 2.7 mm, RVD +10.2 %, SLIVER07 score 40.3 (the same before the surface lesions; 29.0 before the heart model; 0.876, +17.6 % and
// 19.2 with the first form of the dark rim; 0.848, 5.3 mm and +28.5 % before the edge snap, growing pieces and vessel inlets; the kidney under the
// liver leaks in; the heart above the dome did too, Dice 0.82 and ASD 6.6 mm, until the dome contact closed it off).
// Since energy competition's repeat is trimmed (2026-12-07, later): Dice 0.932, ASD 1.87 mm, RVD
// 9.0 %, score 53.8. Since the layer clip and the edge snap's reach in mm (2026-12-07, night):
// Dice 0.951, ASD 1.18 mm, RVD +3.1 %, score 71.7; the bounds below were raised with them, the
// score's to ten points under the measured one.
TEST(LiverPipeline, CoarsePhantomIsFound)
{
    const Case c = phantom_case({1.4, 1.4, 5.0}, 3);
    const seg::LiverResult r = seg::segment_liver(c.hu);
    ASSERT_TRUE(r.seed.found) << r.seed.message;
    // The seed must be liver: the whole pipeline trusts it.
    EXPECT_GE(precision_in(r.seed.mask, core::axial_slice(c.truth, r.seed.slice)), 0.99);
    EXPECT_TRUE(r.start.found) << r.start.message;
    const auto m = seg::evaluate_segmentation(r.mask, c.truth);
    const double score = seg::sliver_score(m).total;
    std::cerr << "coarse phantom: Dice " << m.dice << ", ASD " << m.surface.average << " mm, RVD " << m.rvd
              << " %, SLIVER07 score " << score << "\n";
    EXPECT_GE(m.dice, 0.93);
    EXPECT_LE(m.surface.average, 2.0);
    EXPECT_LE(std::abs(m.rvd), 10.0);
    // The score is lower at 5 mm slices (the kidney's volume and distance errors); a bound ten
    // points under the measured 71.7, which the heart and kidney leaks of the earlier forms fall
    // below. Scores move by several points when a build changes one slice's outcome (liver.md),
    // hence the margin.
    EXPECT_GE(score, 61.0);
    // The propagation stops below the start slice (the heart/lung slice).
    EXPECT_LT(r.last_slice, r.start.slice);
}

// The same anatomy stored head to feet (the slices reversed, the third axis turned round, every
// voxel in place) gives the same liver: the pipeline runs in reverse slice order and maps its
// result back, so the mask is the reverse of the head-up run's bit for bit (the data it runs on
// is the same) and every slice index counts from the other end. Without the mapping, the heart
// above the dome was read as below the liver (the demo phantom scored 21.0 instead of 76.0).
TEST(LiverPipeline, SlicesFromHeadToFeetGiveTheSameLiver)
{
    const Case c = phantom_case({1.4, 1.4, 5.0}, 3);
    const core::ImageF reversed = core::reverse_slices(c.hu);
    ASSERT_LT(reversed.axis(2).z, 0.0);
    const seg::LiverResult up = seg::segment_liver(c.hu);
    const seg::LiverResult down = seg::segment_liver(reversed);
    ASSERT_TRUE(up.start.found) << up.start.message;
    const int nz = c.hu.size[2];
    EXPECT_EQ(test::voxels_differing(core::reverse_slices(down.mask), up.mask), 0u);
    EXPECT_EQ(test::voxels_differing(core::reverse_slices(down.stacked), up.stacked), 0u);
    EXPECT_TRUE(core::same_grid(down.mask, reversed));
    EXPECT_EQ(down.start.slice, nz - 1 - up.start.slice);
    EXPECT_EQ(down.seed.slice, nz - 1 - up.seed.slice);
    EXPECT_EQ(down.seed_slice, nz - 1 - up.seed_slice);
    EXPECT_EQ(down.first_slice, nz - 1 - up.last_slice);
    EXPECT_EQ(down.last_slice, nz - 1 - up.first_slice);
    EXPECT_NEAR(down.start.heart_centre.z, nz - 1 - up.start.heart_centre.z, 1e-9);
    // The seed's one-slice grid is its slice of the input's.
    EXPECT_TRUE(core::same_grid(down.seed.mask, core::axial_slice(reversed, down.seed.slice)));
    ASSERT_EQ(down.slices.size(), up.slices.size());
    for (std::size_t i = 1; i < down.slices.size(); ++i)
        EXPECT_EQ(down.slices[i].slice, down.slices[i - 1].slice + 1); // ascending, as documented
    EXPECT_EQ(down.slices.front().slice, nz - 1 - up.slices.back().slice);
    EXPECT_NEAR(down.volume_ml, up.volume_ml, 1e-9);
}

// The same anatomy stored with its rows and columns reversed (x and y turned round, the way a
// NIfTI volume in RAS is stored against DICOM's LPS): the pipeline turns the volume back to the
// patient frame's axes before it runs, so the liver is the same bit for bit, and the heart centre
// and the seed are mapped to the input's grid. Before that, the seed search's cells (laid from
// voxel (0, 0)) fell elsewhere on the reversed grid: the demo phantom scored 75.8 against 76.0,
// ct-small 9.4 against 10.8 (liver.md, "Orientation"). propagate_liver takes its seed on the
// input's grid likewise.
TEST(LiverPipeline, RowsAndColumnsReversedGiveTheSameLiver)
{
    const Case c = phantom_case({1.4, 1.4, 5.0}, 3);
    const std::array<bool, 3> xy{true, true, false};
    const core::ImageF turned = core::flip_axes(c.hu, xy);
    ASSERT_LT(turned.axis(0).x, 0.0);
    ASSERT_LT(turned.axis(1).y, 0.0);
    const seg::LiverResult lps = seg::segment_liver(c.hu);
    const seg::LiverResult ras = seg::segment_liver(turned);
    ASSERT_TRUE(lps.start.found) << lps.start.message;
    EXPECT_EQ(test::voxels_differing(core::flip_axes(ras.mask, xy), lps.mask), 0u);
    EXPECT_EQ(test::voxels_differing(core::flip_axes(ras.stacked, xy), lps.stacked), 0u);
    EXPECT_TRUE(core::same_grid(ras.mask, turned));
    EXPECT_EQ(ras.start.slice, lps.start.slice);
    EXPECT_EQ(ras.seed_slice, lps.seed_slice);
    EXPECT_EQ(ras.first_slice, lps.first_slice);
    EXPECT_EQ(ras.last_slice, lps.last_slice);
    EXPECT_NEAR(ras.start.heart_centre.x, c.hu.size[0] - 1 - lps.start.heart_centre.x, 1e-9);
    EXPECT_NEAR(ras.start.heart_centre.y, c.hu.size[1] - 1 - lps.start.heart_centre.y, 1e-9);
    EXPECT_NEAR(ras.start.rotation_deg, lps.start.rotation_deg, 1e-9); // in the patient frame
    EXPECT_TRUE(core::same_grid(ras.seed.mask, core::axial_slice(turned, ras.seed.slice)));
    EXPECT_EQ(test::voxels_differing(core::flip_axes(ras.seed.mask, xy), lps.seed.mask), 0u);
    EXPECT_GT(test::voxels_differing(ras.seed.mask, lps.seed.mask), 0u); // the mapping did something

    // The propagation alone, from the seed as it lies on each grid.
    const seg::LiverResult p_lps = seg::propagate_liver(c.hu, lps.seed.mask, lps.seed.slice);
    const seg::LiverResult p_ras = seg::propagate_liver(turned, ras.seed.mask, ras.seed.slice);
    EXPECT_GT(test::count(p_lps.mask), 0u);
    EXPECT_EQ(test::voxels_differing(core::flip_axes(p_ras.mask, xy), p_lps.mask), 0u);
}

// The same anatomy stored as a coronal stack (rows along x, columns to the feet, slices to the
// back, as a coronal MR series is): segmented on its axial slices, the same liver bit for bit,
// the slice indices counting along the stored axis that runs along the body (here reversed).
// Before, the start slice and the seed refused such a volume. propagate_liver, whose seed is one
// of the volume's slices, refuses it with a message.
TEST(LiverPipeline, ACoronalStackGivesTheSameLiver)
{
    const Case c = phantom_case({1.4, 1.4, 5.0}, 3);
    const core::AxisOrder order = test::coronal_storage();
    const core::ImageF coronal = core::reorder_axes(c.hu, order);
    ASSERT_LT(coronal.axis(1).z, -0.99);
    const seg::LiverResult axial = seg::segment_liver(c.hu);
    const seg::LiverResult r = seg::segment_liver(coronal);
    ASSERT_TRUE(axial.start.found) << axial.start.message;
    EXPECT_TRUE(core::same_grid(r.mask, coronal));
    EXPECT_EQ(test::voxels_differing(r.mask, core::reorder_axes(axial.mask, order)), 0u);
    const int nz = c.hu.size[2];
    EXPECT_EQ(r.start.slice, nz - 1 - axial.start.slice);
    EXPECT_EQ(r.first_slice, nz - 1 - axial.last_slice);
    EXPECT_NEAR(r.start.heart_centre.x, axial.start.heart_centre.x, 1e-9);
    EXPECT_NEAR(r.start.heart_centre.y, nz - 1 - axial.start.heart_centre.z, 1e-9);
    EXPECT_NEAR(r.start.heart_centre.z, axial.start.heart_centre.y, 1e-9);
    // The seed stays the axial slice it is, with that slice's geometry.
    EXPECT_EQ(test::voxels_differing(r.seed.mask, axial.seed.mask), 0u);
    EXPECT_TRUE(core::same_grid(r.seed.mask, axial.seed.mask));
    try {
        seg::propagate_liver(coronal, axial.seed.mask, axial.seed.slice);
        ADD_FAILURE() << "a coronal stack's seed slice accepted";
    } catch (const core::InvalidInputError& e) {
        EXPECT_NE(std::string(e.what()).find("not axial"), std::string::npos) << e.what();
    }
}

// 0.9 x 0.9 x 3 mm, noise seed 5. Measured: Dice 0.952, ASD 1.4 mm, SLIVER07 score 69.9 (0.908
// and 3.9 mm before the edge snap, growing pieces and vessel inlets; 0.875 and 4.9 mm before the
// dome contact). The score's bound is ten points under the measured one (see the test above).
// Since energy competition's repeat is trimmed (2026-12-07, later): Dice 0.966, ASD 1.02 mm, RVD
// 3.3 %, score 72.3. Since the layer clip and the edge snap's reach in mm (2026-12-07, night):
// Dice 0.967, ASD 0.95 mm, RVD -0.3 %, score 77.1 (above the second rater's 75 on a phantom used
// for nothing else); the bounds below were raised with them.
TEST(LiverPipeline, FinePhantomIsFound)
{
    const Case c = phantom_case({0.9, 0.9, 3.0}, 5);
    const seg::LiverResult r = seg::segment_liver(c.hu);
    const auto m = seg::evaluate_segmentation(r.mask, c.truth);
    const double score = seg::sliver_score(m).total;
    std::cerr << "fine phantom: Dice " << m.dice << ", ASD " << m.surface.average << " mm, RVD " << m.rvd
              << " %, SLIVER07 score " << score << "\n";
    EXPECT_GE(m.dice, 0.95);
    EXPECT_LE(m.surface.average, 1.5);
    EXPECT_GE(score, 67.0);
    // Every slice of the propagation is reported once, in ascending order.
    for (std::size_t i = 1; i < r.slices.size(); ++i)
        EXPECT_EQ(r.slices[i].slice, r.slices[i - 1].slice + 1);
}

// The propagation alone, from the true liver of the centroid slice shrunk by 10 mm: what the
// slice-by-slice driver achieves when the seed is right (no heart is known, so no dome contact
// is sought). Measured: Dice 0.88 (0.81 before the edge snap, growing pieces and vessel inlets;
// no rib cage, no start slice: the heart and kidney leaks are larger than in the whole pipeline).
// Since energy competition's repeat is trimmed (2026-12-07, later): Dice 0.852.
TEST(LiverPipeline, PropagationFromAKnownSeed)
{
    const Case c = phantom_case({1.4, 1.4, 5.0}, 3);
    const int k0 = c.info.landmark("liver_centroid").index[2];
    const core::LabelImage3D sl = core::axial_slice(c.truth, k0);
    core::LabelImage3D outside(sl.geometry(), 0);
    for (std::size_t i = 0; i < sl.data.size(); ++i)
        outside.data[i] = sl.data[i] ? 0 : 1;
    const core::ImageF d = seg::euclidean_distance(outside);
    core::LabelImage3D seed(sl.geometry(), 0);
    for (std::size_t i = 0; i < sl.data.size(); ++i)
        seed.data[i] = sl.data[i] && double(d.data[i]) > 10.0 ? 1 : 0;
    const seg::LiverResult r = seg::propagate_liver(c.hu, seed, k0);
    const auto m = seg::evaluate_segmentation(r.mask, c.truth);
    std::cerr << "propagation from a known seed: Dice " << m.dice << "\n";
    EXPECT_GE(m.dice, 0.76);
    EXPECT_LE(r.first_slice, k0);
    EXPECT_GE(r.last_slice, k0);
}

// The dome contact (docs/algorithms/liver.md, "The dome contact") on a phantom that neither it
// nor the pipeline was tuned on (1.0 x 1.0 x 2.5 mm, noise seed 11). Without it the propagation
// takes the heart wall over the dome; with it the columns above the diaphragm's z-valley are
// closed. Measured (2026-12-07, since the seed's window): 32 982 heart voxels (wall and blood) in
// the mask without, 9 541 with (-71 %); Dice 0.939 -> 0.958 (with the 60 mm seed window 33 945 ->
// 9 572, 0.936 -> 0.955; before the heart model 47 223 -> 5 889). The bounds ask for half of
// each gain.
// Since energy competition's repeat is trimmed (2026-12-07, later): heart voxels 63 737 -> 14 638,
// Dice 0.9216 -> 0.9615.
TEST(LiverPipeline, DomeContactKeepsTheHeartOut)
{
    const Case c = phantom_case({1.0, 1.0, 2.5}, 11);
    seg::LiverParams on; // the dome contact alone: the heart model closes the heart too (next test)
    on.use_heart_model = false;
    seg::LiverParams off = on;
    off.use_dome_contact = false;
    const seg::LiverResult with = seg::segment_liver(c.hu, on);
    const seg::LiverResult without = seg::segment_liver(c.hu, off);
    auto heart = [&](const core::LabelImage3D& m) {
        return voxels_on(m, c.labels, {phantom::kHeart, phantom::kHeartBlood});
    };
    const double d_on = seg::evaluate_segmentation(with.mask, c.truth).dice;
    const double d_off = seg::evaluate_segmentation(without.mask, c.truth).dice;
    std::cerr << "dome contact: heart voxels " << heart(without.mask) << " -> " << heart(with.mask) << ", Dice "
              << d_off << " -> " << d_on << "\n";
    // Contacts are closed only going up, above the seed.
    int closed = 0;
    for (const auto& s : with.slices) {
        if (s.above_contact_mm2 > 0) {
            ++closed;
            EXPECT_GT(s.slice, with.seed_slice + 1) << s.slice;
        }
    }
    EXPECT_GT(closed, 0);
    for (const auto& s : without.slices)
        EXPECT_EQ(s.above_contact_mm2, 0.0);
    EXPECT_LT(double(heart(with.mask)), 0.58 * double(heart(without.mask)));
    EXPECT_GE(d_on, d_off + 0.014);
}

// The dome contact's ring broken by noise (LiverParams::contact_min_area_mm2): the heart's base
// meets the dome along rings, and where noise breaks a ring its fragments (1.5-3.3 cm² on this
// phantom) fell below the old 3 cm² minimum and were ignored, so the heart wall over the dome was
// followed up (15-23 cm² a slice). The demo's grid with another noise seed (0.7 x 0.7 x 2.5 mm,
// seed 54) and a shape memory trained on two coarse phantoms, as `lseg train` builds it; the
// minimum was chosen on a sweep of 21 phantoms (liver.md). Measured, 300 -> 150 mm²: heart voxels
// 35 752 -> 4 322, SLIVER07 score 68.2 -> 85.2. Bounds: half the heart voxels, half the score's gain.
// Since energy competition's repeat is trimmed (2026-12-07, later): heart voxels 48 788 -> 4 029,
// score 63.9 -> 87.3. Since the layer clip (2026-12-07, night), which keeps part of the heart wall
// out of the snake's start on its own: heart voxels 16 578 -> 4 435, score 81.3 -> 87.6; the
// score's bound is half of that gain.
TEST(LiverPipeline, BrokenDomeContactRingStillCounts)
{
    const Case a = phantom_case({1.4, 1.4, 5.0}, 3), b = phantom_case({2.0, 2.0, 2.5}, 4);
    const seg::ShapeMemory memory = seg::train_shape_memory({&a.hu, &b.hu}, {&a.truth, &b.truth});
    const Case c = phantom_case({0.7, 0.7, 2.5}, 54);
    seg::LiverParams p;
    const seg::LiverResult now = seg::segment_liver(c.hu, p, &memory);
    p.contact_min_area_mm2 = 300.0;
    const seg::LiverResult before = seg::segment_liver(c.hu, p, &memory);
    const auto heart = [&](const core::LabelImage3D& m) {
        return voxels_on(m, c.labels, {phantom::kHeart, phantom::kHeartBlood});
    };
    const double s_now = seg::sliver_score(seg::evaluate_segmentation(now.mask, c.truth)).total;
    const double s_before = seg::sliver_score(seg::evaluate_segmentation(before.mask, c.truth)).total;
    std::cerr << "broken ring: heart voxels " << heart(before.mask) << " -> " << heart(now.mask) << ", score "
              << s_before << " -> " << s_now << "\n";
    EXPECT_LT(double(heart(now.mask)), 0.5 * double(heart(before.mask)));
    EXPECT_GE(s_now, s_before + 3.1);
}

// The heart model (LiverParams::use_heart_model): at thick slices the diaphragm over the dome is
// no z-valley and the dome contact finds little, so the heart wall is taken in the liver's place.
// The heart's blood pool, followed down from the start slice and widened by the myocardium's 10
// mm, closes it. On a phantom used for nothing else (1.2 x 1.2 x 5 mm, noise seed 17). Measured:
// heart voxels in the mask 13 339 without, 5 052 with; Dice 0.913 -> 0.928. Truth voxels missed
// 8 221 -> 10 152: with the heart closed, the dome's top slice 33 reads 38 % outside the liver's
// grey levels and the tissue stop ends the run there (1 890 liver voxels; without the model the
// slice is kept with 3 052 voxels of heart). Before the seed slice's window was widened
// (2026-12-07) the model missed no more liver (9 310 -> 7 526). Bounds: two thirds of the heart
// voxels, half the Dice gain, at most 2 500 more liver voxels missed (that slice).
// Since energy competition's repeat is trimmed (2026-12-07, later): heart in the mask 17 813 ->
// 5 865, Dice 0.9127 -> 0.9398, liver missed 6 065 -> 6 373.
TEST(LiverPipeline, HeartModelKeepsTheHeartOutAtThickSlices)
{
    const Case c = phantom_case({1.2, 1.2, 5.0}, 17);
    seg::LiverParams off;
    off.use_heart_model = false;
    const seg::LiverResult with = seg::segment_liver(c.hu);
    const seg::LiverResult without = seg::segment_liver(c.hu, off);
    const auto heart = [&](const core::LabelImage3D& m) {
        return voxels_on(m, c.labels, {phantom::kHeart, phantom::kHeartBlood});
    };
    const auto missed = [&](const core::LabelImage3D& m) { return test::voxels_missed(m, c.truth); };
    const double d_on = seg::evaluate_segmentation(with.mask, c.truth).dice;
    const double d_off = seg::evaluate_segmentation(without.mask, c.truth).dice;
    std::cerr << "heart model: " << with.heart_model_voxels << " voxels; heart in the mask " << heart(without.mask)
              << " -> " << heart(with.mask) << ", Dice " << d_off << " -> " << d_on << ", liver missed "
              << missed(without.mask) << " -> " << missed(with.mask) << "\n";
    EXPECT_GT(with.heart_model_voxels, 0u);
    EXPECT_EQ(without.heart_model_voxels, 0u);
    int closed = 0;
    for (const auto& s : with.slices)
        closed += s.heart_mm2 > 0;
    EXPECT_GT(closed, 0);
    EXPECT_LT(double(heart(with.mask)), 2.0 / 3.0 * double(heart(without.mask)));
    EXPECT_GE(d_on, d_off + 0.009);
    EXPECT_LE(missed(with.mask), missed(without.mask) + 2500.0);
    seg::LiverParams bad;
    bad.heart_min_area_fraction = 1.5;
    EXPECT_THROW(seg::segment_liver(c.hu, bad), core::InvalidInputError);
}

// Volumes it cannot handle get a clear error, never a garbage mask.
TEST(LiverPipeline, RefusesWhatItCannotSegment)
{
    core::ImageGeometry g;
    g.size = {64, 64, 12};
    g.spacing = {3.0, 3.0, 5.0};
    // Constant image (no contrast at all).
    EXPECT_THROW(seg::segment_liver(core::ImageF(g, 0.f)), seg::LiverNotFoundError);
    // Uniform noise over the HU range: no homogeneous liver-like tissue.
    core::ImageF noise(g);
    std::mt19937 rng(4);
    std::uniform_real_distribution<float> u(-1000.f, 1000.f);
    for (auto& v : noise.data)
        v = u(rng);
    EXPECT_THROW(seg::segment_liver(noise), seg::LiverNotFoundError);
    // A few slices only: a volume, not a slice, is needed.
    core::ImageGeometry thin = g;
    thin.size[2] = 3;
    try {
        seg::segment_liver(core::ImageF(thin, 0.f));
        FAIL() << "three slices were accepted";
    } catch (const seg::LiverNotFoundError&) {
        FAIL() << "three slices should be refused as too few, not searched";
    } catch (const core::InvalidInputError& e) {
        EXPECT_NE(std::string(e.what()).find("slices"), std::string::npos) << e.what();
    }
    // Non-finite values.
    core::ImageF nan(g, 0.f);
    nan.data[5] = std::numeric_limits<float>::quiet_NaN();
    EXPECT_THROW(seg::segment_liver(nan), core::InvalidInputError);
    // So is a negative or non-finite growth bound or window.
    for (const auto& [name, set] : {std::pair<std::string, void (*)(seg::LiverParams&)>{
                                        "growth_slack_mm", [](seg::LiverParams& q) { q.growth_slack_mm = -1.0; }},
                                    {"max_growth_per_mm",
                                     [](seg::LiverParams& q) { q.max_growth_per_mm = std::numeric_limits<double>::infinity(); }},
                                    {"window_growth_per_mm", [](seg::LiverParams& q) { q.window_growth_per_mm = -0.5; }}}) {
        seg::LiverParams q;
        set(q);
        try {
            seg::segment_liver(core::ImageF(g, 0.f), q);
            ADD_FAILURE() << "a bad " << name << " should be refused";
        } catch (const core::InvalidInputError& e) {
            EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
        }
    }
    // A dome-contact parameter that is negative or not finite is named, before any work.
    seg::LiverParams bad;
    bad.contact_sigmas = std::numeric_limits<double>::quiet_NaN();
    try {
        seg::segment_liver(core::ImageF(g, 0.f), bad);
        FAIL() << "a NaN contact_sigmas should be refused";
    } catch (const core::InvalidInputError& e) {
        EXPECT_NE(std::string(e.what()).find("contact_sigmas"), std::string::npos) << e.what();
    }
    bad = {};
    bad.contact_min_area_mm2 = -1;
    EXPECT_THROW(seg::segment_liver(core::ImageF(g, 0.f), bad), core::InvalidInputError);
}

// Only the slices below the liver (pelvis-like: bowel, kidneys' lower poles): no liver.
TEST(LiverPipeline, NoLiverBelowTheLiver)
{
    const Case c = phantom_case({2.8, 2.8, 5.0}, 2);
    int first = c.truth.size[2];
    for (int k = 0; k < c.truth.size[2] && first == c.truth.size[2]; ++k)
        for (int j = 0; j < c.truth.size[1] && first == c.truth.size[2]; ++j)
            for (int i = 0; i < c.truth.size[0]; ++i)
                if (c.truth.at(i, j, k)) {
                    first = k;
                    break;
                }
    ASSERT_GE(first, 6) << "the phantom's field of view should reach below the liver";
    core::ImageGeometry g = c.hu.geometry();
    g.size[2] = first - 1; // slices strictly below the liver
    core::ImageF below(g);
    std::copy(c.hu.data.begin(), c.hu.data.begin() + static_cast<std::ptrdiff_t>(g.voxel_count()), below.data.begin());
    EXPECT_THROW(seg::segment_liver(below), seg::LiverNotFoundError);
}

// 0.8 x 0.8 x 2.5 mm, noise seed 13. Below the liver's tip the K-means layer nearest the liver's
// grey level is muscle and bowel (centre about 20 HU, band up to about 70 HU): before the layer
// had to hold the liver's grey level, the propagation followed it 4 slices below the tip (4 946
// false voxels, first slice 8 against the truth's 12); measured after: first slice 13, no voxel
// below the tip, Dice 0.908 (now first slice 14 and Dice 0.963, with the edge snap, growing
// pieces, vessel inlets and dark rim). The bound allows one slice of partial volume at the tip.
// Since energy competition's repeat is trimmed (2026-12-07, later): first slice 13 (truth 12), Dice
// 0.972.
TEST(LiverPipeline, StopsAtTheLiversTip)
{
    const Case c = phantom_case({0.8, 0.8, 2.5}, 13);
    const int first = lowest_slice(c.truth);
    const seg::LiverResult r = seg::segment_liver(c.hu);
    const auto m = seg::evaluate_segmentation(r.mask, c.truth);
    std::cerr << "tip: first slice " << r.first_slice << " (truth " << first << "), Dice " << m.dice << "\n";
    EXPECT_GE(r.first_slice, first - 1);
    EXPECT_GE(m.dice, 0.88); // measured 0.963 (0.908 before the edge snap and vessel inlets)
}

// The edge snap (LiverParams::use_edge_snap): the propagated snakes end at their iteration bound
// with the contour short of the edge, and the truth's outermost ring is missed. On this phantom
// (0.8 x 0.8 x 2.5 mm, seed 13) with the 3-D pass off, so that the stacked contours are measured:
// the share of the truth's voxels that lie just outside the mask (4-neighbours in the slice of a
// mask voxel), and Dice and ASD. Measured: missed rim 2.4 % -> 1.3 %, Dice 0.950 -> 0.961, ASD 1.83
// -> 1.63 mm (with the vessel inlets and the dark rim; before them 2.9 % -> 1.9 %, 0.933 -> 0.944, 3.08 -> 2.94 mm).
// Bounds: the rim down by a quarter, about half the Dice gain, ASD not worse.
// Since energy competition's repeat is trimmed (2026-12-07, later): missed rim 2.10 % -> 1.10 %,
// Dice 0.9640 -> 0.9718, ASD 1.05 -> 0.91 mm.
TEST(LiverPipeline, EdgeSnapTakesTheMissedRim)
{
    const Case c = phantom_case({0.8, 0.8, 2.5}, 13);
    seg::LiverParams p;
    p.use_3d_pass = false;
    const seg::LiverResult on = seg::segment_liver(c.hu, p);
    p.use_edge_snap = false;
    const seg::LiverResult off = seg::segment_liver(c.hu, p);
    const auto rim_missed = [&](const core::LabelImage3D& m) {
        std::size_t rim = 0, truth = 0;
        for (int k = 0; k < m.size[2]; ++k)
            for (int j = 1; j + 1 < m.size[1]; ++j)
                for (int i = 1; i + 1 < m.size[0]; ++i) {
                    if (!c.truth.at(i, j, k))
                        continue;
                    ++truth;
                    rim += !m.at(i, j, k) &&
                           (m.at(i - 1, j, k) || m.at(i + 1, j, k) || m.at(i, j - 1, k) || m.at(i, j + 1, k));
                }
        return double(rim) / double(truth);
    };
    const auto m_on = seg::evaluate_segmentation(on.mask, c.truth);
    const auto m_off = seg::evaluate_segmentation(off.mask, c.truth);
    std::cerr << "edge snap: missed rim " << 100 * rim_missed(off.mask) << " % -> " << 100 * rim_missed(on.mask)
              << " % of the truth, Dice " << m_off.dice << " -> " << m_on.dice << ", ASD " << m_off.surface.average
              << " -> " << m_on.surface.average << " mm\n";
    EXPECT_LT(rim_missed(on.mask), 0.75 * rim_missed(off.mask));
    EXPECT_GE(m_on.dice, m_off.dice + 0.007);
    EXPECT_LE(m_on.surface.average, m_off.surface.average);
}

// The two directions on two threads, the edge snaps run by whichever thread is free (a direction
// that has ended takes over the other's): the same mask, voxel for voxel, as one thread running
// both directions and then every snap. Each slice's work is deterministic and reads nothing
// another thread writes, so any difference is a race.
TEST(LiverPipeline, TwoThreadsGiveTheMaskOfOne)
{
    const Case c = phantom_case({1.4, 1.4, 5.0}, 3);
    seg::LiverParams p;
    const seg::LiverResult two = seg::segment_liver(c.hu, p);
    p.parallel_directions = false;
    const seg::LiverResult one = seg::segment_liver(c.hu, p);
    ASSERT_EQ(two.slices.size(), one.slices.size());
    EXPECT_GT(two.slices.size(), 10u);
    EXPECT_EQ(test::voxels_differing(one.mask, two.mask), 0u);
}

// Growing pieces (LiverParams::drop_growing_pieces): past the liver's widest slice a separate
// piece of the contour that grows from one slice to the next is not liver. On this phantom (1.0 x
// 1.0 x 3 mm, seed 4; the limit was chosen on others, liver.md) the rule acts on two slices and
// the piece it drops at the lower one is the right kidney under the liver's tip, carried down
// from there. Measured (2026-12-07, since the seed's window): voxels outside the truth 38 293 ->
// 28 314, right kidney 8 130 fewer, Dice 0.949 -> 0.956 (with the 60 mm seed window 37 602 ->
// 31 057, 5 505 fewer, 0.948 -> 0.954; 43 308 -> 36 339 before the wall margin). Bounds: half of
// each gain.
// Since energy competition's repeat is trimmed (2026-12-07, later): outside the truth 50 855 ->
// 27 428 (right kidney 29 218 -> 6 235), Dice 0.9392 -> 0.9614, on 4 slices.
TEST(LiverPipeline, GrowingPiecesAreDropped)
{
    const Case c = phantom_case({1.0, 1.0, 3.0}, 4);
    seg::LiverParams p;
    const seg::LiverResult on = seg::segment_liver(c.hu, p);
    p.drop_growing_pieces = false;
    const seg::LiverResult off = seg::segment_liver(c.hu, p);
    const auto outside = [&](const core::LabelImage3D& m) { return test::voxels_outside(m, c.truth); };
    const auto m_on = seg::evaluate_segmentation(on.mask, c.truth);
    const auto m_off = seg::evaluate_segmentation(off.mask, c.truth);
    int acted = 0;
    for (const auto& s : on.slices)
        acted += s.grown_pieces_mm2 > 0;
    for (const auto& s : off.slices)
        EXPECT_EQ(s.grown_pieces_mm2, 0.0);
    const auto kidney = [&](const core::LabelImage3D& m) { return voxels_on(m, c.labels, {phantom::kRightKidney}); };
    std::cerr << "growing pieces: voxels outside the truth " << outside(off.mask) << " -> " << outside(on.mask)
              << " (right kidney " << kidney(off.mask) << " -> " << kidney(on.mask) << "), Dice " << m_off.dice
              << " -> " << m_on.dice << ", acted on " << acted << " slices\n";
    EXPECT_GE(acted, 1);
    EXPECT_LT(double(outside(on.mask)) + 3400.0, double(outside(off.mask)));
    EXPECT_LT(double(kidney(on.mask)) + 3400.0, double(kidney(off.mask)));
    EXPECT_GE(m_on.dice, m_off.dice + 0.003);
    p.drop_growing_pieces = true;
    p.piece_growth_limit = 0.5;
    EXPECT_THROW(seg::segment_liver(c.hu, p), core::InvalidInputError);
}

// Growing pieces, their lineage (LiverParams::piece_lineage_limit): on thinner slices the right
// kidney, once split off the liver under its tip, grows by only a few per cent a slice, below the
// per-slice limit, and was carried down to below the tip; since it split off it has grown while
// the liver beside it shrank. On this phantom (1.0 x 1.0 x 2.5 mm, seed 11; the limit was not
// chosen on it, liver.md) the lineage rule drops it. Measured: right kidney 15 041 -> 6 796 voxels, Dice
// 0.943 -> 0.950, SLIVER07 score 58.0 -> 68.1. Bounds: half of each gain.
// Since energy competition's repeat is trimmed (2026-12-07, later): right kidney 28 217 -> 6 424,
// Dice 0.9492 -> 0.9675, score 41.2 -> 76.7.
TEST(LiverPipeline, KidneyCarriedBesideTheTipIsDropped)
{
    const Case c = phantom_case({1.0, 1.0, 2.5}, 11);
    seg::LiverParams p;
    const seg::LiverResult on = seg::segment_liver(c.hu, p);
    p.piece_lineage_limit = 100.0;
    const seg::LiverResult off = seg::segment_liver(c.hu, p);
    const auto kidney = [&](const core::LabelImage3D& m) { return voxels_on(m, c.labels, {phantom::kRightKidney}); };
    const auto m_on = seg::evaluate_segmentation(on.mask, c.truth);
    const auto m_off = seg::evaluate_segmentation(off.mask, c.truth);
    const double s_on = seg::sliver_score(m_on).total, s_off = seg::sliver_score(m_off).total;
    std::cerr << "piece lineage: right kidney " << kidney(off.mask) << " -> " << kidney(on.mask) << ", Dice "
              << m_off.dice << " -> " << m_on.dice << ", score " << s_off << " -> " << s_on << "\n";
    EXPECT_LT(double(kidney(on.mask)) + 4100.0, double(kidney(off.mask)));
    EXPECT_GE(m_on.dice, m_off.dice + 0.0035);
    EXPECT_GE(s_on, s_off + 5.0);
    p.piece_lineage_limit = 0.9;
    EXPECT_THROW(seg::segment_liver(c.hu, p), core::InvalidInputError);
}

// Vessel-cut pieces (LiverParams::keep_vessel_cut_pieces): going up, a hepatic vein runs from the
// IVC across the liver, and the previous contour, cut along the vein's edges, falls into the main
// piece and a wedge behind the vein (the liver between the vein, the IVC and the back). The wedge
// is small and only a seventh of its border lies on the rim, so it was dropped as an organ would
// be; what separates it from the main piece is brighter than the liver (the vein), so it now
// starts the snake. On this phantom (1.0 x 1.0 x 3 mm, seed 4; the rule and reach were set on
// 0.8 x 0.8 x 2.5 mm, seed 13, liver.md) it acts on two slices. Measured (since the seed's
// window, 2026-12-07): truth voxels missed 17 151 -> 13 165, voxels outside the truth 27 953 ->
// 28 314, Dice 0.9523 -> 0.9564, score 69.4 -> 72.1 (with the 60 mm seed window, three slices,
// 20 648 -> 13 051, 28 900 -> 31 057, 0.9475 -> 0.9538, 66.7 -> 68.7). Bounds: half of each
// gain, and at most 3 000 voxels more outside the truth. Run with energy competition's repeat as
// the thesis has it (SnakeParams::repeat_keep_voxels -1): with the repeat trimmed to the first
// run (the default) the contour keeps the wedge on this phantom by itself, and the rule has
// nothing left to win (on and off 72.4).
TEST(LiverPipeline, PieceCutOffByAVeinStartsTheSnake)
{
    const Case c = phantom_case({1.0, 1.0, 3.0}, 4);
    seg::LiverParams p;
    p.snake.repeat_keep_voxels = -1;
    const OnOff r = on_and_off(c, p, [](seg::LiverParams& q) { q.keep_vessel_cut_pieces = false; });
    for (const auto& s : r.off.slices)
        EXPECT_EQ(s.vessel_cut_mm2, 0.0);
    r.print("vessel-cut pieces on " + std::to_string(vessel_cut_slices(r.on)) + " slices");
    EXPECT_GE(vessel_cut_slices(r.on), 1);
    EXPECT_LT(r.missed_on + 2000.0, r.missed_off);
    EXPECT_LT(r.outside_on, r.outside_off + 3000.0);
    EXPECT_GE(r.m_on.dice, r.m_off.dice + 0.0020);
    EXPECT_GE(r.score_on, r.score_off + 1.3);
    p.vessel_cut_reach_mm = 0.0;
    EXPECT_THROW(seg::segment_liver(c.hu, p), core::InvalidInputError);
}

// Vessel-cut pieces across a wide vein (LiverParams::vessel_cut_midline_reach_mm): on this phantom
// (0.8 x 0.8 x 3 mm, seed 8, where the case was found) the wedge behind the left hepatic vein on
// slice 44 lies 8-10 mm from the main piece on either side of the vein and its widened edge lines,
// so no pixel is within the 8 mm reach of both and the wedge was dropped; judged on the midline of
// that gap (median 157 HU against a level of 113) it starts the snake, and the liver behind the
// vein is kept on the slices above. Measured (since the seed's window, 2026-12-07): truth voxels
// missed 38 430 -> 27 235, voxels outside the truth 16 597 -> 19 588, Dice 0.9618 -> 0.9678, score
// 71.8 -> 80.5 (with the 60 mm seed window 42 279 -> 32 784, 15 044 -> 17 075, 69.7 -> 75.4).
// Bounds: half of each gain, and at most 5 000 voxels more outside the truth (under half the
// voxels it wins back). Run with the thesis's repeat (repeat_keep_voxels -1): with the trimmed
// repeat (the default) the wedge is never cut off on this phantom (score 85.1 on and off).
TEST(LiverPipeline, PieceBehindAWideVeinStartsTheSnake)
{
    const Case c = phantom_case({0.8, 0.8, 3.0}, 8);
    seg::LiverParams p;
    p.snake.repeat_keep_voxels = -1;
    expect_midline_gains(c, p, "wide vein", 5500.0, 0.0030, 4.3, 5000.0);
    p.vessel_cut_midline_reach_mm = -1.0;
    EXPECT_THROW(seg::segment_liver(c.hu, p), core::InvalidInputError);
}

// The seed slice's window (LiverParams::widen_seed_window): the seed lies on the patient's right,
// and a window of its box + 60 mm ended short of the left lobe on every phantom, so the seed
// contour stopped at the window's edge and the propagation, bounded per slice, never caught up.
// A contour that reaches its window's edge is segmented again on the whole slice. On a phantom
// used for nothing else here (0.65 x 0.65 x 3 mm, seed 34). Measured: truth pixels missed on the
// seed slice 774 -> 273, truth voxels missed 68 774 -> 50 963, outside the truth 9 453 -> 16 531 (the
// lobe's partial-volume rim at the dome, where the dark rim step trims less), Dice 0.9637 ->
// 0.9690, score 70.3 -> 78.7; since energy competition's repeat is trimmed to the first run
// (2026-12-07) missed 40 005 -> 34 229, outside 15 363 -> 16 244, Dice 0.9747 -> 0.9770, score
// 80.1 -> 84.0; since the iteration bound is scaled to the pixel (2026-12-07, evening; 215
// iterations here) missed 38 170 -> 33 518, outside 16 458 -> 17 293, Dice 0.9751 -> 0.9769,
// score 82.6 -> 84.1. Bounds: the seed slice's misses halved, about half of each gain, the outside
// no more than 10 000 voxels up. A contour that stops inside its window keeps it
// (LiverPipeline.T1LikePhantomIsSegmentedAsMr: the leak stop ends it there).
TEST(LiverPipeline, SeedContourCutByItsWindowIsRedoneOnTheWholeSlice)
{
    const Case c = phantom_case({0.65, 0.65, 3.0}, 34);
    const OnOff r = on_and_off(c, seg::LiverParams{}, [](seg::LiverParams& q) { q.widen_seed_window = false; });
    const auto widened = [](const seg::LiverResult& x) {
        return std::count_if(x.slices.begin(), x.slices.end(),
                             [](const seg::LiverSliceReport& s) { return s.seed_window_widened; });
    };
    const auto seed_missed = [&](const seg::LiverResult& x) {
        return test::voxels_missed(core::axial_slice(x.stacked, x.seed_slice), core::axial_slice(c.truth, x.seed_slice));
    };
    r.print("seed window: seed slice missed " + std::to_string(std::lround(seed_missed(r.off))) + " -> " +
            std::to_string(std::lround(seed_missed(r.on))));
    EXPECT_EQ(r.on.seed_slice, r.off.seed_slice);
    EXPECT_EQ(widened(r.on), 1);
    EXPECT_EQ(widened(r.off), 0);
    EXPECT_LE(seed_missed(r.on), 0.5 * seed_missed(r.off));
    EXPECT_LT(r.missed_on + 2800.0, r.missed_off);
    EXPECT_LT(r.outside_on, r.outside_off + 10000.0);
    EXPECT_GE(r.m_on.dice, r.m_off.dice + 0.0009);
    EXPECT_GE(r.score_on, r.score_off + 0.7);
}

// The same on a phantom with thin slices (0.9 x 0.9 x 1.5 mm, seed 42): the wedge behind the vein
// on slice 88 is dropped, and the narrowest gap to the main piece runs past the vein's end through
// liver that the edge lines cut from the start contour, so the midline's median reads liver grey
// (95 HU against the level of 114); its upper quartile reads the vein (142). Measured: truth voxels
// missed 47 898 -> 31 344, outside the truth 29 699 -> 30 555, Dice 0.9661 -> 0.9731, score
// 74.2 -> 81.3 (with the median: no change). Bounds: half of each gain, at most 3 000 voxels more
// outside the truth. Run with the seed slice's window as it was (widen_seed_window off): on the
// whole seed slice the propagation reaches slice 88 differently, the wedge is lost before the
// piece rule sees it (liver.md, "The seed's window"), and this rule has nothing to act on.
// Since energy competition's repeat is trimmed (2026-12-07, later): vessel-cut pieces on 1 -> 2
// slices, missed 46 264 -> 34 373, outside 26 513 -> 27 073, Dice 0.9682 -> 0.9733, score 75.1 ->
// 81.0. Run with the fixed iteration bound (propagation_reference_pixel_mm 0): with the bound
// scaled to the pixel (156 iterations here) the wedge is never cut off (on and off: score 79.8).
TEST(LiverPipeline, WideVeinGapIsReadByItsBrightQuarter)
{
    const Case c = phantom_case({0.9, 0.9, 1.5}, 42);
    seg::LiverParams p;
    p.widen_seed_window = false;
    p.propagation_reference_pixel_mm = 0.0;
    expect_midline_gains(c, p, "wide vein, thin slices", 8000.0, 0.0035, 3.5);
}

// The same phantom with the seed's window widened (the default): the propagation reaches slice 87
// with the left hepatic vein's trunk open to the liver's surface, so the previous contour has a
// notch along it, and on slice 88, where the trunk cuts the wedge behind it off, the gap across
// the vein lay outside the previous contour's filled outline; the midline saw only the fat in the
// vena cava's groove. Bright pixels now count as within the liver. Measured (midline rule off ->
// on): vessel-cut pieces kept on 2 -> 3 slices, truth voxels missed 40 561 -> 24 092, outside the
// truth 30 876 -> 31 029, Dice 0.9689 -> 0.9762, score 76.2 -> 82.1 (before this change on and off
// were the same: 76.2). Bounds: half of each gain, at most 3 000 voxels more outside the truth.
// Since energy competition's repeat is trimmed (2026-12-07, later): vessel-cut pieces on 1 -> 2
// slices, missed 39 078 -> 23 684, outside 26 783 -> 27 822, Dice 0.9713 -> 0.9777, score 77.2 ->
// 83.4. Run with the fixed iteration bound (propagation_reference_pixel_mm 0): with the bound
// scaled to the pixel (156 iterations here) the propagation reaches slice 88 with the wedge
// already joined and the rule keeps the same piece on and off (score 81.2 both; liver.md, "The
// iteration bound in mm").
TEST(LiverPipeline, WedgeBehindAVeinOpenToTheSurfaceIsKept)
{
    const Case c = phantom_case({0.9, 0.9, 1.5}, 42);
    seg::LiverParams p;
    p.propagation_reference_pixel_mm = 0.0;
    expect_midline_gains(c, p, "vein open to the surface", 8000.0, 0.0036, 2.9);
}

// Vessel inlets (LiverParams::fill_vessel_inlets, SLIVER07 convention): the hepatic veins run to
// the IVC, so in a slice they are channels open to the liver's surface, which the contour leaves
// out and the 3-D pass's hole filling cannot reach; the SLIVER07 truth counts them as liver. On
// this phantom (0.8 x 0.8 x 2.5 mm, seed 13; the radius and level were not chosen on it): the
// share of the hepatic veins in the mask, the IVC voxels (not liver) it takes, the maximum
// surface distance, Dice and the SLIVER07 score. Measured (2026-12-07, since the seed's window):
// veins 0.486 -> 0.855, IVC 4 414 -> 5 160 of its 52 000 voxels (the inlets add 1.4 % of it, the
// mouth of its groove; the rest the propagation takes where the IVC meets the liver), maximum
// distance 38.1 -> 22.5 mm, Dice 0.961 -> 0.968, score 62.7 -> 76.4 (with the 60 mm seed window:
// veins 0.52 -> 0.82, IVC 1 436 -> 2 666, score 60.7 -> 72.3). Bounds: half of each gain, the
// score at least 62, the IVC the inlets add under 5 % of it and all of it in the mask under 15 %.
// Since energy competition's repeat is trimmed (2026-12-07, later): veins 0.556 -> 0.952, IVC 1 045
// -> 1 861 voxels (3.6 %), maximum distance 38.1 -> 19.5 mm, Dice 0.966 -> 0.972, score 68.3 ->
// 80.0.
TEST(LiverPipeline, VesselInletsAreFilled)
{
    const Case c = phantom_case({0.8, 0.8, 2.5}, 13);
    seg::LiverParams p;
    const seg::LiverResult on = seg::segment_liver(c.hu, p);
    p.fill_vessel_inlets = false;
    const seg::LiverResult off = seg::segment_liver(c.hu, p);
    const auto share = [&](const core::LabelImage3D& m, std::uint8_t label) {
        const std::size_t in = voxels_on(m, c.labels, {label});
        const std::size_t all = static_cast<std::size_t>(std::count(c.labels.data.begin(), c.labels.data.end(), label));
        return std::pair<std::size_t, double>{in, all ? double(in) / double(all) : 0.0};
    };
    const auto m_on = seg::evaluate_segmentation(on.mask, c.truth);
    const auto m_off = seg::evaluate_segmentation(off.mask, c.truth);
    const auto [veins_on, veins_on_share] = share(on.mask, phantom::kHepaticVein);
    const auto [veins_off, veins_off_share] = share(off.mask, phantom::kHepaticVein);
    const auto [ivc_on, ivc_on_share] = share(on.mask, phantom::kIvc);
    const auto [ivc_off, ivc_off_share] = share(off.mask, phantom::kIvc);
    std::cerr << "vessel inlets: " << on.vessel_inlet_voxels << " voxels added; hepatic veins in the mask "
              << veins_off_share << " -> " << veins_on_share << ", IVC voxels " << ivc_off << " -> " << ivc_on
              << " (share " << ivc_on_share << "), max distance " << m_off.surface.maximum << " -> "
              << m_on.surface.maximum << " mm, Dice " << m_off.dice << " -> " << m_on.dice << ", SLIVER07 score "
              << seg::sliver_score(m_off).total << " -> " << seg::sliver_score(m_on).total << "\n";
    EXPECT_EQ(off.vessel_inlet_voxels, 0u);
    EXPECT_GT(veins_on_share, veins_off_share + 0.14);
    EXPECT_LT(ivc_on_share - ivc_off_share, 0.05);
    EXPECT_LT(ivc_on_share, 0.15);
    EXPECT_LT(m_on.surface.maximum, m_off.surface.maximum - 5.0);
    EXPECT_GE(m_on.dice, m_off.dice + 0.003);
    EXPECT_GE(seg::sliver_score(m_on).total, 62.0);
    EXPECT_GE(seg::sliver_score(m_on).total, seg::sliver_score(m_off).total + 5.0);
    // The parenchyma convention leaves vessels out: nothing is added.
    p.fill_vessel_inlets = true;
    p.post.convention = seg::LiverConvention::Parenchyma;
    EXPECT_EQ(seg::segment_liver(c.hu, p).vessel_inlet_voxels, 0u);
    p.post.convention = seg::LiverConvention::Sliver07;
    p.vessel_inlet_closing_mm = 0.0;
    EXPECT_THROW(seg::segment_liver(c.hu, p), core::InvalidInputError) << "no closing radius";
}

// Surface lesions (LiverParams::fill_surface_lesions): the phantom's boundary tumour (a 13 mm
// sphere at -30 HU cut by the liver's lateral surface next to the ribs, the thesis's failure case)
// is a notch the contour runs round; under SLIVER07 it is liver, and the tumour step looks only
// inside the liver mask. On this phantom (0.8 x 0.8 x 2.5 mm, seed 13; the rule was set on the
// default phantom) measured: the boundary tumour's voxels in the mask 1 564 -> 3 354 of 5 072,
// SLIVER07 score 70.3 -> 71.4; the final masks differ by 2 013 voxels, 2 012 of them liver (the
// rest partial volume at the tumour's edge). Bounds: at least 1 000 more of the tumour's voxels, at
// least 90 % of the difference on the liver {1..4}, the score not lower; a parenchyma-convention
// run adds nothing. Run with energy competition's repeat as the thesis has it (repeat_keep_voxels
// -1), where these figures were measured: with the trimmed repeat (the default) the lesion fill
// still takes the tumour (1 776 -> 3 658 voxels, score 79.8 -> 80.0), but the two runs part
// further up too, and only 3 297 of the 4 947 voxels they differ by are liver. Likewise with the
// fixed iteration bound (propagation_reference_pixel_mm 0): scaled to the pixel (175 iterations
// here) the fill takes the tumour (1 493 -> 3 294 voxels, score 76.9 -> 79.9) and 5 887 of the
// 6 723 voxels the runs differ by are liver (88 %).
TEST(LiverPipeline, SurfaceLesionNextToTheRibsIsLiver)
{
    const Case c = phantom_case({0.8, 0.8, 2.5}, 13);
    const auto it = std::find_if(c.info.tumours.begin(), c.info.tumours.end(),
                                 [](const phantom::TumourTruth& t) { return t.name == "boundary"; });
    ASSERT_NE(it, c.info.tumours.end());
    // The boundary tumour's voxels: tumour label within its equivalent radius + 5 mm of its centroid
    // (the other two tumours lie several centimetres away).
    const auto boundary_voxels = [&](const core::LabelImage3D& m) {
        std::size_t n = 0;
        for (int k = 0; k < m.size[2]; ++k)
            for (int j = 0; j < m.size[1]; ++j)
                for (int i = 0; i < m.size[0]; ++i)
                    if (c.labels.at(i, j, k) == phantom::kTumour && m.at(i, j, k) &&
                        core::distance(m.index_to_physical(i, j, k), it->centroid) < it->equivalent_radius_mm + 5.0)
                        ++n;
        return n;
    };
    seg::LiverParams p;
    p.snake.repeat_keep_voxels = -1;
    p.propagation_reference_pixel_mm = 0.0;
    const seg::LiverResult on = seg::segment_liver(c.hu, p);
    p.fill_surface_lesions = false;
    const seg::LiverResult off = seg::segment_liver(c.hu, p);
    const std::size_t all = boundary_voxels(c.labels);
    const std::size_t in_on = boundary_voxels(on.mask), in_off = boundary_voxels(off.mask);
    std::size_t added = 0, added_liver = 0;
    for (std::size_t i = 0; i < on.mask.data.size(); ++i)
        if (on.mask.data[i] && !off.mask.data[i]) {
            ++added;
            added_liver += c.truth.data[i] ? 1 : 0;
        }
    const double s_on = seg::sliver_score(seg::evaluate_segmentation(on.mask, c.truth)).total;
    const double s_off = seg::sliver_score(seg::evaluate_segmentation(off.mask, c.truth)).total;
    std::cerr << "surface lesions: " << on.surface_lesion_voxels << " voxels added; boundary tumour in the mask "
              << in_off << " -> " << in_on << " of " << all << "; final masks differ by " << added << " voxels, "
              << added_liver << " of them liver; SLIVER07 score " << s_off << " -> " << s_on << "\n";
    EXPECT_EQ(off.surface_lesion_voxels, 0u);
    EXPECT_GT(on.surface_lesion_voxels, 0u);
    EXPECT_GE(in_on, in_off + 1000);
    EXPECT_GE(double(added_liver), 0.9 * double(added));
    EXPECT_GE(s_on, s_off);
    p.fill_surface_lesions = true;
    p.post.convention = seg::LiverConvention::Parenchyma;
    EXPECT_EQ(seg::segment_liver(c.hu, p).surface_lesion_voxels, 0u);
    p.post.convention = seg::LiverConvention::Sliver07;
    p.surface_lesions.core_mm = 0.0;
    EXPECT_THROW(seg::segment_liver(c.hu, p), core::InvalidInputError) << "no core radius";
}

// The tissue stop (LiverParams::use_tissue_stop) at the liver's lower tip: on this phantom (1.0 x
// 1.0 x 3 mm, seed 4; the stop's threshold was set on the labelled inputs of liver.md, not on it)
// the contour crosses from the liver's tip into the right kidney (112 HU against the liver's 105)
// and, without the stop, follows it down to the volume's first slice. Measured: truth's lowest
// slice 11 (a sliver of the tip); with the stop the mask begins at slice 12 (the stop ends the
// propagation at 11, where more than 35 % of the contour is kidney), Dice 0.935;
// without it slice 0, Dice 0.919. Bounds: within two slices of the tip with the
// stop, more than five below it without, and Dice not lower. The growing-pieces rule is off here:
// on this phantom it drops the kidney's lineage too (LiverPipeline.GrowingPiecesAreDropped), and
// the test is of the stop alone. The tissue trim (on) must not carry the contour on: at slice 11
// the contour's liver-grey core (the kidney, 112 HU, and the tip's sliver) keeps 58 % of it but
// covers only 8 % of the widest slice, under the trim's 10 %; with that bound at 0 the trim keeps
// it and the kidney is followed to slice 0 (the failure the bound removes). Run with energy
// competition's repeat as the thesis has it (SnakeParams::repeat_keep_voxels -1): with the repeat
// trimmed to the first run (the default) slice 11's contour holds less fat (under the stop's 35 %)
// and, without the growing-pieces rule, the kidney is followed down; with that rule (the
// default) the run still ends at slice 12 (liver.md, "What energy competition's repeat keeps").
// Run without the layer clip too: the clip keeps the fat out of slice 11's start contour, and the
// stop's scenario is again gone (without the growing-pieces rule the kidney is followed to slice
// 0; with it, the default, the sweep's score on this grid rises, 73.9 -> 75.6).
TEST(LiverPipeline, TissueStopEndsAtTheLiversTip)
{
    const Case c = phantom_case({1.0, 1.0, 3.0}, 4);
    const int first = lowest_slice(c.truth);
    seg::LiverParams p;
    p.drop_growing_pieces = false;
    p.snake.repeat_keep_voxels = -1;
    p.layer_clip_sigmas = 0.0;
    const seg::LiverResult r = seg::segment_liver(c.hu, p);
    p.use_tissue_stop = false;
    const seg::LiverResult off = seg::segment_liver(c.hu, p);
    const auto m = seg::evaluate_segmentation(r.mask, c.truth);
    const auto m_off = seg::evaluate_segmentation(off.mask, c.truth);
    std::cerr << "tissue stop: first slice " << r.first_slice << " (truth " << first << ", without the stop "
              << off.first_slice << "), Dice " << m.dice << " (" << m_off.dice << ")\n";
    EXPECT_GE(r.first_slice, first - 2);
    EXPECT_LT(off.first_slice, first - 5); // the failure the stop removes
    EXPECT_GE(m.dice, m_off.dice);
    const auto stopped =
        std::find_if(r.slices.begin(), r.slices.end(), [](const seg::LiverSliceReport& s) { return s.not_liver; });
    ASSERT_NE(stopped, r.slices.end());
    EXPECT_GT(stopped->outside_fraction, p.tissue_stop_fraction);
    EXPECT_LE(stopped->slice, first); // it stopped at the tip's last sliver or below, not inside the liver
    for (const auto& s : r.slices)
        EXPECT_EQ(s.tissue_trim_mm2, 0.0) << "slice " << s.slice;
    p.use_tissue_stop = true;
    p.tissue_trim_min_area_fraction = 0.0;
    const seg::LiverResult unbounded = seg::segment_liver(c.hu, p);
    EXPECT_LT(unbounded.first_slice, first - 5);
    p.tissue_trim_min_area_fraction = 0.1;

    p.tissue_stop_fraction = 0.0;
    EXPECT_THROW(seg::segment_liver(c.hu, p), core::InvalidInputError);
    p.tissue_stop_fraction = 0.35;
    p.tissue_stop_sigmas = -1.0;
    EXPECT_THROW(seg::segment_liver(c.hu, p), core::InvalidInputError);
}

// The tissue trim (LiverParams::trim_at_tissue_stop): at thick slices the dome's top slices hold
// lung partial volume and the heart's wall, and the upward contour there lay 41 % outside the
// liver's grey levels, so the tissue stop ended the propagation three slices under the dome's
// top. Its liver-grey core keeps 57 % of it (34 % of the widest slice's area): the contour goes on
// as that core. On a phantom used for nothing else (1.6 x 1.6 x 5 mm, noise seed 6; the fractions
// were set on the real scans and the 0.7-1.2 mm phantoms of liver.md). Measured (2026-12-07,
// since the seed's window): trimmed on 2 slices, the mask's top slice 28 -> 33 (truth 34), truth
// voxels missed 15 789 -> 3 666, voxels outside the truth 9 085 -> 12 308 (the heart wall and the
// diaphragm beside the recovered dome), Dice 0.882 -> 0.930, score 32.0 -> 57.2 (with the 60 mm
// seed window: one slice, top 30 -> 33, missed 8 382 -> 3 182, outside 12 992 -> 14 876, score
// 47.1 -> 49.3; the bounds below were set then and hold with room). Bounds: the top at least two
// slices higher, about half of the older gains, at most 4 000 voxels more outside.
// Since energy competition's repeat is trimmed (2026-12-07, later): one slice trimmed, top slice 31
// -> 33, missed 5 188 -> 2 557, outside 12 317 -> 13 022, Dice 0.9224 -> 0.9319, score 55.0 ->
// 56.6. Run with the fixed iteration bound (propagation_reference_pixel_mm 0): with the bound
// scaled to the pixel (88 iterations here) the dome's contours hold less of the heart's wall, the
// tissue stop never fires and the top slice is 33 either way (score 55.7). Since the layer clip and
// the edge snap's reach in mm (2026-12-07, night): one slice trimmed, top 31 -> 33, missed 5 229 ->
// 2 676, outside 10 864 -> 11 416, Dice 0.928 -> 0.938, score 58.7 -> 60.8; the missed voxels'
// bound is half of that gain.
TEST(LiverPipeline, TissueTrimKeepsTheDomeAtThickSlices)
{
    const Case c = phantom_case({1.6, 1.6, 5.0}, 6);
    seg::LiverParams p;
    p.propagation_reference_pixel_mm = 0.0;
    const seg::LiverResult on = seg::segment_liver(c.hu, p);
    p.trim_at_tissue_stop = false;
    const seg::LiverResult off = seg::segment_liver(c.hu, p);
    int trimmed = 0;
    for (const auto& s : on.slices)
        trimmed += s.tissue_trim_mm2 > 0;
    for (const auto& s : off.slices)
        EXPECT_EQ(s.tissue_trim_mm2, 0.0);
    const auto missed = [&](const core::LabelImage3D& m) { return test::voxels_missed(m, c.truth); };
    const auto outside = [&](const core::LabelImage3D& m) { return test::voxels_outside(m, c.truth); };
    const auto m_on = seg::evaluate_segmentation(on.mask, c.truth);
    const auto m_off = seg::evaluate_segmentation(off.mask, c.truth);
    const double s_on = seg::sliver_score(m_on).total, s_off = seg::sliver_score(m_off).total;
    std::cerr << "tissue trim: trimmed " << trimmed << " slices, top slice " << off.last_slice << " -> "
              << on.last_slice << ", missed " << missed(off.mask) << " -> " << missed(on.mask) << ", outside "
              << outside(off.mask) << " -> " << outside(on.mask) << ", Dice " << m_off.dice << " -> " << m_on.dice
              << ", score " << s_off << " -> " << s_on << "\n";
    EXPECT_GE(trimmed, 1);
    EXPECT_GE(on.last_slice, off.last_slice + 2);
    EXPECT_LT(missed(on.mask) + 1270.0, missed(off.mask));
    EXPECT_LT(outside(on.mask), outside(off.mask) + 4000.0);
    EXPECT_GE(m_on.dice, m_off.dice + 0.0085);
    EXPECT_GE(s_on, s_off + 0.85);
    p.trim_at_tissue_stop = true;
    p.tissue_trim_keep = 0.0;
    EXPECT_THROW(seg::segment_liver(c.hu, p), core::InvalidInputError);
    p.tissue_trim_keep = 0.4;
    p.tissue_trim_opening_px = -1;
    EXPECT_THROW(seg::segment_liver(c.hu, p), core::InvalidInputError);
    p.tissue_trim_opening_px = 2;
    p.tissue_trim_min_area_fraction = 1.5;
    EXPECT_THROW(seg::segment_liver(c.hu, p), core::InvalidInputError);
}

// The wall margin (1.2 x 1.2 x 5 mm, seed 17): at thick slices the contours take the subcostal
// layer and the wall muscle between the liver and the ribs (65 and 50 HU against the liver's
// 105, blurred into one another); dropping what lies within 6 mm inside the rib ring removes
// most of it and no liver. Measured (2026-12-07, since the seed's window): subcostal layer in
// the mask 4 475 -> 1 487 voxels (wall muscle and other soft tissue 3 240 -> 2 531), 3 957 voxels
// dropped of which 0 liver, Dice 0.919 -> 0.928, score 54.7 -> 59.1 (with the 60 mm seed window
// 5 979 -> 1 955, 4 333 -> 3 254, 5 446 dropped, 0.928 -> 0.941, 57.3 -> 63.6). The phantom's subcostal layer is 6 mm thick by
// construction, so the bounds below are loose where they rest on the phantom (half the layer
// gone, fewer than 2 % liver among the dropped voxels) and the gains are asserted at a third.
// Since energy competition's repeat is trimmed (2026-12-07, later): subcostal layer 3 117 -> 965,
// other soft tissue 3 013 -> 2 542, 2 874 voxels dropped (0 liver), Dice 0.9331 -> 0.9398, score
// 57.9 -> 61.1. Since the iteration bound is scaled to the pixel (2026-12-07, evening; 117
// iterations here): subcostal layer 2 003 -> 705, other soft tissue 2 929 -> 2 651, 1 737 voxels
// dropped (0 liver), Dice 0.9331 -> 0.9371, score 59.2 -> 61.1; the gains are asserted at half.
TEST(LiverPipeline, WallMarginDropsTheLayerUnderTheRibs)
{
    const Case c = phantom_case({1.2, 1.2, 5.0}, 17);
    seg::LiverParams p;
    const seg::LiverResult with = seg::segment_liver(c.hu, p);
    p.wall_margin_mm = 0.0;
    const seg::LiverResult without = seg::segment_liver(c.hu, p);
    const auto wall = [&](const core::LabelImage3D& m) { return voxels_on(m, c.labels, {phantom::kSubcostal}); };
    const auto soft = [&](const core::LabelImage3D& m) { return voxels_on(m, c.labels, {phantom::kSoftTissue}); };
    std::size_t dropped = 0, dropped_liver = 0, added = 0;
    for (std::size_t i = 0; i < with.mask.data.size(); ++i) {
        dropped += without.mask.data[i] && !with.mask.data[i];
        dropped_liver += without.mask.data[i] && !with.mask.data[i] && c.truth.data[i];
        added += with.mask.data[i] && !without.mask.data[i];
    }
    const auto m_on = seg::evaluate_segmentation(with.mask, c.truth);
    const auto m_off = seg::evaluate_segmentation(without.mask, c.truth);
    const double s_on = seg::sliver_score(m_on).total, s_off = seg::sliver_score(m_off).total;
    std::cerr << "wall margin: subcostal layer in the mask " << wall(without.mask) << " -> " << wall(with.mask)
              << ", muscle and other soft tissue " << soft(without.mask) << " -> " << soft(with.mask) << ", "
              << with.wall_margin_voxels << " voxels dropped (" << dropped_liver << " liver), Dice " << m_off.dice
              << " -> " << m_on.dice << ", score " << s_off << " -> " << s_on << "\n";
    EXPECT_EQ(without.wall_margin_voxels, 0u);
    EXPECT_EQ(dropped, with.wall_margin_voxels) << "the margin only drops, after everything else";
    EXPECT_EQ(added, 0u);
    EXPECT_LT(2 * wall(with.mask), wall(without.mask));
    EXPECT_LT(double(dropped_liver), 0.02 * double(dropped));
    EXPECT_GE(m_on.dice, m_off.dice + 0.002);
    EXPECT_GE(s_on, s_off + 0.9);
    p.wall_margin_mm = -1.0;
    EXPECT_THROW(seg::segment_liver(c.hu, p), core::InvalidInputError);
}

// The layer clip (1.2 x 1.2 x 5 mm, seed 17): at thick slices the soft-tissue K-means layer of a
// propagated slice is 2.4-4.4 times wider than the seed contour's band (105 +- 4 HU here: the
// partial volume of the liver with its neighbours widens the cluster), and holds the contrast-
// filled IVC, the stomach and the kidney's pole where they touch the liver. The previous contour's
// kept pieces start the snake only within that band (median +- 2.5 robust sd, the tissue
// stop's), so those organs are no longer in the snake's start. Measured (2026-12-07, off -> on):
// outside the liver 17 576 -> 10 964 voxels (IVC, stomach and kidney 8 314 -> 2 592), missed
// 7 497 -> 6 713, Dice 0.9371 -> 0.9550, score 61.1 -> 73.3. Bounds: half of the gains; the
// three organs at under half of what they were (measured 0.31). With the edge snap's reach in mm
// (same night): outside 17 383 -> 10 736 (the organs 8 221 -> 2 553), missed 7 828 -> 7 185, Dice
// 0.9367 -> 0.9543, score 61.4 -> 73.6.
TEST(LiverPipeline, LayerClipKeepsThickSlicesInsideTheLiver)
{
    const Case c = phantom_case({1.2, 1.2, 5.0}, 17);
    seg::LiverParams p;
    ASSERT_EQ(p.layer_clip_sigmas, 2.5);
    const seg::LiverResult on = seg::segment_liver(c.hu, p);
    p.layer_clip_sigmas = 0.0;
    const seg::LiverResult off = seg::segment_liver(c.hu, p);
    const auto missed = [&](const core::LabelImage3D& m) { return test::voxels_missed(m, c.truth); };
    const auto outside = [&](const core::LabelImage3D& m) { return test::voxels_outside(m, c.truth); };
    const auto organs = [&](const core::LabelImage3D& m) {
        return voxels_on(m, c.labels, {phantom::kIvc, phantom::kStomach, phantom::kRightKidney});
    };
    const auto m_on = seg::evaluate_segmentation(on.mask, c.truth);
    const auto m_off = seg::evaluate_segmentation(off.mask, c.truth);
    const double s_on = seg::sliver_score(m_on).total, s_off = seg::sliver_score(m_off).total;
    std::cerr << "layer clip: missed " << missed(off.mask) << " -> " << missed(on.mask) << ", outside "
              << outside(off.mask) << " -> " << outside(on.mask) << " (IVC, stomach and kidney " << organs(off.mask)
              << " -> " << organs(on.mask) << "), Dice " << m_off.dice << " -> " << m_on.dice << ", score " << s_off
              << " -> " << s_on << "\n";
    EXPECT_LT(double(organs(on.mask)), 0.5 * double(organs(off.mask)));
    EXPECT_LT(outside(on.mask) + 3300.0, outside(off.mask));
    EXPECT_LT(missed(on.mask), missed(off.mask) + 400.0);
    EXPECT_GE(m_on.dice, m_off.dice + 0.009);
    EXPECT_GE(s_on, s_off + 6.0);
    p.layer_clip_sigmas = -1.0;
    EXPECT_THROW(seg::segment_liver(c.hu, p), core::InvalidInputError);
    p.layer_clip_sigmas = std::numeric_limits<double>::quiet_NaN();
    EXPECT_THROW(seg::segment_liver(c.hu, p), core::InvalidInputError);
}

TEST(LiverPipeline, PropagationChecksItsSeed)
{
    core::ImageGeometry g;
    g.size = {32, 32, 8};
    const core::ImageF img(g, 100.f);
    core::ImageGeometry gs = g;
    gs.size[2] = 1;
    EXPECT_THROW(seg::propagate_liver(img, core::LabelImage3D(gs, 0), 3), core::InvalidInputError); // empty
    EXPECT_THROW(seg::propagate_liver(img, core::LabelImage3D(gs, 1), 9), core::InvalidInputError); // off the grid
    core::ImageGeometry wrong = gs;
    wrong.size[0] = 16;
    EXPECT_THROW(seg::propagate_liver(img, core::LabelImage3D(wrong, 1), 3), core::InvalidInputError);
    // Head to feet: the slice is checked before it is mapped, so the message names the one given.
    const core::ImageF reversed = core::reverse_slices(img);
    for (int k : {9, -1})
        try {
            seg::propagate_liver(reversed, core::LabelImage3D(gs, 1), k);
            ADD_FAILURE() << "seed slice " << k << " accepted";
        } catch (const core::InvalidInputError& e) {
            EXPECT_NE(std::string(e.what()).find("seed slice " + std::to_string(k) + " is outside"), std::string::npos)
                << e.what();
        }
    EXPECT_THROW(seg::propagate_liver(reversed, core::LabelImage3D(gs, 0), 3), core::InvalidInputError); // empty
}

namespace {

// The CT phantom's T1-weighted look (phantom::t1_weighted) times a smooth shading of
// +-`shading` across the body, right to left (MR's intensity inhomogeneity).
core::ImageF t1_like(const core::ImageF& hu, double shading = 0.15)
{
    core::ImageF out = phantom::t1_weighted(hu);
    const int nx = hu.size[0];
    for (std::size_t v = 0; v < out.data.size(); ++v) {
        const double x = double(static_cast<int>(v % static_cast<std::size_t>(nx))) / (nx - 1); // 0 right .. 1 left
        out.data[v] = static_cast<float>(double(out.data[v]) * (1.0 + shading - 2.0 * shading * x));
    }
    return out;
}

} // namespace

// Strong shading (gain 1.45 on the right to 0.55 on the left, as a surface coil's falloff can
// be) pushes the liver's far side out of the liver-like band: the MR path misses part of it.
// Dividing the field out first (MrParams::bias_correction) brings the volume back. Measured on
// this phantom (1.2 x 1.2 x 4 mm, seed 3; the bias-field work was done on 1.4 x 1.4 x 5 mm, seed
// 7): without the correction RVD -22.7 %, Dice 0.841; with it RVD +1.4 %, Dice 0.849, gain
// 0.59..1.39 (before the edge snap and growing pieces: -17.6 %, 0.815 and +0.9 %, 0.847; before
// the tissue stop: +4.7 %, 0.833). Bounds: |RVD| under 8 % and Dice 0.82 with it, and the correction
// at least halving |RVD|.
// Since the seed window's hold rule (2026-12-07): without the correction the window's contour
// stands: RVD -13.1 % -> 5.0 %, Dice 0.852 -> 0.854.
TEST(LiverPipeline, BiasFieldCorrectionRecoversAShadedMr)
{
    const Case c = phantom_case({1.2, 1.2, 4.0}, 3);
    const core::ImageF mr = t1_like(c.hu, 0.45);
    seg::LiverParams p;
    p.mr.bias_correction = false;
    const auto plain = seg::evaluate_segmentation(seg::segment_liver(mr, p).mask, c.truth);
    p.mr.bias_correction = true;
    const seg::LiverResult r = seg::segment_liver(mr, p);
    const auto corrected = seg::evaluate_segmentation(r.mask, c.truth);
    std::cerr << "shaded T1-like phantom: RVD " << plain.rvd << " % -> " << corrected.rvd << " %, Dice " << plain.dice
              << " -> " << corrected.dice << ", gain " << r.bias_min_gain << ".." << r.bias_max_gain << "\n";
    EXPECT_TRUE(r.bias_corrected);
    EXPECT_LT(r.bias_min_gain, 0.75); // the true field spans 0.55..1.45 (over the tissue, less)
    EXPECT_GT(r.bias_max_gain, 1.25);
    EXPECT_LE(std::abs(corrected.rvd), 8.0);
    EXPECT_GE(corrected.dice, 0.82);
    EXPECT_LE(std::abs(corrected.rvd), 0.5 * std::abs(plain.rvd));
}

// The seed slice's window is widened only when the whole slice's contour holds the window's
// (LiverParams::seed_window_hold; LiverPipeline.SeedContourCutByItsWindowIsRedoneOnTheWholeSlice):
// the snake's thresholds follow what its window takes in, and on a strongly shaded MR (the bias
// field test's phantom, not corrected) the seed contour reaches its window's edge yet on the whole
// slice stops at 67 cm2 instead of 168, the dim far side lost. Measured: always widening (hold 0)
// Dice 0.675, RVD -46.3 %; with the hold rule the window's contour stands, Dice 0.843, RVD -21.1 %.
// Bounds: no slice widened by default, one with hold 0, half the Dice gain.
// Since energy competition's repeat is trimmed (2026-12-07, later): always widened Dice 0.759 (RVD
// -30.4 %), held 0.852 (-13.1 %).
TEST(LiverPipeline, SeedWindowStandsWhereTheWholeSliceHoldsLess)
{
    const Case c = phantom_case({1.2, 1.2, 4.0}, 3);
    const core::ImageF mr = t1_like(c.hu, 0.45);
    seg::LiverParams p;
    p.mr.bias_correction = false;
    const seg::LiverResult kept = seg::segment_liver(mr, p);
    p.seed_window_hold = 0.0;
    const seg::LiverResult always = seg::segment_liver(mr, p);
    const auto widened = [](const seg::LiverResult& x) {
        return std::count_if(x.slices.begin(), x.slices.end(),
                             [](const seg::LiverSliceReport& s) { return s.seed_window_widened; });
    };
    const auto m_kept = seg::evaluate_segmentation(kept.mask, c.truth);
    const auto m_always = seg::evaluate_segmentation(always.mask, c.truth);
    std::cerr << "shaded MR, seed window: always widened Dice " << m_always.dice << " RVD " << m_always.rvd
              << " %, held Dice " << m_kept.dice << " RVD " << m_kept.rvd << " %\n";
    EXPECT_EQ(widened(kept), 0);
    EXPECT_EQ(widened(always), 1);
    EXPECT_GE(m_kept.dice, m_always.dice + 0.084);
    p.seed_window_hold = -0.5;
    EXPECT_THROW(seg::segment_liver(mr, p), core::InvalidInputError);
}

// Auto's rule on what it will meet: a CT has air (below -500 HU) outside the body and in the
// lungs; an MR magnitude image has no value there.
// The propagated slices' bound is a front travel in mm: 200 iterations at the 0.7 mm pixels it
// was set on, scaled by 0.7 mm over the pixel (the geometric mean of x and y), rounded, never
// below 1; a reference of 0 leaves it as it is; nonsense is refused before any work.
TEST(LiverPipeline, IterationBoundScalesWithThePixel)
{
    seg::LiverParams p;
    EXPECT_EQ(seg::propagation_iteration_bound(p, 0.7, 0.7), 200);
    EXPECT_EQ(seg::propagation_iteration_bound(p, 3.0, 3.0), 47);   // 140 / 3 = 46.7
    EXPECT_EQ(seg::propagation_iteration_bound(p, 0.35, 0.35), 400);
    EXPECT_EQ(seg::propagation_iteration_bound(p, 0.7, 2.8), 100);  // geometric mean 1.4 mm
    EXPECT_EQ(seg::propagation_iteration_bound(p, 1000.0, 1000.0), 1);
    p.propagation_reference_pixel_mm = 0.0;
    EXPECT_EQ(seg::propagation_iteration_bound(p, 3.0, 3.0), 200);
    EXPECT_THROW(seg::propagation_iteration_bound(p, 0.0, 1.0), core::InvalidInputError);
    p.propagation_reference_pixel_mm = -0.7;
    EXPECT_THROW(seg::propagation_iteration_bound(p, 1.0, 1.0), core::InvalidInputError);
    p = seg::LiverParams{};
    p.propagation_max_iterations = 0;
    EXPECT_THROW(seg::propagation_iteration_bound(p, 1.0, 1.0), core::InvalidInputError);
    const Case c = phantom_case({2.8, 2.8, 5.0}, 2);
    EXPECT_THROW(seg::segment_liver(c.hu, p), core::InvalidInputError);
}

// The edge snap's reach in mm (LiverParams::snap_reference_pixel_mm): its band and iterations,
// set on 0.7 mm pixels, scale by 0.7 mm over the pixel's geometric mean, rounded, at least 1;
// nonsense is refused, by segment_liver too before any work.
TEST(LiverPipeline, SnapReachScalesWithThePixel)
{
    seg::LiverParams p;
    const auto both = [&](double px, double py) {
        const seg::SnapParams s = seg::liver_snap_params(p, px, py);
        EXPECT_EQ(s.gvf_iterations, p.snap.gvf_iterations);
        EXPECT_EQ(s.gate_level, p.snap.gate_level);
        return std::pair<int, int>(s.band, s.iterations);
    };
    EXPECT_EQ(both(0.7, 0.7), std::make_pair(3, 20));
    EXPECT_EQ(both(0.977, 0.977), std::make_pair(2, 14)); // ct-dicom: 2.15 and 14.3
    EXPECT_EQ(both(3.0, 3.0), std::make_pair(1, 5));      // 0.7 and 4.7
    EXPECT_EQ(both(0.35, 0.35), std::make_pair(6, 40));
    EXPECT_EQ(both(0.7, 2.8), std::make_pair(2, 10));     // geometric mean 1.4 mm
    EXPECT_EQ(both(1000.0, 1000.0), std::make_pair(1, 1));
    p.snap_reference_pixel_mm = 0.0;
    EXPECT_EQ(both(3.0, 3.0), std::make_pair(3, 20));
    EXPECT_THROW(seg::liver_snap_params(p, 0.0, 1.0), core::InvalidInputError);
    EXPECT_THROW(seg::liver_snap_params(p, 1.0, std::numeric_limits<double>::infinity()), core::InvalidInputError);
    p.snap_reference_pixel_mm = std::numeric_limits<double>::quiet_NaN();
    EXPECT_THROW(seg::liver_snap_params(p, 1.0, 1.0), core::InvalidInputError);
    p = seg::LiverParams{};
    p.snap.iterations = 0;
    EXPECT_THROW(seg::liver_snap_params(p, 1.0, 1.0), core::InvalidInputError);
    p = seg::LiverParams{};
    p.snap_reference_pixel_mm = -0.7;
    const Case c = phantom_case({2.8, 2.8, 5.0}, 2);
    EXPECT_THROW(seg::segment_liver(c.hu, p), core::InvalidInputError);
    p.use_edge_snap = false; // the snap's settings are not read without it
    EXPECT_NO_THROW(seg::segment_liver(c.hu, p));
}

TEST(LiverPipeline, ModalityIsDetectedFromAir)
{
    const Case c = phantom_case({2.8, 2.8, 5.0}, 2);
    EXPECT_EQ(seg::detect_modality(c.hu), seg::Modality::Ct);
    EXPECT_EQ(seg::detect_modality(t1_like(c.hu)), seg::Modality::Mr);
    EXPECT_THROW(seg::detect_modality(c.hu, 0.0), core::InvalidInputError);
    EXPECT_THROW(seg::detect_modality(core::ImageF{}), core::InvalidInputError);
    EXPECT_STREQ(seg::modality_name(seg::Modality::Mr), "MR");
}

// The map's arithmetic: the liver value reads 100, noise_hu per liver sd away from it on either
// side, floored at -1000; nonsense parameters are refused.
TEST(LiverPipeline, MrLiverContrastMap)
{
    core::ImageGeometry g;
    g.size = {4, 1, 1};
    core::ImageF mr(g);
    mr.data = {97.f, 82.f, 127.f, 5000.f};
    const core::ImageF m = seg::mr_liver_contrast(mr, 97.0, 15.0, 30.0);
    EXPECT_NEAR(m.data[0], 100.f, 1e-4);
    EXPECT_NEAR(m.data[1], 70.f, 1e-4); // one sd darker
    EXPECT_NEAR(m.data[2], 40.f, 1e-4); // two sd brighter
    EXPECT_EQ(m.data[3], -1000.f);
    EXPECT_THROW(seg::mr_liver_contrast(mr, 97.0, 0.0, 30.0), core::InvalidInputError);
    EXPECT_THROW(seg::mr_liver_contrast(mr, std::numeric_limits<double>::quiet_NaN(), 15.0, 30.0),
                 core::InvalidInputError);
    EXPECT_THROW(seg::mr_liver_contrast(mr, 97.0, 15.0, -1.0), core::InvalidInputError);
}

// The MR path end to end on a T1-like phantom (1.4 x 1.4 x 5 mm, noise seed 7, not used
// elsewhere): detected as MR, seeded inside the liver on the MR's own grey levels (not in the
// dark, homogeneous lungs that a plain [0, 99th percentile] range picked), segmented on the
// liver-contrast map. Measured: Dice 0.870, ASD 6.0 mm, RVD -15.4 % (the coarse phantom's heart and
// kidney contacts, as on its CT: LiverPipeline.CoarsePhantomIsFound). The growing pieces' lineage
// drops the right kidney carried below the tip (8 494 -> 1 936 kidney voxels: Dice 0.846 -> 0.870,
// ASD 7.4 -> 6.0 mm), which had made up for missed liver in the volume (RVD -7.4 -> -15.4 %); the
// RVD bound is the measured value plus a third.
TEST(LiverPipeline, T1LikePhantomIsSegmentedAsMr)
{
    const Case c = phantom_case({1.4, 1.4, 5.0}, 7);
    const seg::LiverResult r = seg::segment_liver(t1_like(c.hu));
    EXPECT_EQ(r.modality, seg::Modality::Mr);
    EXPECT_FALSE(r.start.found); // no heart template on MR
    ASSERT_TRUE(r.seed.found) << r.seed.message;
    // The seed contour stops inside its window (the leak stop): the window is kept.
    for (const auto& s : r.slices)
        EXPECT_FALSE(s.seed_window_widened) << "slice " << s.slice;
    EXPECT_GE(precision_in(r.seed.mask, core::axial_slice(c.truth, r.seed.slice)), 0.99) << r.seed.message;
    const auto m = seg::evaluate_segmentation(r.mask, c.truth);
    std::cerr << "T1-like phantom: Dice " << m.dice << ", ASD " << m.surface.average << " mm, RVD " << m.rvd << " %\n";
    EXPECT_GE(m.dice, 0.80);
    EXPECT_LE(m.surface.average, 9.5);
    EXPECT_LE(std::abs(m.rvd), 20.0);
}
