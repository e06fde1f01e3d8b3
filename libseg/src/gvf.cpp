#include "lobe/seg/gvf.h"

#include "detail/vectorise.h"

#include <omp.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <limits>
#include <string>
#include <thread>
#include <utility>
#include <vector>

namespace lobe::seg {
namespace {

using Index = std::ptrdiff_t;

//! Below this many voxels of work a loop runs on one thread: forking costs more than it saves,
//! and on a busy machine a descheduled helper thread stalls the whole loop.
constexpr Index kParallelMin = Index(1) << 15;

//! One component of the flow or of a coefficient: image-sized, so it takes the images' allocator
//! and is moved into the result without a copy.
using Field = core::BigVector<float>;

//! Per-voxel coefficients of the explicit step, time step folded in:
//!     v <- v + a·Σ_nb (v_nb - v) - r·v + c,   a = Δt·h, r = Δt·p, c = Δt·p·∇f.
//! Stored as arrays of floats so that each iteration only streams them (no exp per step).
struct Coefficients {
    Field a, r;
    std::array<Field, 3> c;
    std::array<Field, 3> grad; // ∇f, the initial field
    double time_step = 0.0;
};

void check_params(const core::ImageF& edge, const GvfParams& p, const char* fn)
{
    const std::string what = std::string(fn) + ": edge map";
    core::validate_geometry(edge, what);
    if (edge.data.size() != edge.voxel_count())
        throw core::InvalidInputError(what + ": holds " + std::to_string(edge.data.size()) + " values for " +
                                      std::to_string(edge.voxel_count()) + " voxels");
    if (p.model == GvfModel::Gvf && !(p.mu >= 0.0 && std::isfinite(p.mu)))
        throw core::InvalidInputError(std::string(fn) + ": mu must be finite and >= 0, got " + std::to_string(p.mu));
    if (p.model == GvfModel::Ggvf && !(p.k > 0.0 && std::isfinite(p.k)))
        throw core::InvalidInputError(std::string(fn) + ": k must be finite and > 0, got " + std::to_string(p.k));
    if (!(p.time_step > 0.0 && std::isfinite(p.time_step)))
        throw core::InvalidInputError(std::string(fn) + ": time_step must be finite and > 0, got " +
                                      std::to_string(p.time_step));
    if (p.iterations < 0)
        throw core::InvalidInputError(std::string(fn) + ": iterations must be >= 0, got " +
                                      std::to_string(p.iterations));
    if (!(p.tolerance >= 0.0 && std::isfinite(p.tolerance)))
        throw core::InvalidInputError(std::string(fn) + ": tolerance must be finite and >= 0");
    for (float v : edge.data)
        if (!std::isfinite(v))
            throw core::InvalidInputError(what + " has non-finite values (NaN or infinity)");
}

int iteration_count(const core::ImageGeometry& g, const GvfParams& p)
{
    // The thesis's minimum: a third of the longest in-plane row, rounded up (512 -> 171).
    return p.iterations > 0 ? p.iterations : (std::max(g.size[0], g.size[1]) + 2) / 3;
}

//! ∇f in index units at voxel (i, j, k): central differences, one-sided on the border (as
//! `gradient`, but per voxel so that the band-limited flow touches only its band).
std::array<float, 3> grad_at(const core::ImageF& f, int i, int j, int k)
{
    std::array<float, 3> g{0.f, 0.f, 0.f};
    const int pos[3] = {i, j, k};
    const Index stride[3] = {1, f.size[0], Index(f.size[0]) * f.size[1]};
    const float* c = f.data.data() + f.index(i, j, k);
    for (int a = 0; a < 3; ++a) {
        const int n = f.size[static_cast<std::size_t>(a)];
        if (n == 1)
            continue;
        const int p = pos[a];
        const float lo = p > 0 ? c[-stride[a]] : c[0];
        const float hi = p < n - 1 ? c[stride[a]] : c[0];
        g[static_cast<std::size_t>(a)] = (hi - lo) * ((p > 0 && p < n - 1) ? 0.5f : 1.f);
    }
    return g;
}

//! Coefficients at the listed voxels (`at(m)` gives the m-th voxel's (i, j, k)), time step
//! reduced to the bound below which every step is a convex combination of v, its neighbours
//! and ∇f: 1 - Δt·(2·dim·h + p) >= 0. Then |v| per component never exceeds max(|v0|, |∇f|), for
//! GVF too, where the header's 1/(2·dim·max h) alone would let p = |∇f|^2 overshoot at edges.
template <class At>
Coefficients make_coefficients(const core::ImageF& f, const GvfParams& p, int dim, std::size_t count, At at)
{
    Coefficients co;
    co.a.resize(count);
    co.r.resize(count);
    for (auto& v : co.c)
        v.resize(count);
    for (auto& v : co.grad)
        v.resize(count);
    const double inv_k2 = p.model == GvfModel::Ggvf ? 1.0 / (p.k * p.k) : 0.0;
    double worst = 0.0;
    const Index n = static_cast<Index>(count);
#pragma omp parallel for if (n > kParallelMin) schedule(static) reduction(max : worst)
    for (Index m = 0; m < n; ++m) {
        const auto u = static_cast<std::size_t>(m);
        const std::array<int, 3> ijk = at(u);
        const std::array<float, 3> g = grad_at(f, ijk[0], ijk[1], ijk[2]);
        const double gx = g[0], gy = g[1], gz = g[2];
        const double g2 = gx * gx + gy * gy + gz * gz;
        double h, q;
        if (p.model == GvfModel::Ggvf) {
            h = std::exp(-g2 * inv_k2);
            q = 1.0 - h;
        } else {
            h = p.mu;
            q = g2;
        }
        co.a[u] = static_cast<float>(h);
        co.r[u] = static_cast<float>(q);
        for (std::size_t a = 0; a < 3; ++a)
            co.grad[a][u] = g[a];
        worst = std::max(worst, 2.0 * dim * h + q);
    }
    // 0.999: the float coefficients must not round past the bound.
    const double bound = worst > 0.0 ? 0.999 / worst : p.time_step;
    co.time_step = std::min(p.time_step, bound);
    const auto dt = static_cast<float>(co.time_step);
#pragma omp parallel for if (n > kParallelMin) schedule(static)
    for (Index m = 0; m < n; ++m) {
        const auto u = static_cast<std::size_t>(m);
        co.a[u] *= dt;
        co.r[u] *= dt;
        for (std::size_t a = 0; a < 3; ++a)
            co.c[a][u] = co.r[u] * co.grad[a][u];
    }
    return co;
}

//! Pointers into one row of one component for full_chunk.
struct Row {
    const float* w;  // v on the row
    const float* ym; // v on the rows j-1, j+1, k-1, k+1 (the row itself on the border)
    const float* yp;
    const float* zm;
    const float* zp;
    const float* a; // coefficients (see Coefficients)
    const float* r;
    const float* c;
    float* out; // v on the row after the step
    float* d2;  // |Δv|^2 summed over the components so far
};

//! Voxels [i0, i1) of a row, x neighbours i-1 and i+1 (FIRST: the first component, which
//! starts d2). The pointers are restrict parameters, not struct members, because only then
//! does GCC 12 vectorise the loop (2-3x faster).
template <int NC, bool FIRST>
LOBE_VECTOR_CLONES void row_interior(const float* __restrict w, const float* __restrict ym, const float* __restrict yp,
                                     const float* __restrict zm, const float* __restrict zp, const float* __restrict a,
                                     const float* __restrict r, const float* __restrict c, float* __restrict out,
                                     float* __restrict d2, Index i0, Index i1)
{
    for (Index i = i0; i < i1; ++i) {
        const float x = w[i];
        float lap = (w[i - 1] - x) + (w[i + 1] - x) + (ym[i] - x) + (yp[i] - x);
        if (NC == 3)
            lap += (zm[i] - x) + (zp[i] - x);
        const float y = x + a[i] * lap - r[i] * x + c[i];
        out[i] = y;
        const float dy = y - x;
        d2[i] = (FIRST ? 0.f : d2[i]) + dy * dy;
    }
}

template <int NC, bool FIRST> void row_interior(const Row& q, Index i0, Index i1)
{
    row_interior<NC, FIRST>(q.w, q.ym, q.yp, q.zm, q.zp, q.a, q.r, q.c, q.out, q.d2, i0, i1);
}

//! One voxel with explicit x neighbours (the row's ends, where the ghost is the voxel itself).
template <int NC> void row_voxel(const Row& row, Index i, Index im, Index ip, bool first)
{
    const float* w = row.w;
    const float x = w[i];
    float lap = (w[im] - x) + (w[ip] - x) + (row.ym[i] - x) + (row.yp[i] - x);
    if (NC == 3)
        lap += (row.zm[i] - x) + (row.zp[i] - x);
    const float y = x + row.a[i] * lap - row.r[i] * x + row.c[i];
    row.out[i] = y;
    const float dy = y - x;
    row.d2[i] = (first ? 0.f : row.d2[i]) + dy * dy;
}

//! Rows [r0, r1) of one explicit step over the whole grid, NC components (2 in 2-D, 3 in
//! 3-D). The mirrored border is the half-sample one (ghost = centre): a missing neighbour adds
//! (v - v) = 0, the zero-flux rule of the band-limited flow, so a full band reproduces this;
//! the update is the same expression, operand for operand, as band_chunk's. `d2` holds nx
//! floats. Returns max |Δv|^2 over the rows.
template <int NC>
float full_chunk(const core::ImageGeometry& g, const Coefficients& co, const std::array<Field, 3>& cur,
                 std::array<Field, 3>& next, Index r0, Index r1, std::vector<float>& d2)
{
    const Index nx = g.size[0], ny = g.size[1], nz = g.size[2];
    const Index sy = nx, sz = nx * ny;
    float worst = 0.f;
    for (Index row = r0; row < r1; ++row) {
        const Index j = row % ny, k = row / ny;
        const Index base = row * nx;
        const Index oym = j > 0 ? -sy : 0, oyp = j < ny - 1 ? sy : 0;
        const Index ozm = k > 0 ? -sz : 0, ozp = k < nz - 1 ? sz : 0;
        for (int comp = 0; comp < NC; ++comp) {
            const auto cc = static_cast<std::size_t>(comp);
            const float* w = cur[cc].data() + base;
            const Row rw{w,
                         w + oym,
                         w + oyp,
                         w + ozm,
                         w + ozp,
                         co.a.data() + base,
                         co.r.data() + base,
                         co.c[cc].data() + base,
                         next[cc].data() + base,
                         d2.data()};
            const bool first = comp == 0;
            if (nx == 1) {
                row_voxel<NC>(rw, 0, 0, 0, first);
                continue;
            }
            row_voxel<NC>(rw, 0, 0, 1, first); // the row's ends apart: no branch in the loop
            if (first)
                row_interior<NC, true>(rw, 1, nx - 1);
            else
                row_interior<NC, false>(rw, 1, nx - 1);
            row_voxel<NC>(rw, nx - 1, nx - 2, nx - 1, first);
        }
        for (float v : d2)
            worst = v > worst ? v : worst;
    }
    return worst;
}

//! Band voxels [m0, m1) of one explicit step on the band's compact arrays; nb[d][m] is the
//! compact index of voxel m's neighbour in direction d, or m itself when that neighbour is
//! outside the band or the image. Returns max |Δv|^2.
template <int NC>
float band_chunk(const Coefficients& co, const std::array<std::vector<std::uint32_t>, 6>& nb,
                 const std::array<Field, 3>& cur, std::array<Field, 3>& next, Index m0,
                 Index m1)
{
    float worst = 0.f;
    for (Index m = m0; m < m1; ++m) {
        const auto u = static_cast<std::size_t>(m);
        float d2 = 0.f;
        for (int comp = 0; comp < NC; ++comp) {
            const auto cc = static_cast<std::size_t>(comp);
            const float* v = cur[cc].data();
            const float x = v[u];
            float lap = (v[nb[0][u]] - x) + (v[nb[1][u]] - x) + (v[nb[2][u]] - x) + (v[nb[3][u]] - x);
            if (NC == 3)
                lap += (v[nb[4][u]] - x) + (v[nb[5][u]] - x);
            const float y = x + co.a[u] * lap - co.r[u] * x + co.c[cc][u];
            next[cc][u] = y;
            d2 += (y - x) * (y - x);
        }
        worst = d2 > worst ? d2 : worst;
    }
    return worst;
}

//! Chunk c of a step reads chunks deps[c].first..deps[c].second of the previous state (itself
//! included); the relation is symmetric (if c reads c', c' reads c), as the stencil is.
using ChunkDeps = std::vector<std::pair<Index, Index>>;

float bits_to_float(std::uint32_t b)
{
    float f;
    std::memcpy(&f, &b, sizeof f);
    return f;
}

//! Runs `iterations` explicit steps over chunks of the grid (or band) on an OpenMP team, with
//! no barrier per step: chunk c may do step s as soon as every chunk it reads has done step
//! s - 1 (so a thread can run ahead on chunks far from a slow one, a wavefront). Why: on a busy
//! machine, a barrier per step waits each time for whichever thread the OS has descheduled;
//! 171 GGVF steps on 512 x 512 then took 5-10x longer with two threads than with one (median
//! 0.6-0.9 s, worst 3.4 s, against 0.12 s). Dependencies also cover the write-after-read
//! hazard of the ping-pong buffers: step s writes buffer (s+1) % 2 over state s-1, which only
//! chunks that read c still use, and they have finished step s-1.
//! With a tolerance, steps stay in lockstep (no chunk starts step s before all have finished
//! s - 1 and its change was checked), so that stopping leaves state s intact in its buffer.
//! `work(step, chunk, scratch)` reads buffer step % 2, writes the other and returns max |Δv|^2
//! of the chunk. Every chunk's arithmetic is fixed, so the result does not depend on which
//! thread did what. Sets res.iterations and res.last_change; returns the iterations run.
template <class Work>
int run_steps(int iterations, const ChunkDeps& deps, double tolerance, bool parallel, Work work, GvfResult& res)
{
    if (iterations == 0)
        return 0;
    const Index chunks = static_cast<Index>(deps.size());
    const bool lockstep = tolerance > 0.0;
    // Per chunk: the steps it has done, and whether a thread is working on it. Per step: how
    // many chunks have done it.
    std::vector<std::atomic<int>> progress(deps.size());
    std::vector<std::atomic<bool>> busy(deps.size());
    std::vector<std::atomic<Index>> finished(static_cast<std::size_t>(iterations));
    // max |Δv|^2 per step, as float bits: non-negative floats order like their bit patterns.
    std::vector<std::atomic<std::uint32_t>> change(static_cast<std::size_t>(iterations));
    for (std::size_t c = 0; c < deps.size(); ++c) {
        progress[c].store(0, std::memory_order_relaxed);
        busy[c].store(false, std::memory_order_relaxed);
    }
    for (std::size_t t = 0; t < change.size(); ++t) {
        finished[t].store(0, std::memory_order_relaxed);
        change[t].store(0, std::memory_order_relaxed);
    }
    std::atomic<int> open{0};          // lockstep: steps < open are done everywhere and checked
    std::atomic<int> stop{iterations}; // lowered when a step's change drops below tolerance
#pragma omp parallel if (parallel)
    {
        std::vector<float> scratch;
        // Threads start their sweeps at different chunks, so they rarely race for one.
        Index cursor = chunks * omp_get_thread_num() / std::max(1, omp_get_num_threads());
        int idle = 0;
        for (;;) {
            const int target = stop.load(std::memory_order_acquire);
            bool all_done = true, worked = false;
            for (Index n = 0; n < chunks && !worked; ++n) {
                const Index c = (cursor + n) % chunks;
                const auto u = static_cast<std::size_t>(c);
                const int step = progress[u].load(std::memory_order_acquire);
                if (step >= target)
                    continue;
                all_done = false;
                if ((lockstep && step > open.load(std::memory_order_acquire)) ||
                    busy[u].load(std::memory_order_relaxed))
                    continue;
                bool ready = true;
                for (Index d = deps[u].first; d <= deps[u].second && ready; ++d)
                    ready = progress[static_cast<std::size_t>(d)].load(std::memory_order_acquire) >= step;
                if (!ready || busy[u].exchange(true, std::memory_order_acquire))
                    continue;
                if (progress[u].load(std::memory_order_acquire) != step) { // another thread got there first
                    busy[u].store(false, std::memory_order_release);
                    continue;
                }
                const float m = work(step, c, scratch);
                std::uint32_t bits;
                std::memcpy(&bits, &m, sizeof bits);
                auto& ch = change[static_cast<std::size_t>(step)];
                std::uint32_t seen = ch.load(std::memory_order_relaxed);
                while (bits > seen && !ch.compare_exchange_weak(seen, bits, std::memory_order_relaxed)) {
                }
                progress[u].store(step + 1, std::memory_order_release); // publishes the chunk's writes
                busy[u].store(false, std::memory_order_release);
                // acq_rel: the last chunk of a step sees every chunk's change for it.
                if (finished[static_cast<std::size_t>(step)].fetch_add(1, std::memory_order_acq_rel) + 1 == chunks &&
                    lockstep) {
                    if (std::sqrt(double(bits_to_float(ch.load(std::memory_order_relaxed)))) < tolerance)
                        stop.store(step + 1, std::memory_order_relaxed);
                    open.store(step + 1, std::memory_order_release); // publishes `stop` too
                }
                cursor = c + 1;
                worked = true;
                idle = 0;
            }
            if (all_done)
                break;
            // Nothing ready: a chunk this one needs is in another thread's hands. Spin briefly,
            // then give the core away (that thread may be waiting for it).
            if (!worked && ++idle > 64)
                std::this_thread::yield();
        }
    }
    const int ran = std::min(stop.load(), iterations);
    res.iterations = ran;
    res.last_change = std::sqrt(double(bits_to_float(change[static_cast<std::size_t>(ran - 1)].load())));
    return ran;
}

} // namespace

GvfResult gradient_vector_flow(const core::ImageF& edge, const GvfParams& params)
{
    check_params(edge, params, "gradient_vector_flow");
    const int nx = edge.size[0], ny = edge.size[1], nz = edge.size[2];
    const int dim = nz > 1 ? 3 : 2;
    const std::size_t n = edge.voxel_count();
    Coefficients co = make_coefficients(edge, params, dim, n, [&](std::size_t m) {
        const auto i = static_cast<int>(m % static_cast<std::size_t>(nx));
        const auto j = static_cast<int>((m / static_cast<std::size_t>(nx)) % static_cast<std::size_t>(ny));
        const auto k = static_cast<int>(m / (static_cast<std::size_t>(nx) * static_cast<std::size_t>(ny)));
        return std::array<int, 3>{i, j, k};
    });

    GvfResult res;
    // v starts as ∇f (its z part is 0 in 2-D); ping-pong between two buffers.
    std::array<std::array<Field, 3>, 2> buf;
    buf[0] = std::move(co.grad);
    buf[1] = buf[0];
    const Index rows = Index(ny) * nz;
    // Chunks of ~8k voxels: long enough to amortise the scheduling, short enough to balance.
    const Index rows_per_chunk = std::max<Index>(1, 8192 / nx);
    const Index chunks = (rows + rows_per_chunk - 1) / rows_per_chunk;
    const Index reach = nz > 1 ? ny : 1; // rows between z (3-D) or y (2-D) neighbours
    ChunkDeps deps(static_cast<std::size_t>(chunks));
    for (Index c = 0; c < chunks; ++c) {
        const Index r0 = c * rows_per_chunk, r1 = std::min(rows, r0 + rows_per_chunk);
        deps[static_cast<std::size_t>(c)] = {std::max<Index>(0, r0 - reach) / rows_per_chunk,
                                             std::min(rows - 1, r1 - 1 + reach) / rows_per_chunk};
    }
    auto work = [&](int step, Index chunk, std::vector<float>& d2) {
        d2.resize(static_cast<std::size_t>(nx));
        const auto& cur = buf[static_cast<std::size_t>(step % 2)];
        auto& next = buf[static_cast<std::size_t>(1 - step % 2)];
        const Index r0 = chunk * rows_per_chunk, r1 = std::min(rows, r0 + rows_per_chunk);
        return dim == 3 ? full_chunk<3>(edge, co, cur, next, r0, r1, d2)
                        : full_chunk<2>(edge, co, cur, next, r0, r1, d2);
    };
    const int ran =
        run_steps(iteration_count(edge, params), deps, params.tolerance, Index(n) > kParallelMin, work, res);
    auto& v = buf[static_cast<std::size_t>(ran % 2)];

    res.field = VectorField(edge.geometry());
    for (std::size_t a = 0; a < 3; ++a)
        res.field.c[a].data = std::move(v[a]);
    return res;
}

GvfResult gradient_vector_flow(const core::ImageF& edge, const core::LabelImage3D& band, const GvfParams& params)
{
    check_params(edge, params, "gradient_vector_flow (band)");
    core::validate_geometry(band, "gradient_vector_flow: band");
    if (!core::same_grid(edge, band) || band.data.size() != edge.data.size())
        throw core::InvalidInputError("gradient_vector_flow: the band and the edge map are on different grids");
    const int nx = edge.size[0], ny = edge.size[1], nz = edge.size[2];
    const int dim = nz > 1 ? 3 : 2;

    // Compact band: voxel list in scan order (cache-friendly), row by row, so that every voxel's
    // row and each row's place in the list are known without a search.
    const std::size_t rows = static_cast<std::size_t>(ny) * static_cast<std::size_t>(nz);
    std::vector<std::size_t> voxels;
    std::vector<std::uint32_t> row_of;              // per voxel: its grid row j + ny * k
    std::vector<std::size_t> row_start(rows + 1, 0); // per row: where its voxels begin in the list
    for (std::size_t r = 0; r < rows; ++r) {
        row_start[r] = voxels.size();
        const std::size_t q0 = r * static_cast<std::size_t>(nx);
        for (std::size_t q = q0; q < q0 + static_cast<std::size_t>(nx); ++q)
            if (band.data[q] != 0) {
                voxels.push_back(q);
                row_of.push_back(static_cast<std::uint32_t>(r));
            }
    }
    if (voxels.size() >= std::numeric_limits<std::uint32_t>::max())
        throw core::InvalidInputError("gradient_vector_flow: the band has more than 2^32 - 1 voxels");
    row_start[rows] = voxels.size();
    const std::size_t count = voxels.size();
    auto ijk_of = [&](std::size_t m) {
        const std::size_t r = row_of[m];
        return std::array<int, 3>{static_cast<int>(voxels[m] - r * static_cast<std::size_t>(nx)),
                                  static_cast<int>(r % static_cast<std::size_t>(ny)),
                                  static_cast<int>(r / static_cast<std::size_t>(ny))};
    };

    // Neighbour table, nb[2a + s][m] (axis a, s = 0 below, 1 above): the compact index of voxel
    // m's neighbour, or m itself when the neighbour is outside the band or the image. Along x it
    // is the previous or next voxel of the list; along y and z a walk through the target row
    // beside the walk through m's own row (both sorted), so the table costs one pass over the
    // band and memory scales with the band, not the image (no full-image index map).
    std::array<std::vector<std::uint32_t>, 6> nb;
    for (auto& t : nb)
        t.resize(count);
    const Index cn = static_cast<Index>(count);
    const Index nrows = static_cast<Index>(rows);
    const Index x_stride[3] = {1, nx, Index(nx) * ny};
#pragma omp parallel for if (cn > kParallelMin) schedule(static)
    for (Index r = 0; r < nrows; ++r) {
        const std::size_t m0 = row_start[static_cast<std::size_t>(r)], m1 = row_start[static_cast<std::size_t>(r) + 1];
        if (m0 == m1)
            continue;
        const int j = static_cast<int>(r % ny), k = static_cast<int>(r / ny);
        for (std::size_t m = m0; m < m1; ++m) {
            const std::size_t q = voxels[m];
            const auto self = static_cast<std::uint32_t>(m);
            nb[0][m] = m > m0 && voxels[m - 1] == q - 1 ? self - 1 : self;
            nb[1][m] = m + 1 < m1 && voxels[m + 1] == q + 1 ? self + 1 : self;
        }
        const int pos[3] = {0, j, k};
        for (int a = 1; a < 3; ++a)
            for (int s = 0; s < 2; ++s) {
                auto& slots = nb[static_cast<std::size_t>(2 * a + s)];
                const int p = pos[a] + (s ? 1 : -1);
                if (p < 0 || p >= edge.size[static_cast<std::size_t>(a)]) {
                    for (std::size_t m = m0; m < m1; ++m)
                        slots[m] = static_cast<std::uint32_t>(m);
                    continue;
                }
                const Index row2 = r + (s ? 1 : -1) * (a == 1 ? Index(1) : Index(ny));
                std::size_t t = row_start[static_cast<std::size_t>(row2)];
                const std::size_t t1 = row_start[static_cast<std::size_t>(row2) + 1];
                for (std::size_t m = m0; m < m1; ++m) {
                    const auto target = static_cast<std::size_t>(static_cast<Index>(voxels[m]) + (s ? 1 : -1) * x_stride[a]);
                    while (t < t1 && voxels[t] < target)
                        ++t;
                    slots[m] = t < t1 && voxels[t] == target ? static_cast<std::uint32_t>(t) : static_cast<std::uint32_t>(m);
                }
            }
    }

    Coefficients co = make_coefficients(edge, params, dim, count, ijk_of);
    GvfResult res;
    std::array<std::array<Field, 3>, 2> buf;
    buf[0] = std::move(co.grad);
    buf[1] = buf[0];
    constexpr Index kChunk = 4096;
    const Index chunks = std::max<Index>(1, (cn + kChunk - 1) / kChunk);
    ChunkDeps deps(static_cast<std::size_t>(chunks));
    for (Index c = 0; c < chunks; ++c) {
        Index lo = c, hi = c;
        for (Index m = c * kChunk; m < std::min(cn, (c + 1) * kChunk); ++m)
            for (const auto& t : nb) {
                const Index d = static_cast<Index>(t[static_cast<std::size_t>(m)]) / kChunk;
                lo = std::min(lo, d);
                hi = std::max(hi, d);
            }
        deps[static_cast<std::size_t>(c)] = {lo, hi};
    }
    auto work = [&](int step, Index chunk, std::vector<float>&) {
        const auto& cur = buf[static_cast<std::size_t>(step % 2)];
        auto& next = buf[static_cast<std::size_t>(1 - step % 2)];
        const Index m0 = chunk * kChunk, m1 = std::min(cn, m0 + kChunk);
        return dim == 3 ? band_chunk<3>(co, nb, cur, next, m0, m1) : band_chunk<2>(co, nb, cur, next, m0, m1);
    };
    const int ran = run_steps(iteration_count(edge, params), deps, params.tolerance, cn > kParallelMin, work, res);
    const auto& v = buf[static_cast<std::size_t>(ran % 2)];

    res.field = VectorField(edge.geometry());
    for (std::size_t a = 0; a < 3; ++a)
        for (std::size_t m = 0; m < count; ++m)
            res.field.c[a].data[voxels[m]] = v[a][m];
    return res;
}

} // namespace lobe::seg
