// Surface lesions (lobe/seg/surface_lesions.h) on a scene built in code: a cylinder of 100 units
// (radius 40 mm, 11 slices of 2.5 mm) in fat of -100, with pieces at its surface that a contour
// would have run round: a lesion of 70 (a ball of 12.5 mm radius centred 5 mm inside the surface,
// the part inside the cylinder: the phantom's boundary tumour), the same lesion under an
// exclusion, a cyst of -50 (darker than the half-way level), a small lesion of 70 (5 mm, centred 2
// mm inside) and a radial slot of 70, 1.6 mm wide and 20 mm deep. The mask is the cylinder less
// all of them; the grey range is [0, 90): above half-way to fat, below the object's band.
#include "lobe/seg/surface_lesions.h"

#include "lobe/core/errors.h"

#include "common/masks.h"

#include <gtest/gtest.h>

#include <cmath>

using namespace lobe;

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kPixel = 0.8, kSlice = 2.5; // mm
constexpr double kRadius = 50;               // the cylinder [px]
constexpr int kSize = 140, kCentre = 70;     // the slice [px]
constexpr int kSlices = 11;

struct Scene {
    core::ImageF image;
    core::LabelImage3D mask, lesion, excluded_lesion, exclude, cyst, small, slot;
};

// Inside the ball of radius r_mm centred depth_mm inside the cylinder's surface at angle theta,
// on slice 5.
bool in_ball(int i, int j, int k, double theta_deg, double r_mm, double depth_mm)
{
    const double rc = kRadius - depth_mm / kPixel;
    const double cx = kCentre + rc * std::cos(theta_deg * kPi / 180),
                 cy = kCentre + rc * std::sin(theta_deg * kPi / 180);
    return std::hypot((i - cx) * kPixel, (j - cy) * kPixel, (k - 5) * kSlice) <= r_mm;
}

Scene scene()
{
    core::ImageGeometry g;
    g.size = {kSize, kSize, kSlices};
    g.spacing = {kPixel, kPixel, kSlice};
    const core::LabelImage3D empty(g, 0);
    Scene s{core::ImageF(g, -100.f), empty, empty, empty, empty, empty, empty, empty};
    for (int k = 0; k < kSlices; ++k)
        for (int j = 0; j < kSize; ++j)
            for (int i = 0; i < kSize; ++i) {
                const double dx = i - kCentre, dy = j - kCentre;
                if (std::hypot(dx, dy) > kRadius)
                    continue;
                const double th = std::atan2(dy, dx) * 180 / kPi;
                const bool lesion = in_ball(i, j, k, -90, 12.5, 5), excluded = in_ball(i, j, k, 180, 12.5, 5),
                           cyst = in_ball(i, j, k, 0, 12.5, 5), small = in_ball(i, j, k, 45, 5, 2),
                           slot = std::abs(th - 90) * kPi / 180 * std::hypot(dx, dy) < 1.0 &&
                                  std::hypot(dx, dy) > kRadius - 25;
                s.image.at(i, j, k) = cyst ? -50.f : (lesion || excluded || small || slot) ? 70.f : 100.f;
                s.mask.at(i, j, k) = !(lesion || excluded || cyst || small || slot);
                s.lesion.at(i, j, k) = lesion;
                s.excluded_lesion.at(i, j, k) = excluded;
                s.cyst.at(i, j, k) = cyst;
                s.small.at(i, j, k) = small;
                s.slot.at(i, j, k) = slot;
            }
    // The exclusion (as the heart model is in the liver pipeline): a box round the lesion at 180 deg.
    for (int k = 0; k < kSlices; ++k)
        for (int j = 45; j < 96; ++j)
            for (int i = 5; i < 50; ++i)
                s.exclude.at(i, j, k) = 1;
    return s;
}

std::size_t added_on(const seg::SurfaceLesionResult& r, const core::LabelImage3D& before,
                     const core::LabelImage3D& where)
{
    std::size_t n = 0;
    for (std::size_t i = 0; i < before.data.size(); ++i)
        n += r.mask.data[i] && !before.data[i] && where.data[i] ? 1 : 0;
    return n;
}

} // namespace

// The lesion is added; the cyst (darker than lo; its blurred rim is thin), the small lesion (under
// min_ml), the slot (thin: no core) and the excluded lesion are not; nothing outside the cylinder
// is.
// Measured: 2 656 voxels added, all of them the lesion's, of its 3 822: the closing does not reach
// the notch's mouth (a disc of 15 mm sitting outside dips about 5 mm into a 23 mm wide mouth; the
// documented limit). Bounds: at least 60 % of the lesion, at least 90 % of the additions on it,
// none on the others.
TEST(SurfaceLesions, AddsTheLesionInTheNotchAndNothingElse)
{
    const Scene s = scene();
    core::LabelImage3D exclude = s.exclude;
    const seg::SurfaceLesionResult r = seg::fill_surface_lesions(s.image, s.mask, 0.0, 90.0, &exclude);
    const std::size_t on_lesion = added_on(r, s.mask, s.lesion);
    std::cerr << "surface lesions: " << r.added << " added, " << on_lesion << " of the lesion's "
              << test::count(s.lesion) << "; excluded lesion " << added_on(r, s.mask, s.excluded_lesion) << ", cyst "
              << added_on(r, s.mask, s.cyst) << ", small lesion " << added_on(r, s.mask, s.small) << ", slot "
              << added_on(r, s.mask, s.slot) << "\n";
    EXPECT_EQ(r.added, test::count(r.mask) - test::count(s.mask));
    EXPECT_GE(double(on_lesion), 0.6 * double(test::count(s.lesion)));
    EXPECT_GE(double(on_lesion), 0.9 * double(r.added));
    EXPECT_EQ(added_on(r, s.mask, s.excluded_lesion), 0u);
    EXPECT_EQ(added_on(r, s.mask, s.cyst), 0u);
    EXPECT_EQ(added_on(r, s.mask, s.small), 0u) << "a 4 mm lesion: below min_ml (the documented limit)";
    EXPECT_EQ(added_on(r, s.mask, s.slot), 0u);
    // Nothing is removed, and nothing leaves the cylinder (the closing of a convex outline stays in it).
    for (int k = 0; k < kSlices; ++k)
        for (int j = 0; j < kSize; ++j)
            for (int i = 0; i < kSize; ++i) {
                ASSERT_FALSE(s.mask.at(i, j, k) && !r.mask.at(i, j, k));
                if (r.mask.at(i, j, k)) {
                    ASSERT_LE(std::hypot(i - double(kCentre), j - double(kCentre)), kRadius + 0.5);
                }
            }
}

// Without the exclusion the second lesion is added as the first. With no minimum volume and no
// core fraction every candidate piece is added: the small lesion (measured 201 of its 230 voxels),
// and thin pieces that the core test keeps out, what it is for: the slot (33 of 275) and the
// cyst's partial-volume rim (317 voxels of the cyst's 3 822, between its -50 and the object's 100).
TEST(SurfaceLesions, ExclusionAndCoreTestDecide)
{
    const Scene s = scene();
    const seg::SurfaceLesionResult all = seg::fill_surface_lesions(s.image, s.mask, 0.0, 90.0);
    EXPECT_GE(double(added_on(all, s.mask, s.excluded_lesion)), 0.6 * double(test::count(s.excluded_lesion)));
    EXPECT_EQ(added_on(all, s.mask, s.excluded_lesion), added_on(all, s.mask, s.lesion)); // the same shape
    seg::SurfaceLesionParams p;
    p.core_fraction = 0.0;
    p.min_ml = 0.0;
    const seg::SurfaceLesionResult loose = seg::fill_surface_lesions(s.image, s.mask, 0.0, 90.0, nullptr, p);
    std::cerr << "loose: small lesion " << added_on(loose, s.mask, s.small) << " of " << test::count(s.small)
              << ", slot " << added_on(loose, s.mask, s.slot) << " of " << test::count(s.slot) << ", cyst "
              << added_on(loose, s.mask, s.cyst) << " of " << test::count(s.cyst) << "\n";
    EXPECT_GT(added_on(loose, s.mask, s.small), 0u);
    EXPECT_GT(added_on(loose, s.mask, s.slot), 0u);
    EXPECT_GT(added_on(loose, s.mask, s.cyst), 0u);
}

// Refusals, and an empty mask: nothing added, no error.
TEST(SurfaceLesions, RefusesBadInputAndSurvivesAnEmptyMask)
{
    const Scene s = scene();
    EXPECT_THROW(seg::fill_surface_lesions(s.image, s.mask, 90.0, 0.0), core::InvalidInputError); // lo >= hi
    EXPECT_THROW(seg::fill_surface_lesions(s.image, s.mask, std::nan(""), 90.0), core::InvalidInputError);
    core::ImageGeometry other = s.mask.geometry();
    other.size[2] = 3;
    EXPECT_THROW(seg::fill_surface_lesions(s.image, core::LabelImage3D(other, 0), 0.0, 90.0), core::InvalidInputError);
    const core::LabelImage3D wrong(other, 0);
    EXPECT_THROW(seg::fill_surface_lesions(s.image, s.mask, 0.0, 90.0, &wrong), core::InvalidInputError);
    for (auto bad : {&seg::SurfaceLesionParams::closing_mm, &seg::SurfaceLesionParams::core_mm}) {
        seg::SurfaceLesionParams p;
        p.*bad = 0.0;
        EXPECT_THROW(seg::fill_surface_lesions(s.image, s.mask, 0.0, 90.0, nullptr, p), core::InvalidInputError);
    }
    seg::SurfaceLesionParams p;
    p.core_fraction = 1.5;
    EXPECT_THROW(seg::fill_surface_lesions(s.image, s.mask, 0.0, 90.0, nullptr, p), core::InvalidInputError);
    const seg::SurfaceLesionResult none =
        seg::fill_surface_lesions(s.image, core::LabelImage3D(s.mask.geometry(), 0), 0.0, 90.0);
    EXPECT_EQ(none.added, 0u);
    EXPECT_EQ(test::count(none.mask), 0u);
}
