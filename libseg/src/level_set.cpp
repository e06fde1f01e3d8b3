// Narrow-band level-set evolution (thesis §4.11-4.12, eq. 4.29-4.32). Design, sign conventions,
// band and re-initialisation policy, time step and convergence test: docs/algorithms/level_set.md.
#include "lobe/seg/level_set.h"

#include "detail/vectorise.h"
#include "lobe/seg/distance_transform.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
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
constexpr std::uint8_t kRepairQueued = 4; // a candidate of the redistancing's repair

// Neighbour bits of a band voxel: which face neighbours exist (grid border, inactive axis) and
// whether one of them is outside the band (the front near such a voxel triggers re-initialisation).
constexpr std::uint8_t kHasXm = 1, kHasXp = 2, kHasYm = 4, kHasYp = 8, kHasZm = 16, kHasZp = 32, kEdge = 64;

// A stationary front keeps steepening φ (the pressure keeps pushing on both sides of it), so φ is
// also re-initialised at this period, not only when the front nears the band edge.
constexpr int kReinitPeriod = 50;

// Below this |∇φ|^2 the curvature is undefined (flat φ, e.g. the centre of a tiny blob): no term.
constexpr double kMinGrad2 = 1e-12;

// One iteration over a smaller band takes well under a millisecond: a second thread gains little
// there and loses a scheduler time slice per barrier whenever the machine is busy.
constexpr Index kParallelBand = Index(1) << 15;
// A level of the redistancing's breadth-first search costs about 10x more per voxel.
constexpr Index kParallelLevel = Index(1) << 12;
// Same reasoning for the passes over the whole grid (validation, time step): a 512 x 512 slice
// takes ~0.2 ms per pass on one thread, and measured 20 ms slower on two on a busy machine.
constexpr Index kParallelGrid = Index(1) << 20;

double sq(double v)
{
    return v * v;
}

// Arithmetic type of the band update: float halves the latency of its division and square root;
// φ is stored as float anyway.
using Real = float;
inline Real sqr(Real v)
{
    return v * v;
}

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
    for (std::size_t a = 0; a < 3; ++a) {
        g.n[a] = geo.size[a];
        g.h[a] = geo.spacing[a];
        g.active[a] = geo.size[a] > 1;
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
    std::uint8_t nb; // kHas* and kEdge bits
};

// A row's consecutive band voxels: band_[b, b + len) are the voxels v, v + 1, ..., v + len - 1.
// Away from the grid border their update is a dense stencil the compiler vectorises.
struct BandRun {
    Index v;
    std::int32_t b, len;
    std::int32_t i;    // x index of the first voxel
    bool interior_row; // every in-plane (and in 3-D, z) neighbour row exists
};

// ---------------------------------------------------------------------------- validation

void check_image(const ImageF& img, const core::ImageGeometry& grid, const std::string& what, bool nonnegative)
{
    if (!core::same_grid(img.geometry(), grid) || img.data.size() != grid.voxel_count())
        throw InvalidInputError("evolve_level_set: " + what + " is not on the level set's grid");
    const float* d = img.data.data();
    const auto n = static_cast<Index>(img.data.size());
    bool bad = false, negative = false;
#pragma omp parallel for schedule(static) reduction(|| : bad, negative) if (n >= kParallelGrid)
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
    if (p.leak_checks < 0 || !(p.leak_slowdown > 0.0 && p.leak_slowdown <= 1.0) || !(p.leak_rise >= 1.0) ||
        !std::isfinite(p.leak_rise))
        fail("leak_checks must be >= 0, leak_slowdown in (0, 1] and leak_rise finite and >= 1");
}

// ---------------------------------------------------------------------------- the evolution

class Evolver {
  public:
    Evolver(ImageF& phi, const SpeedTerms& terms, const LevelSetParams& params)
        : g_(make_grid(phi.geometry())), phi_(phi), params_(params), width_(params.band_voxels * g_.hmax),
          patch_(0.5 * g_.hmax), other_(g_.count), flags_(g_.count, 0), slot_(g_.count, -1)
    {
        cur_ = phi.data.data();
        nxt_ = other_.data();
        eps_ = terms.curvature_weight;
        curv_ = eps_ > 0.0;
        stop_ = terms.stopping ? terms.stopping->data.data() : nullptr;
        if (curv_ && !stop_) { // no stopping function: g = 1 everywhere
            ones_.assign(g_.count, 1.f);
            stop_ = ones_.data();
        }
        press_ = terms.pressure ? terms.pressure->data.data() : nullptr;
        if (terms.advection)
            for (std::size_t a = 0; a < 3; ++a)
                adv_[a] = g_.active[a] ? terms.advection->c[a].data.data() : nullptr;
        has_adv_ = adv_[0] || adv_[1] || adv_[2];
        for (std::size_t a = 0; a < 3; ++a)
            ih_[a] = 1.0 / g_.h[a];
        kappa_max_ = g_.dims / g_.hmin;
        dt_ = time_step();
        for (std::size_t a = 0; a < 3; ++a)
            rih_[a] = static_cast<Real>(ih_[a]);
        rkappa_max_ = static_cast<Real>(kappa_max_);
        rdt_ = static_cast<Real>(dt_);
        // Face neighbours first: their patch is usually the nearest, which prunes the others.
        for (int order = 1; order <= 3; ++order)
            for (int dk = -1; dk <= 1; ++dk)
                for (int dj = -1; dj <= 1; ++dj)
                    for (int di = -1; di <= 1; ++di)
                        if (std::abs(di) + std::abs(dj) + std::abs(dk) == order && (g_.active[2] || dk == 0))
                            ring_.push_back(di + dj * g_.stride[1] + dk * g_.stride[2]);
    }

    double dt() const { return dt_; }

    //! Rebuilds the band around the zero level set of the current φ (sub-voxel redistancing);
    //! false if there is no front (no sign change anywhere).
    bool redistance(bool initial);

    //! One explicit step over the band; false if the front vanished or filled the grid.
    bool step(bool& near_edge);

    //! The convergence measure over the interval since the previous check.
    double check();

    //! The net growth over the interval the last check() measured: voxels that became inside
    //! minus those that became outside, per boundary voxel.
    double growth() const { return growth_; }

    //! The current φ (valid until the next step).
    const float* current() const { return cur_; }

    //! Leaves the latest φ in the result image.
    void finish()
    {
        if (cur_ != phi_.data.data())
            std::copy(cur_, cur_ + g_.count, phi_.data.begin());
    }

  private:
    // A flat piece of the front, one per interface voxel: a point on it and its unit normal.
    struct Patch {
        std::array<float, 3> foot;   // [mm, along the index axes]
        std::array<float, 3> normal; // zero if unknown (the patch is then a point)
    };
    // A voxel reached by the redistancing.
    struct Visit {
        Index idx;
        std::int32_t i, j, k;
        float d; // distance to the front [mm]
        bool inside;
        std::int32_t patch; // the nearest patch found
    };

    double time_step() const;
    bool interface_site(Index v, int i, int j, int k);
    double patch_distance2(const std::array<double, 3>& x, const Patch& s, double bound) const;
    void nearest_patch(Visit& q) const;
    template <class F> bool any_face_neighbour(const Visit& q, F&& f) const;
    template <class Push> void expand(Visit from, Push&& push);
    void place(std::size_t begin, std::size_t end);
    bool violates(const Visit& q) const;
    void repair(std::size_t first);
    template <class Terms> void step_band(Index& inside, bool& near);
    void index_band();
    std::uint8_t neighbour_bits(int i, int j, int k) const;
    bool any_sign(bool inside) const;
    void account(Index v)
    {
        const auto u = static_cast<std::size_t>(v);
        if ((cur_[u] < 0.f) != ((flags_[u] & kSnapInside) != 0)) {
            ++pending_changes_;
            pending_grew_ += cur_[u] < 0.f;
            flags_[u] ^= kSnapInside;
        }
    }

    Grid g_;
    ImageF& phi_;
    LevelSetParams params_;
    double width_; // band half-width W [mm]
    double patch_; // radius of the flat front patch around a foot point [mm]
    double eps_ = 0.0;
    bool curv_ = false, has_adv_ = false;
    const float* stop_ = nullptr;
    const float* press_ = nullptr;
    std::array<const float*, 3> adv_{nullptr, nullptr, nullptr};
    std::array<double, 3> ih_{};
    double kappa_max_ = 0.0;
    double dt_ = 0.0;
    std::array<Real, 3> rih_{}; // the same in the update's arithmetic type
    Real rkappa_max_ = 0, rdt_ = 0;

    // Two full copies of φ: a step reads one and writes the band of the other, then they swap.
    // Voxels outside the band hold ±W in both. Grid-sized arrays are BigVectors (huge pages in 3-D).
    core::BigVector<float> other_;
    core::BigVector<float> ones_; // g when the terms have no stopping function
    float* cur_ = nullptr;
    float* nxt_ = nullptr;
    core::BigVector<std::uint8_t> flags_;
    core::BigVector<std::int32_t> slot_; // during redistancing: voxel -> its patch; -1 not reached, -2 queued
    std::vector<Patch> patches_;
    std::vector<Visit> visits_; // in breadth-first order, the interface voxels first
    std::vector<Visit> repair_; // candidates of the repair
    std::vector<Index> ring_;   // offsets of the 8 (2-D) or 26 (3-D) neighbours
    std::vector<BandVoxel> band_;
    std::vector<BandRun> runs_;         // band_ cut into row runs
    std::vector<Index> edge_voxels_;    // band voxels with kEdge
    std::vector<BandVoxel> spare_band_; // the next band is built here, then sorted into band_
    std::vector<std::size_t> row_end_;  // the band sort's row offsets
    Index pending_changes_ = 0;         // status changes of voxels that left the band since the last check
    Index pending_grew_ = 0;            // ... of them, those that became inside
    double growth_ = 0.0;               // net growth at the last check, per boundary voxel
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
#pragma omp parallel for schedule(static) reduction(max : worst) if (n >= kParallelGrid)
    for (Index v = 0; v < n; ++v) {
        double r = 0.0;
        if (curv_)
            r += curv_rate * double(stop_[v]); // stop_ is g, or ones_ without a stopping function
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

// Which terms of eq. 4.29 act, and whether the grid is 3-D: compile-time, so that the update of a
// run of voxels has no branches and vectorises.
template <bool k3D_, bool curv_, bool press_, bool adv_> struct Terms {
    static constexpr bool k3D = k3D_, curv = curv_, press = press_, adv = adv_;
};

// Calls f(Terms<...>{}) with run-time flags (3-D, curvature, pressure, advection) made
// compile-time, one flag at a time.
template <bool... Fixed> struct TermFlags {
    template <class F> static void call(F&& f) { f(Terms<Fixed...>{}); }
    template <class F, class... Rest> static void call(F&& f, bool next, Rest... rest)
    {
        if (next)
            TermFlags<Fixed..., true>::call(f, rest...);
        else
            TermFlags<Fixed..., false>::call(f, rest...);
    }
};

// The constants of one band update, as locals: members would be reloaded after every store
// through the float output pointer, which may alias them.
struct Kernel {
    const float* phi;
    Index sy, sz;
    Real ihx, ihy, ihz;
    Real kappa_max, dt;
    double eps;
    // The term images, read at the voxel like φ (contiguous along a run). The caller guarantees
    // the ones its Terms read are present.
    const float* stop;
    const float* press;
    const float* u;
    const float* w;
    const float* z;
};

// ε g at voxel v, as the update uses it.
inline Real curvature_weight(double eps, const float* stop, Index v)
{
    return static_cast<float>(eps * double(stop[v]));
}

// Where a voxel's face neighbours are, as offsets: the grid border replicates the edge voxel
// (offset 0, zero normal derivative), so a front may touch the border.
struct Neighbours {
    Index xm, xp, ym, yp, zm, zp;
};

// One voxel of eq. 4.29: φ + Δt (ε g κ|∇φ| - P|∇φ|_Godunov - V·∇φ_upwind), φ read at phi[0] and
// the offsets n. Written with selects rather than branches so that a run of voxels vectorises;
// each select picks the value the branch would have computed, so the result is the same.
template <class Terms>
LOBE_ALWAYS_INLINE float updated(const Kernel& k, const float* phi, const Neighbours& n, Real curv, Real pr, Real u,
                                 Real w, Real z)
{
    auto p = [phi](Index off) { return Real(phi[off]); };
    const Index xm = n.xm, xp = n.xp, ym = n.ym, yp = n.yp;
    const Real ihx = k.ihx, ihy = k.ihy, ihz = k.ihz;
    const Real c = p(0);
    const Real dmx = (c - p(xm)) * ihx, dpx = (p(xp) - c) * ihx;
    const Real dmy = (c - p(ym)) * ihy, dpy = (p(yp) - c) * ihy;
    Index zm = 0, zp = 0;
    Real dmz = 0, dpz = 0;
    constexpr bool k3D = Terms::k3D;
    if constexpr (k3D) {
        zm = n.zm;
        zp = n.zp;
        dmz = (c - p(zm)) * ihz;
        dpz = (p(zp) - c) * ihz;
    }

    Real rate = Real(0);
    if constexpr (Terms::curv) {
        // κ = div(∇φ/|∇φ|) (eq. 4.30; in 3-D the sum of the principal curvatures), central differences.
        const Real fx = Real(0.5) * (dmx + dpx), fy = Real(0.5) * (dmy + dpy);
        const Real fxx = (dpx - dmx) * ihx, fyy = (dpy - dmy) * ihy;
        const Real fxy = (p(xp + yp) - p(xp + ym) - p(xm + yp) + p(xm + ym)) * Real(0.25) * ihx * ihy;
        Real num = 0, g2 = 0;
        if constexpr (k3D) {
            const Real fz = Real(0.5) * (dmz + dpz), fzz = (dpz - dmz) * ihz;
            const Real fxz = (p(xp + zp) - p(xp + zm) - p(xm + zp) + p(xm + zm)) * Real(0.25) * ihx * ihz;
            const Real fyz = (p(yp + zp) - p(yp + zm) - p(ym + zp) + p(ym + zm)) * Real(0.25) * ihy * ihz;
            num = fxx * (fy * fy + fz * fz) + fyy * (fx * fx + fz * fz) + fzz * (fx * fx + fy * fy) -
                  Real(2) * (fx * fy * fxy + fx * fz * fxz + fy * fz * fyz);
            g2 = fx * fx + fy * fy + fz * fz;
        } else {
            num = fxx * fy * fy - Real(2) * fx * fy * fxy + fyy * fx * fx;
            g2 = fx * fx + fy * fy;
        }
        // κ|∇φ| = num / |∇φ|^2, with κ clamped to the grid's resolvable curvature so that a
        // near-flat φ cannot blow up. Below kMinGrad2 there is no term (the quotient computed
        // there is discarded).
        const Real quotient = num / g2, clamped = std::copysign(k.kappa_max * std::sqrt(g2), num);
        const Real kg = num * num > k.kappa_max * k.kappa_max * g2 * g2 * g2 ? clamped : quotient;
        rate = g2 > Real(kMinGrad2) ? rate + curv * kg : rate;
    }
    if constexpr (Terms::press) {
        // Osher-Sethian / Godunov: P > 0 moves the front outwards (φ decreases), taking the
        // one-sided differences from the side the front comes from.
        Real out = sqr(std::max(dmx, Real(0))) + sqr(std::min(dpx, Real(0))) + sqr(std::max(dmy, Real(0))) +
                   sqr(std::min(dpy, Real(0)));
        Real in = sqr(std::min(dmx, Real(0))) + sqr(std::max(dpx, Real(0))) + sqr(std::min(dmy, Real(0))) +
                  sqr(std::max(dpy, Real(0)));
        if constexpr (k3D) {
            out += sqr(std::max(dmz, Real(0))) + sqr(std::min(dpz, Real(0)));
            in += sqr(std::min(dmz, Real(0))) + sqr(std::max(dpz, Real(0)));
        }
        rate = pr != Real(0) ? rate - pr * std::sqrt(pr > Real(0) ? out : in) : rate;
    }
    if constexpr (Terms::adv) {
        // First-order upwind (eq. 4.32): the front moves along V (absent components are 0).
        rate -= u * (u > Real(0) ? dmx : dpx) + w * (w > Real(0) ? dmy : dpy);
        if constexpr (k3D)
            rate -= z * (z > Real(0) ? dmz : dpz);
    }
    return static_cast<float>(c + k.dt * rate);
}

// The voxels [v, v + n) of an interior run (every neighbour inside the grid, every term image
// the Terms read present): a dense loop.
template <class Terms>
LOBE_VECTOR_CLONES Index update_interior(const Kernel& k, Index v, std::int32_t n, float* __restrict out)
{
    const Neighbours nb{-1, 1, -k.sy, k.sy, -k.sz, k.sz};
    Index in = 0;
    for (Index x = v; x < v + n; ++x) {
        const Real curv = Terms::curv ? curvature_weight(k.eps, k.stop, x) : Real(0);
        const Real pr = Terms::press ? Real(k.press[x]) : Real(0);
        const Real u = Terms::adv ? Real(k.u[x]) : Real(0), w = Terms::adv ? Real(k.w[x]) : Real(0);
        const Real z = Terms::adv && Terms::k3D ? Real(k.z[x]) : Real(0);
        const float f = updated<Terms>(k, k.phi + x, nb, curv, pr, u, w, z);
        out[x] = f;
        in += f < 0.f;
    }
    return in;
}

template <class Terms> void Evolver::step_band(Index& inside, bool& near)
{
    const Kernel kern{cur_, g_.stride[1], g_.stride[2], rih_[0], rih_[1], rih_[2], rkappa_max_,
                      rdt_, eps_,         stop_,        press_,  adv_[0], adv_[1], adv_[2]};
    const BandVoxel* band = band_.data();
    const BandRun* runs = runs_.data();
    const int last_i = g_.n[0] - 1;
    const bool vectorise = params_.vectorise;
    float* out = nxt_;
    // A voxel on the grid border: its missing neighbours are itself, and so are the components
    // of V along inactive axes (0).
    auto border = [&](std::int32_t b) {
        const BandVoxel& bv = band[b];
        const Index v = bv.idx;
        const std::uint8_t m = bv.nb;
        const Neighbours nb{m & kHasXm ? -1 : 0,      m & kHasXp ? 1 : 0,        m & kHasYm ? -kern.sy : 0,
                            m & kHasYp ? kern.sy : 0, m & kHasZm ? -kern.sz : 0, m & kHasZp ? kern.sz : 0};
        const auto component = [v](const float* c) { return c ? Real(c[v]) : Real(0); };
        const float f =
            updated<Terms>(kern, kern.phi + v, nb, Terms::curv ? curvature_weight(kern.eps, kern.stop, v) : Real(0),
                           component(kern.press), component(kern.u), component(kern.w), component(kern.z));
        out[v] = f;
        return Index(f < 0.f);
    };
    const auto nr = static_cast<Index>(runs_.size());
    Index in = 0;
#pragma omp parallel for schedule(static) reduction(+ : in) if (Index(band_.size()) >= kParallelBand)
    for (Index r = 0; r < nr; ++r) {
        const BandRun& run = runs[r];
        std::int32_t lo = 0, hi = run.len;
        if (run.interior_row && vectorise) {
            if (run.i == 0)
                in += border(run.b + lo++);
            if (lo < hi && run.i + hi - 1 == last_i)
                in += border(run.b + --hi);
            in += update_interior<Terms>(kern, run.v + lo, hi - lo, out);
        } else {
            for (std::int32_t t = lo; t < hi; ++t)
                in += border(run.b + t);
        }
    }
    inside = in;
    // The front within one voxel of a band-edge voxel.
    const double trigger = g_.hmax;
    near = std::any_of(edge_voxels_.begin(), edge_voxels_.end(),
                       [out, trigger](Index v) { return std::abs(double(out[v])) <= trigger; });
}

bool Evolver::step(bool& near_edge)
{
    Index inside = 0;
    // Which terms act is fixed for the run: each combination gets its own loop without branches.
    const auto with = [&](auto terms) { step_band<decltype(terms)>(inside, near_edge); };
    TermFlags<>::call(with, g_.active[2], curv_, press_ != nullptr, has_adv_);
    std::swap(cur_, nxt_);
    // Voxels outside the band never change sign, and the band surrounds every front, so an
    // all-outside (all-inside) band means no voxel is inside (outside) unless the front escaped
    // the band; the full scan settles that rare case.
    const auto nb = static_cast<Index>(band_.size());
    if (inside == 0)
        return any_sign(true);
    if (inside == nb)
        return any_sign(false);
    return true;
}

bool Evolver::any_sign(bool inside) const
{
    const auto n = static_cast<Index>(g_.count);
    const float* p = cur_;
    bool found = false;
#pragma omp parallel for schedule(static) reduction(|| : found) if (n >= kParallelGrid)
    for (Index v = 0; v < n; ++v)
        found = found || ((p[v] < 0.f) == inside);
    return found;
}

double Evolver::check()
{
    const auto nb = static_cast<Index>(band_.size());
    const float* p = cur_;
    const Index sy = g_.stride[1], sz = g_.stride[2];
    Index changed = 0, boundary = 0, grew = 0;
#pragma omp parallel for schedule(static) reduction(+ : changed, boundary, grew) if (nb >= kParallelBand)
    for (Index b = 0; b < nb; ++b) {
        const BandVoxel& bv = band_[static_cast<std::size_t>(b)];
        const auto v = static_cast<std::size_t>(bv.idx);
        const bool in = p[v] < 0.f;
        if (in != ((flags_[v] & kSnapInside) != 0)) {
            ++changed;
            grew += in;
            flags_[v] ^= kSnapInside;
        }
        if (in) {
            const Index i = bv.idx;
            const std::uint8_t m = bv.nb;
            boundary += ((m & kHasXm) && p[i - 1] >= 0.f) || ((m & kHasXp) && p[i + 1] >= 0.f) ||
                        ((m & kHasYm) && p[i - sy] >= 0.f) || ((m & kHasYp) && p[i + sy] >= 0.f) ||
                        ((m & kHasZm) && p[i - sz] >= 0.f) || ((m & kHasZp) && p[i + sz] >= 0.f);
        }
    }
    changed += pending_changes_;
    grew += pending_grew_;
    pending_changes_ = pending_grew_ = 0;
    const double per = 1.0 / double(std::max<Index>(boundary, 1));
    growth_ = double(2 * grew - changed) * per; // voxels that joined minus those that left
    return double(changed) * per;
}

std::uint8_t Evolver::neighbour_bits(int i, int j, int k) const
{
    std::uint8_t m = 0;
    if (g_.active[0])
        m |= static_cast<std::uint8_t>((i > 0 ? kHasXm : 0) | (i < g_.n[0] - 1 ? kHasXp : 0));
    if (g_.active[1])
        m |= static_cast<std::uint8_t>((j > 0 ? kHasYm : 0) | (j < g_.n[1] - 1 ? kHasYp : 0));
    if (g_.active[2])
        m |= static_cast<std::uint8_t>((k > 0 ? kHasZm : 0) | (k < g_.n[2] - 1 ? kHasZp : 0));
    return m;
}

// A voxel with a face neighbour of the other sign. Its distance to the front is |φ| / |∇φ|, the
// derivative along an axis that crosses the front being the difference across the front (the
// larger one if both neighbours cross) and the central difference along the others. Exact for a
// linear φ, and along a crossing axis it keeps the zero where linear interpolation of the old φ
// had it (Russo & Smereka 2000), so redistancing does not move the front; unlike their larger
// one-sided difference it ignores the jump to a clamped ±W neighbour at the band edge. The foot
// point lies that far along the central-difference normal.
bool Evolver::interface_site(Index v, int i, int j, int k)
{
    const float* p = cur_;
    const std::array<int, 3> ijk{i, j, k};
    const double f = p[v];
    const bool in = f < 0.0;
    // Most band voxels have no neighbour of the other sign: settle that before any arithmetic.
    bool other_sign = false;
    for (std::size_t a = 0; a < 3 && !other_sign; ++a)
        if (g_.active[a])
            other_sign = (ijk[a] > 0 && (p[v - g_.stride[a]] < 0.f) != in) ||
                         (ijk[a] < g_.n[a] - 1 && (p[v + g_.stride[a]] < 0.f) != in);
    if (!other_sign)
        return false;
    double big2 = 0.0;
    std::array<double, 3> grad{0, 0, 0};
    for (std::size_t a = 0; a < 3; ++a) {
        if (!g_.active[a])
            continue;
        const bool hm = ijk[a] > 0, hp = ijk[a] < g_.n[a] - 1;
        const double fm = hm ? double(p[v - g_.stride[a]]) : f;
        const double fp = hp ? double(p[v + g_.stride[a]]) : f;
        const bool cm = hm && (fm < 0.0) != in, cp = hp && (fp < 0.0) != in;
        grad[a] = (fp - fm) * ih_[a] / double((hm ? 1 : 0) + (hp ? 1 : 0));
        double da = std::abs(grad[a]);
        if (cm || cp)
            da = std::max(cm ? std::abs(f - fm) : 0.0, cp ? std::abs(fp - f) : 0.0) * ih_[a];
        big2 += da * da;
    }
    const double d = std::abs(f) / std::sqrt(big2); // big2 > 0: the signs differ across an axis
    const double gn = std::sqrt(sq(grad[0]) + sq(grad[1]) + sq(grad[2]));
    const auto id = static_cast<std::int32_t>(patches_.size());
    Patch patch{};
    const std::array<double, 3> x{i * g_.h[0], j * g_.h[1], k * g_.h[2]};
    for (std::size_t a = 0; a < 3; ++a) {
        const double n = gn > 0.0 ? grad[a] / gn : 0.0;
        patch.normal[a] = static_cast<float>(n);
        patch.foot[a] = static_cast<float>(x[a] - (in ? -d : d) * n);
    }
    patches_.push_back(patch);
    visits_.push_back({v, i, j, k, static_cast<float>(d), in, id});
    slot_[static_cast<std::size_t>(v)] = id;
    nxt_[v] = static_cast<float>(d); // scratch for the repair (see place)
    return true;
}

// Squared distance from x to the front as seen from a patch: a flat disc of radius `patch_` around
// the foot point, perpendicular to the normal. Far better than the distance to the
// foot point itself, which overestimates by up to s^2/(8d) for foot points s apart.
double Evolver::patch_distance2(const std::array<double, 3>& x, const Patch& s, double bound) const
{
    const std::array<double, 3> r{x[0] - double(s.foot[0]), x[1] - double(s.foot[1]), x[2] - double(s.foot[2])};
    const double dn = r[0] * double(s.normal[0]) + r[1] * double(s.normal[1]) + r[2] * double(s.normal[2]);
    const double dn2 = dn * dn;
    if (dn2 >= bound) // the distance is at least |dn|: cannot beat the best so far
        return dn2;
    const double lateral2 = std::max(sq(r[0]) + sq(r[1]) + sq(r[2]) - dn2, 0.0);
    if (lateral2 <= patch_ * patch_)
        return dn2;
    return dn2 + sq(std::sqrt(lateral2) - patch_);
}

// Candidates come from the whole 3x3(x3) neighbourhood: with face neighbours only, the nearest
// patch often fails to reach voxels a few layers away (Danielsson's error, 0.3 voxel at 3 voxels).
// Neighbours often share a patch; a repeat of the last one or of the best is skipped.
void Evolver::nearest_patch(Visit& q) const
{
    const std::array<double, 3> x{q.i * g_.h[0], q.j * g_.h[1], q.k * g_.h[2]};
    double best = std::numeric_limits<double>::infinity();
    std::int32_t best_patch = -1, last = -1;
    auto consider = [&](std::int32_t pt) {
        if (pt < 0 || pt == last || pt == best_patch)
            return;
        last = pt;
        const double d2 = patch_distance2(x, patches_[static_cast<std::size_t>(pt)], best);
        if (d2 < best) {
            best = d2;
            best_patch = pt;
        }
    };
    const bool interior = q.i > 0 && q.j > 0 && q.i < g_.n[0] - 1 && q.j < g_.n[1] - 1 &&
                          (!g_.active[2] || (q.k > 0 && q.k < g_.n[2] - 1));
    if (interior) {
        for (const Index off : ring_)
            consider(slot_[static_cast<std::size_t>(q.idx + off)]);
    } else {
        const int k0 = g_.active[2] ? -1 : 0, k1 = g_.active[2] ? 1 : 0;
        for (int dk = k0; dk <= k1; ++dk)
            for (int dj = -1; dj <= 1; ++dj)
                for (int di = -1; di <= 1; ++di) {
                    const int ni = q.i + di, nj = q.j + dj, nk = q.k + dk;
                    if (ni < 0 || nj < 0 || nk < 0 || ni >= g_.n[0] || nj >= g_.n[1] || nk >= g_.n[2])
                        continue;
                    consider(slot_[static_cast<std::size_t>(q.idx + di + dj * g_.stride[1] + dk * g_.stride[2])]);
                }
    }
    // best_patch >= 0: the voxel that queued q belongs to an earlier level
    q.d = static_cast<float>(std::sqrt(best));
    q.patch = best_patch;
}

// Calls f(w, r, a) for each face neighbour w (voxel index r, along axis a) of q inside the grid,
// until f returns true; returns whether one did.
template <class F> bool Evolver::any_face_neighbour(const Visit& q, F&& f) const
{
    const std::array<int, 3> ijk{q.i, q.j, q.k};
    for (std::size_t a = 0; a < 3; ++a) {
        if (!g_.active[a])
            continue;
        for (int sd = -1; sd <= 1; sd += 2) {
            std::array<int, 3> r = ijk;
            r[a] += sd;
            if (r[a] < 0 || r[a] >= g_.n[a])
                continue;
            if (f(q.idx + sd * g_.stride[a], r, a))
                return true;
        }
    }
    return false;
}

// Hands each face neighbour of `from` that is neither placed nor queued to push(visit).
template <class Push> void Evolver::expand(const Visit from, Push&& push) // a copy: push may grow visits_
{
    any_face_neighbour(from, [&](Index w, const std::array<int, 3>& r, std::size_t) {
        auto& sl = slot_[static_cast<std::size_t>(w)];
        if (sl == -1) {
            sl = -2;
            push(Visit{w, r[0], r[1], r[2], 0.f, cur_[w] < 0.f, -1});
        }
        return false;
    });
}

// Gives the queued visits [begin, end) their nearest patch and publishes it; they read only the
// patches published before, so they are independent. The distance of every placed voxel is kept
// in nxt_, free scratch during the redistancing (each visited voxel is rewritten at its end).
void Evolver::place(std::size_t begin, std::size_t end)
{
    const auto lo = static_cast<Index>(begin), hi = static_cast<Index>(end);
#pragma omp parallel for schedule(static) if (hi - lo >= kParallelLevel)
    for (Index t = lo; t < hi; ++t)
        nearest_patch(visits_[static_cast<std::size_t>(t)]);
    for (std::size_t t = begin; t < end; ++t) {
        const auto v = static_cast<std::size_t>(visits_[t].idx);
        slot_[v] = visits_[t].patch;
        nxt_[v] = visits_[t].d;
    }
}

// Whether q's distance exceeds a placed face neighbour's by more than their spacing: impossible
// for the true distance, and for the distance to the neighbour's patch, which is 1-Lipschitz.
bool Evolver::violates(const Visit& q) const
{
    const double d = nxt_[q.idx], tol = 1e-3 * g_.hmin;
    return any_face_neighbour(q, [&](Index w, const std::array<int, 3>&, std::size_t a) {
        const auto u = static_cast<std::size_t>(w);
        return slot_[u] >= 0 && double(nxt_[u]) < d - g_.h[a] - tol;
    });
}

// The levels count face steps, not millimetres, and the voxels of one level do not see each
// other's patches. So a voxel may be reached first from a far part of the front (on an
// anisotropic grid, by a few long steps along z while the near part arrives a level later by
// short ones in plane) and keep the far patch; beyond the band width it then also stops the
// search, leaving a hole in the band beside the front, and the edge test fires at the next step
// (on a 0.7 x 0.7 x 2.5 mm volume φ was re-initialised at 294 of 340 steps). The repair: a voxel
// that violates the triangle inequality with a face neighbour takes the nearest of its
// neighbours' patches again (all placed now), then its neighbours are checked in turn; a voxel
// that so enters the band expands. Every change lowers a distance, so the rounds end; the bound
// only caps a pathological front. The candidates are voxel records, their distance and patch
// living in nxt_ and slot_.
void Evolver::repair(std::size_t first)
{
    constexpr int kMaxRounds = 32;
    std::vector<Visit>& cand = repair_;
    cand.clear();
    {
        const std::size_t count = visits_.size();
        std::vector<std::uint8_t> bad(count, 0);
        const auto lo = static_cast<Index>(first), hi = static_cast<Index>(count);
#pragma omp parallel for schedule(static) if (hi - lo >= kParallelLevel)
        for (Index t = lo; t < hi; ++t)
            bad[static_cast<std::size_t>(t)] = violates(visits_[static_cast<std::size_t>(t)]);
        for (std::size_t t = first; t < count; ++t)
            if (bad[t])
                cand.push_back(visits_[t]);
    }
    std::vector<Visit> better;
    for (int round = 0; round < kMaxRounds && !cand.empty(); ++round) {
        // Jacobi: every candidate reads the patches as they were before the round.
        better.resize(cand.size());
        const auto n = static_cast<Index>(cand.size());
#pragma omp parallel for schedule(static) if (n >= kParallelLevel)
        for (Index c = 0; c < n; ++c) {
            Visit q = cand[static_cast<std::size_t>(c)];
            nearest_patch(q);
            better[static_cast<std::size_t>(c)] = q;
        }
        const std::size_t placed = visits_.size();
        cand.clear();
        for (const Visit& q : better) {
            const auto v = static_cast<std::size_t>(q.idx);
            if (!(q.d < nxt_[v]))
                continue;
            const bool enters = double(nxt_[v]) > width_ && double(q.d) <= width_;
            slot_[v] = q.patch;
            nxt_[v] = q.d;
            if (enters)
                expand(q, [this](const Visit& w) { visits_.push_back(w); });
            cand.push_back(q); // the changed voxels; their neighbours are the next candidates
        }
        place(placed, visits_.size());
        std::vector<Visit> next;
        for (const Visit& q : cand)
            any_face_neighbour(q, [&](Index w, const std::array<int, 3>& r, std::size_t) {
                const auto u = static_cast<std::size_t>(w);
                const std::int32_t pt = slot_[u];
                // Placed, not an interface voxel (whose own patch defines the front), not
                // already a candidate.
                if (pt < 0 || (static_cast<std::size_t>(pt) < first && visits_[static_cast<std::size_t>(pt)].idx == w) ||
                    (flags_[u] & kRepairQueued))
                    return false;
                const Visit cw{w, r[0], r[1], r[2], nxt_[u], cur_[w] < 0.f, pt};
                if (violates(cw)) {
                    flags_[u] |= kRepairQueued;
                    next.push_back(cw);
                }
                return false;
            });
        for (const Visit& q : next)
            flags_[static_cast<std::size_t>(q.idx)] &= static_cast<std::uint8_t>(~kRepairQueued);
        cand.swap(next);
    }
}

// The step's view of the sorted band: its row runs and its edge voxels.
void Evolver::index_band()
{
    const std::size_t n = band_.size();
    runs_.clear();
    edge_voxels_.clear();
    const bool y_rows = g_.active[1];
    for (std::size_t b = 0; b < n; ++b) {
        const BandVoxel& bv = band_[b];
        if (bv.nb & kEdge)
            edge_voxels_.push_back(bv.idx);
        if (!runs_.empty() && bv.idx == band_[b - 1].idx + 1 && bv.j == band_[b - 1].j && bv.k == band_[b - 1].k) {
            ++runs_.back().len;
            continue;
        }
        const bool interior =
            y_rows && bv.j > 0 && bv.j < g_.n[1] - 1 && (!g_.active[2] || (bv.k > 0 && bv.k < g_.n[2] - 1));
        runs_.push_back(BandRun{bv.idx, static_cast<std::int32_t>(b), 1, bv.i, interior});
    }
}

// Sub-voxel redistancing restricted to the band: interface voxels get the local distance above
// and define the front patches; the patches then spread outwards breadth-first, each voxel taking
// the nearest patch among its already reached neighbours', stopping beyond the band width. Cost
// O(band voxels), not O(grid) as a full distance transform; the sign of every voxel is kept.
bool Evolver::redistance(bool initial)
{
    patches_.clear();
    visits_.clear();
    if (initial) {
        for (int k = 0; k < g_.n[2]; ++k)
            for (int j = 0; j < g_.n[1]; ++j)
                for (int i = 0; i < g_.n[0]; ++i)
                    interface_site(i + g_.stride[1] * j + g_.stride[2] * k, i, j, k);
    } else {
        for (const BandVoxel& bv : band_)
            interface_site(bv.idx, bv.i, bv.j, bv.k);
    }
    const bool front = !visits_.empty();

    const std::size_t interface_visits = visits_.size();
    std::size_t begin = 0, end = visits_.size();
    while (begin < end) {
        for (std::size_t t = begin; t < end; ++t)
            if (double(visits_[t].d) <= width_)
                expand(visits_[t], [this](const Visit& w) { visits_.push_back(w); });
        begin = end;
        end = visits_.size();
        place(begin, end);
    }
    repair(interface_visits);

    const auto W = static_cast<float>(width_);
    // Inside voxels stay strictly negative so that the inside set is exactly preserved.
    const auto tiny = static_cast<float>(1e-4 * g_.hmin);
    float* a = cur_;
    float* b = nxt_;
    if (initial) {
        for (std::size_t v = 0; v < g_.count; ++v) {
            const bool in = a[v] < 0.f;
            flags_[v] = in ? kSnapInside : 0;
            a[v] = in ? -W : W;
        }
    } else {
        for (const BandVoxel& bv : band_)
            flags_[static_cast<std::size_t>(bv.idx)] &= static_cast<std::uint8_t>(~kInBand);
    }
    std::vector<BandVoxel>& fresh = spare_band_;
    fresh.clear();
    for (const Visit& q : visits_) {
        const auto v = static_cast<std::size_t>(q.idx);
        slot_[v] = -1;
        const float d = b[v]; // the distance, repaired (see place)
        if (double(d) > width_) {
            a[v] = b[v] = q.inside ? -W : W;
            continue;
        }
        a[v] = b[v] = q.inside ? -std::max(d, tiny) : d;
        flags_[v] |= kInBand;
        fresh.push_back(BandVoxel{q.idx, q.i, q.j, q.k, neighbour_bits(q.i, q.j, q.k)});
    }
    if (initial) {
        std::copy(a, a + g_.count, b);
    } else {
        // Voxels leaving the band freeze: account their status change now, clamp them to ±W.
        for (const BandVoxel& bv : band_) {
            const auto v = static_cast<std::size_t>(bv.idx);
            if (!(flags_[v] & kInBand)) {
                account(bv.idx);
                a[v] = b[v] = a[v] < 0.f ? -W : W;
            }
        }
    }
    // In memory order, not breadth-first order: a step then reads φ's neighbourhoods nearly
    // sequentially (the evolution on a 512 x 512 x 80 volume took 13.3 s instead of 22.7 s).
    // A counting sort by grid row, then each row's few dozen voxels by index: the same order as
    // sorting the whole band by index, at a fraction of a comparison sort's cost.
    const std::size_t rows = static_cast<std::size_t>(g_.n[1]) * static_cast<std::size_t>(g_.n[2]);
    const auto row_of = [this](const BandVoxel& bv) {
        return static_cast<std::size_t>(bv.j) + static_cast<std::size_t>(g_.n[1]) * static_cast<std::size_t>(bv.k);
    };
    row_end_.assign(rows + 1, 0);
    for (const BandVoxel& bv : fresh)
        ++row_end_[row_of(bv) + 1];
    for (std::size_t r = 0; r < rows; ++r)
        row_end_[r + 1] += row_end_[r];
    band_.resize(fresh.size());
    for (const BandVoxel& bv : fresh)
        band_[row_end_[row_of(bv)]++] = bv; // row_end_[r] ends as row r's end
    for (std::size_t r = 0, first = 0; r < rows; first = row_end_[r], ++r)
        std::sort(band_.begin() + static_cast<std::ptrdiff_t>(first),
                  band_.begin() + static_cast<std::ptrdiff_t>(row_end_[r]),
                  [](const BandVoxel& x, const BandVoxel& y) { return x.idx < y.idx; });
    const Index sy = g_.stride[1], sz = g_.stride[2];
    auto out = [this](Index w) { return !(flags_[static_cast<std::size_t>(w)] & kInBand); };
    for (BandVoxel& bv : band_) {
        const Index i = bv.idx;
        const std::uint8_t m = bv.nb;
        if (((m & kHasXm) && out(i - 1)) || ((m & kHasXp) && out(i + 1)) || ((m & kHasYm) && out(i - sy)) ||
            ((m & kHasYp) && out(i + sy)) || ((m & kHasZm) && out(i - sz)) || ((m & kHasZp) && out(i + sz)))
            bv.nb |= kEdge;
    }
    index_band();
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
                check_image(terms.advection->c[a], phi0.geometry(), "advection component " + std::to_string(a), false);

    LevelSetResult r;
    r.phi = phi0;
    Evolver ev(r.phi, terms, params);
    r.time_step = ev.dt();
    bool alive = ev.redistance(true);
    int streak = 0;
    // Leak stop: the largest and lowest net growth so far, φ at the lowest, and how many checks
    // in a row the growth has risen since.
    double peak = 0.0, lowest = std::numeric_limits<double>::infinity();
    std::vector<float> at_lowest;
    int lowest_iteration = 0, rising = 0;
    double previous_growth = 0.0;
    bool leaked = false;
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
            if (params.leak_checks > 0) {
                const double g = ev.growth();
                peak = std::max(peak, g);
                if (g < lowest) {
                    lowest = g;
                    lowest_iteration = it;
                    at_lowest.assign(ev.current(), ev.current() + r.phi.data.size());
                    rising = 0;
                } else if (lowest >= -params.convergence_tolerance && lowest < params.leak_slowdown * peak &&
                           g > previous_growth) {
                    // (A front that shrank at its lowest, lowest < -tolerance, is left alone: its
                    // lowest state is no contour from before a leak.)
                    // A leak spreads: it grows its own front, so its growth rises check after check.
                    // The rise is real if it exceeds either a fraction of the lowest growth or the
                    // flicker level (the convergence tolerance); a slow steady leak from a front
                    // that never quite stopped has a high lowest, and the ratio alone missed it.
                    const double rise = std::min((params.leak_rise - 1.0) * lowest, params.convergence_tolerance);
                    if (++rising >= params.leak_checks && g > params.convergence_tolerance && g - lowest > rise) {
                        leaked = true;
                        break;
                    }
                } else {
                    rising = 0;
                }
                previous_growth = g;
            }
        }
    }
    ev.finish();
    if (leaked) {
        // The front had slowed down at the edges and is now speeding up again through a gap:
        // return it as it was when it moved least.
        std::copy(at_lowest.begin(), at_lowest.end(), r.phi.data.begin());
        r.leak_stopped = true;
        r.leak_iteration = lowest_iteration;
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
                                        std::to_string(s.y) + ", " + std::to_string(s.z) + ") lies outside the grid");
    ImageF phi(grid, 0.f);
    const auto& h = grid.spacing;
    const int nx = grid.size[0], ny = grid.size[1];
    const auto n = static_cast<Index>(grid.voxel_count());
    // Exact signed distance outside the union of balls; inside, the depth in the nearest ball.
#pragma omp parallel for schedule(static) if (n * Index(seeds.size()) >= kParallelGrid)
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
        std::array<int, 3> ijk{};
        for (std::size_t a = 0; a < 3; ++a) // s[a] = -0.5 rounds to -1
            ijk[a] = std::clamp(int(std::lround(s[int(a)])), 0, grid.size[a] - 1);
        float& f = phi.at(ijk[0], ijk[1], ijk[2]);
        f = std::min(f, static_cast<float>(-1e-3 * std::min({h[0], h[1], h[2]})));
    }
    return phi;
}

} // namespace lobe::seg
