// Narrow-band level-set evolution (thesis §4.11-4.12, eq. 4.29-4.32). Design, sign conventions,
// band and re-initialisation policy, time step and convergence test: docs/algorithms/level_set.md.
#include "lobe/seg/level_set.h"

#include "lobe/seg/distance_transform.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

namespace lobe::seg {
namespace {

using core::ImageF;
using core::InvalidInputError;
using Index = std::int64_t;

// Per-voxel flag bits of the working grid.
constexpr std::uint8_t kInBand = 1;     // the voxel is in the current band
constexpr std::uint8_t kSnapInside = 2; // inside at the voxel's last convergence accounting

// A stationary front keeps steepening φ (the pressure keeps pushing on both sides of it), so φ is
// also re-initialised at this period, not only when the front nears the band edge.
constexpr int kReinitPeriod = 50;

// Below this |∇φ|^2 the curvature is undefined (flat φ, e.g. the centre of a tiny blob): no term.
constexpr double kMinGrad2 = 1e-12;

double sq(double v) { return v * v; }

struct Grid {
    std::array<int, 3> n{};
    std::array<Index, 3> stride{};
    std::array<double, 3> h{};
    std::array<bool, 3> active{}; // axes with more than one voxel (z is inactive on a 2-D slice)
    int dims = 0;
    double hmin = 0, hmax = 0;
    std::size_t count = 0;
};

Grid make_grid(const core::ImageGeometry& geo)
{
    Grid g;
    g.count = geo.voxel_count();
    for (int a = 0; a < 3; ++a) {
        const auto ua = static_cast<std::size_t>(a);
        g.n[ua] = geo.size[ua];
        g.h[ua] = geo.spacing[ua];
        g.active[ua] = geo.size[ua] > 1;
    }
    g.stride = {1, g.n[0], Index{g.n[0]} * g.n[1]};
    g.hmin = std::numeric_limits<double>::infinity();
    for (std::size_t a = 0; a < 3; ++a)
        if (g.active[a]) {
            ++g.dims;
            g.hmin = std::min(g.hmin, g.h[a]);
            g.hmax = std::max(g.hmax, g.h[a]);
        }
    if (g.dims == 0) // a single voxel: nothing can move, but keep the numbers finite
        g.hmin = g.hmax = *std::max_element(g.h.begin(), g.h.end());
    return g;
}

struct BandVoxel {
    Index idx;
    std::int32_t i, j, k;
    bool edge; // has a face neighbour outside the band: the front near it triggers re-initialisation
};

// ---------------------------------------------------------------------------- validation

void check_image(const ImageF& img, const core::ImageGeometry& grid, const std::string& what, bool nonnegative)
{
    if (!core::same_grid(img.geometry(), grid) || img.data.size() != grid.voxel_count())
        throw InvalidInputError("evolve_level_set: " + what + " is not on the level set's grid");
    const float* d = img.data.data();
    const auto n = static_cast<Index>(img.data.size());
    bool bad = false, negative = false;
#pragma omp parallel for schedule(static) reduction(|| : bad, negative)
    for (Index v = 0; v < n; ++v) {
        bad = bad || !std::isfinite(d[v]);
        negative = negative || d[v] < 0.f;
    }
    if (bad)
        throw InvalidInputError("evolve_level_set: " + what + " has non-finite values");
    if (nonnegative && negative)
        throw InvalidInputError("evolve_level_set: " + what + " has negative values (it must be >= 0)");
}

void check_params(const LevelSetParams& p)
{
    auto fail = [](const std::string& m) { throw InvalidInputError("evolve_level_set: " + m); };
    if (p.band_voxels < 2)
        fail("band_voxels must be at least 2, is " + std::to_string(p.band_voxels));
    if (!(p.cfl > 0.0 && p.cfl <= 1.0))
        fail("cfl must be in (0, 1], is " + std::to_string(p.cfl));
    if (p.max_iterations < 0)
        fail("max_iterations must not be negative");
    if (p.check_interval < 1 || p.convergence_checks < 1)
        fail("check_interval and convergence_checks must be at least 1");
    if (!(p.convergence_tolerance >= 0.0) || !std::isfinite(p.convergence_tolerance))
        fail("convergence_tolerance must be finite and >= 0");
}

// ---------------------------------------------------------------------------- the evolution

class Evolver {
public:
    Evolver(ImageF& phi, const SpeedTerms& terms, const LevelSetParams& params)
        : g_(make_grid(phi.geometry())), phi_(phi.data.data()), params_(params),
          width_(params.band_voxels * g_.hmax), flags_(g_.count, 0), slot_(g_.count, -1)
    {
        eps_ = terms.curvature_weight;
        curv_ = eps_ > 0.0;
        stop_ = terms.stopping ? terms.stopping->data.data() : nullptr;
        press_ = terms.pressure ? terms.pressure->data.data() : nullptr;
        if (terms.advection)
            for (std::size_t a = 0; a < 3; ++a)
                adv_[a] = g_.active[a] ? terms.advection->c[a].data.data() : nullptr;
        has_adv_ = adv_[0] || adv_[1] || adv_[2];
        for (std::size_t a = 0; a < 3; ++a)
            ih_[a] = 1.0 / g_.h[a];
        kappa_max_ = g_.dims / g_.hmin;
        dt_ = time_step();
    }

    double dt() const { return dt_; }

    //! Rebuilds the band around the zero level set of the current φ (sub-voxel redistancing);
    //! false if there is no front (no sign change anywhere).
    bool redistance(bool initial);

    //! One explicit step over the band; returns false if the front vanished or filled the grid.
    bool step(bool& near_edge);

    //! The convergence measure over the interval since the previous check.
    double check();

private:
    double time_step() const;
    template <bool k3D>
    float updated(const BandVoxel& bv) const;
    bool interface_site(Index v, int i, int j, int k);
    void account(Index v)
    {
        const bool in = phi_[v] < 0.f;
        if (in != ((flags_[static_cast<std::size_t>(v)] & kSnapInside) != 0)) {
            ++pending_changes_;
            flags_[static_cast<std::size_t>(v)] ^= kSnapInside;
        }
    }
    bool any_sign(bool inside) const;

    struct Site {
        Index idx;
        std::int32_t i, j, k;
        bool inside;
        double d;                   // distance to the zero level set [mm]
        std::array<double, 3> foot; // nearest point found on the zero level set [mm, index-aligned]
    };

    Grid g_;
    float* phi_;
    LevelSetParams params_;
    double width_; // band half-width W [mm]
    double eps_ = 0.0;
    bool curv_ = false, has_adv_ = false;
    const float* stop_ = nullptr;
    const float* press_ = nullptr;
    std::array<const float*, 3> adv_{nullptr, nullptr, nullptr};
    std::array<double, 3> ih_{};
    double kappa_max_ = 0.0;
    double dt_ = 0.0;

    std::vector<std::uint8_t> flags_;
    std::vector<std::int32_t> slot_; // voxel -> index in sites_ during redistancing; -1 none, -2 queued
    std::vector<Site> sites_;
    std::vector<BandVoxel> band_;
    std::vector<float> next_;
    Index pending_changes_ = 0; // status changes of voxels that left the band since the last check
};

// Δt = cfl / max over the grid of the sum of the terms' explicit stability rates: advection
// Σ|V_a|/h_a, pressure |P| sqrt(Σ 1/h_a^2) (the Godunov Hamiltonian's Lipschitz bound), curvature
// 4 ε g Σ 1/h_a^2 (i.e. Δt ε g Σ 2/h_a^2 <= 1/2). Computed once: the terms are static (L3774).
double Evolver::time_step() const
{
    double inv_h2 = 0;
    for (std::size_t a = 0; a < 3; ++a)
        if (g_.active[a])
            inv_h2 += ih_[a] * ih_[a];
    const double press_rate = std::sqrt(inv_h2);
    const double curv_rate = 4.0 * eps_ * inv_h2;
    const auto n = static_cast<Index>(g_.count);
    double worst = 0.0;
#pragma omp parallel for schedule(static) reduction(max : worst)
    for (Index v = 0; v < n; ++v) {
        double r = 0.0;
        if (curv_)
            r += curv_rate * (stop_ ? double(stop_[v]) : 1.0);
        if (press_)
            r += press_rate * std::abs(double(press_[v]));
        for (std::size_t a = 0; a < 3; ++a)
            if (adv_[a])
                r += std::abs(double(adv_[a][v])) * ih_[a];
        worst = std::max(worst, r);
    }
    // No term moves anything: any Δt will do, the run converges at its first checks.
    return worst > 0.0 ? params_.cfl / worst : params_.cfl * g_.hmin;
}

// One voxel of eq. 4.29: φ + Δt (ε g κ|∇φ| - P|∇φ|_Godunov - V·∇φ_upwind). The grid border
// replicates the edge voxel (zero normal derivative), so a front may touch the border.
template <bool k3D>
float Evolver::updated(const BandVoxel& bv) const
{
    const float* phi = phi_;
    const Index v = bv.idx;
    auto p = [phi, v](Index off) { return double(phi[v + off]); };
    const Index sy = g_.stride[1], sz = g_.stride[2];
    const Index xm = bv.i > 0 ? -1 : 0, xp = bv.i < g_.n[0] - 1 ? 1 : 0;
    const Index ym = bv.j > 0 ? -sy : 0, yp = bv.j < g_.n[1] - 1 ? sy : 0;
    Index zm = 0, zp = 0;
    if constexpr (k3D) {
        zm = bv.k > 0 ? -sz : 0;
        zp = bv.k < g_.n[2] - 1 ? sz : 0;
    }
    const double ihx = ih_[0], ihy = ih_[1], ihz = ih_[2];
    const double c = p(0);
    const double fxm = p(xm), fxp = p(xp), fym = p(ym), fyp = p(yp);
    const double dmx = (c - fxm) * ihx, dpx = (fxp - c) * ihx;
    const double dmy = (c - fym) * ihy, dpy = (fyp - c) * ihy;
    double fzm = c, fzp = c, dmz = 0, dpz = 0;
    if constexpr (k3D) {
        fzm = p(zm);
        fzp = p(zp);
        dmz = (c - fzm) * ihz;
        dpz = (fzp - c) * ihz;
    }

    double rate = 0.0;
    if (curv_) {
        // κ = div(∇φ/|∇φ|) (eq. 4.30; in 3-D the sum of the principal curvatures), central differences.
        const double fx = 0.5 * (dmx + dpx), fy = 0.5 * (dmy + dpy);
        const double fxx = (dpx - dmx) * ihx, fyy = (dpy - dmy) * ihy;
        const double fxy = (p(xp + yp) - p(xp + ym) - p(xm + yp) + p(xm + ym)) * 0.25 * ihx * ihy;
        double num = 0, g2 = 0;
        if constexpr (k3D) {
            const double fz = 0.5 * (dmz + dpz), fzz = (dpz - dmz) * ihz;
            const double fxz = (p(xp + zp) - p(xp + zm) - p(xm + zp) + p(xm + zm)) * 0.25 * ihx * ihz;
            const double fyz = (p(yp + zp) - p(yp + zm) - p(ym + zp) + p(ym + zm)) * 0.25 * ihy * ihz;
            num = fxx * (fy * fy + fz * fz) + fyy * (fx * fx + fz * fz) + fzz * (fx * fx + fy * fy) -
                  2.0 * (fx * fy * fxy + fx * fz * fxz + fy * fz * fyz);
            g2 = fx * fx + fy * fy + fz * fz;
        } else {
            num = fxx * fy * fy - 2.0 * fx * fy * fxy + fyy * fx * fx;
            g2 = fx * fx + fy * fy;
        }
        if (g2 > kMinGrad2) {
            const double gn = std::sqrt(g2);
            // The clamp at the grid's resolvable curvature keeps a near-flat φ from blowing up.
            const double kappa = std::clamp(num / (g2 * gn), -kappa_max_, kappa_max_);
            rate += eps_ * (stop_ ? double(stop_[v]) : 1.0) * kappa * gn;
        }
    }
    if (press_) {
        // Osher-Sethian / Godunov: P > 0 moves the front outwards (φ decreases), taking the
        // one-sided differences from the side the front comes from.
        const double pr = press_[v];
        if (pr > 0.0) {
            double s = sq(std::max(dmx, 0.0)) + sq(std::min(dpx, 0.0)) + sq(std::max(dmy, 0.0)) + sq(std::min(dpy, 0.0));
            if constexpr (k3D)
                s += sq(std::max(dmz, 0.0)) + sq(std::min(dpz, 0.0));
            rate -= pr * std::sqrt(s);
        } else if (pr < 0.0) {
            double s = sq(std::min(dmx, 0.0)) + sq(std::max(dpx, 0.0)) + sq(std::min(dmy, 0.0)) + sq(std::max(dpy, 0.0));
            if constexpr (k3D)
                s += sq(std::min(dmz, 0.0)) + sq(std::max(dpz, 0.0));
            rate -= pr * std::sqrt(s);
        }
    }
    if (has_adv_) {
        // First-order upwind (eq. 4.32): the front moves along V.
        if (adv_[0]) {
            const double u = adv_[0][v];
            rate -= u * (u > 0.0 ? dmx : dpx);
        }
        if (adv_[1]) {
            const double u = adv_[1][v];
            rate -= u * (u > 0.0 ? dmy : dpy);
        }
        if constexpr (k3D)
            if (adv_[2]) {
                const double u = adv_[2][v];
                rate -= u * (u > 0.0 ? dmz : dpz);
            }
    }
    return static_cast<float>(c + dt_ * rate);
}

bool Evolver::step(bool& near_edge)
{
    const auto nb = static_cast<Index>(band_.size());
    next_.resize(band_.size());
    const bool three_d = g_.active[2];
    const double trigger = g_.hmax; // the front within one voxel of a band-edge voxel
    Index inside = 0;
    bool near = false;
#pragma omp parallel if (nb > 1024)
    {
#pragma omp for schedule(static) reduction(+ : inside) reduction(|| : near)
        for (Index b = 0; b < nb; ++b) {
            const BandVoxel& bv = band_[static_cast<std::size_t>(b)];
            const float f = three_d ? updated<true>(bv) : updated<false>(bv);
            next_[static_cast<std::size_t>(b)] = f;
            inside += f < 0.f;
            near = near || (bv.edge && std::abs(double(f)) <= trigger);
        }
#pragma omp for schedule(static)
        for (Index b = 0; b < nb; ++b)
            phi_[band_[static_cast<std::size_t>(b)].idx] = next_[static_cast<std::size_t>(b)];
    }
    near_edge = near;
    // Voxels outside the band never change sign, and the band surrounds every front, so an
    // all-outside (all-inside) band means no voxel is inside (outside) unless the front escaped
    // the band; the full scan settles that rare case.
    if (inside == 0)
        return any_sign(true);
    if (inside == nb)
        return any_sign(false);
    return true;
}

bool Evolver::any_sign(bool inside) const
{
    const auto n = static_cast<Index>(g_.count);
    bool found = false;
#pragma omp parallel for schedule(static) reduction(|| : found)
    for (Index v = 0; v < n; ++v)
        found = found || ((phi_[v] < 0.f) == inside);
    return found;
}

double Evolver::check()
{
    const auto nb = static_cast<Index>(band_.size());
    Index changed = 0, boundary = 0;
    const std::array<std::size_t, 3> axes{0, 1, 2};
#pragma omp parallel for schedule(static) reduction(+ : changed, boundary) if (nb > 1024)
    for (Index b = 0; b < nb; ++b) {
        const BandVoxel& bv = band_[static_cast<std::size_t>(b)];
        const auto v = static_cast<std::size_t>(bv.idx);
        const bool in = phi_[v] < 0.f;
        if (in != ((flags_[v] & kSnapInside) != 0)) {
            ++changed;
            flags_[v] ^= kSnapInside;
        }
        if (!in)
            continue;
        const std::array<int, 3> ijk{bv.i, bv.j, bv.k};
        bool touches = false;
        for (std::size_t a : axes) {
            if (!g_.active[a])
                continue;
            if ((ijk[a] > 0 && phi_[v - static_cast<std::size_t>(g_.stride[a])] >= 0.f) ||
                (ijk[a] < g_.n[a] - 1 && phi_[v + static_cast<std::size_t>(g_.stride[a])] >= 0.f))
                touches = true;
        }
        boundary += touches;
    }
    changed += pending_changes_;
    pending_changes_ = 0;
    return double(changed) / double(std::max<Index>(boundary, 1));
}

// A voxel with a face neighbour of the other sign: its distance to the front is that of the
// plane through the per-axis crossings (linear interpolation of φ), d = 1/sqrt(Σ 1/d_a^2), and
// its foot point is that plane's nearest point. First-order accurate and keeps the zero level
// set where linear interpolation of φ puts it.
bool Evolver::interface_site(Index v, int i, int j, int k)
{
    const std::array<int, 3> ijk{i, j, k};
    const double fv = phi_[v];
    const bool in = fv < 0.0;
    double inv2 = 0.0;
    std::array<double, 3> dir{0, 0, 0};
    bool any = false, zero = false;
    for (std::size_t a = 0; a < 3; ++a) {
        if (!g_.active[a])
            continue;
        double best = std::numeric_limits<double>::infinity();
        double side = 0.0;
        for (int s = -1; s <= 1; s += 2) {
            const int na = ijk[a] + s;
            if (na < 0 || na >= g_.n[a])
                continue;
            const double fn = phi_[v + s * g_.stride[a]];
            if ((fn < 0.0) == in)
                continue;
            const double t = g_.h[a] * fv / (fv - fn); // in [0, h_a]: the signs differ
            if (t < best) {
                best = t;
                side = s;
            }
        }
        if (side == 0.0)
            continue;
        any = true;
        if (best <= 0.0)
            zero = true;
        else {
            inv2 += 1.0 / (best * best);
            dir[a] = side / best;
        }
    }
    if (!any)
        return false;
    Site s{v, i, j, k, in, 0.0, {i * g_.h[0], j * g_.h[1], k * g_.h[2]}};
    if (!zero) {
        const double d2 = 1.0 / inv2;
        s.d = std::sqrt(d2);
        for (std::size_t a = 0; a < 3; ++a)
            s.foot[a] += dir[a] * d2;
    }
    slot_[static_cast<std::size_t>(v)] = static_cast<std::int32_t>(sites_.size());
    sites_.push_back(s);
    return true;
}

// Sub-voxel redistancing restricted to the band: interface voxels get the plane distance and
// foot point above; the foot points then spread outwards breadth-first (each voxel takes the
// nearest foot among its already reached face neighbours), stopping beyond the band width.
// Cost O(band voxels), versus O(grid) for a full distance transform; the sign of every voxel is
// kept, so the inside set is unchanged.
bool Evolver::redistance(bool initial)
{
    sites_.clear();
    if (initial) {
        for (int k = 0; k < g_.n[2]; ++k)
            for (int j = 0; j < g_.n[1]; ++j)
                for (int i = 0; i < g_.n[0]; ++i)
                    interface_site(i + g_.stride[1] * j + g_.stride[2] * k, i, j, k);
    } else {
        for (const BandVoxel& bv : band_)
            interface_site(bv.idx, bv.i, bv.j, bv.k);
    }
    const bool front = !sites_.empty();

    std::vector<std::size_t> level(sites_.size());
    for (std::size_t s = 0; s < level.size(); ++s)
        level[s] = s;
    std::vector<Site> queued;
    while (!level.empty()) {
        queued.clear();
        for (std::size_t s : level) {
            const Site site = sites_[s];
            if (site.d > width_)
                continue;
            const std::array<int, 3> ijk{site.i, site.j, site.k};
            for (std::size_t a = 0; a < 3; ++a) {
                if (!g_.active[a])
                    continue;
                for (int sd = -1; sd <= 1; sd += 2) {
                    const int na = ijk[a] + sd;
                    if (na < 0 || na >= g_.n[a])
                        continue;
                    const Index w = site.idx + sd * g_.stride[a];
                    auto& sl = slot_[static_cast<std::size_t>(w)];
                    if (sl != -1)
                        continue;
                    sl = -2;
                    std::array<int, 3> nijk = ijk;
                    nijk[a] = na;
                    queued.push_back({w, nijk[0], nijk[1], nijk[2], phi_[w] < 0.f, 0.0, {}});
                }
            }
        }
        level.clear();
        for (Site& q : queued) {
            const std::array<int, 3> ijk{q.i, q.j, q.k};
            const std::array<double, 3> x{q.i * g_.h[0], q.j * g_.h[1], q.k * g_.h[2]};
            double best = std::numeric_limits<double>::infinity();
            for (std::size_t a = 0; a < 3; ++a) {
                if (!g_.active[a])
                    continue;
                for (int sd = -1; sd <= 1; sd += 2) {
                    const int na = ijk[a] + sd;
                    if (na < 0 || na >= g_.n[a])
                        continue;
                    const std::int32_t su = slot_[static_cast<std::size_t>(q.idx + sd * g_.stride[a])];
                    if (su < 0)
                        continue;
                    const auto& f = sites_[static_cast<std::size_t>(su)].foot;
                    const double d2 = sq(x[0] - f[0]) + sq(x[1] - f[1]) + sq(x[2] - f[2]);
                    if (d2 < best) {
                        best = d2;
                        q.foot = f;
                    }
                }
            }
            q.d = std::sqrt(best);
            slot_[static_cast<std::size_t>(q.idx)] = static_cast<std::int32_t>(sites_.size());
            level.push_back(sites_.size());
            sites_.push_back(q);
        }
    }

    const auto W = static_cast<float>(width_);
    // Inside voxels stay strictly negative so that the inside set is exactly preserved.
    const auto tiny = static_cast<float>(1e-4 * g_.hmin);
    if (initial) {
        for (std::size_t v = 0; v < g_.count; ++v) {
            const bool in = phi_[v] < 0.f;
            flags_[v] = in ? kSnapInside : 0;
            phi_[v] = in ? -W : W;
        }
    } else {
        // Voxels leaving the band freeze: account their status change now, clamp them to ±W.
        for (const BandVoxel& bv : band_) {
            const auto v = static_cast<std::size_t>(bv.idx);
            const std::int32_t s = slot_[v];
            if (s < 0 || sites_[static_cast<std::size_t>(s)].d > width_) {
                account(bv.idx);
                phi_[v] = phi_[v] < 0.f ? -W : W;
            }
            flags_[v] &= static_cast<std::uint8_t>(~kInBand);
        }
    }
    band_.clear();
    for (const Site& s : sites_) {
        const auto v = static_cast<std::size_t>(s.idx);
        slot_[v] = -1;
        if (s.d > width_) {
            phi_[v] = s.inside ? -W : W;
            continue;
        }
        const auto d = static_cast<float>(s.d);
        phi_[v] = s.inside ? -std::max(d, tiny) : d;
        flags_[v] |= kInBand;
        band_.push_back({s.idx, s.i, s.j, s.k, false});
    }
    for (BandVoxel& bv : band_) {
        const std::array<int, 3> ijk{bv.i, bv.j, bv.k};
        for (std::size_t a = 0; a < 3 && !bv.edge; ++a) {
            if (!g_.active[a])
                continue;
            if ((ijk[a] > 0 && !(flags_[static_cast<std::size_t>(bv.idx - g_.stride[a])] & kInBand)) ||
                (ijk[a] < g_.n[a] - 1 && !(flags_[static_cast<std::size_t>(bv.idx + g_.stride[a])] & kInBand)))
                bv.edge = true;
        }
    }
    return front;
}

} // namespace

LevelSetResult evolve_level_set(const ImageF& phi0, const SpeedTerms& terms, const LevelSetParams& params)
{
    core::validate_geometry(phi0.geometry(), "evolve_level_set: phi0");
    check_params(params);
    check_image(phi0, phi0.geometry(), "phi0", false);
    if (!std::isfinite(terms.curvature_weight) || terms.curvature_weight < 0.0)
        throw InvalidInputError("evolve_level_set: the curvature weight must be finite and >= 0");
    if (terms.stopping)
        check_image(*terms.stopping, phi0.geometry(), "the stopping function", true);
    if (terms.pressure)
        check_image(*terms.pressure, phi0.geometry(), "the pressure", false);
    if (terms.advection)
        for (std::size_t a = 0; a < 3; ++a)
            if (phi0.size[a] > 1) // a 2-D field's z component is ignored
                check_image(terms.advection->c[a], phi0.geometry(), "advection component " + std::to_string(a),
                            false);

    LevelSetResult r;
    r.phi = phi0;
    Evolver ev(r.phi, terms, params);
    r.time_step = ev.dt();
    bool alive = ev.redistance(true);
    int streak = 0;
    for (int it = 1; alive && it <= params.max_iterations; ++it) {
        bool near_edge = false;
        alive = ev.step(near_edge);
        r.iterations = it;
        if (!alive)
            break;
        if (near_edge || it % kReinitPeriod == 0) {
            alive = ev.redistance(false);
            ++r.reinitialisations;
        }
        if (it % params.check_interval == 0) {
            r.last_change = ev.check();
            streak = r.last_change < params.convergence_tolerance ? streak + 1 : 0;
            if (streak >= params.convergence_checks) {
                r.converged = true;
                break;
            }
        }
    }
    r.mask = core::LabelImage3D(r.phi.geometry(), 0);
    for (std::size_t v = 0; v < r.phi.data.size(); ++v)
        r.mask.data[v] = r.phi.data[v] < 0.f ? 1 : 0;
    return r;
}

ImageF initial_level_set(const core::LabelImage3D& mask)
{
    core::validate_geometry(mask.geometry(), "initial_level_set: mask");
    if (mask.data.size() != mask.voxel_count())
        throw InvalidInputError("initial_level_set: the mask's data size does not match its grid");
    std::size_t inside = 0;
    for (std::uint8_t m : mask.data)
        inside += m != 0;
    if (inside == 0)
        throw InvalidInputError("initial_level_set: the mask is empty (no contour to start from)");
    if (inside == mask.data.size())
        throw InvalidInputError("initial_level_set: the mask fills the whole grid (no contour to start from)");
    return signed_distance(mask);
}

ImageF level_set_from_seeds(const core::ImageGeometry& grid, const std::vector<core::Vec3>& seeds, double radius_mm)
{
    core::validate_geometry(grid, "level_set_from_seeds: grid");
    if (!std::isfinite(radius_mm) || !(radius_mm > 0.0))
        throw InvalidInputError("level_set_from_seeds: the radius must be finite and positive, is " +
                                std::to_string(radius_mm));
    if (seeds.empty())
        throw InvalidInputError("level_set_from_seeds: no seeds given");
    for (const core::Vec3& s : seeds)
        for (int a = 0; a < 3; ++a)
            if (!std::isfinite(s[a]) || s[a] < -0.5 || s[a] >= grid.size[static_cast<std::size_t>(a)] - 0.5)
                throw InvalidInputError("level_set_from_seeds: seed (" + std::to_string(s.x) + ", " +
                                        std::to_string(s.y) + ", " + std::to_string(s.z) +
                                        ") lies outside the grid");
    ImageF phi(grid, 0.f);
    const auto& h = grid.spacing;
    const int nx = grid.size[0], ny = grid.size[1];
    const auto n = static_cast<Index>(grid.voxel_count());
    // Exact signed distance outside the union of balls; inside, the depth in the nearest ball.
#pragma omp parallel for schedule(static)
    for (Index v = 0; v < n; ++v) {
        const double i = double(v % nx), j = double((v / nx) % ny), k = double(v / (Index{nx} * ny));
        double best = std::numeric_limits<double>::infinity();
        for (const core::Vec3& s : seeds)
            best = std::min(best, sq((i - s.x) * h[0]) + sq((j - s.y) * h[1]) + sq((k - s.z) * h[2]));
        phi.data[static_cast<std::size_t>(v)] = static_cast<float>(std::sqrt(best) - radius_mm);
    }
    // A ball smaller than a voxel may miss every voxel centre: its nearest voxel is made inside so
    // that every seed starts a contour.
    for (const core::Vec3& s : seeds) {
        const int i = int(std::lround(s.x)), j = int(std::lround(s.y)), k = int(std::lround(s.z));
        float& f = phi.at(i, j, k);
        f = std::min(f, static_cast<float>(-1e-3 * std::min({h[0], h[1], h[2]})));
    }
    return phi;
}

} // namespace lobe::seg
