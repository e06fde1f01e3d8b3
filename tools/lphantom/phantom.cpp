#include "lphantom/phantom.h"

#include "lobe/core/errors.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstddef>
#include <limits>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

// How it works (docs/phantom.md): every tissue is an analytic shape in mm. classify(p) answers
// "which tissue is at p" in a fixed priority order (body wall, then organs that indent the liver,
// then the liver with its internal structures, then the rest). The label volume samples it at the
// voxel centres; the CT averages it over sub-samples of the voxel footprint where a voxel touches
// another tissue (partial volume, mostly the slice thickness), then applies a Gaussian PSF and
// Gaussian noise. The vessel trees are grown once, deterministically, inside the analytic liver.

namespace lobe::phantom {

using core::Vec3;

namespace {

constexpr double kPi = 3.14159265358979323846;

// ------------------------------------------------------------------------------------------
// Tissues: finer than labels (one label may hold several CT numbers).

enum Tissue : std::uint8_t {
    TAir, TSkin, TSubcutFat, TMuscle, TSubcostal, TRibCortex, TRibMarrow, TCartilage,
    TLung, TMediastinum, TDiaphragm, TAbdFat,
    TLiver, TPortal, THepatic, TTumour0, TTumour1, TTumour2, TFissureFat, TNeckFat,
    THeartWall, THeartLine, THeartBlood,
    TKidneyR, TKidneyRLine, TKidneyL, TKidneyLLine, TRenalSinus,
    TIvc, TAorta, TSpineCortex, TSpineMarrow, TDisc, TCsf,
    TSpleen, TStomachWall, TStomachFluid, TStomachGas, TBile, TPortalExtra,
    TBowel, TBowelGas, TBowelFluid, TPancreas,
    TCount
};

struct TissueDef {
    Label label;
    double PhantomHu::*hu;
};

// Tumour HU is liver + contrast, so the tumour rows point at liver and are corrected below.
constexpr TissueDef kTissues[TCount] = {
    {kBackground, &PhantomHu::air},        {kSoftTissue, &PhantomHu::skin},
    {kFat, &PhantomHu::fat},               {kSoftTissue, &PhantomHu::muscle},
    {kSubcostal, &PhantomHu::subcostal},   {kBone, &PhantomHu::bone_cortex},
    {kBone, &PhantomHu::bone_marrow},      {kBone, &PhantomHu::cartilage},
    {kLungs, &PhantomHu::lung},            {kMediastinum, &PhantomHu::mediastinal_fat},
    {kSoftTissue, &PhantomHu::muscle},     {kFat, &PhantomHu::fat},
    {kLiver, &PhantomHu::liver},           {kPortalVein, &PhantomHu::portal_vein},
    {kHepaticVein, &PhantomHu::hepatic_vein}, {kTumour, &PhantomHu::liver},
    {kTumour, &PhantomHu::liver},          {kTumour, &PhantomHu::liver},
    {kFat, &PhantomHu::fat},               {kFat, &PhantomHu::fat},
    {kHeart, &PhantomHu::heart_wall},      {kHeart, &PhantomHu::contact_line},
    {kHeartBlood, &PhantomHu::heart_blood},
    {kRightKidney, &PhantomHu::kidney},    {kRightKidney, &PhantomHu::contact_line},
    {kLeftKidney, &PhantomHu::kidney},     {kLeftKidney, &PhantomHu::contact_line},
    {kFat, &PhantomHu::fat},
    {kIvc, &PhantomHu::ivc},               {kAorta, &PhantomHu::aorta},
    {kSpine, &PhantomHu::bone_cortex},     {kSpine, &PhantomHu::bone_marrow},
    {kSpine, &PhantomHu::disc},            {kSpine, &PhantomHu::csf},
    {kSpleen, &PhantomHu::spleen},         {kStomach, &PhantomHu::stomach_wall},
    {kStomach, &PhantomHu::stomach_fluid}, {kStomach, &PhantomHu::gas},
    {kGallbladder, &PhantomHu::bile},      {kPortalVeinExtra, &PhantomHu::portal_vein},
    {kSoftTissue, &PhantomHu::bowel},      {kSoftTissue, &PhantomHu::gas},
    {kSoftTissue, &PhantomHu::stomach_fluid}, {kSoftTissue, &PhantomHu::pancreas},
};
constexpr bool all_tissues_defined()
{
    for (const auto& t : kTissues)
        if (t.hu == nullptr) return false;
    return true;
}
static_assert(all_tissues_defined(), "one row of kTissues per Tissue, in the enum's order");

// ------------------------------------------------------------------------------------------
// Small geometry.

struct Box {
    Vec3 lo{std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity(),
            std::numeric_limits<double>::infinity()};
    Vec3 hi{-std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity(),
            -std::numeric_limits<double>::infinity()};
    bool contains(const Vec3& p) const
    {
        return p.x >= lo.x && p.x <= hi.x && p.y >= lo.y && p.y <= hi.y && p.z >= lo.z && p.z <= hi.z;
    }
    void add(const Vec3& p)
    {
        lo = {std::min(lo.x, p.x), std::min(lo.y, p.y), std::min(lo.z, p.z)};
        hi = {std::max(hi.x, p.x), std::max(hi.y, p.y), std::max(hi.z, p.z)};
    }
    void add(const Box& b)
    {
        add(b.lo);
        add(b.hi);
    }
    Box grown(double m) const { return {lo - Vec3{m, m, m}, hi + Vec3{m, m, m}}; }
};

// Rotation from yaw (about z), then pitch (about y), then roll (about x), degrees. Rows are the
// local axes in world coordinates, so local = R (p - c).
struct Rot {
    std::array<double, 9> m{1, 0, 0, 0, 1, 0, 0, 0, 1};
    static Rot from_deg(double yaw, double pitch = 0, double roll = 0)
    {
        const double a = yaw * kPi / 180, b = pitch * kPi / 180, c = roll * kPi / 180;
        const double ca = std::cos(a), sa = std::sin(a), cb = std::cos(b), sb = std::sin(b);
        const double cc = std::cos(c), sc = std::sin(c);
        // world-from-local W = Rz(a) Ry(b) Rx(c); store its transpose (local-from-world).
        const std::array<double, 9> w{ca * cb, ca * sb * sc - sa * cc, ca * sb * cc + sa * sc,
                                      sa * cb, sa * sb * sc + ca * cc, sa * sb * cc - ca * sc,
                                      -sb,     cb * sc,                cb * cc};
        Rot r;
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j)
                r.m[static_cast<std::size_t>(3 * i + j)] = w[static_cast<std::size_t>(3 * j + i)];
        return r;
    }
    Vec3 apply(const Vec3& v) const
    {
        return {m[0] * v.x + m[1] * v.y + m[2] * v.z, m[3] * v.x + m[4] * v.y + m[5] * v.z,
                m[6] * v.x + m[7] * v.y + m[8] * v.z};
    }
    Vec3 apply_transpose(const Vec3& v) const
    {
        return {m[0] * v.x + m[3] * v.y + m[6] * v.z, m[1] * v.x + m[4] * v.y + m[7] * v.z,
                m[2] * v.x + m[5] * v.y + m[8] * v.z};
    }
};

// An ellipsoid, optionally tapered (the x and y semi-axes scale with 1 + taper_z * qz / az and
// the y and z semi-axes with 1 - taper_x * max(0, qx) / ax), in a rotated frame.
struct Ellipsoid {
    Vec3 c;
    Vec3 a{1, 1, 1};
    Rot rot;
    double taper_z = 0;
    double taper_x = 0;
    Box box;

    Ellipsoid() = default;
    Ellipsoid(Vec3 centre, Vec3 semi, Rot r = {}, double tz = 0, double tx = 0)
        : c(centre), a(semi), rot(r), taper_z(tz), taper_x(tx)
    {
        // The bounding box of the untapered ellipsoid grown by the taper's largest widening.
        const double grow = 1.0 + std::abs(taper_z);
        Vec3 half;
        for (int i = 0; i < 3; ++i) {
            double s = 0;
            for (int j = 0; j < 3; ++j) {
                const double aj = a[j] * (j < 2 ? grow : 1.0);
                s += rot.m[static_cast<std::size_t>(3 * j + i)] * rot.m[static_cast<std::size_t>(3 * j + i)] * aj * aj;
            }
            half[i] = std::sqrt(s) + 1e-6;
        }
        box = {c - half, c + half};
    }
    // Normalised squared radius and the local semi-axes actually used at p.
    double rho2(const Vec3& p, Vec3* q_out = nullptr, Vec3* a_out = nullptr) const
    {
        const Vec3 q = rot.apply(p - c);
        Vec3 s = a;
        if (taper_z != 0) {
            const double f = std::max(0.2, 1.0 + taper_z * q.z / a.z);
            s.x *= f;
            s.y *= f;
        }
        if (taper_x != 0 && q.x > 0) {
            const double f = std::max(0.2, 1.0 - taper_x * q.x / a.x);
            s.y *= f;
            s.z *= f;
        }
        if (q_out) *q_out = q;
        if (a_out) *a_out = s;
        return (q.x * q.x) / (s.x * s.x) + (q.y * q.y) / (s.y * s.y) + (q.z * q.z) / (s.z * s.z);
    }
    bool inside(const Vec3& p) const { return box.contains(p) && rho2(p) <= 1.0; }
    // First-order signed distance [mm] (exact on the surface, fine within a few mm of it).
    double sdf(const Vec3& p) const
    {
        Vec3 q, s;
        const double r2 = rho2(p, &q, &s);
        const double gx = q.x / (s.x * s.x), gy = q.y / (s.y * s.y), gz = q.z / (s.z * s.z);
        const double g = 2.0 * std::sqrt(gx * gx + gy * gy + gz * gz);
        return (r2 - 1.0) / std::max(g, 1e-9);
    }
};

struct Sphere {
    Vec3 c;
    double r = 0;
};

// Squared distance from p to segment [a, b].
double dist2_segment(const Vec3& p, const Vec3& a, const Vec3& b)
{
    const Vec3 ab = b - a;
    const double l2 = dot(ab, ab);
    double t = l2 > 0 ? dot(p - a, ab) / l2 : 0.0;
    t = std::clamp(t, 0.0, 1.0);
    const Vec3 d = p - (a + ab * t);
    return dot(d, d);
}

double smooth_min(double a, double b, double k)
{
    const double h = std::max(k - std::abs(a - b), 0.0) / k;
    return std::min(a, b) - h * h * k * 0.25;
}

struct Capsule {
    Vec3 a, b;
    double r = 0;
    Tissue tissue = TPortal;
    Box box;
};

// A slab fissure snapped to the voxel grid along x, cut from the anterior liver surface to a
// fixed depth below it (the surface depth is tabulated per mm of z at the nominal x, so it does
// not depend on the grid).
struct Fissure {
    double x0 = 0, x1 = 0;        // exact walls [mm]
    double y_lo = -200;           // the cut starts outside the liver
    double z_lo = 0, z_hi = 0;
    double x_nominal = 0;         // grid-independent centre, for the vessel planner's keep-out
    std::vector<double> y_floor;  // per 1 mm of z from z_lo: the cut's posterior end [mm]
    double y_max = -200;          // the largest y_floor
    double floor_at(double z) const
    {
        if (y_floor.empty()) return y_lo;
        const auto i = static_cast<std::size_t>(std::clamp(std::lround(z - z_lo), 0L, static_cast<long>(y_floor.size()) - 1));
        return y_floor[i];
    }
    bool inside(const Vec3& p) const
    {
        return p.x > x0 && p.x < x1 && p.z > z_lo && p.z < z_hi && p.y > y_lo && p.y < floor_at(p.z);
    }
};

// ------------------------------------------------------------------------------------------
// The anatomy. All numbers are millimetres in LPS, chosen to look like an adult abdomen around
// the T10-L2 levels with the liver's dome near the top of the default field of view.

// Body outline: an ellipse, a little flatter at the back.
constexpr double kBodyAx = 165, kBodyAyAnt = 118, kBodyAyPost = 112, kBodyCy = -3;
constexpr double kSkin = 2.0, kSubcostalBand = 6.0;
// Vertebral levels: centres every 27 mm, T12 at z = -50.
constexpr double kZT12 = -50, kVertPitch = 27;
// Ribs: heads at the vertebral levels, descending 45 mm per radian towards the front.
constexpr double kRibSlope = 45, kRibHalfDepth = 3.5, kRibHalfHeight = 5.5, kRibCortex = 1.2;
constexpr double kRibStart = 0.28; // radians from the posterior midline
constexpr double kDiaphragm = 4.0;
// The inferior vena cava, vertical.
constexpr double kIvcX = -28, kIvcY = 5, kIvcRx = 12, kIvcRy = 11;
constexpr double kNeckWidth = 7.0, kNeckZLo = -22, kNeckZHi = 56;
constexpr double kAortaX = 14, kAortaY = 20, kAortaR = 11;

class Anatomy {
public:
    Anatomy(const PhantomParams& params, const core::ImageGeometry& grid);

    // The tissue at p. `fissures` = false leaves out the grid-snapped fissures (the planner and
    // the volume quadrature must not depend on the grid).
    Tissue classify(const Vec3& p, bool fissures = true) const
    {
        const Tissue t = outer(p, fissures);
        return t == TLiver ? inner(p) : t;
    }
    Tissue outer(const Vec3& p, bool fissures) const;
    Tissue inner(const Vec3& p) const;

    bool liver_envelope(const Vec3& p) const { return outer(p, false) == TLiver; }
    double liver_sdf(const Vec3& p) const; // the smooth union before clipping

    const Box& liver_box() const { return liver_box_; }
    const std::vector<std::vector<Sphere>>& tumours() const { return tumours_; }
    const std::vector<Fissure>& fissures() const { return fissures_; }
    const Ellipsoid& heart() const { return heart_; }
    const Ellipsoid& kidney_r() const { return kidney_r_; }

    void set_vessels(std::vector<Capsule> capsules);
    bool in_tumour(const Vec3& p, int* which = nullptr) const;

    static double diaphragm_z(double x, double y)
    {
        // Two domes, a saddle under the heart, and deep posterior recesses.
        const double dr = 78 - ((x + 55) * (x + 55) + 0.8 * (y + 5) * (y + 5)) / 200;
        const double dl = 68 - ((x - 55) * (x - 55) + 0.8 * y * y) / 200;
        const double sx = (x - 10) / 35, sy = (y + 25) / 40, s2 = sx * sx + sy * sy;
        const double saddle = s2 < 12.0 ? 6.0 * std::exp(-s2) : 0.0; // below 4e-5 mm beyond
        return std::max(dr, dl) - saddle - 0.6 * std::max(0.0, y - 10);
    }

private:
    Tissue wall(const Vec3& p, double d, double dx, double dy, double r) const;
    Tissue spine(const Vec3& p) const;
    bool in_liver(const Vec3& p) const;

    std::vector<Ellipsoid> liver_parts_;
    Box liver_box_;
    Ellipsoid heart_, heart_blood_;
    Ellipsoid kidney_r_, kidney_l_, sinus_r_, sinus_l_;
    Ellipsoid spleen_, stomach_, stomach_inner_, gallbladder_;
    std::vector<Ellipsoid> small_bowel_;
    std::vector<Capsule> colon_;
    std::vector<Capsule> pancreas_;
    Capsule antrum_;
    Box bowel_box_;
    std::vector<std::vector<Sphere>> tumours_;
    std::vector<Box> tumour_boxes_;
    std::vector<Fissure> fissures_;
    double line_ = 1.0;

    // Vessels with a uniform bucket grid over their bounding box.
    std::vector<Capsule> vessels_;
    Capsule portal_trunk_;
    bool have_trunk_ = false;
    Box vbox_;
    double cell_ = 8.0;
    std::array<int, 3> vdim_{0, 0, 0};
    std::vector<int> vstart_, vlist_;
};

Anatomy::Anatomy(const PhantomParams& params, const core::ImageGeometry& grid)
    : line_(params.contact_line_mm)
{
    // The liver: smooth union of four deformed ellipsoids (right lobe, its inferior tip, the
    // central part with the caudate lobe, the tapering left lobe).
    liver_parts_ = {
        Ellipsoid({-72, 8, 18}, {68, 78, 64}, Rot::from_deg(0, 0, -25), 0.25),
        Ellipsoid({-88, -25, -32}, {44, 42, 36}, Rot::from_deg(10, 0, -20)),
        Ellipsoid({-20, -5, 18}, {42, 45, 44}, Rot::from_deg(0)),
        Ellipsoid({25, -40, 30}, {80, 36, 28}, Rot::from_deg(15), 0.0, 0.55),
    };
    for (const auto& e : liver_parts_)
        liver_box_.add(e.box);
    liver_box_ = liver_box_.grown(8.0);

    heart_ = Ellipsoid({12, -28, 84}, {62, 50, 44}, Rot::from_deg(-35));
    heart_blood_ = Ellipsoid({12, -28, 92}, {47, 36, 34}, Rot::from_deg(-35));
    kidney_r_ = Ellipsoid({-72, 46, -75}, {26, 22, 52}, Rot::from_deg(-30, 12));
    kidney_l_ = Ellipsoid({74, 46, -62}, {26, 22, 52}, Rot::from_deg(30, -12));
    sinus_r_ = Ellipsoid({-58, 40, -75}, {10, 9, 24}, Rot::from_deg(-30, 12));
    sinus_l_ = Ellipsoid({60, 40, -62}, {10, 9, 24}, Rot::from_deg(30, -12));
    spleen_ = Ellipsoid({95, 45, 20}, {25, 55, 48}, Rot::from_deg(-40));
    stomach_ = Ellipsoid({62, -30, 22}, {36, 30, 48}, Rot::from_deg(30));
    stomach_inner_ = Ellipsoid({62, -30, 22}, {32, 26, 44}, Rot::from_deg(30));
    gallbladder_ = Ellipsoid({-40, -50, -38}, {15, 15, 32}, Rot::from_deg(0, 0, -35));
    small_bowel_ = {Ellipsoid({20, -55, -45}, {20, 16, 14}), Ellipsoid({45, -40, -70}, {18, 16, 16}),
                    Ellipsoid({0, -60, -80}, {20, 15, 15}),  Ellipsoid({-30, -55, -88}, {18, 16, 14}),
                    Ellipsoid({60, -10, -85}, {16, 15, 18}), Ellipsoid({25, -20, -95}, {18, 16, 15}),
                    Ellipsoid({35, -72, -92}, {18, 12, 15}), Ellipsoid({-5, -30, -62}, {14, 14, 12}),
                    Ellipsoid({30, -58, -28}, {18, 15, 14}), Ellipsoid({8, -20, -38}, {14, 13, 12})};
    for (const auto& e : small_bowel_)
        bowel_box_.add(e.box);
    auto capsule = [](Vec3 a, Vec3 b, double r, Tissue t) {
        Capsule c{a, b, r, t, {}};
        c.box.add(a);
        c.box.add(b);
        c.box = c.box.grown(r);
        return c;
    };
    const Vec3 colon[8] = {{-100, -5, -105}, {-95, -30, -64}, {-55, -70, -62}, {20, -80, -62},
                           {70, -55, -40},   {92, -20, -5},   {100, 15, -40},  {100, 20, -105}};
    for (int i = 0; i < 7; ++i)
        colon_.push_back(capsule(colon[i], colon[i + 1], 18, TBowel));
    colon_.push_back(capsule({-35, -15, -45}, {-40, -5, -82}, 10, TBowel)); // duodenum
    antrum_ = capsule({48, -42, -2}, {-12, -52, -26}, 14, TStomachWall);
    pancreas_ = {capsule({-5, 2, -52}, {75, 28, -32}, 10, TPancreas), capsule({-22, -2, -68}, {-5, 2, -52}, 12, TPancreas)};

    if (params.tumours) {
        // Lobular: a core with five lobules. Satellite: one small sphere. Boundary: a sphere that
        // the liver surface cuts, at the lateral wall next to the ribs.
        const Vec3 t0{-95, -20, -28};
        tumours_ = {
            {{t0, 15}, {t0 + Vec3{13, 0, 5}, 10}, {t0 + Vec3{-8, 12, -4}, 10}, {t0 + Vec3{0, -12, 8}, 9},
             {t0 + Vec3{5, 6, -13}, 9}, {t0 + Vec3{-10, -6, 12}, 8}},
            {{t0 + Vec3{35, -15, 35}, 6}},
            {{{-124, -10, 22}, 13}},
        };
        for (const auto& t : tumours_) {
            Box b;
            for (const auto& s : t) {
                b.add(s.c - Vec3{s.r, s.r, s.r});
                b.add(s.c + Vec3{s.r, s.r, s.r});
            }
            tumour_boxes_.push_back(b);
        }
    }

    // Fissures from the anterior surface, walls on voxel boundaries so that exactly
    // width_voxels voxel centres fall inside along x.
    auto snapped = [&](double x_nominal, int width, double depth, double z_lo, double z_hi) {
        const double sx = grid.spacing[0];
        const double ox = grid.origin[0];
        Fissure f;
        f.x_nominal = x_nominal;
        // even: centred on a voxel boundary; odd: centred on a voxel centre
        const double c = width % 2 == 0 ? std::round((x_nominal - ox) / sx - 0.5) + 0.5 : std::round((x_nominal - ox) / sx);
        f.x0 = ox + (c - width / 2.0) * sx;
        f.x1 = ox + (c + width / 2.0) * sx;
        f.z_lo = z_lo;
        f.z_hi = z_hi;
        for (double z = z_lo; z <= z_hi + 0.5; z += 1.0) {
            double y = -150;
            while (y < 0 && !liver_envelope({x_nominal, y, z}))
                y += 0.25;
            f.y_floor.push_back(y < 0 ? y + depth : -200.0);
            f.y_max = std::max(f.y_max, f.y_floor.back());
        }
        return f;
    };
    if (params.fissure_width_voxels > 0)
        fissures_.push_back(snapped(8.0, params.fissure_width_voxels, 20.0, 12, 40));
    if (params.odd_fissure_width_voxels > 0)
        fissures_.push_back(snapped(-62.0, params.odd_fissure_width_voxels, 20.0, 0, 34));
}

double Anatomy::liver_sdf(const Vec3& p) const
{
    double f = liver_parts_[0].sdf(p);
    for (std::size_t i = 1; i < liver_parts_.size(); ++i)
        f = smooth_min(f, liver_parts_[i].sdf(p), 14.0);
    return f;
}

bool Anatomy::in_liver(const Vec3& p) const
{
    if (!liver_box_.contains(p))
        return false;
    // Posterior limit: the bare area on the right, a groove for the IVC, thin behind the left lobe.
    const double x = p.x;
    if (x > -40) {
        const double y_post = x < -12 ? 31.0 : std::max(-12.0, 31.0 - 1.5 * (x + 12));
        if (p.y > y_post)
            return false;
    }
    return liver_sdf(p) < 0.0;
}

bool Anatomy::in_tumour(const Vec3& p, int* which) const
{
    for (std::size_t t = 0; t < tumours_.size(); ++t) {
        if (!tumour_boxes_[t].contains(p))
            continue;
        for (const auto& s : tumours_[t]) {
            const Vec3 d = p - s.c;
            if (dot(d, d) <= s.r * s.r) {
                if (which) *which = static_cast<int>(t);
                return true;
            }
        }
    }
    return false;
}

Tissue Anatomy::wall(const Vec3& p, double d, double dx, double dy, double r) const
{
    // Layer thicknesses vary around the body: thinner fat at the back, thick back muscles near
    // the midline.
    const double post = std::max(0.0, dy) / std::max(r, 1e-6);
    const double t_fat = 15.0 - 6.0 * post;
    const double t_muscle = post > 0 ? 10.0 + 30.0 * std::exp(-(dx / 40.0) * (dx / 40.0)) * post * post : 10.0;
    const double d_fat = kSkin + t_fat;
    const double d_muscle = d_fat + t_muscle;
    if (d < kSkin) return TSkin;
    if (d < d_fat) return TSubcutFat;
    // Ribs sit at the inner side of the muscle layer.
    const double d_rib = d_muscle - kRibHalfDepth - 0.5;
    if (std::abs(d - d_rib) < kRibHalfDepth) {
        const double theta = std::atan2(std::abs(dx), dy); // 0 at the back, pi at the front
        if (theta >= kRibStart) {
            const double u = (p.z + kRibSlope * theta - kZT12) / kVertPitch;
            const int k0 = 12 - static_cast<int>(std::lround(u));
            for (int k = k0 - 1; k <= k0 + 1; ++k) {
                if (k < 2 || k > 12) continue;
                static constexpr double kEnd[13] = {0, 0, 0.9, 0.9, 0.9, 0.9, 0.9, 0.9, 0.85, 0.8, 0.72, 0.55, 0.42};
                const double end = kEnd[k] * kPi;
                if (theta > end) continue;
                const double zc = kZT12 + (12 - k) * kVertPitch - kRibSlope * theta;
                const double er = (d - d_rib) / kRibHalfDepth, ez = (p.z - zc) / kRibHalfHeight;
                if (er * er + ez * ez > 1.0) continue;
                if (k <= 10 && theta > end - 0.25 * kPi) return TCartilage;
                const double ir = (d - d_rib) / (kRibHalfDepth - kRibCortex);
                const double iz = (p.z - zc) / (kRibHalfHeight - kRibCortex);
                return ir * ir + iz * iz <= 1.0 ? TRibMarrow : TRibCortex;
            }
        }
    }
    if (d < d_muscle) return TMuscle;
    if (d < d_muscle + kSubcostalBand) return TSubcostal;
    return TCount; // inside the cavity
}

Tissue Anatomy::spine(const Vec3& p) const
{
    if (p.x < -36 || p.x > 36 || p.y < 31 || p.y > 104)
        return TCount;
    const double m = std::round((p.z - kZT12) / kVertPitch);
    const double dz = p.z - (kZT12 + m * kVertPitch);
    const bool disc = std::abs(dz) > kVertPitch / 2 - 3.5;
    // vertebral body
    const double bx = p.x / 21.0, by = (p.y - 50) / 18.0;
    if (bx * bx + by * by <= 1.0) {
        if (disc) return TDisc;
        const double ix = p.x / 19.5, iy = (p.y - 50) / 16.5;
        return ix * ix + iy * iy <= 1.0 ? TSpineMarrow : TSpineCortex;
    }
    const double cx = p.x, cy = p.y - 78;
    const double rc2 = cx * cx + cy * cy;
    if (rc2 <= 8.0 * 8.0) return TCsf;
    if (disc) return TCount;
    if (rc2 <= 13.0 * 13.0 && p.y > 66) return TSpineCortex;                 // arch
    if (std::abs(p.x) < 4 && p.y > 86 && p.y < 104 && std::abs(dz) < 9) return TSpineCortex; // spinous
    if (std::abs(p.x) > 8 && p.y > 72 && p.y < 81 && std::abs(dz) < 7) return TSpineCortex;  // transverse
    return TCount;
}

Tissue Anatomy::outer(const Vec3& p, bool with_fissures) const
{
    // Body outline and wall.
    const double dx = p.x, dy = p.y - kBodyCy;
    const double ay = dy < 0 ? kBodyAyAnt : kBodyAyPost;
    const double rho2 = (dx * dx) / (kBodyAx * kBodyAx) + (dy * dy) / (ay * ay);
    if (rho2 >= 1.0)
        return TAir;
    const Tissue sp = spine(p);
    if (sp != TCount)
        return sp;
    const double r = std::sqrt(dx * dx + dy * dy);
    const double rho = std::sqrt(rho2);
    const double d = rho > 1e-9 ? r / rho - r : 1e9; // depth below the skin along the ray
    if (d < 70.0) {
        const Tissue w = wall(p, d, dx, dy, r);
        if (w != TCount)
            return w;
    }

    // Great vessels.
    {
        const double ax = p.x - kAortaX, ayy = p.y - kAortaY;
        if (ax * ax + ayy * ayy <= kAortaR * kAortaR) return TAorta;
        const double ix = (p.x - kIvcX) / kIvcRx, iy = (p.y - kIvcY) / kIvcRy;
        if (ix * ix + iy * iy <= 1.0) return TIvc;
        // the crura of the diaphragm beside the aorta
        if (p.z < 45 && p.z > -75) {
            const double cx = std::abs(p.x) - 15, cy = p.y - 32;
            if (cx * cx + cy * cy < 36.0) return TDiaphragm;
        }
    }
    // Heart: sits on the diaphragm and indents the liver's dome (the weak contact).
    if (heart_.box.contains(p)) {
        const double s = heart_.sdf(p);
        if (s <= 0) {
            if (s > -line_) return THeartLine;
            return heart_blood_.inside(p) ? THeartBlood : THeartWall;
        }
    }
    // Thorax above the diaphragm.
    const double dz = diaphragm_z(p.x, p.y);
    if (p.z > dz) {
        if (std::abs(p.x - 6) < 26 && p.y > -10) return TMediastinum;
        return TLung;
    }
    if (p.z > dz - kDiaphragm) return TDiaphragm;

    // Kidneys: the right one indents the liver's posterior-inferior surface (the weak contact).
    if (kidney_r_.box.contains(p)) {
        const double s = kidney_r_.sdf(p);
        if (s <= 0) {
            if (s > -line_) return TKidneyRLine;
            return sinus_r_.inside(p) ? TRenalSinus : TKidneyR;
        }
    }
    if (kidney_l_.box.contains(p)) {
        const double s = kidney_l_.sdf(p);
        if (s <= 0) {
            if (s > -line_) return TKidneyLLine;
            return sinus_l_.inside(p) ? TRenalSinus : TKidneyL;
        }
    }
    if (p.z < -30) {
        const double s = std::min(15.0, 6.0 + 0.3 * (-30 - p.z));
        const double px = std::abs(p.x) - 30, py = p.y - 50;
        if (px * px + py * py <= s * s) return TMuscle; // psoas
    }
    if (spleen_.inside(p)) return TSpleen;
    if (gallbladder_.inside(p)) return TBile;
    // The Omega concavity's neck: a narrow slot from the IVC to the back of the liver.
    if (p.z > kNeckZLo && p.z < kNeckZHi && p.y > kIvcY && p.y < 60 && std::abs(p.x - kIvcX) < kNeckWidth / 2)
        return TNeckFat;
    if (with_fissures)
        for (const auto& f : fissures_)
            if (f.inside(p)) return TFissureFat;
    if (in_liver(p)) return TLiver;
    if (have_trunk_ && portal_trunk_.box.contains(p) &&
        dist2_segment(p, portal_trunk_.a, portal_trunk_.b) <= portal_trunk_.r * portal_trunk_.r)
        return TPortalExtra;
    if (stomach_.inside(p)) {
        if (!stomach_inner_.inside(p)) return TStomachWall;
        return p.y < stomach_.c.y - 10 ? TStomachGas : TStomachFluid;
    }
    if (antrum_.box.contains(p)) { // the antrum runs to the right, towards the duodenum
        const double d2 = dist2_segment(p, antrum_.a, antrum_.b);
        if (d2 <= antrum_.r * antrum_.r)
            return d2 > (antrum_.r - 4) * (antrum_.r - 4) ? TStomachWall : TStomachFluid;
    }
    {
        // the deepest of the overlapping colon pieces decides, so that joints show no wall
        const Capsule* best = nullptr;
        double depth = 0, t_best = 0;
        for (const auto& c : colon_) {
            if (!c.box.contains(p)) continue;
            const Vec3 ab = c.b - c.a;
            const double t = std::clamp(dot(p - c.a, ab) / dot(ab, ab), 0.0, 1.0);
            const double dd = c.r - norm(p - (c.a + ab * t));
            if (dd >= 0 && (!best || dd > depth)) {
                best = &c;
                depth = dd;
                t_best = t;
            }
        }
        if (best) {
            if (depth < 3.0) return TBowel;
            // gas floats to the front (the patient lies supine)
            return p.y < best->a.y + (best->b.y - best->a.y) * t_best - 4 ? TBowelGas : TBowelFluid;
        }
    }
    for (const auto& c : pancreas_)
        if (c.box.contains(p) && dist2_segment(p, c.a, c.b) <= c.r * c.r) return TPancreas;
    if (bowel_box_.contains(p))
        for (const auto& e : small_bowel_)
            if (e.inside(p)) return TBowel;
    return TAbdFat;
}

Tissue Anatomy::inner(const Vec3& p) const
{
    int which = 0;
    if (in_tumour(p, &which))
        return static_cast<Tissue>(TTumour0 + which);
    if (!vessels_.empty() && vbox_.contains(p)) {
        const int i = std::min(vdim_[0] - 1, static_cast<int>((p.x - vbox_.lo.x) / cell_));
        const int j = std::min(vdim_[1] - 1, static_cast<int>((p.y - vbox_.lo.y) / cell_));
        const int k = std::min(vdim_[2] - 1, static_cast<int>((p.z - vbox_.lo.z) / cell_));
        const std::size_t c = static_cast<std::size_t>(i + vdim_[0] * (j + vdim_[1] * k));
        for (int n = vstart_[c]; n < vstart_[c + 1]; ++n) {
            const Capsule& v = vessels_[static_cast<std::size_t>(vlist_[static_cast<std::size_t>(n)])];
            if (v.box.contains(p) && dist2_segment(p, v.a, v.b) <= v.r * v.r)
                return v.tissue;
        }
    }
    return TLiver;
}

void Anatomy::set_vessels(std::vector<Capsule> capsules)
{
    vessels_ = std::move(capsules);
    have_trunk_ = false;
    if (vessels_.empty())
        return;
    // The first portal capsule is the trunk from outside the liver.
    for (const auto& v : vessels_)
        if (v.tissue == TPortal) {
            portal_trunk_ = v;
            have_trunk_ = true;
            break;
        }
    vbox_ = Box{};
    for (const auto& v : vessels_)
        vbox_.add(v.box);
    for (int a = 0; a < 3; ++a)
        vdim_[static_cast<std::size_t>(a)] = std::max(1, static_cast<int>(std::ceil((vbox_.hi[a] - vbox_.lo[a]) / cell_)));
    const std::size_t ncell = static_cast<std::size_t>(vdim_[0]) * static_cast<std::size_t>(vdim_[1]) *
                              static_cast<std::size_t>(vdim_[2]);
    std::vector<std::vector<int>> cells(ncell);
    for (std::size_t n = 0; n < vessels_.size(); ++n) {
        const Box& b = vessels_[n].box;
        auto cell_range = [&](int a, double lo, double hi, int& c0, int& c1) {
            c0 = std::clamp(static_cast<int>((lo - vbox_.lo[a]) / cell_), 0, vdim_[static_cast<std::size_t>(a)] - 1);
            c1 = std::clamp(static_cast<int>((hi - vbox_.lo[a]) / cell_), 0, vdim_[static_cast<std::size_t>(a)] - 1);
        };
        int i0, i1, j0, j1, k0, k1;
        cell_range(0, b.lo.x, b.hi.x, i0, i1);
        cell_range(1, b.lo.y, b.hi.y, j0, j1);
        cell_range(2, b.lo.z, b.hi.z, k0, k1);
        for (int k = k0; k <= k1; ++k)
            for (int j = j0; j <= j1; ++j)
                for (int i = i0; i <= i1; ++i) {
                    const Vec3 clo{vbox_.lo.x + i * cell_, vbox_.lo.y + j * cell_, vbox_.lo.z + k * cell_};
                    const Vec3 cc = clo + Vec3{cell_ / 2, cell_ / 2, cell_ / 2};
                    // keep only cells the tube can reach
                    const double reach = vessels_[n].r + cell_ * 0.8661;
                    if (dist2_segment(cc, vessels_[n].a, vessels_[n].b) <= reach * reach)
                        cells[static_cast<std::size_t>(i + vdim_[0] * (j + vdim_[1] * k))].push_back(static_cast<int>(n));
                }
    }
    vstart_.assign(ncell + 1, 0);
    vlist_.clear();
    for (std::size_t c = 0; c < ncell; ++c) {
        vstart_[c] = static_cast<int>(vlist_.size());
        vlist_.insert(vlist_.end(), cells[c].begin(), cells[c].end());
    }
    vstart_[ncell] = static_cast<int>(vlist_.size());
}

// ------------------------------------------------------------------------------------------
// Vessel trees: grown once inside the analytic liver, from guided trunks, by choosing for each
// pair of children the directions that keep the most clearance from the liver surface, the
// tumours, the fissures and the other vessels. Grid- and seed-independent.

struct Segment {
    Vec3 a, b;
    double r = 0;
    int level = 1;
    VesselTree tree = VesselTree::Portal;
    int node_a = 0, node_b = 0;
    int parent = -1;
};

// The analytic liver envelope sampled on a fixed 2 mm lattice over its bounding box (grid- and
// seed-independent): the vessel planner's distance map and the liver volume both come from it.
struct EnvelopeGrid {
    static constexpr double kH = 2.0;
    Vec3 lo;
    std::array<int, 3> n{0, 0, 0};
    std::vector<std::uint8_t> in;

    explicit EnvelopeGrid(const Anatomy& an)
    {
        const Box& b = an.liver_box();
        lo = b.lo;
        for (int a = 0; a < 3; ++a)
            n[static_cast<std::size_t>(a)] = static_cast<int>(std::ceil((b.hi[a] - b.lo[a]) / kH)) + 1;
        in.assign(static_cast<std::size_t>(n[0]) * static_cast<std::size_t>(n[1]) * static_cast<std::size_t>(n[2]), 0);
        std::size_t i = 0;
        for (int z = 0; z < n[2]; ++z)
            for (int y = 0; y < n[1]; ++y)
                for (int x = 0; x < n[0]; ++x, ++i)
                    in[i] = an.liver_envelope(node(x, y, z)) ? 1 : 0;
    }
    std::size_t idx(int i, int j, int k) const
    {
        return static_cast<std::size_t>(i) +
               static_cast<std::size_t>(n[0]) * (static_cast<std::size_t>(j) + static_cast<std::size_t>(n[1]) * static_cast<std::size_t>(k));
    }
    Vec3 node(int i, int j, int k) const { return lo + Vec3{i * kH, j * kH, k * kH}; }
};

class TreePlanner {
public:
    TreePlanner(const Anatomy& anatomy, const EnvelopeGrid& envelope, const PhantomParams& params)
        : an_(anatomy), radii_(params.vessel_radius_mm)
    {
        build_depth(envelope);
    }

    int add_node(const Vec3& p, double r)
    {
        nodes_.push_back({p, r});
        return static_cast<int>(nodes_.size()) - 1;
    }
    int add_segment(int node_a, const Vec3& b, int level, VesselTree tree, int parent)
    {
        Segment s;
        s.a = nodes_[static_cast<std::size_t>(node_a)].position;
        s.b = b;
        s.r = radius(level);
        s.level = level;
        s.tree = tree;
        s.node_a = node_a;
        s.node_b = add_node(b, s.r);
        s.parent = parent;
        segs_.push_back(s);
        return static_cast<int>(segs_.size()) - 1;
    }
    double radius(int level) const { return radii_[static_cast<std::size_t>(level - 1)]; }
    int levels() const { return static_cast<int>(radii_.size()); }

    // Depth below the liver surface [mm] (negative outside), from a chamfer distance map of the
    // analytic envelope on a fixed 2 mm grid: cheap enough to score thousands of candidates.
    double depth(const Vec3& p) const
    {
        double f[3];
        int i0[3];
        for (int a = 0; a < 3; ++a) {
            const double u = (p[a] - dlo_[a]) / kH;
            if (u < 0 || u >= dn_[static_cast<std::size_t>(a)] - 1) return -1;
            i0[a] = static_cast<int>(u);
            f[a] = u - i0[a];
        }
        double acc = 0;
        for (int c = 0; c < 8; ++c) {
            const int di = c & 1, dj = (c >> 1) & 1, dk = (c >> 2) & 1;
            const double w = (di ? f[0] : 1 - f[0]) * (dj ? f[1] : 1 - f[1]) * (dk ? f[2] : 1 - f[2]);
            acc += w * static_cast<double>(dmap_[didx(i0[0] + di, i0[1] + dj, i0[2] + dk)]);
        }
        return acc - kH / 2;
    }

    // Clearance score of a candidate segment [mm]: the smallest of its depth inside the liver
    // and its distances to tumours and other vessels beyond the required margins (negative:
    // infeasible).
    double score(const Vec3& a, const Vec3& b, double r, int parent, int sibling) const
    {
        const double len = norm(b - a);
        const int n = std::max(2, static_cast<int>(std::ceil(len / 2.0)));
        const double r_parent = parent >= 0 ? segs_[static_cast<std::size_t>(parent)].r : 0.0;
        double best = 30.0;
        Box cb;
        cb.add(a);
        cb.add(b);
        cb = cb.grown(r + best + 8.0);
        for (int i = 1; i <= n; ++i) {
            const double t = double(i) / n;
            const Vec3 q = a + (b - a) * t;
            if (near_fissure(q, r + 2.0)) return -1;
            best = std::min(best, depth(q) - r - 2.0);
            if (best < 0) return -1;
            for (const auto& tum : an_.tumours())
                for (const auto& s : tum) {
                    best = std::min(best, norm(q - s.c) - s.r - r - 3.0);
                    if (best < 0) return -1;
                }
            const double along = t * len;
            for (std::size_t s = 0; s < segs_.size(); ++s) {
                const Segment& o = segs_[s];
                if (o.b.x < cb.lo.x && o.a.x < cb.lo.x) continue;
                if (o.b.x > cb.hi.x && o.a.x > cb.hi.x) continue;
                if (o.b.y < cb.lo.y && o.a.y < cb.lo.y) continue;
                if (o.b.y > cb.hi.y && o.a.y > cb.hi.y) continue;
                if (o.b.z < cb.lo.z && o.a.z < cb.lo.z) continue;
                if (o.b.z > cb.hi.z && o.a.z > cb.hi.z) continue;
                const int si = static_cast<int>(s);
                // the junction with the parent and the sibling is shared
                if ((si == parent || si == sibling) && along < r_parent + 2 * r + 6.0) continue;
                const double c = std::sqrt(dist2_segment(q, o.a, o.b)) - r - o.r - 2.0;
                best = std::min(best, c);
                if (best < 0) return -1;
            }
        }
        return best;
    }

    // Grows two children (or one) at the end of segment `si`, choosing the directions with the
    // largest clearance, so that the tree spreads through the free space.
    void branch(int si)
    {
        const Segment parent = segs_[static_cast<std::size_t>(si)];
        const int level = parent.level + 1;
        if (level > levels()) return;
        const double r = radius(level);
        const Vec3 u = normalized(parent.b - parent.a);
        Vec3 e1 = cross(u, Vec3{0, 0, 1});
        if (norm(e1) < 0.2) e1 = cross(u, Vec3{1, 0, 0});
        e1 = normalized(e1);
        const Vec3 e2 = cross(u, e1);
        const double nominal = std::max(12.0, 40.0 * std::pow(0.72, level - 2));
        static const double kAlpha[6] = {25, 35, 45, 55, 65, 80};
        static const double kSibling[5] = {180, 135, 225, 100, 260};
        static const double kLen[4] = {1.0, 0.75, 0.55, 0.4};
        auto dir = [&](double alpha, double phi) {
            const double al = alpha * kPi / 180, f = phi * kPi / 180;
            return u * std::cos(al) + (e1 * std::cos(f) + e2 * std::sin(f)) * std::sin(al);
        };
        for (double lf : kLen) {
            const double len = nominal * lf;
            double best = -1;
            Vec3 best_a, best_b;
            for (double alpha : kAlpha)
                for (int k = 0; k < 12; ++k) {
                    const double phi = 30.0 * k;
                    const Vec3 ba = parent.b + dir(alpha, phi) * len;
                    const double sa = score(parent.b, ba, r, si, -1);
                    if (sa <= best) continue;
                    // the sibling must also keep clear of the first child
                    segs_.push_back({parent.b, ba, r, level, parent.tree, 0, 0, si});
                    for (double off : kSibling)
                        for (double beta : {alpha, alpha + 10, alpha - 10}) {
                            const Vec3 bb = parent.b + dir(beta, phi + off) * len;
                            const double sb = score(parent.b, bb, r, si, static_cast<int>(segs_.size()) - 1);
                            const double s = std::min(sa, sb);
                            if (s > best) {
                                best = s;
                                best_a = ba;
                                best_b = bb;
                            }
                        }
                    segs_.pop_back();
                }
            if (best >= 0) {
                add_segment(parent.node_b, best_a, level, parent.tree, si);
                add_segment(parent.node_b, best_b, level, parent.tree, si);
                return;
            }
        }
        // No room for a pair: one child if it fits.
        for (double lf : kLen) {
            const double len = nominal * lf;
            double best = -1;
            Vec3 best_a;
            for (double alpha : kAlpha)
                for (int k = 0; k < 12; ++k) {
                    const Vec3 ba = parent.b + dir(alpha, 30.0 * k) * len;
                    const double s = score(parent.b, ba, r, si, -1);
                    if (s > best) {
                        best = s;
                        best_a = ba;
                    }
                }
            if (best >= 0) {
                add_segment(parent.node_b, best_a, level, parent.tree, si);
                return;
            }
        }
    }

    void grow()
    {
        // Portal vein: trunk from the confluence behind the pancreas to the hilum, then the
        // right and left portal veins.
        const int conf = add_node({12, 10, -62}, radius(1));
        const int trunk = add_segment(conf, {-32, -18, -2}, 1, VesselTree::Portal, -1);
        std::vector<int> frontier;
        if (levels() >= 2) {
            const int b = segs_[static_cast<std::size_t>(trunk)].node_b;
            const Vec3 bp = nodes_[static_cast<std::size_t>(b)].position;
            frontier.push_back(add_segment(b, bp + normalized(Vec3{-1, 0.05, 0.1}) * 38, 2, VesselTree::Portal, trunk));
            frontier.push_back(add_segment(b, bp + normalized(Vec3{1, -0.45, 0.45}) * 52, 2, VesselTree::Portal, trunk));
        }
        // Hepatic veins: right, middle and left trunks from the IVC.
        const Vec3 dirs[3] = {normalized(Vec3{-1, -0.2, -0.25}), normalized(Vec3{0.05, -1, -0.35}),
                              normalized(Vec3{1, -0.65, -0.15})};
        const double zs[3] = {40, 43, 38};
        const double lens[3] = {52, 50, 46};
        for (int h = 0; h < 3; ++h) {
            const int root = add_node({kIvcX, kIvcY, zs[h]}, radius(1));
            frontier.push_back(add_segment(root, Vec3{kIvcX, kIvcY, zs[h]} + dirs[h] * lens[h], 1,
                                           VesselTree::Hepatic, -1));
        }
        // Breadth first, so that the larger branches of both trees take their space first.
        while (!frontier.empty()) {
            std::vector<int> next;
            for (int s : frontier) {
                const std::size_t before = segs_.size();
                branch(s);
                for (std::size_t n = before; n < segs_.size(); ++n)
                    next.push_back(static_cast<int>(n));
            }
            frontier = std::move(next);
        }
    }

    const std::vector<Segment>& segments() const { return segs_; }
    const std::vector<VesselNode>& nodes() const { return nodes_; }

private:
    static constexpr double kH = EnvelopeGrid::kH;

    // Keep-out around the fissures at their nominal places, 6 mm either side (3 voxels of 4 mm),
    // so that the tree does not depend on the spacing.
    bool near_fissure(const Vec3& q, double m) const
    {
        for (const auto& f : an_.fissures()) {
            if (std::abs(q.x - f.x_nominal) > 6.0 + m || q.z < f.z_lo - m || q.z > f.z_hi + m) continue;
            const double zc = std::clamp(q.z, f.z_lo, f.z_hi);
            if (q.y < std::max(f.floor_at(zc - m), std::max(f.floor_at(zc), f.floor_at(zc + m))) + m) return true;
        }
        return false;
    }

    std::size_t didx(int i, int j, int k) const
    {
        return static_cast<std::size_t>(i) +
               static_cast<std::size_t>(dn_[0]) * (static_cast<std::size_t>(j) + static_cast<std::size_t>(dn_[1]) * static_cast<std::size_t>(k));
    }

    void build_depth(const EnvelopeGrid& env)
    {
        dlo_ = env.lo;
        dn_ = env.n;
        dmap_.assign(env.in.size(), 0.0f);
        for (int k = 1; k < dn_[2] - 1; ++k)
            for (int j = 1; j < dn_[1] - 1; ++j)
                for (int i = 1; i < dn_[0] - 1; ++i)
                    dmap_[didx(i, j, k)] = env.in[env.idx(i, j, k)] ? 1e6f : 0.0f;
        // Two-pass chamfer distance with the 26-neighbourhood (weights h, h*sqrt2, h*sqrt3).
        auto pass = [&](int sgn) {
            const int k0 = sgn > 0 ? 1 : dn_[2] - 2, k1 = sgn > 0 ? dn_[2] - 1 : 0;
            const int j0 = sgn > 0 ? 1 : dn_[1] - 2, j1 = sgn > 0 ? dn_[1] - 1 : 0;
            const int i0 = sgn > 0 ? 1 : dn_[0] - 2, i1 = sgn > 0 ? dn_[0] - 1 : 0;
            for (int k = k0; k != k1; k += sgn)
                for (int j = j0; j != j1; j += sgn)
                    for (int i = i0; i != i1; i += sgn) {
                        float& d = dmap_[didx(i, j, k)];
                        if (d == 0.0f) continue;
                        // the 13 neighbours already visited in this pass
                        for (int dk = -1; dk <= 0; ++dk)
                            for (int dj = -1; dj <= 1; ++dj)
                                for (int di = -1; di <= 1; ++di) {
                                    if (dk == 0 && (dj > 0 || (dj == 0 && di >= 0))) continue;
                                    const float w = static_cast<float>(kH * std::sqrt(double(di * di + dj * dj + dk * dk)));
                                    d = std::min(d, dmap_[didx(i + sgn * di, j + sgn * dj, k + sgn * dk)] + w);
                                }
                    }
        };
        pass(1);
        pass(-1);
    }

    const Anatomy& an_;
    std::vector<double> radii_;
    std::vector<Segment> segs_;
    std::vector<VesselNode> nodes_;
    Vec3 dlo_;
    std::array<int, 3> dn_{0, 0, 0};
    std::vector<float> dmap_;
};

// ------------------------------------------------------------------------------------------
// Noise: a counter-based generator (SplitMix64 of seed and voxel index) and the polar method,
// so that a voxel's noise does not depend on the order of evaluation nor on the standard
// library (std::normal_distribution differs between implementations).

std::uint64_t splitmix64(std::uint64_t x)
{
    x += 0x9E3779B97F4A7C15ULL;
    x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ULL;
    x = (x ^ (x >> 27)) * 0x94D049BB133111EBULL;
    return x ^ (x >> 31);
}

double to_unit(std::uint64_t x) // (0, 1]
{
    return (static_cast<double>(x >> 11) + 1.0) * (1.0 / 9007199254740992.0);
}

// In-place separable Gaussian along one axis, replicating the edges.
void blur_axis(std::vector<float>& v, const std::array<int, 3>& n, int axis, double sigma_vox)
{
    const int radius = static_cast<int>(std::ceil(3.0 * sigma_vox));
    if (radius < 1 || sigma_vox <= 0)
        return;
    std::vector<float> w(static_cast<std::size_t>(2 * radius + 1));
    double sum = 0;
    for (int i = -radius; i <= radius; ++i) {
        const double x = i / sigma_vox;
        w[static_cast<std::size_t>(i + radius)] = static_cast<float>(std::exp(-0.5 * x * x));
        sum += static_cast<double>(w[static_cast<std::size_t>(i + radius)]);
    }
    for (auto& x : w)
        x = static_cast<float>(static_cast<double>(x) / sum);
    const std::size_t nx = static_cast<std::size_t>(n[0]), ny = static_cast<std::size_t>(n[1]), nz = static_cast<std::size_t>(n[2]);
    const std::size_t r = static_cast<std::size_t>(radius);
    if (axis == 0) {
        std::vector<float> line(nx + 2 * r);
        for (std::size_t start = 0; start < v.size(); start += nx) {
            std::copy(v.begin() + static_cast<std::ptrdiff_t>(start), v.begin() + static_cast<std::ptrdiff_t>(start + nx), line.begin() + static_cast<std::ptrdiff_t>(r));
            for (std::size_t i = 0; i < r; ++i) {
                line[i] = line[r];
                line[nx + r + i] = line[nx + r - 1];
            }
            for (std::size_t i = 0; i < nx; ++i) {
                float acc = 0;
                for (std::size_t t = 0; t < w.size(); ++t)
                    acc += w[t] * line[i + t];
                v[start + i] = acc;
            }
        }
        return;
    }
    // y and z: whole rows of x at a time, so that the inner loop is contiguous (and vectorised).
    // The volume is [outer][len][inner] with inner contiguous; work on chunks of inner.
    const std::size_t outer = axis == 1 ? nz : 1, len = axis == 1 ? ny : nz, inner = axis == 1 ? nx : nx * ny;
    const std::size_t chunk = std::min<std::size_t>(inner, 4096);
    std::vector<float> tmp(len * chunk);
    for (std::size_t o = 0; o < outer; ++o)
        for (std::size_t c0 = 0; c0 < inner; c0 += chunk) {
            const std::size_t cn = std::min(chunk, inner - c0);
            float* base = v.data() + o * len * inner + c0;
            for (std::size_t l = 0; l < len; ++l)
                std::copy(base + l * inner, base + l * inner + cn, tmp.data() + l * chunk);
            for (std::size_t l = 0; l < len; ++l) {
                float* out = base + l * inner;
                std::fill(out, out + cn, 0.0f);
                for (std::size_t t = 0; t < w.size(); ++t) {
                    const long src_l = std::clamp(static_cast<long>(l + t) - static_cast<long>(r), 0L, static_cast<long>(len) - 1);
                    const float* src = tmp.data() + static_cast<std::size_t>(src_l) * chunk;
                    const float wt = w[t];
                    for (std::size_t i = 0; i < cn; ++i)
                        out[i] += wt * src[i];
                }
            }
        }
}

std::string fmt(double v)
{
    std::ostringstream s;
    s << v;
    return s.str();
}

} // namespace

// ------------------------------------------------------------------------------------------

const std::vector<LabelInfo>& label_table()
{
    static const std::vector<LabelInfo> table = {
        {kBackground, "background", "outside the body (air)"},
        {kLiver, "liver", "liver parenchyma"},
        {kPortalVein, "portal_vein", "portal vein inside the liver"},
        {kHepaticVein, "hepatic_veins", "hepatic veins"},
        {kTumour, "tumour", "liver tumours (lobular, satellite, boundary)"},
        {kSoftTissue, "soft_tissue", "skin, wall and back muscles, diaphragm, psoas, bowel, pancreas"},
        {kFat, "fat", "subcutaneous and intra-abdominal fat, fissures, IVC neck, renal sinus"},
        {kBone, "bone", "ribs (cortex, marrow) and costal cartilage"},
        {kHeart, "heart", "heart wall: myocardium and the pericardial line touching the liver"},
        {kRightKidney, "right_kidney", "right kidney and its capsule line touching the liver"},
        {kIvc, "ivc", "inferior vena cava"},
        {kLungs, "lungs", "lungs"},
        {kSpleen, "spleen", "spleen"},
        {kAorta, "aorta", "aorta"},
        {kSpine, "spine", "vertebrae, discs and spinal canal"},
        {kSubcostal, "subcostal", "subcostal tissue: inner wall layer between ribs and organs"},
        {kLeftKidney, "left_kidney", "left kidney"},
        {kStomach, "stomach", "stomach wall, fluid and gas"},
        {kGallbladder, "gallbladder", "gallbladder (bile)"},
        {kPortalVeinExtra, "portal_vein_extrahepatic", "portal vein trunk outside the liver"},
        {kHeartBlood, "heart_blood", "heart chambers (blood pool)"},
        {kMediastinum, "mediastinum", "mediastinal fat between the lungs"},
    };
    return table;
}

const Landmark& PhantomTruth::landmark(const std::string& name) const
{
    for (const auto& l : landmarks)
        if (l.name == name)
            return l;
    throw core::InvalidInputError("phantom truth: no landmark called '" + name + "'");
}

core::ImageGeometry phantom_geometry(const PhantomParams& params)
{
    core::ImageGeometry g;
    g.size = params.size;
    g.spacing = params.spacing;
    for (std::size_t a = 0; a < 3; ++a)
        g.origin[a] = params.center[a] - 0.5 * (params.size[a] - 1) * params.spacing[a];
    return g;
}

std::array<int, 3> size_for_spacing(const std::array<double, 3>& spacing)
{
    const std::array<double, 3> fov{512 * 0.7, 512 * 0.7, 80 * 2.5};
    std::array<int, 3> s{};
    for (std::size_t a = 0; a < 3; ++a)
        s[a] = spacing[a] > 0 ? std::max(1, static_cast<int>(std::ceil(fov[a] / spacing[a] - 1e-9))) : 0;
    return s;
}

std::string params_problem(const PhantomParams& p)
{
    const char* axis[3] = {"x", "y", "z"};
    for (std::size_t a = 0; a < 3; ++a) {
        if (!std::isfinite(p.spacing[a]) || !(p.spacing[a] > 0))
            return std::string("spacing along ") + axis[a] + " is " + fmt(p.spacing[a]) + " mm (must be finite and positive)";
        if (p.spacing[a] > 50)
            return std::string("spacing along ") + axis[a] + " is " + fmt(p.spacing[a]) + " mm (at most 50 mm)";
        if (!std::isfinite(p.center[a]))
            return "the grid centre is not finite";
    }
    for (std::size_t a = 0; a < 3; ++a)
        if (p.size[a] <= 0)
            return std::string("size along ") + axis[a] + " is " + std::to_string(p.size[a]) + " (must be positive)";
    const double voxels = double(p.size[0]) * double(p.size[1]) * double(p.size[2]);
    if (voxels > double(1 << 29))
        return "the grid has " + fmt(voxels) + " voxels (at most 2^29 = 536870912)";
    if (!std::isfinite(p.noise_sigma_hu) || p.noise_sigma_hu < 0)
        return "noise sigma is " + fmt(p.noise_sigma_hu) + " HU (must be >= 0)";
    if (!std::isfinite(p.blur_sigma_mm) || p.blur_sigma_mm < 0 || p.blur_sigma_mm > 20)
        return "blur sigma is " + fmt(p.blur_sigma_mm) + " mm (must be in [0, 20])";
    if (!std::isfinite(p.supersample_mm) || !(p.supersample_mm > 0.05))
        return "supersample step is " + fmt(p.supersample_mm) + " mm (must be > 0.05)";
    if (p.fissure_width_voxels < 0 || p.fissure_width_voxels > 8)
        return "fissure width is " + std::to_string(p.fissure_width_voxels) + " voxels (must be in [0, 8])";
    if (p.odd_fissure_width_voxels < 0 || p.odd_fissure_width_voxels > 8)
        return "odd fissure width is " + std::to_string(p.odd_fissure_width_voxels) + " voxels (must be in [0, 8])";
    if (p.vessels) {
        if (p.vessel_radius_mm.empty() || p.vessel_radius_mm.size() > 8)
            return "between 1 and 8 vessel radii are needed";
        for (std::size_t i = 0; i < p.vessel_radius_mm.size(); ++i) {
            const double r = p.vessel_radius_mm[i];
            if (!std::isfinite(r) || r < 0.3 || r > 8)
                return "vessel radius of level " + std::to_string(i + 1) + " is " + fmt(r) + " mm (must be in [0.3, 8])";
            if (i > 0 && !(r < p.vessel_radius_mm[i - 1]))
                return "vessel radii must decrease with the branch level";
        }
    }
    if (!std::isfinite(p.contact_line_mm) || p.contact_line_mm < 0 || p.contact_line_mm > 5)
        return "contact line is " + fmt(p.contact_line_mm) + " mm (must be in [0, 5])";
    for (double c : p.tumour_contrast_hu)
        if (!std::isfinite(c) || std::abs(c) > 500)
            return "tumour contrast " + fmt(c) + " HU is out of range";
    return {};
}

PhantomResult generate_phantom(const PhantomParams& params)
{
    const std::string problem = params_problem(params);
    if (!problem.empty())
        throw core::InvalidInputError("phantom: " + problem);

    using clock = std::chrono::steady_clock;
    PhantomResult res;
    auto t0 = clock::now();
    auto lap = [&](const std::string& name) {
        const auto t1 = clock::now();
        res.timings.emplace_back(name, std::chrono::duration<double>(t1 - t0).count());
        t0 = t1;
    };

    const core::ImageGeometry g = phantom_geometry(params);
    Anatomy an(params, g);

    const EnvelopeGrid env(an);
    lap("liver envelope");

    // Vessel trees.
    std::vector<Segment> segs;
    if (params.vessels) {
        TreePlanner planner(an, env, params);
        planner.grow();
        segs = planner.segments();
        res.truth.vessel_nodes = planner.nodes();
        std::vector<Capsule> caps;
        for (const auto& s : segs) {
            Capsule c{s.a, s.b, s.r, s.tree == VesselTree::Portal ? TPortal : THepatic, {}};
            c.box.add(s.a);
            c.box.add(s.b);
            c.box = c.box.grown(s.r);
            caps.push_back(c);
        }
        an.set_vessels(std::move(caps));
    }
    lap("vessel trees");

    // Tissues at the voxel centres.
    const int nx = g.size[0], ny = g.size[1], nz = g.size[2];
    const std::size_t n = g.voxel_count();
    std::vector<std::uint8_t> tissue(n);
    {
        std::size_t idx = 0;
        for (int k = 0; k < nz; ++k) {
            const double z = g.origin[2] + k * g.spacing[2];
            for (int j = 0; j < ny; ++j) {
                const double y = g.origin[1] + j * g.spacing[1];
                for (int i = 0; i < nx; ++i, ++idx)
                    tissue[idx] = an.classify({g.origin[0] + i * g.spacing[0], y, z});
            }
        }
    }
    lap("classify");

    res.labels = core::LabelImage3D(g);
    for (std::size_t i = 0; i < n; ++i)
        res.labels.data[i] = kTissues[tissue[i]].label;

    // HU of each tissue.
    std::array<float, TCount> hu{};
    for (int t = 0; t < TCount; ++t)
        hu[static_cast<std::size_t>(t)] = static_cast<float>(params.hu.*(kTissues[t].hu));
    for (int t = 0; t < 3; ++t)
        hu[static_cast<std::size_t>(TTumour0 + t)] = static_cast<float>(params.hu.liver + params.tumour_contrast_hu[static_cast<std::size_t>(t)]);

    // Partial volume: voxels next to another tissue average sub-samples over their footprint,
    // an odd number per axis (the centre is the label's sample), at most 27 in all so that
    // coarse grids stay fast.
    std::array<int, 3> ns{};
    for (std::size_t a = 0; a < 3; ++a)
        ns[a] = 2 * static_cast<int>(std::floor(params.spacing[a] / (2.0 * params.supersample_mm))) + 1;
    while (ns[0] * ns[1] * ns[2] > 27) {
        auto& m = *std::max_element(ns.begin(), ns.end());
        m -= 2;
    }
    std::vector<float> v(n);
    {
        const std::size_t sx = 1, sy = static_cast<std::size_t>(nx), sz = static_cast<std::size_t>(nx) * static_cast<std::size_t>(ny);
        const int nsub = ns[0] * ns[1] * ns[2];
        std::size_t idx = 0;
        for (int k = 0; k < nz; ++k)
            for (int j = 0; j < ny; ++j)
                for (int i = 0; i < nx; ++i, ++idx) {
                    const std::uint8_t t = tissue[idx];
                    const bool edge = (i > 0 && tissue[idx - sx] != t) || (i + 1 < nx && tissue[idx + sx] != t) ||
                                      (j > 0 && tissue[idx - sy] != t) || (j + 1 < ny && tissue[idx + sy] != t) ||
                                      (k > 0 && tissue[idx - sz] != t) || (k + 1 < nz && tissue[idx + sz] != t);
                    if (!edge || nsub == 1) {
                        v[idx] = hu[t];
                        continue;
                    }
                    double acc = 0;
                    for (int c = 0; c < ns[2]; ++c) {
                        const double z = g.origin[2] + (k + (c + 0.5) / ns[2] - 0.5) * g.spacing[2];
                        for (int b = 0; b < ns[1]; ++b) {
                            const double y = g.origin[1] + (j + (b + 0.5) / ns[1] - 0.5) * g.spacing[1];
                            for (int a = 0; a < ns[0]; ++a) {
                                const bool centre = 2 * a + 1 == ns[0] && 2 * b + 1 == ns[1] && 2 * c + 1 == ns[2];
                                const double x = g.origin[0] + (i + (a + 0.5) / ns[0] - 0.5) * g.spacing[0];
                                acc += static_cast<double>(hu[centre ? static_cast<Tissue>(t) : an.classify({x, y, z})]);
                            }
                        }
                    }
                    v[idx] = static_cast<float>(acc / nsub);
                }
    }
    lap("partial volume");

    if (params.blur_sigma_mm > 0)
        for (int a = 0; a < 3; ++a)
            blur_axis(v, g.size, a, params.blur_sigma_mm / params.spacing[static_cast<std::size_t>(a)]);
    lap("blur");

    res.ct = core::Image3D<std::int16_t>(g);
    {
        const double sigma = params.noise_sigma_hu;
        const std::uint64_t key = splitmix64(params.seed ^ 0x6C6F6265ULL); // "lobe"
        for (std::size_t i = 0; i < n; i += 2) {
            double n0 = 0, n1 = 0;
            if (sigma > 0) {
                // Marsaglia's polar method: a pair of normals without trigonometry; rejected
                // points draw again from the same voxel's hash chain.
                std::uint64_t h = key ^ (i * 0x9E3779B97F4A7C15ULL);
                double a, b, q;
                do {
                    h = splitmix64(h);
                    a = 2.0 * to_unit(h) - 1.0;
                    h = splitmix64(h);
                    b = 2.0 * to_unit(h) - 1.0;
                    q = a * a + b * b;
                } while (q >= 1.0 || q == 0.0);
                const double f = sigma * std::sqrt(-2.0 * std::log(q) / q);
                n0 = a * f;
                n1 = b * f;
            }
            auto put = [&](std::size_t at, double noise) {
                const double x = std::nearbyint(static_cast<double>(v[at]) + noise);
                res.ct.data[at] = static_cast<std::int16_t>(std::clamp(x, -1024.0, 3071.0));
            };
            put(i, n0);
            if (i + 1 < n) put(i + 1, n1);
        }
    }
    lap("noise");

    // Ground truth.
    PhantomTruth& tr = res.truth;
    for (const auto& s : segs) {
        VesselEdge e;
        e.from = s.node_a;
        e.to = s.node_b;
        e.level = s.level;
        e.tree = s.tree;
        e.radius_mm = s.r;
        e.length_mm = norm(s.b - s.a);
        int inside = 0;
        const int m = 50;
        for (int i = 0; i <= m; ++i)
            inside += an.liver_envelope(s.a + (s.b - s.a) * (double(i) / m)) ? 1 : 0;
        e.inside_liver = double(inside) / (m + 1);
        tr.vessel_edges.push_back(e);
    }

    // Liver volume: midpoint quadrature of the analytic envelope on its 2 mm lattice (random
    // error about 0.4 mL, thin features quantised to 2 mm: about 1 mL), minus the fissure slabs
    // computed on their own finer grid.
    Vec3 centroid{}, dome{0, 0, -1e9};
    {
        const double h = EnvelopeGrid::kH;
        const Box& b = an.liver_box();
        double count = 0;
        for (int k = 0; k < env.n[2]; ++k)
            for (int j = 0; j < env.n[1]; ++j)
                for (int i = 0; i < env.n[0]; ++i)
                    if (env.in[env.idx(i, j, k)]) {
                        const Vec3 p = env.node(i, j, k);
                        count += 1;
                        centroid += p;
                        if (p.z > dome.z) dome = p;
                    }
        centroid /= std::max(count, 1.0);
        double vol = count * h * h * h;
        for (const auto& f : an.fissures()) {
            const double hy = 0.25, hz = 0.25;
            const int nxs = 4;
            const double hx = (f.x1 - f.x0) / nxs;
            double c = 0;
            for (double z = f.z_lo + hz / 2; z < f.z_hi; z += hz)
                for (double y = std::max(f.y_lo, b.lo.y) + hy / 2; y < f.y_max; y += hy)
                    for (int a = 0; a < nxs; ++a)
                        if (y < f.floor_at(z) && an.liver_envelope({f.x0 + (a + 0.5) * hx, y, z})) c += 1;
            vol -= c * hx * hy * hz;
        }
        tr.liver_volume_ml = vol / 1000.0;
    }

    // Tumours: volume and centroid by quadrature at 0.5 mm (error far below 0.1 mL).
    static const char* kNames[3] = {"lobular", "satellite", "boundary"};
    for (std::size_t t = 0; t < an.tumours().size(); ++t) {
        Box b;
        for (const auto& s : an.tumours()[t]) {
            b.add(s.c - Vec3{s.r, s.r, s.r});
            b.add(s.c + Vec3{s.r, s.r, s.r});
        }
        const double h = 0.5;
        double count = 0;
        Vec3 c{};
        bool touches = false;
        for (double z = b.lo.z + h / 2; z < b.hi.z; z += h)
            for (double y = b.lo.y + h / 2; y < b.hi.y; y += h)
                for (double x = b.lo.x + h / 2; x < b.hi.x; x += h) {
                    int which = -1;
                    const Vec3 p{x, y, z};
                    if (!an.in_tumour(p, &which) || which != static_cast<int>(t)) continue;
                    if (!an.liver_envelope(p)) {
                        touches = true;
                        continue;
                    }
                    count += 1;
                    c += p;
                }
        TumourTruth tt;
        tt.name = kNames[t];
        tt.centroid = c / std::max(count, 1.0);
        tt.volume_ml = count * h * h * h / 1000.0;
        tt.equivalent_radius_mm = std::cbrt(3.0 * tt.volume_ml * 1000.0 / (4.0 * kPi));
        tt.contrast_hu = params.tumour_contrast_hu[t];
        tt.touches_boundary = touches;
        tr.tumours.push_back(tt);
    }

    // Contacts with heart and right kidney: centroids of heart/kidney points with liver 2 mm away.
    auto contact_centroid = [&](const Ellipsoid& e, Tissue a, Tissue line) {
        const double h = 1.5;
        Box b = e.box;
        Vec3 c{};
        double count = 0;
        static const Vec3 kDirs[6] = {{2, 0, 0}, {-2, 0, 0}, {0, 2, 0}, {0, -2, 0}, {0, 0, 2}, {0, 0, -2}};
        for (double z = b.lo.z; z < b.hi.z; z += h)
            for (double y = b.lo.y; y < b.hi.y; y += h)
                for (double x = b.lo.x; x < b.hi.x; x += h) {
                    const Vec3 p{x, y, z};
                    if (!an.liver_box().contains(p)) continue;
                    if (e.sdf(p) < -3.0) continue; // only near the organ's surface
                    const Tissue t = an.outer(p, false);
                    if (t != a && t != line) continue;
                    for (const auto& d : kDirs)
                        if (an.liver_envelope(p + d)) {
                            c += p;
                            count += 1;
                            break;
                        }
                }
        return count > 0 ? c / count : e.c;
    };

    auto add_landmark = [&](const std::string& name, const std::string& desc, const Vec3& p) {
        Landmark l;
        l.name = name;
        l.description = desc;
        l.position = p;
        const Vec3 ijk = g.physical_to_index(p);
        for (int a = 0; a < 3; ++a)
            l.index[static_cast<std::size_t>(a)] = static_cast<int>(std::lround(ijk[a]));
        tr.landmarks.push_back(l);
    };
    const Vec3 heart_c = contact_centroid(an.heart(), THeartWall, THeartLine);
    const Vec3 kidney_c = contact_centroid(an.kidney_r(), TKidneyR, TKidneyRLine);
    add_landmark("liver_centroid", "centroid of the liver", centroid);
    add_landmark("liver_dome", "highest point of the liver, under the right dome of the diaphragm", dome);
    add_landmark("heart_lungs", "above the liver: the heart between both lungs (the thesis's start slice)",
                 {0, 0, dome.z + 12});
    add_landmark("heart_liver_contact", "heart wall touching the liver dome, a thin line between them", heart_c);
    add_landmark("kidney_liver_contact", "right kidney touching the liver's posterior-inferior surface", kidney_c);
    add_landmark("ivc_omega", "IVC deep in the liver's back surface behind a narrow neck (Omega concavity)",
                 {kIvcX, kIvcY, 20});
    if (!an.fissures().empty()) {
        const auto& f = an.fissures()[0];
        const double zm = (f.z_lo + f.z_hi) / 2;
        add_landmark("even_fissure", "thin fissure of even width (" + std::to_string(params.fissure_width_voxels) +
                     " voxels) from the anterior surface", {(f.x0 + f.x1) / 2, f.floor_at(zm) - 10, zm});
        tr.fissure_width_mm = f.x1 - f.x0;
    }
    if (an.fissures().size() > 1) {
        const auto& f = an.fissures()[1];
        const double zm = (f.z_lo + f.z_hi) / 2;
        add_landmark("odd_fissure", "thin fissure of odd width (" + std::to_string(params.odd_fissure_width_voxels) +
                     " voxels) from the anterior surface", {(f.x0 + f.x1) / 2, f.floor_at(zm) - 10, zm});
        tr.odd_fissure_width_mm = f.x1 - f.x0;
    }
    for (const auto& t : tr.tumours)
        add_landmark("tumour_" + t.name, t.name + " tumour", t.centroid);
    if (!segs.empty()) {
        add_landmark("portal_bifurcation", "portal vein splits into right and left branches", segs[0].b);
        add_landmark("hepatic_confluence", "hepatic veins join the IVC", {kIvcX, kIvcY, 43});
    }
    add_landmark("ribs_subcostal", "ribs and subcostal tissue next to the liver's lateral surface", {-128, -10, 0});
    tr.ivc_neck_width_mm = kNeckWidth;
    tr.ivc_body_width_mm = 2 * kIvcRx;
    lap("ground truth");
    return res;
}

core::CentrelineGraph truth_graph(const PhantomTruth& truth)
{
    core::CentrelineGraph g;
    for (const auto& n : truth.vessel_nodes)
        g.nodes.push_back({n.position, n.radius_mm});
    for (const auto& e : truth.vessel_edges) {
        core::CentrelineEdge ce;
        ce.from = e.from;
        ce.to = e.to;
        ce.level = e.level;
        ce.label = e.tree == VesselTree::Portal ? kPortalVein : kHepaticVein;
        ce.radius_mm = e.radius_mm;
        ce.length_mm = e.length_mm;
        ce.points = {truth.vessel_nodes[static_cast<std::size_t>(e.from)].position,
                     truth.vessel_nodes[static_cast<std::size_t>(e.to)].position};
        ce.point_radius = {e.radius_mm, e.radius_mm};
        g.edges.push_back(std::move(ce));
    }
    return g;
}

std::size_t add_vessel_gap(PhantomResult& ph, const PhantomParams& params, int edge, double start_mm, double length_mm,
                           double contrast_fraction)
{
    if (edge < 0 || edge >= static_cast<int>(ph.truth.vessel_edges.size()))
        throw core::InvalidInputError("add_vessel_gap: no vessel edge " + std::to_string(edge));
    if (!(contrast_fraction >= 0 && contrast_fraction <= 1))
        throw core::InvalidInputError("add_vessel_gap: the contrast fraction must be in [0, 1]");
    const VesselEdge& e = ph.truth.vessel_edges[static_cast<std::size_t>(edge)];
    const Vec3 a = ph.truth.vessel_nodes[static_cast<std::size_t>(e.from)].position;
    const Vec3 b = ph.truth.vessel_nodes[static_cast<std::size_t>(e.to)].position;
    const Vec3 axis = normalized(b - a);
    const double vessel_hu = e.tree == VesselTree::Portal ? params.hu.portal_vein : params.hu.hepatic_vein;
    const double drop = (1 - contrast_fraction) * (vessel_hu - params.hu.liver);
    const Vec3 lo_p = a + axis * start_mm, hi_p = a + axis * (start_mm + length_mm);
    const double reach = e.radius_mm + 1.0;
    const core::ImageGeometry& g = ph.ct;
    std::array<int, 3> lo{}, hi{};
    for (int d = 0; d < 3; ++d) {
        const Vec3 c0 = g.physical_to_index(lo_p), c1 = g.physical_to_index(hi_p);
        lo[static_cast<std::size_t>(d)] = std::max(0, static_cast<int>(std::floor(std::min(c0[d], c1[d]) - reach / g.spacing[static_cast<std::size_t>(d)] - 1)));
        hi[static_cast<std::size_t>(d)] = std::min(g.size[static_cast<std::size_t>(d)] - 1,
                                                   static_cast<int>(std::ceil(std::max(c0[d], c1[d]) + reach / g.spacing[static_cast<std::size_t>(d)] + 1)));
    }
    std::size_t changed = 0;
    for (int k = lo[2]; k <= hi[2]; ++k)
        for (int j = lo[1]; j <= hi[1]; ++j)
            for (int i = lo[0]; i <= hi[0]; ++i) {
                const Vec3 p = g.index_to_physical(i, j, k);
                const double t = dot(p - a, axis);
                if (t < start_mm || t > start_mm + length_mm)
                    continue;
                const double d = norm(p - (a + axis * t));
                // full drop inside the tube, fading over the partial-volume rim
                const double w = std::clamp((e.radius_mm + 0.5 - d) / 1.0, 0.0, 1.0);
                if (w <= 0)
                    continue;
                auto& v = ph.ct.at(i, j, k);
                v = static_cast<std::int16_t>(std::lround(std::clamp(v - w * drop, -1024.0, 3071.0)));
                ++changed;
            }
    return changed;
}

core::ImageF t1_weighted(const core::ImageF& hu)
{
    static const std::array<std::pair<float, float>, 8> knots = {{{-1000.f, 0.f},
                                                                  {-800.f, 10.f},
                                                                  {-100.f, 450.f},
                                                                  {10.f, 40.f},
                                                                  {50.f, 55.f},
                                                                  {105.f, 100.f},
                                                                  {160.f, 50.f},
                                                                  {600.f, 20.f}}};
    core::ImageF out = hu;
    for (float& v : out.data) {
        const float h = std::clamp(v, knots.front().first, knots.back().first);
        std::size_t i = 1;
        while (i + 1 < knots.size() && h > knots[i].first)
            ++i;
        const auto [x0, y0] = knots[i - 1];
        const auto [x1, y1] = knots[i];
        v = y0 + (y1 - y0) * (h - x0) / (x1 - x0);
    }
    return out;
}

} // namespace lobe::phantom
