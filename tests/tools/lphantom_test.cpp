// The synthetic patient: every feature docs/phantom.md promises is present and measurable, in
// process (lobe_phantom) and through the lphantom program.
#include "lphantom/phantom.h"

#include "lobe/io/hdf5.h"
#include "lobe/io/metaimage.h"

#include "common/run_tool.h"
#include "common/test_data.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <set>

using namespace lobe;
using phantom::PhantomParams;
using phantom::PhantomResult;
namespace fs = std::filesystem;

namespace {

// The default phantom (512 x 512 x 80, 0.7 x 0.7 x 2.5 mm), built once: the documented slice
// indices refer to it.
const PhantomResult& fine()
{
    static const PhantomResult r = phantom::generate_phantom({});
    return r;
}

// The same patient on a coarse 2 x 2 x 4 mm grid.
PhantomParams coarse_params()
{
    PhantomParams p;
    p.spacing = {2.0, 2.0, 4.0};
    p.size = phantom::size_for_spacing(p.spacing);
    return p;
}
const PhantomResult& coarse()
{
    static const PhantomResult r = phantom::generate_phantom(coarse_params());
    return r;
}

// A small grid for tests that generate several phantoms.
PhantomParams tiny_params()
{
    PhantomParams p;
    p.spacing = {4.0, 4.0, 6.0};
    p.size = phantom::size_for_spacing(p.spacing);
    return p;
}

bool liver_mask(std::uint8_t l) { return l >= 1 && l <= 4; }

struct Mean {
    double mean = 0;
    std::size_t n = 0;
};

// Mean CT of the voxels of `label` whose box neighbourhood (+-rxy in x and y, +-rz in z) holds
// only that label, optionally only within `radius` mm of `centre`. Three voxels in-plane keep the
// Gaussian PSF (0.6 mm, under one voxel) and the partial-volume sub-samples out of the mean.
Mean interior_mean(const PhantomResult& r, std::uint8_t label, int rxy = 3, int rz = 1,
                   const core::Vec3* centre = nullptr, double radius = 0)
{
    const auto& L = r.labels;
    double sum = 0;
    std::size_t n = 0;
    for (int k = rz; k < L.size[2] - rz; ++k)
        for (int j = rxy; j < L.size[1] - rxy; ++j)
            for (int i = rxy; i < L.size[0] - rxy; ++i) {
                if (L.at(i, j, k) != label) continue;
                if (centre && distance(L.index_to_physical(i, j, k), *centre) > radius) continue;
                bool inside = true;
                for (int c = -rz; inside && c <= rz; ++c)
                    for (int b = -rxy; inside && b <= rxy; ++b)
                        for (int a = -rxy; inside && a <= rxy; ++a)
                            inside = L.at(i + a, j + b, k + c) == label;
                if (!inside) continue;
                sum += r.ct.at(i, j, k);
                ++n;
            }
    return {n ? sum / double(n) : 0.0, n};
}

// Tolerance for a mean over n voxels of noise sigma: 5 standard errors plus 0.5 HU for rounding
// to integers and the PSF's far tail.
double mean_tolerance(double sigma, std::size_t n) { return 5.0 * sigma / std::sqrt(double(std::max<std::size_t>(n, 1))) + 0.5; }

// Where liver (la) meets an organ (lb) alone (no third label within 2 voxels in-plane, 1 in z,
// so that lung or fat at the rim of the patch stays out of the means): the voxels of each side
// that touch the other (26-neighbours), and those one step further away.
struct Contact {
    Mean a_touch, b_touch; // first layer on each side
    Mean a_next, b_next;   // second layer: the other label within 2 voxels but not 1
};

Contact contact(const PhantomResult& r, std::uint8_t la, std::uint8_t lb)
{
    const auto& L = r.labels;
    Contact c;
    for (int k = 1; k < L.size[2] - 1; ++k)
        for (int j = 2; j < L.size[1] - 2; ++j)
            for (int i = 2; i < L.size[0] - 2; ++i) {
                const std::uint8_t l = L.at(i, j, k);
                if (l != la && l != lb) continue;
                const std::uint8_t other = l == la ? lb : la;
                bool near1 = false, near2 = false, pure = true;
                for (int dc = -1; pure && dc <= 1; ++dc)
                    for (int db = -2; pure && db <= 2; ++db)
                        for (int da = -2; pure && da <= 2; ++da) {
                            const std::uint8_t n = L.at(i + da, j + db, k + dc);
                            pure = n == la || n == lb;
                            if (n != other) continue;
                            (std::abs(da) <= 1 && std::abs(db) <= 1 ? near1 : near2) = true;
                        }
                if (!pure || !(near1 || near2)) continue;
                Mean& m = l == la ? (near1 ? c.a_touch : c.a_next) : (near1 ? c.b_touch : c.b_next);
                m.mean += r.ct.at(i, j, k);
                ++m.n;
            }
    for (Mean* m : {&c.a_touch, &c.b_touch, &c.a_next, &c.b_next})
        if (m->n) m->mean /= double(m->n);
    return c;
}

std::array<int, 3> index_of(const PhantomResult& r, const core::Vec3& p)
{
    const core::Vec3 f = r.labels.physical_to_index(p);
    return {static_cast<int>(std::lround(f.x)), static_cast<int>(std::lround(f.y)), static_cast<int>(std::lround(f.z))};
}

// Length along x of the run of voxels around (i, j, k) for which `pred` holds, and the labels
// just outside it on both ends.
struct Run {
    int length = 0;
    std::uint8_t left = 0, right = 0;
};
template <class P>
Run run_x(const PhantomResult& r, int i, int j, int k, P pred)
{
    const auto& L = r.labels;
    Run run;
    if (!pred(L.at(i, j, k))) return run;
    int a = i, b = i;
    while (a > 0 && pred(L.at(a - 1, j, k))) --a;
    while (b + 1 < L.size[0] && pred(L.at(b + 1, j, k))) ++b;
    run.length = b - a + 1;
    run.left = a > 0 ? L.at(a - 1, j, k) : 0;
    run.right = b + 1 < L.size[0] ? L.at(b + 1, j, k) : 0;
    return run;
}

// The IVC Omega: at the landmark's slice, the non-liver run through the IVC's centre is the
// IVC's width, and the run through the neck (between the IVC's back and the liver's back) is
// the neck's width; liver must close both runs on both sides.
void expect_omega(const PhantomResult& r, double tol_vox)
{
    const auto& lm = r.truth.landmark("ivc_omega");
    const double sx = r.labels.spacing[0];
    const auto c = index_of(r, lm.position);
    const Run body = run_x(r, c[0], c[1], c[2], [](std::uint8_t l) { return !liver_mask(l); });
    // 5 mm behind the IVC's back wall (y = 5 + 11 mm): inside the 15 mm long neck
    const auto n = index_of(r, lm.position + core::Vec3{0, 11 + 5, 0});
    const Run neck = run_x(r, n[0], n[1], n[2], [](std::uint8_t l) { return !liver_mask(l); });
    EXPECT_NEAR(body.length * sx, r.truth.ivc_body_width_mm, tol_vox * sx);
    EXPECT_NEAR(neck.length * sx, r.truth.ivc_neck_width_mm, tol_vox * sx);
    EXPECT_LT(neck.length * 2, body.length) << "the neck must be narrower than half the IVC";
    EXPECT_TRUE(liver_mask(body.left) && liver_mask(body.right)) << "liver on both sides of the IVC";
    EXPECT_TRUE(liver_mask(neck.left) && liver_mask(neck.right)) << "liver on both sides of the neck";
    EXPECT_EQ(r.labels.at(c[0], c[1], c[2]), phantom::kIvc);
}

// A fissure: the run of fat at the landmark is exactly `width` voxels, between liver voxels.
void expect_fissure(const PhantomResult& r, const std::string& name, int width)
{
    const auto c = index_of(r, r.truth.landmark(name).position);
    const Run run = run_x(r, c[0], c[1], c[2], [](std::uint8_t l) { return l == phantom::kFat; });
    EXPECT_EQ(run.length, width) << name;
    EXPECT_EQ(run.left, phantom::kLiver) << name;
    EXPECT_EQ(run.right, phantom::kLiver) << name;
}

// Fraction of each level's centreline points (every 1 mm, inside the liver) whose voxel carries
// the vessel's label.
std::map<int, double> centreline_recall(const PhantomResult& r, phantom::VesselTree tree)
{
    std::map<int, std::pair<int, int>> hit;
    const std::uint8_t label = tree == phantom::VesselTree::Portal ? phantom::kPortalVein : phantom::kHepaticVein;
    for (const auto& e : r.truth.vessel_edges) {
        if (e.tree != tree) continue;
        const core::Vec3 a = r.truth.vessel_nodes[static_cast<std::size_t>(e.from)].position;
        const core::Vec3 b = r.truth.vessel_nodes[static_cast<std::size_t>(e.to)].position;
        const int n = std::max(1, static_cast<int>(e.length_mm));
        for (int s = 0; s <= n; ++s) {
            const auto ijk = index_of(r, a + (b - a) * (double(s) / n));
            if (!r.labels.contains(ijk[0], ijk[1], ijk[2])) continue;
            const std::uint8_t l = r.labels.at(ijk[0], ijk[1], ijk[2]);
            if (l == phantom::kIvc || l == phantom::kPortalVeinExtra) continue; // trunk ends
            auto& h = hit[e.level];
            ++h.second;
            h.first += l == label ? 1 : 0;
        }
    }
    std::map<int, double> recall;
    for (const auto& [level, h] : hit)
        recall[level] = h.second ? double(h.first) / h.second : 0.0;
    return recall;
}

test::ToolRun lphantom(const std::string& args, const fs::path& scratch)
{
    return test::run_tool(LPHANTOM_EXE, args, scratch);
}

std::size_t count_files(const fs::path& dir)
{
    std::size_t n = 0;
    if (fs::is_directory(dir))
        for (const auto& e : fs::recursive_directory_iterator(dir))
            n += e.is_regular_file() ? 1 : 0;
    return n;
}

} // namespace

TEST(Phantom, ParamsAreValidated)
{
    EXPECT_EQ(phantom::params_problem({}), "");
    PhantomParams p;
    p.spacing[2] = -1;
    EXPECT_NE(phantom::params_problem(p).find("spacing along z"), std::string::npos);
    EXPECT_THROW(phantom::generate_phantom(p), core::InvalidInputError);
    p = {};
    p.size[0] = 0;
    EXPECT_NE(phantom::params_problem(p).find("size along x"), std::string::npos);
    p = {};
    p.noise_sigma_hu = -3;
    EXPECT_NE(phantom::params_problem(p).find("noise"), std::string::npos);
    p = {};
    p.vessel_radius_mm = {2, 3};
    EXPECT_NE(phantom::params_problem(p).find("decrease"), std::string::npos);
    p = {};
    p.size = {100000, 100000, 100};
    EXPECT_NE(phantom::params_problem(p).find("voxels"), std::string::npos);
}

TEST(Phantom, GeometryIsAsAsked)
{
    const auto& r = fine();
    EXPECT_EQ(r.ct.size, (std::array<int, 3>{512, 512, 80}));
    EXPECT_EQ(r.ct.spacing, (std::array<double, 3>{0.7, 0.7, 2.5}));
    // centred on (0, 0, 0): origin = -(size - 1) / 2 * spacing, exact in binary to 1e-9
    EXPECT_NEAR(r.ct.origin[0], -178.85, 1e-9);
    EXPECT_NEAR(r.ct.origin[2], -98.75, 1e-9);
    EXPECT_EQ(r.ct.direction, (std::array<double, 9>{1, 0, 0, 0, 1, 0, 0, 0, 1}));
    EXPECT_TRUE(core::same_grid(r.ct, r.labels));

    PhantomParams p = tiny_params();
    p.center = {-40, 0, 10};
    const auto g = phantom::phantom_geometry(p);
    EXPECT_EQ(g.size, (std::array<int, 3>{90, 90, 34}));  // 358.4 / 4 and 200 / 6, rounded up
    const core::Vec3 mid = g.index_to_physical(core::Vec3{(g.size[0] - 1) / 2.0, (g.size[1] - 1) / 2.0, (g.size[2] - 1) / 2.0});
    EXPECT_NEAR(mid.x, -40, 1e-9);
    EXPECT_NEAR(mid.z, 10, 1e-9);
}

TEST(Phantom, SameSeedSameBytesOtherSeedOnlyOtherNoise)
{
    PhantomParams p = tiny_params();
    const PhantomResult a = phantom::generate_phantom(p);
    const PhantomResult b = phantom::generate_phantom(p);
    EXPECT_EQ(a.ct.data, b.ct.data);
    EXPECT_EQ(a.labels.data, b.labels.data);
    p.seed = 2;
    const PhantomResult c = phantom::generate_phantom(p);
    EXPECT_EQ(a.labels.data, c.labels.data) << "the anatomy must not depend on the seed";
    EXPECT_DOUBLE_EQ(a.truth.liver_volume_ml, c.truth.liver_volume_ml);
    // Two independent N(0, 12 HU) draws rounded to integers coincide with probability about
    // 1 / (2 sqrt(pi) 12) = 2.4 %; the difference has mean 0 and sigma 12 sqrt(2) = 17 HU.
    std::size_t same = 0;
    double diff = 0, diff2 = 0;
    for (std::size_t i = 0; i < a.ct.data.size(); ++i) {
        const double d = double(a.ct.data[i]) - double(c.ct.data[i]);
        same += d == 0 ? 1 : 0;
        diff += d;
        diff2 += d * d;
    }
    const double n = double(a.ct.data.size());
    EXPECT_LT(double(same) / n, 0.05);
    // Clamping at -1024 HU (air) removes noise from some voxels, so sigma is bounded, not exact.
    EXPECT_NEAR(diff / n, 0.0, 0.2);
    EXPECT_GT(std::sqrt(diff2 / n), 12.0);
    EXPECT_LT(std::sqrt(diff2 / n), 17.5);
}

TEST(Phantom, LiverVolumeMatchesTheAnalyticShape)
{
    // Counting voxel centres is the midpoint rule on the voxel grid; its error is dominated by
    // thin features quantised to whole voxels (the 7 mm IVC neck: +-1 column of about 15 x 80 mm
    // = 1.2 mL at 1 mm; 2.4 mL at 2 mm), far below 0.5 % (about 7 mL) and 1 % (14 mL).
    for (const PhantomResult* r : {&fine(), &coarse()}) {
        const double voxel_ml = r->labels.spacing[0] * r->labels.spacing[1] * r->labels.spacing[2] / 1000.0;
        std::size_t n = 0;
        for (auto l : r->labels.data)
            n += liver_mask(l) ? 1 : 0;
        const double tol = r == &fine() ? 0.005 : 0.01;
        EXPECT_NEAR(double(n) * voxel_ml, r->truth.liver_volume_ml, tol * r->truth.liver_volume_ml);
    }
    // an adult liver: 1.2-1.8 L
    EXPECT_GT(fine().truth.liver_volume_ml, 1200);
    EXPECT_LT(fine().truth.liver_volume_ml, 1800);
    EXPECT_NEAR(fine().truth.liver_volume_ml, coarse().truth.liver_volume_ml, 0.01 * fine().truth.liver_volume_ml);
}

TEST(Phantom, TissuesHaveTheDocumentedHu)
{
    const auto& r = fine();
    const phantom::PhantomHu hu;
    const double sigma = PhantomParams{}.noise_sigma_hu;
    const std::pair<std::uint8_t, double> expected[] = {
        {phantom::kLiver, hu.liver},    {phantom::kHeart, hu.heart_wall}, {phantom::kRightKidney, hu.kidney},
        {phantom::kSpleen, hu.spleen},  {phantom::kIvc, hu.ivc},          {phantom::kAorta, hu.aorta},
        {phantom::kGallbladder, hu.bile}};
    for (const auto& [label, value] : expected) {
        const Mean m = interior_mean(r, label);
        ASSERT_GT(m.n, 100u) << "label " << int(label);
        EXPECT_NEAR(m.mean, value, mean_tolerance(sigma, m.n)) << "label " << int(label);
    }
    // the weak contacts are weak by design: a few HU apart
    EXPECT_LE(std::abs(hu.heart_wall - hu.liver), 10);
    EXPECT_LE(std::abs(hu.kidney - hu.liver), 10);
}

TEST(Phantom, HeartAndKidneyTouchTheLiverAcrossAFaintLine)
{
    const phantom::PhantomHu hu;
    const double sigma = PhantomParams{}.noise_sigma_hu;
    for (const PhantomResult* r : {&fine(), &coarse()}) {
        const double px = r->labels.spacing[0] * r->labels.spacing[1];
        for (const auto& [organ, organ_hu] : {std::pair<std::uint8_t, double>{phantom::kHeart, hu.heart_wall},
                                              std::pair<std::uint8_t, double>{phantom::kRightKidney, hu.kidney}}) {
            const Contact c = contact(*r, phantom::kLiver, organ);
            const std::string what = "organ " + std::to_string(organ) + " at " + std::to_string(r->labels.spacing[0]) + " mm";
            // The patches are about 40 cm^2 (heart) and 10 cm^2 (kidney) seen along z; at
            // least 5 cm^2 of liver voxels must touch the organ alone.
            EXPECT_GT(double(c.a_touch.n) * px, 500.0) << what;
            ASSERT_GT(c.a_next.n, 50u) << what;
            ASSERT_GT(c.b_next.n, 50u) << what;
            // One voxel away from the contact the two sides differ by the tissues' few HU (5 and
            // 7): tolerance from the noise of both means plus 1.5 HU of partial-volume residue.
            const double tol = std::sqrt(2.0) * mean_tolerance(sigma, std::min(c.a_next.n, c.b_next.n)) + 1.5;
            EXPECT_NEAR(c.b_next.mean - c.a_next.mean, organ_hu - hu.liver, tol) << what;
            // The 1 mm line of 45 HU belongs to the organ's label: the organ's touching layer dips
            // by up to about 25 HU (a 2.5 mm slice holding 1 mm of line: -22 HU), the liver's by
            // less (the PSF only); both far weaker than a real edge (liver/fat: 205 HU).
            const double organ_dip = c.b_next.mean - c.b_touch.mean, liver_dip = c.a_next.mean - c.a_touch.mean;
            EXPECT_GT(organ_dip, 3.0) << what << ": the line must be there";
            EXPECT_LT(organ_dip, 30.0) << what << ": and faint";
            EXPECT_GT(liver_dip, -tol) << what;
            EXPECT_LT(liver_dip, 30.0) << what;
        }
    }
}

TEST(Phantom, IvcMakesAnOmegaConcavityWithANarrowNeck)
{
    // Widths are quantised to whole voxels: 1.5 voxels of tolerance.
    expect_omega(fine(), 1.5);
    expect_omega(coarse(), 1.5);
}

TEST(Phantom, EvenFissureIsTwoVoxelsWideOddOneThree)
{
    for (const PhantomResult* r : {&fine(), &coarse()}) {
        expect_fissure(*r, "even_fissure", 2);
        expect_fissure(*r, "odd_fissure", 3);
        EXPECT_NEAR(r->truth.fissure_width_mm, 2 * r->labels.spacing[0], 1e-9);
    }
    // The fissure is dark: the CT in it is far below the liver even after the PSF.
    const auto& r = fine();
    const auto c = index_of(r, r.truth.landmark("even_fissure").position);
    double sum = 0;
    int n = 0;
    for (int j = c[1] - 2; j <= c[1] + 2; ++j)
        for (int i = c[0] - 3; i <= c[0] + 3; ++i)
            if (r.labels.at(i, j, c[2]) == phantom::kFat) {
                sum += r.ct.at(i, j, c[2]);
                ++n;
            }
    ASSERT_EQ(n, 10); // 2 columns x 5 rows
    const double fissure = sum / n;
    EXPECT_LT(fissure, 40.0) << "mean CT in the fissure; liver is 105, fat -100";
}

TEST(Phantom, VesselTreesBranchFourLevelsWithDecreasingRadius)
{
    const auto& r = fine();
    for (const auto tree : {phantom::VesselTree::Portal, phantom::VesselTree::Hepatic}) {
        std::map<int, std::pair<int, double>> levels; // count, radius
        for (const auto& e : r.truth.vessel_edges)
            if (e.tree == tree) {
                levels[e.level].first++;
                levels[e.level].second = e.radius_mm;
            }
        ASSERT_GE(levels.size(), 4u);
        double prev = 1e9;
        for (const auto& [level, cr] : levels) {
            EXPECT_LT(cr.second, prev) << "radius must shrink with the level";
            prev = cr.second;
            // binary branching: at least half of the possible branches found room
            const int trunks = tree == phantom::VesselTree::Portal ? 1 : 3;
            EXPECT_GE(cr.first, trunks << (level - 1) >> 1) << "level " << level;
        }
        // Centreline voxels carry the vessel label at every level (the smallest radius,
        // 1.5 mm, still covers the nearest voxel centre: 0.35 mm in-plane, 1.25 mm in z away).
        for (const auto& [level, rec] : centreline_recall(r, tree))
            EXPECT_GT(rec, 0.9) << "level " << level;
    }
    // every vessel voxel lies in the liver: its 6-neighbours are liver, vessel, tumour, or
    // where the trees leave it, the IVC and the extrahepatic portal vein (the hilum).
    const auto& L = r.labels;
    std::size_t vessel = 0, outside = 0;
    for (int k = 1; k < L.size[2] - 1; ++k)
        for (int j = 1; j < L.size[1] - 1; ++j)
            for (int i = 1; i < L.size[0] - 1; ++i) {
                const auto l = L.at(i, j, k);
                if (l != phantom::kPortalVein && l != phantom::kHepaticVein) continue;
                ++vessel;
                const std::uint8_t nb[6] = {L.at(i - 1, j, k), L.at(i + 1, j, k), L.at(i, j - 1, k),
                                            L.at(i, j + 1, k), L.at(i, j, k - 1), L.at(i, j, k + 1)};
                for (auto n : nb)
                    if (!liver_mask(n) && n != phantom::kIvc && n != phantom::kPortalVeinExtra) {
                        ++outside;
                        break;
                    }
            }
    EXPECT_GT(vessel, 10000u);
    // only the portal trunk, where it crosses the liver surface at the hilum, may touch the outside
    EXPECT_LT(double(outside) / double(vessel), 0.01);
    // contrast-enhanced: brighter than liver
    const phantom::PhantomHu hu;
    EXPECT_NEAR(interior_mean(r, phantom::kPortalVein, 2, 0).mean, hu.portal_vein, 6.0);
}

TEST(Phantom, TumoursAreLobularHypodenseAndOneTouchesTheSurface)
{
    const auto& r = fine();
    ASSERT_EQ(r.truth.tumours.size(), 3u);
    const double liver = interior_mean(r, phantom::kLiver).mean;
    const double sigma = PhantomParams{}.noise_sigma_hu;
    std::size_t tumour_voxels = 0;
    for (auto l : r.labels.data)
        tumour_voxels += l == phantom::kTumour ? 1 : 0;
    double truth_ml = 0;
    for (const auto& t : r.truth.tumours) {
        truth_ml += t.volume_ml;
        const Mean m = interior_mean(r, phantom::kTumour, 2, 1, &t.centroid, t.equivalent_radius_mm + 5);
        ASSERT_GT(m.n, 20u) << t.name;
        EXPECT_NEAR(m.mean - liver, t.contrast_hu, mean_tolerance(sigma, m.n) + 0.5) << t.name;
        EXPECT_GE(-t.contrast_hu, 15) << t.name;
        EXPECT_LE(-t.contrast_hu, 30) << t.name;
    }
    // voxel count vs analytic volumes: the 6 mm satellite and lobules make this coarser than
    // the liver; 5 %.
    const double voxel_ml = 0.7 * 0.7 * 2.5 / 1000.0;
    EXPECT_NEAR(double(tumour_voxels) * voxel_ml, truth_ml, 0.05 * truth_ml);
    EXPECT_EQ(r.truth.tumours[0].name, "lobular");
    EXPECT_GT(r.truth.tumours[0].equivalent_radius_mm, 15.0); // larger than its 15 mm core
    EXPECT_LT(r.truth.tumours[1].volume_ml, 2.0);             // satellite
    EXPECT_TRUE(r.truth.tumours[2].touches_boundary);
    EXPECT_FALSE(r.truth.tumours[0].touches_boundary);
}

TEST(Phantom, CoarseSpacingKeepsEveryFeature)
{
    // Fissures, contacts and the Omega neck are checked on the coarse grid above; here the
    // rest: every label, both trees at every level, all three tumours.
    const auto& r = coarse();
    std::set<int> present(r.labels.data.begin(), r.labels.data.end());
    for (const auto& l : phantom::label_table())
        EXPECT_TRUE(present.count(l.label)) << l.name;
    for (const auto tree : {phantom::VesselTree::Portal, phantom::VesselTree::Hepatic}) {
        const auto rec = centreline_recall(r, tree);
        ASSERT_EQ(rec.size(), 4u);
        // At 2 x 2 x 4 mm a 1.5 mm vessel misses the nearest voxel centre where it passes
        // between slices (up to 2 mm away), so the finest level only needs to be visible.
        for (const auto& [level, v] : rec)
            EXPECT_GT(v, level <= 3 ? 0.8 : 0.3) << "level " << level;
    }
    for (const auto& t : r.truth.tumours) {
        const auto c = index_of(r, t.centroid);
        EXPECT_EQ(r.labels.at(c[0], c[1], c[2]), phantom::kTumour) << t.name;
    }
}

TEST(Phantom, OtherSpacingsRasteriseTheSamePatient)
{
    // Odd spacings: the fissures stay exactly 2 and 3 voxels, the Omega keeps its neck, and the
    // liver keeps its volume (1 %: see LiverVolumeMatchesTheAnalyticShape).
    for (const std::array<double, 3> sp : {std::array<double, 3>{1.1, 1.1, 3.3}, std::array<double, 3>{3.0, 3.0, 3.0}}) {
        PhantomParams p;
        p.spacing = sp;
        p.size = phantom::size_for_spacing(sp);
        p.seed = 5;
        const PhantomResult r = phantom::generate_phantom(p);
        expect_fissure(r, "even_fissure", 2);
        expect_fissure(r, "odd_fissure", 3);
        expect_omega(r, 1.5);
        std::size_t n = 0;
        for (auto l : r.labels.data)
            n += liver_mask(l) ? 1 : 0;
        EXPECT_NEAR(double(n) * sp[0] * sp[1] * sp[2] / 1000.0, fine().truth.liver_volume_ml, 0.01 * fine().truth.liver_volume_ml);
        EXPECT_EQ(r.truth.vessel_edges.size(), fine().truth.vessel_edges.size()) << "the trees do not depend on the grid";
    }
}

TEST(Phantom, ToolHelpVersionAndBadOptions)
{
    const auto dir = test::scratch_dir();
    auto run = lphantom("--help", dir);
    EXPECT_EQ(run.exit_code, 0);
    EXPECT_NE(run.out.find("OUT_DIR"), std::string::npos);
    EXPECT_NE(run.out.find("--spacing"), std::string::npos);
    run = lphantom("--version", dir);
    EXPECT_EQ(run.exit_code, 0);
    EXPECT_NE(run.out.find(LOBE_VERSION_STRING), std::string::npos);

    const fs::path out = dir / "out";
    const std::pair<std::string, std::string> bad[] = {
        {"--spacing 0.7,0.7,-2.5", "spacing along z"},
        {"--size 0,512,80", "size along x"},
        {"--noise -5", "noise"},
        {"--spacing 1,2", ""}, // CLI11: wrong number of values
    };
    for (const auto& [args, message] : bad) {
        run = lphantom(test::shell_quote(out.string()) + " " + args, dir);
        EXPECT_NE(run.exit_code, 0) << args;
        EXPECT_NE(run.err.find(message), std::string::npos) << args << ": " << run.err;
        EXPECT_EQ(count_files(out), 0u) << args;
    }
    // an output folder that cannot be created (below a regular file)
    std::ofstream(dir / "file.txt") << "x";
    run = lphantom(test::shell_quote((dir / "file.txt" / "out").string()) + " --spacing 6", dir);
    EXPECT_EQ(run.exit_code, 2);
    EXPECT_NE(run.err.find("file.txt"), std::string::npos) << run.err;
}

TEST(Phantom, ToolWritesImagesTruthAndPictures)
{
    const auto dir = test::scratch_dir();
    const fs::path out = dir / "out", png = dir / "png";
    const auto run = lphantom(test::shell_quote(out.string()) + " --spacing 4,4,6 --seed 7 --png " +
                                  test::shell_quote(png.string()),
                              dir);
    ASSERT_EQ(run.exit_code, 0) << run.err;
    for (const char* f : {"ct.mhd", "ct.raw", "labels.mhd", "labels.raw", "truth.json", "phantom.h5", "phantom.xdmf"})
        EXPECT_TRUE(fs::is_regular_file(out / f)) << f;
    EXPECT_EQ(count_files(out), 7u) << "no temporary files left behind";

    // the files hold exactly what the library generates
    PhantomParams p = tiny_params();
    p.seed = 7;
    const PhantomResult ref = phantom::generate_phantom(p);
    const auto ct = io::read_metaimage(out / "ct.mhd");
    ASSERT_EQ(core::pixel_type(ct), core::PixelType::Int16);
    const auto& cti = std::get<core::Image3D<std::int16_t>>(ct);
    EXPECT_TRUE(core::same_grid(cti, ref.ct, 1e-6));
    EXPECT_EQ(cti.data, ref.ct.data);
    const auto labels = io::read_metaimage(out / "labels.mhd");
    ASSERT_EQ(core::pixel_type(labels), core::PixelType::UInt8);
    EXPECT_EQ(std::get<core::LabelImage3D>(labels).data, ref.labels.data);

    // the container holds the same CT and labels, the label names, and this run's provenance
    const io::Hdf5Reader h5(out / "phantom.h5");
    EXPECT_EQ(std::get<core::ImageI16>(h5.read_image("ct")).data, ref.ct.data);
    const io::LabelVolume truth = h5.read_labels("truth");
    EXPECT_EQ(truth.image.data, ref.labels.data);
    ASSERT_EQ(truth.table.size(), phantom::label_table().size());
    EXPECT_EQ(truth.table[1].name, phantom::label_table()[1].name);
    const auto history = h5.provenance();
    ASSERT_EQ(history.size(), 1u);
    EXPECT_EQ(history[0].tool, "lphantom");
    bool has_seed = false;
    for (const auto& [k, v] : history[0].parameters)
        has_seed |= k == "seed" && v == "7";
    EXPECT_TRUE(has_seed);

    std::ifstream jf(out / "truth.json");
    const auto j = nlohmann::json::parse(jf);
    EXPECT_EQ(j["lobe_version"], LOBE_VERSION_STRING);
    EXPECT_EQ(j["parameters"]["seed"], 7);
    EXPECT_NEAR(j["liver"]["volume_ml"].get<double>(), ref.truth.liver_volume_ml, 1e-9);
    EXPECT_EQ(j["tumours"].size(), 3u);
    EXPECT_EQ(j["vessels"]["edges"].size(), ref.truth.vessel_edges.size());
    EXPECT_TRUE(j["timings_s"].contains("generate"));
    EXPECT_GE(j["labels"].size(), 20u);

    // pictures: PNG files, with and without the overlay
    std::size_t pngs = 0;
    for (const auto& e : fs::directory_iterator(png)) {
        std::ifstream f(e.path(), std::ios::binary);
        char sig[8] = {};
        f.read(sig, 8);
        EXPECT_EQ(std::string(sig + 1, 3), "PNG") << e.path();
        ++pngs;
    }
    EXPECT_GE(pngs, 12u); // 9 views, with and without labels, fewer where two share a slice
    EXPECT_TRUE(fs::exists(png / "phantom-axial-ivc-omega-labels.png"));
}
