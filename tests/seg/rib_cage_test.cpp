// Tests of lobe/seg/rib_cage.h: the ring on a synthetic torso with known rib geometry, on the
// phantom (liver inside, subcutaneous fat outside), the snake leak it stops, slices and volumes
// without ribs, the helpers, speed on a 512 x 512 x 80 volume, and bad input.
#include "lobe/seg/rib_cage.h"

#include "lobe/core/any_image.h"
#include "lobe/core/errors.h"
#include "lobe/seg/distance_transform.h"
#include "lobe/seg/snake.h"

#include "common/timing.h"

#if __has_include("lphantom/phantom.h")
#include "lphantom/phantom.h"
#define LOBE_HAVE_PHANTOM 1
#endif

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <iostream>
#include <limits>

using namespace lobe;

namespace {

constexpr double kPi = 3.14159265358979323846;

//! A synthetic torso on a 1 mm grid: an elliptic body (semi-axes 150 x 110 mm, soft tissue
//! 40 HU) in air; ribs (700 HU) filling the elliptic shell between 0.80 and 0.86 of the body
//! radius, sloping so that each slice shows them over alternating 15° sectors (shifted 6° per
//! slice, so 4 overlapped slices cover the turn) except in the anterior 90° (the cartilage
//! gap); a vertebral body (500 HU) whose front is 30 mm behind the centre; an "organ" (100 HU)
//! filling 0.7 of the body. `rib_slices` limits the ribs to slices k >= nz - rib_slices.
struct Torso {
    core::ImageF hu;
    core::LabelImage3D organ;
};

double ellipse_radius(double th) // body radius [mm] along angle th (x = cos, y = sin)
{
    const double c = std::cos(th), s = std::sin(th);
    return 1.0 / std::sqrt(c * c / (150.0 * 150.0) + s * s / (110.0 * 110.0));
}

bool anterior(double th) // within 45° of -y (anterior in LPS)
{
    double d = std::abs(std::remainder(th - (-kPi / 2), 2 * kPi));
    return d < kPi / 4;
}

Torso torso(int n, int nz, double spacing = 1.0, int rib_slices = -1)
{
    core::ImageGeometry g;
    g.size = {n, n, nz};
    g.spacing = {spacing, spacing, 2.5};
    Torso t{core::ImageF(g, -1000.f), core::LabelImage3D(g, 0)};
    const double c = (n - 1) / 2.0;
    // The in-plane geometry once; only the ribs' sectors change with k.
    const std::size_t plane = static_cast<std::size_t>(n) * static_cast<std::size_t>(n);
    std::vector<double> theta(plane), rho(plane);
    std::vector<char> spine(plane);
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
            const double x = (i - c) * spacing, y = (j - c) * spacing;
            const std::size_t q = static_cast<std::size_t>(i) + static_cast<std::size_t>(j) * static_cast<std::size_t>(n);
            theta[q] = std::atan2(y, x);
            rho[q] = std::hypot(x, y) / ellipse_radius(theta[q]);
            spine[q] = x * x / (20.0 * 20.0) + (y - 48.0) * (y - 48.0) / (18.0 * 18.0) <= 1.0; // front at y = 30 mm
        }
    for (int k = 0; k < nz; ++k) {
        const bool ribs_here = rib_slices < 0 || k >= nz - rib_slices;
        for (std::size_t q = 0; q < plane; ++q) {
            const std::size_t v3 = q + plane * static_cast<std::size_t>(k);
            float v = rho[q] < 1.0 ? 40.f : -1000.f;
            if (rho[q] < 0.7) {
                v = 100.f;
                t.organ.data[v3] = 1;
            }
            const double deg = theta[q] * 180.0 / kPi + 360.0 + 6.0 * k;
            if (ribs_here && rho[q] >= 0.80 && rho[q] < 0.86 && !anterior(theta[q]) && std::fmod(deg, 30.0) < 15.0)
                v = 700.f;
            if (spine[q])
                v = 500.f;
            t.hu.data[v3] = v;
        }
    }
    return t;
}

//! Ray index of voxel (i, j) in ring `r`.
std::size_t ray_of(const seg::RibRing& r, int i, int j, const core::ImageGeometry& g)
{
    double th = std::atan2((j - r.centre_j) * g.spacing[1], (i - r.centre_i) * g.spacing[0]);
    if (th < 0)
        th += 2 * kPi;
    const auto na = r.radius_mm.size();
    return static_cast<std::size_t>(std::lround(th * double(na) / (2 * kPi))) % na;
}

bool all_equal(const core::LabelImage3D& m, std::uint8_t v)
{
    return std::all_of(m.data.begin(), m.data.end(), [v](std::uint8_t x) { return x == v; });
}

} // namespace

// The ring lies on the ribs' inner surface: on rays that meet bone its radius is 0.80 of the
// body radius to within 2 mm on >= 90 % of them (measured 94-99 %; rays are marched in 1 mm steps, so the first
// bone sample lies up to 1 mm beyond the surface, plus up to 0.7 mm of rounding to the 1 mm
// pixel grid), and within 3 mm everywhere (rays grazing a rib's end face at a gap). The organ is
// inside; the anterior 90° without ribs (wider than max_gap_deg = 40°) is left unconstrained,
// and the vertebral body, which lies behind the centre, never pulls the ring in front of it:
// the ring takes the outermost bone.
TEST(RibCage, RingFollowsTheInnerRibSurface)
{
    const Torso t = torso(340, 8);
    const auto r = seg::rib_cage(t.hu);
    for (int k = 0; k < 8; ++k) {
        ASSERT_TRUE(r.valid[static_cast<std::size_t>(k)]) << "slice " << k;
        const auto& ring = r.rings[static_cast<std::size_t>(k)];
        ASSERT_EQ(ring.radius_mm.size(), 360u);
        EXPECT_NEAR(ring.centre_i, 169.5, 0.01);
        EXPECT_NEAR(ring.centre_j, 169.5, 0.01);
        int bone_rays = 0, close = 0, open_rays = 0;
        for (std::size_t a = 0; a < 360; ++a) {
            const double th = 2 * kPi * double(a) / 360.0;
            const double err = std::abs(double(ring.radius_mm[a]) - 0.80 * ellipse_radius(th));
            if (ring.supported[a] == 1) {
                ++bone_rays;
                close += err <= 2.0;
                EXPECT_LE(err, 3.0) << "slice " << k << " ray " << a;
            }
            if (ring.supported[a] == 0) {
                ++open_rays;
                // the anterior 90° (225°..315°), plus a few rays at its edges where only 2 slices
                // are overlapped (the last slice) and a rib end falls short of the gap's edge
                EXPECT_NEAR(double(a), 270.0, 52.0) << "only the cartilage gap is open";
            }
        }
        // 270° carry ribs (4 overlapped slices cover them; 2 at the last slice, bridged); the
        // anterior 90° stays open.
        EXPECT_GT(bone_rays, 180) << "slice " << k;
        EXPECT_GE(close, 0.9 * bone_rays) << "slice " << k;
        EXPECT_GE(open_rays, 88) << "slice " << k;
        EXPECT_NEAR(r.coverage[static_cast<std::size_t>(k)], 1.0 - open_rays / 360.0, 1e-9);
    }
    std::size_t organ = 0, organ_in = 0, organ_in_ring = 0;
    for (std::size_t q = 0; q < t.organ.data.size(); ++q)
        if (t.organ.data[q]) {
            ++organ;
            organ_in += r.inside.data[q];
            organ_in_ring += r.ring.data[q];
        }
    EXPECT_EQ(organ_in, organ);
    EXPECT_EQ(organ_in_ring, 0u) << "the organ is >= 11 mm inside the ring, the band is 3 mm";
    // Bone on the ribs' rays is outside; the anterior subcutaneous region is unconstrained.
    EXPECT_EQ(r.inside.at(169, 169 + 80, 4), 1) << "behind the vertebral body, inside the posterior ribs";
    EXPECT_EQ(r.inside.at(169 + 140, 169, 4), 0) << "lateral rib / wall";
    EXPECT_EQ(r.inside.at(169, 169 - 105, 4), 1) << "anterior wall: no ribs there, no constraint";
    // The band: inside, within 3 mm of the ring, on supported rays only.
    for (std::size_t q = 0; q < r.ring.data.size(); ++q) {
        if (r.ring.data[q]) {
            ASSERT_EQ(r.inside.data[q], 1);
        }
    }
}

// The wall band (the liver pipeline's wall margin): off by default; at 6 mm it holds the voxels
// that lie, along their ray, 0 to 6 mm inside the ring where bone supports it, and none on the
// open anterior rays or in the organ (>= 11 mm inside the ring). The depth bound allows the
// distance transform's ~2 % error, the ellipse's slant between ray and normal (the radial depth
// exceeds the normal one by up to 1/cos 17° = 1.05) and 1 mm for the 1 mm pixels; the cover is
// asserted on rays that meet bone, between 1 and 5 mm deep (measured: every such voxel).
TEST(RibCage, WallBandLiesWithinItsWidthInsideTheRing)
{
    const Torso t = torso(340, 8);
    EXPECT_TRUE(all_equal(seg::rib_cage(t.hu).wall, 0)) << "no wall band unless asked for";
    seg::RibCageParams p;
    p.wall_width_mm = 6.0;
    const auto r = seg::rib_cage(t.hu, p);
    const core::ImageGeometry& g = t.hu.geometry();
    std::size_t wall = 0, deep = 0, open = 0, organ = 0, mid = 0, mid_in = 0;
    for (int k = 0; k < g.size[2]; ++k) {
        const auto& ring = r.rings[static_cast<std::size_t>(k)];
        for (int j = 0; j < g.size[1]; ++j)
            for (int i = 0; i < g.size[0]; ++i) {
                const std::size_t q = t.hu.index(i, j, k);
                const std::size_t a = ray_of(ring, i, j, g);
                const double depth =
                    double(ring.radius_mm[a]) - std::hypot((i - ring.centre_i) * g.spacing[0], (j - ring.centre_j) * g.spacing[1]);
                if (r.wall.data[q]) {
                    ++wall;
                    ASSERT_EQ(r.inside.data[q], 1);
                    deep += depth > 6.0 * 1.02 * 1.05 + 1.0;
                    open += ring.supported[a] == 0;
                    organ += t.organ.data[q];
                }
                if (ring.supported[a] == 1 && depth >= 1.0 && depth <= 5.0) {
                    ++mid;
                    mid_in += r.wall.data[q];
                }
            }
    }
    std::cout << "wall band: " << wall << " voxels, " << mid_in << " of " << mid << " at 1-5 mm on bone rays\n";
    EXPECT_GT(wall, 8u * 3000u) << "a 6 mm band round ~270° of a 700 mm ring on 8 slices";
    EXPECT_EQ(deep, 0u);
    EXPECT_EQ(open, 0u) << "no ribs, no wall";
    EXPECT_EQ(organ, 0u);
    EXPECT_GE(double(mid_in), 0.99 * double(mid));
}

// Bright blobs inside the body do not move the ring: one beyond which a rib lies (the outermost
// bone wins), and one in the open anterior sector 70 mm under the skin (deeper than
// max_depth_mm = 60: a contrast-filled loop, not a rib).
TEST(RibCage, InteriorBoneDoesNotPullTheRingIn)
{
    Torso t = torso(340, 4);
    for (int k = 0; k < 4; ++k)
        for (int j = 0; j < 340; ++j)
            for (int i = 0; i < 340; ++i) {
                const double x = i - 169.5, y = j - 169.5;
                if (std::hypot(x - 80, y) < 6 || std::hypot(x, y + 40) < 6)
                    t.hu.at(i, j, k) = 400.f;
            }
    const auto plain = seg::rib_cage(torso(340, 4).hu);
    const auto r = seg::rib_cage(t.hu);
    for (int k = 0; k < 4; ++k)
        EXPECT_EQ(r.rings[static_cast<std::size_t>(k)].supported, plain.rings[static_cast<std::size_t>(k)].supported)
            << "slice " << k;
    EXPECT_EQ(r.inside.data, plain.inside.data);
}

// Without enough bone a slice is invalid and constrains nothing: inside = 1 everywhere, no ring.
// An MRI-like volume (no bone at all), a tiny field of view inside the body, an empty (all air)
// volume and NaN voxels all end so, without an error.
TEST(RibCage, NoBoneMeansNoConstraint)
{
    Torso mri = torso(120, 3, 3.0);
    for (auto& v : mri.hu.data)
        v = std::min(v, 150.f);
    core::ImageGeometry small;
    small.size = {40, 40, 5};
    small.spacing = {0.7, 0.7, 2.5};
    const core::ImageF fov(small, 60.f);
    const core::ImageF air(small, -1000.f);
    core::ImageF nan(small, std::numeric_limits<float>::quiet_NaN());
    const std::vector<const core::ImageF*> cases{&mri.hu, &fov, &air, &nan};
    for (const core::ImageF* img : cases) {
        const auto r = seg::rib_cage(*img);
        EXPECT_TRUE(std::all_of(r.valid.begin(), r.valid.end(), [](std::uint8_t v) { return v == 0; }));
        EXPECT_TRUE(all_equal(r.inside, 1));
        EXPECT_TRUE(all_equal(r.ring, 0));
    }
}

// Below the rib cage only the spine is bone (~45° of the turn): those slices are invalid; the
// slices whose 4-slice window reaches the ribs are valid.
TEST(RibCage, SlicesBelowTheRibsAreInvalid)
{
    const Torso t = torso(120, 12, 3.0, 6); // ribs on slices 6..11
    const auto r = seg::rib_cage(t.hu);
    for (int k = 0; k < 12; ++k) {
        // the window of slice k is k-1 .. k+2: it reaches rib slice 6 from k = 4 on
        const bool expect_valid = k >= 4;
        EXPECT_EQ(r.valid[static_cast<std::size_t>(k)], expect_valid ? 1 : 0)
            << "slice " << k << " coverage " << r.coverage[static_cast<std::size_t>(k)];
        if (!expect_valid) {
            EXPECT_LT(r.coverage[static_cast<std::size_t>(k)], 0.2) << "spine only";
        }
    }
}

TEST(RibCage, EnhanceAndMaskHelpers)
{
    core::ImageGeometry g;
    g.size = {4, 1, 1};
    core::ImageF f(g);
    f.data = {0.f, 0.2f, 0.6f, 0.2f};
    core::LabelImage3D ring(g, 0);
    ring.data = {1, 1, 1, 0};
    const auto e = seg::enhance_rib_edges(f, ring, 1.0);
    EXPECT_FLOAT_EQ(e.data[0], 0.f) << "no edge is invented";
    EXPECT_FLOAT_EQ(e.data[1], 0.4f);
    EXPECT_FLOAT_EQ(e.data[2], 1.f) << "clamped to 1";
    EXPECT_FLOAT_EQ(e.data[3], 0.2f) << "off the ring: unchanged";
    EXPECT_EQ(seg::enhance_rib_edges(f, ring, 0.0).data, f.data);
    const auto m = seg::mask_outside_rib_cage(f, ring, -5.f);
    EXPECT_EQ(m.data, (core::BigVector<float>{0.f, 0.2f, 0.6f, -5.f}));
    core::ImageGeometry other = g;
    other.size = {3, 1, 1};
    EXPECT_THROW(seg::enhance_rib_edges(f, core::LabelImage3D(other), 1.0), core::InvalidInputError);
    EXPECT_THROW(seg::mask_outside_rib_cage(f, core::LabelImage3D(other), 0.f), core::InvalidInputError);
    EXPECT_THROW(seg::enhance_rib_edges(f, ring, -1.0), core::InvalidInputError);
    EXPECT_THROW(seg::enhance_rib_edges(f, ring, std::numeric_limits<double>::infinity()), core::InvalidInputError);
}

TEST(RibCage, BadParametersAreRefused)
{
    const Torso t = torso(40, 2, 9.0);
    auto expect_throw = [&](auto change) {
        seg::RibCageParams p;
        change(p);
        EXPECT_THROW(seg::rib_cage(t.hu, p), core::InvalidInputError);
    };
    expect_throw([](seg::RibCageParams& p) { p.slices_to_combine = 0; });
    expect_throw([](seg::RibCageParams& p) { p.bone_hu = std::numeric_limits<double>::quiet_NaN(); });
    expect_throw([](seg::RibCageParams& p) { p.angles = 4; });
    expect_throw([](seg::RibCageParams& p) { p.min_coverage = 1.5; });
    expect_throw([](seg::RibCageParams& p) { p.enhance_width_mm = -1; });
    expect_throw([](seg::RibCageParams& p) { p.wall_width_mm = -1; });
    expect_throw([](seg::RibCageParams& p) { p.wall_width_mm = std::numeric_limits<double>::quiet_NaN(); });
    expect_throw([](seg::RibCageParams& p) { p.max_depth_mm = 0; });
    core::ImageF broken = t.hu;
    broken.data.pop_back();
    EXPECT_THROW(seg::rib_cage(broken), core::InvalidInputError);
}

// Speed: 512 x 512 x 80 (the phantom's grid). Measured ~0.25 s on the shared 2-core machine
// under load (docs/algorithms/rib_cage.md), 0.36 s on the Intel one of 2026-11-26 (0.63 s under
// ASan+UBSan); the bound leaves room for a loaded CI and is scaled in a sanitizer build.
TEST(RibCage, A512x512x80VolumeTakesWellUnderTwoSeconds)
{
    const Torso t = torso(512, 80, 0.7);
    const auto t0 = std::chrono::steady_clock::now();
    const auto r = seg::rib_cage(t.hu);
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::cout << "rib_cage on 512 x 512 x 80: " << s << " s\n";
    EXPECT_EQ(std::count(r.valid.begin(), r.valid.end(), 1), 80);
    EXPECT_LT(s, test::time_bound(2.0));
}

#ifdef LOBE_HAVE_PHANTOM
namespace {

phantom::PhantomResult coarse_phantom(double wall_hu = -1)
{
    phantom::PhantomParams pp;
    pp.spacing = {1.4, 1.4, 5.0};
    pp.size = phantom::size_for_spacing(pp.spacing);
    if (wall_hu > 0) {
        pp.hu.muscle = wall_hu;
        pp.hu.subcostal = wall_hu;
    }
    return phantom::generate_phantom(pp);
}

bool liver(int l) { return l >= 1 && l <= 4; }

} // namespace

// The phantom (1.4 x 1.4 x 5 mm): every liver voxel on a valid slice lies inside the ring
// (measured 1.0; asserted >= 0.995), >= 90 % of the liver is on valid slices (measured 99.86 %:
// only the inferior tip's lowest slice, where the 4-slice window holds too little rib, is not),
// and on the rays the ring constrains the subcutaneous fat (fat within 20 mm of the air) is
// outside: <= 1 % (measured 0.7 %, the chords across bridged gaps).
TEST(RibCage, PhantomLiverInsideFatOutside)
{
    const auto ph = coarse_phantom();
    const core::ImageF hu = core::convert_image<float>(ph.ct);
    const auto r = seg::rib_cage(hu);
    core::LabelImage3D air(hu.geometry(), 0);
    for (std::size_t q = 0; q < air.data.size(); ++q)
        air.data[q] = ph.labels.data[q] == phantom::kBackground;
    const core::ImageF to_air = seg::euclidean_distance(air);
    std::size_t liv = 0, liv_valid = 0, liv_in = 0, fat = 0, fat_in = 0;
    const int nx = hu.size[0], ny = hu.size[1];
    for (int k = 0; k < hu.size[2]; ++k) {
        const bool valid = r.valid[static_cast<std::size_t>(k)];
        const auto& ring = r.rings[static_cast<std::size_t>(k)];
        for (int j = 0; j < ny; ++j)
            for (int i = 0; i < nx; ++i) {
                const std::size_t q = hu.index(i, j, k);
                const int l = ph.labels.data[q];
                if (liver(l)) {
                    ++liv;
                    if (valid) {
                        ++liv_valid;
                        liv_in += r.inside.data[q];
                    }
                }
                if (valid && l == phantom::kFat && to_air.data[q] <= 20.f && ring.supported[ray_of(ring, i, j, hu)]) {
                    ++fat;
                    fat_in += r.inside.data[q];
                }
            }
    }
    const double recall = double(liv_in) / double(liv_valid), on_valid = double(liv_valid) / double(liv);
    const double fat_inside = double(fat_in) / double(fat);
    std::cout << "phantom: liver inside " << recall << " (on valid slices, " << on_valid
              << " of the liver), subcutaneous fat inside on constrained rays " << fat_inside << " of " << fat << "\n";
    EXPECT_GE(recall, 0.995);
    EXPECT_GE(on_valid, 0.9);
    EXPECT_GT(fat, 1000u);
    EXPECT_LE(fat_inside, 0.01);
}

// The test that matters (thesis L4700-4709): the wall between the ribs is of liver-like grey
// (muscle and subcostal tissue at 90 HU against the liver's 105), so a CDSG snake started in the
// liver leaks through the intercostal spaces into the body wall. With the image set to the
// window's low end outside the ring (mask_outside_rib_cage), the leak beyond the ribs is gone
// and the total leak shrinks. Measured on slices 16, 20, 24: spill beyond the ring 0.046 / 0.056
// / 0.040 of the liver's area without the ring, <= 0.002 with it; total spill 0.46 -> 0.38.
// What the ring does not stop: the leak into the subcostal layer inside the ribs (see
// docs/algorithms/rib_cage.md: a strong edge at the ring even attracts the GVF across the weak
// liver edge when the layer is a few pixels thin).
TEST(RibCage, SnakeLeaksLessWithTheRing)
{
    const auto ph = coarse_phantom(90.0);
    const core::ImageF hu = core::convert_image<float>(ph.ct);
    const auto rc = seg::rib_cage(hu);
    double total_without = 0, total_with = 0;
    for (int k : {16, 20, 24}) {
        ASSERT_TRUE(rc.valid[static_cast<std::size_t>(k)]);
        const core::ImageF img = core::axial_slice(hu, k);
        const core::LabelImage3D lab = core::axial_slice(ph.labels, k);
        const core::LabelImage3D inside = core::axial_slice(rc.inside, k);
        // The start: the liver shrunk by ~8 mm (as the previous slice's contour would be).
        core::LabelImage3D lmask(lab.geometry(), 0);
        for (std::size_t q = 0; q < lab.data.size(); ++q)
            lmask.data[q] = liver(lab.data[q]);
        const core::ImageF d = seg::euclidean_distance([&] {
            core::LabelImage3D out(lab.geometry(), 0);
            for (std::size_t q = 0; q < lab.data.size(); ++q)
                out.data[q] = !lmask.data[q];
            return out;
        }());
        core::LabelImage3D init(lab.geometry(), 0);
        for (std::size_t q = 0; q < lab.data.size(); ++q)
            init.data[q] = d.data[q] > 8.5f;
        auto spill = [&](const core::LabelImage3D& m, bool beyond_ring) {
            std::size_t n = 0, out = 0;
            for (std::size_t q = 0; q < m.data.size(); ++q) {
                n += lmask.data[q];
                out += m.data[q] && !lmask.data[q] && (!beyond_ring || !inside.data[q]);
            }
            return double(out) / double(n);
        };
        const auto without = seg::segment_snake(img, init);
        const auto with = seg::segment_snake(seg::mask_outside_rib_cage(img, inside, -130.f), init);
        std::cout << "slice " << k << ": spill without ring " << spill(without.mask, false) << " (beyond the ring "
                  << spill(without.mask, true) << "), with ring " << spill(with.mask, false) << " (beyond "
                  << spill(with.mask, true) << ")\n";
        EXPECT_GT(spill(without.mask, true), 0.02) << "slice " << k << ": the leak between the ribs";
        EXPECT_LT(spill(with.mask, true), 0.005) << "slice " << k;
        total_without += spill(without.mask, false);
        total_with += spill(with.mask, false);
    }
    EXPECT_LT(total_with, 0.9 * total_without);
}
#endif
