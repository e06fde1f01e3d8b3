// The force pass's kernels on packed nodes (detail/force_kernels.h): packing, springs, HAVP's
// volume terms, unpacking, each as an AVX2 + FMA kernel and a scalar loop. The spring kernel
// takes four springs at a time: it loads each end's position and velocity records whole (no
// gathers, which this CPU family does slowly), forms the differences as one row per spring,
// sums the rows' products across into one lane per spring for the length and the closing
// speed, computes the four magnitudes with vector sqrt and division, and adds each magnitude
// times its own row to the spring's two nodes in spring order. The volume kernel does the same
// for four tets. docs/benchmarks.md ("Kernels") measures them against the scalar loops.
#include "detail/force_kernels.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define LOBE_FORCE_AVX2 1
#include <immintrin.h>
#endif

namespace lobe::mss::detail {

double* aligned64(std::vector<double>& buf, std::size_t n)
{
    buf.resize(n + 8); // 8 doubles of slack: the first 64-byte boundary lies within them
    const auto addr = reinterpret_cast<std::uintptr_t>(buf.data());
    return buf.data() + ((64 - addr % 64) % 64) / sizeof(double);
}

namespace {

// Which nodes a pass may write: [lo, hi), the rest go to the spill.
// Check = false for the serial pass, which owns every node: the two compares and branches per
// spring measured 15 % of the serial step.
template <bool Check> struct Owned {
    std::size_t lo, span;
    Spill* spill;
    bool owns(std::size_t i) const { return !Check || i - lo < span; } // unsigned: below lo wraps round
};

// Adds g to f[i] (or hands it over).
template <bool Check>
inline void add_to(std::size_t i, double gx, double gy, double gz, double* f, const Owned<Check>& own)
{
    if (own.owns(i)) {
        f[4 * i] += gx;
        f[4 * i + 1] += gy;
        f[4 * i + 2] += gz;
    } else {
        own.spill->push_back({std::int32_t(i), {gx, gy, gz}});
    }
}

// One spring, in the formula of the plain loop.
template <bool Check>
inline double spring_scalar(const SpringArrays& s, std::size_t k, const double* p, double* f, const Owned<Check>& own)
{
    const std::size_t a = std::size_t(s.a[k]), b = std::size_t(s.b[k]);
    const double* pa = p + 8 * a;
    const double* pb = p + 8 * b;
    const double dx = pb[0] - pa[0], dy = pb[1] - pa[1], dz = pb[2] - pa[2];
    const double l = std::sqrt(dx * dx + dy * dy + dz * dz);
    const double inv = 1 / l;
    const double ext = l - s.rest_length[k];
    const double vrel = ((pb[4] - pa[4]) * dx + (pb[5] - pa[5]) * dy + (pb[6] - pa[6]) * dz) * inv;
    // Positive magnitude pulls a towards b: a stretched or separating spring.
    const double m = (s.stiffness[k] * ext + s.damping[k] * vrel) * inv;
    add_to(a, m * dx, m * dy, m * dz, f, own);
    add_to(b, -m * dx, -m * dy, -m * dz, f, own); // x + (-y) is x - y exactly
    return s.stiffness[k] * ext * ext;
}

template <bool Check>
double spring_forces_scalar(const SpringArrays& s, std::size_t first, std::size_t last, const double* p, double* f,
                            const Owned<Check>& own)
{
    double e = 0;
    for (std::size_t k = first; k < last; ++k)
        e += spring_scalar(s, k, p, f, own);
    return e;
}

// One tet's volume term, in the formula of the thesis's eq. 6.8 with its sign errors corrected.
template <bool Check>
inline double volume_scalar(const std::array<std::int32_t, 4>& q, double v0, double kv, const double* p, double* f,
                            const Owned<Check>& own)
{
    const double* x0 = p + 8 * std::size_t(q[0]);
    const double* x1 = p + 8 * std::size_t(q[1]);
    const double* x2 = p + 8 * std::size_t(q[2]);
    const double* x3 = p + 8 * std::size_t(q[3]);
    const double e1x = x1[0] - x0[0], e1y = x1[1] - x0[1], e1z = x1[2] - x0[2];
    const double e2x = x2[0] - x0[0], e2y = x2[1] - x0[1], e2z = x2[2] - x0[2];
    const double e3x = x3[0] - x0[0], e3y = x3[1] - x0[1], e3z = x3[2] - x0[2];
    // 6 grad_1 V = e2 x e3, 6 grad_2 V = e3 x e1, 6 grad_3 V = e1 x e2, and grad_0 V = -(their
    // sum), so the four sum to zero by construction.
    const double g1x = e2y * e3z - e2z * e3y, g1y = e2z * e3x - e2x * e3z, g1z = e2x * e3y - e2y * e3x;
    const double g2x = e3y * e1z - e3z * e1y, g2y = e3z * e1x - e3x * e1z, g2z = e3x * e1y - e3y * e1x;
    const double g3x = e1y * e2z - e1z * e2y, g3y = e1z * e2x - e1x * e2z, g3z = e1x * e2y - e1y * e2x;
    const double dv = (e1x * g1x + e1y * g1y + e1z * g1z) / 6 - v0;
    // E = k_V/2 ((V - V0)/V0)^2 with kv = k_V / V0^2, so f_i = -kv (V - V0) grad_i V.
    const double m = -kv * dv / 6;
    add_to(std::size_t(q[1]), m * g1x, m * g1y, m * g1z, f, own);
    add_to(std::size_t(q[2]), m * g2x, m * g2y, m * g2z, f, own);
    add_to(std::size_t(q[3]), m * g3x, m * g3y, m * g3z, f, own);
    add_to(std::size_t(q[0]), -m * (g1x + g2x + g3x), -m * (g1y + g2y + g3y), -m * (g1z + g2z + g3z), f, own);
    return kv * dv * dv;
}

NodeEnergies pack_nodes_scalar(const NodeArrays& n, std::size_t first, std::size_t last, double* p, double* f)
{
    const double gx = n.gravity[0], gy = n.gravity[1], gz = n.gravity[2], alpha = n.mass_damping;
    NodeEnergies e;
    for (std::size_t i = first; i < last; ++i) {
        const double m = n.mass[i];
        const double* xi = n.x + 3 * i;
        const double* vi = n.v + 3 * i;
        const double* ri = n.rest + 3 * i;
        double* pi = p + 8 * i;
        pi[0] = xi[0];
        pi[1] = xi[1];
        pi[2] = xi[2];
        pi[3] = 0;
        pi[4] = vi[0];
        pi[5] = vi[1];
        pi[6] = vi[2];
        pi[7] = 0;
        f[4 * i] = m * (gx - alpha * vi[0]);
        f[4 * i + 1] = m * (gy - alpha * vi[1]);
        f[4 * i + 2] = m * (gz - alpha * vi[2]);
        f[4 * i + 3] = 0;
        e.gravity -= m * (gx * (xi[0] - ri[0]) + gy * (xi[1] - ri[1]) + gz * (xi[2] - ri[2]));
        e.kinetic += 0.5 * m * (vi[0] * vi[0] + vi[1] * vi[1] + vi[2] * vi[2]);
    }
    return e;
}

void unpack_forces_scalar(const double* f, std::size_t first, std::size_t last, double* out)
{
    for (std::size_t i = first; i < last; ++i) {
        out[3 * i] = f[4 * i];
        out[3 * i + 1] = f[4 * i + 1];
        out[3 * i + 2] = f[4 * i + 2];
    }
}

#ifdef LOBE_FORCE_AVX2
// f[i] += g, or f[i] -= g when Subtract, on a 32-byte record: one load, add and store; a node
// the pass does not own gets the force handed over instead.
template <bool Subtract, bool Check>
__attribute__((target("avx2,fma"), always_inline)) inline void add_row(__m256d g, std::size_t i, double* f,
                                                                       const Owned<Check>& own)
{
    if (own.owns(i)) {
        double* fi = f + 4 * i;
        const __m256d old = _mm256_load_pd(fi);
        _mm256_store_pd(fi, Subtract ? _mm256_sub_pd(old, g) : _mm256_add_pd(old, g));
    } else {
        alignas(32) double r[4];
        _mm256_store_pd(r, g);
        const double sign = Subtract ? -1 : 1;
        own.spill->push_back({std::int32_t(i), {sign * r[0], sign * r[1], sign * r[2]}});
    }
}

// Adds a spring's force row g to f[a] and takes it from f[b]. Consecutive springs of one a
// chain through a store and its reload, and perf blames those stores, yet sparing them
// measured slower both ways tried: a run's sum kept in a register (5 %), and a segmented prefix
// sum over each block of four with one store per run (8 %; docs/benchmarks.md).
template <bool Check>
__attribute__((target("avx2,fma"), always_inline)) inline void add_spring(__m256d g, std::size_t a, std::size_t b,
                                                                          double* f, const Owned<Check>& own)
{
    add_row<false>(g, a, f, own);
    add_row<true>(g, b, f, own);
}

// Lane j = the sum of row j's four lanes.
__attribute__((target("avx2,fma"), always_inline)) inline __m256d sum_rows(__m256d r0, __m256d r1, __m256d r2,
                                                                           __m256d r3)
{
    const __m256d h01 = _mm256_hadd_pd(r0, r1); // r0 01, r1 01, r0 23, r1 23
    const __m256d h23 = _mm256_hadd_pd(r2, r3);
    return _mm256_add_pd(_mm256_blend_pd(h01, h23, 0b1100), _mm256_permute2f128_pd(h01, h23, 0x21));
}

template <bool Check>
__attribute__((target("avx2,fma"))) double spring_forces_avx2(const SpringArrays& s, std::size_t first,
                                                              std::size_t last, const double* p, double* f,
                                                              const Owned<Check>& own)
{
    __m256d energy = _mm256_setzero_pd();
    std::size_t k = first;
    for (; k + 4 <= last; k += 4) {
        const std::size_t a0 = std::size_t(s.a[k]), a1 = std::size_t(s.a[k + 1]), a2 = std::size_t(s.a[k + 2]),
                          a3 = std::size_t(s.a[k + 3]);
        const std::size_t b0 = std::size_t(s.b[k]), b1 = std::size_t(s.b[k + 1]), b2 = std::size_t(s.b[k + 2]),
                          b3 = std::size_t(s.b[k + 3]);
        // Row j: spring j's b - a (position, then velocity); lane 3 is the records' zero pad.
        const __m256d d0 = _mm256_sub_pd(_mm256_load_pd(p + 8 * b0), _mm256_load_pd(p + 8 * a0));
        const __m256d d1 = _mm256_sub_pd(_mm256_load_pd(p + 8 * b1), _mm256_load_pd(p + 8 * a1));
        const __m256d d2 = _mm256_sub_pd(_mm256_load_pd(p + 8 * b2), _mm256_load_pd(p + 8 * a2));
        const __m256d d3 = _mm256_sub_pd(_mm256_load_pd(p + 8 * b3), _mm256_load_pd(p + 8 * a3));
        const __m256d w0 = _mm256_sub_pd(_mm256_load_pd(p + 8 * b0 + 4), _mm256_load_pd(p + 8 * a0 + 4));
        const __m256d w1 = _mm256_sub_pd(_mm256_load_pd(p + 8 * b1 + 4), _mm256_load_pd(p + 8 * a1 + 4));
        const __m256d w2 = _mm256_sub_pd(_mm256_load_pd(p + 8 * b2 + 4), _mm256_load_pd(p + 8 * a2 + 4));
        const __m256d w3 = _mm256_sub_pd(_mm256_load_pd(p + 8 * b3 + 4), _mm256_load_pd(p + 8 * a3 + 4));
        // The two dot products per spring as one lane per spring: the rows' products summed
        // across (no transpose of the rows themselves).
        const __m256d l2 =
            sum_rows(_mm256_mul_pd(d0, d0), _mm256_mul_pd(d1, d1), _mm256_mul_pd(d2, d2), _mm256_mul_pd(d3, d3));
        const __m256d dot =
            sum_rows(_mm256_mul_pd(w0, d0), _mm256_mul_pd(w1, d1), _mm256_mul_pd(w2, d2), _mm256_mul_pd(w3, d3));
        const __m256d l = _mm256_sqrt_pd(l2);
        const __m256d inv = _mm256_div_pd(_mm256_set1_pd(1.0), l);
        const __m256d ext = _mm256_sub_pd(l, _mm256_loadu_pd(s.rest_length + k));
        const __m256d vrel = _mm256_mul_pd(dot, inv);
        const __m256d ks = _mm256_loadu_pd(s.stiffness + k);
        const __m256d m =
            _mm256_mul_pd(_mm256_fmadd_pd(ks, ext, _mm256_mul_pd(_mm256_loadu_pd(s.damping + k), vrel)), inv);
        energy = _mm256_fmadd_pd(_mm256_mul_pd(ks, ext), ext, energy);
        // Each spring's force: its magnitude broadcast times its own row (whose pad stays 0).
        const __m256d g0 = _mm256_mul_pd(_mm256_permute4x64_pd(m, 0x00), d0);
        const __m256d g1 = _mm256_mul_pd(_mm256_permute4x64_pd(m, 0x55), d1);
        const __m256d g2 = _mm256_mul_pd(_mm256_permute4x64_pd(m, 0xAA), d2);
        const __m256d g3 = _mm256_mul_pd(_mm256_permute4x64_pd(m, 0xFF), d3);
        add_spring(g0, a0, b0, f, own);
        add_spring(g1, a1, b1, f, own);
        add_spring(g2, a2, b2, f, own);
        add_spring(g3, a3, b3, f, own);
    }
    alignas(32) double lanes[4];
    _mm256_store_pd(lanes, energy);
    double e = (lanes[0] + lanes[1]) + (lanes[2] + lanes[3]);
    for (; k < last; ++k)
        e += spring_scalar(s, k, p, f, own);
    return e;
}

// a x b on x y z 0 rows: a.yzx b.zxy - a.zxy b.yzx (lane 3 stays 0).
__attribute__((target("avx2,fma"), always_inline)) inline __m256d cross_rows(__m256d a_yzx, __m256d a_zxy,
                                                                             __m256d b_yzx, __m256d b_zxy)
{
    return _mm256_fmsub_pd(a_yzx, b_zxy, _mm256_mul_pd(a_zxy, b_yzx));
}

// One tet's edges and the three gradient rows 6 grad_{1,2,3} V.
struct TetRows {
    __m256d e1, g1, g2, g3;
};

__attribute__((target("avx2,fma"), always_inline)) inline TetRows tet_rows(const std::array<std::int32_t, 4>& q,
                                                                           const double* p)
{
    const __m256d x0 = _mm256_load_pd(p + 8 * std::size_t(q[0]));
    const __m256d e1 = _mm256_sub_pd(_mm256_load_pd(p + 8 * std::size_t(q[1])), x0);
    const __m256d e2 = _mm256_sub_pd(_mm256_load_pd(p + 8 * std::size_t(q[2])), x0);
    const __m256d e3 = _mm256_sub_pd(_mm256_load_pd(p + 8 * std::size_t(q[3])), x0);
    constexpr int kYzx = 0xC9, kZxy = 0xD2; // lanes (1 2 0 3) and (2 0 1 3)
    const __m256d e1a = _mm256_permute4x64_pd(e1, kYzx), e1b = _mm256_permute4x64_pd(e1, kZxy);
    const __m256d e2a = _mm256_permute4x64_pd(e2, kYzx), e2b = _mm256_permute4x64_pd(e2, kZxy);
    const __m256d e3a = _mm256_permute4x64_pd(e3, kYzx), e3b = _mm256_permute4x64_pd(e3, kZxy);
    return {e1, cross_rows(e2a, e2b, e3a, e3b), cross_rows(e3a, e3b, e1a, e1b), cross_rows(e1a, e1b, e2a, e2b)};
}

template <bool Check>
__attribute__((target("avx2,fma"))) double
volume_forces_avx2(const std::array<std::int32_t, 4>* tets, const double* rest_volume, const double* kv,
                   std::size_t first, std::size_t last, const double* p, double* f, const Owned<Check>& own)
{
    // Four tets at a time: their 6 V as one lane each, then each tet's magnitude broadcast onto
    // its own gradient rows.
    __m256d energy = _mm256_setzero_pd();
    std::size_t t = first;
    for (; t + 4 <= last; t += 4) {
        const TetRows r0 = tet_rows(tets[t], p), r1 = tet_rows(tets[t + 1], p), r2 = tet_rows(tets[t + 2], p),
                      r3 = tet_rows(tets[t + 3], p);
        const __m256d vol6 = sum_rows(_mm256_mul_pd(r0.e1, r0.g1), _mm256_mul_pd(r1.e1, r1.g1),
                                      _mm256_mul_pd(r2.e1, r2.g1), _mm256_mul_pd(r3.e1, r3.g1));
        // Products by 1/6, not divisions: the divider's latency sat on this chain (to rounding).
        const __m256d sixth = _mm256_set1_pd(1.0 / 6);
        const __m256d dv = _mm256_fmsub_pd(vol6, sixth, _mm256_loadu_pd(rest_volume + t));
        const __m256d k = _mm256_loadu_pd(kv + t);
        const __m256d m = _mm256_mul_pd(_mm256_mul_pd(k, dv), _mm256_set1_pd(-1.0 / 6));
        energy = _mm256_fmadd_pd(_mm256_mul_pd(k, dv), dv, energy);
        const TetRows* rows[4] = {&r0, &r1, &r2, &r3};
        const __m256d mj[4] = {_mm256_permute4x64_pd(m, 0x00), _mm256_permute4x64_pd(m, 0x55),
                               _mm256_permute4x64_pd(m, 0xAA), _mm256_permute4x64_pd(m, 0xFF)};
        for (std::size_t j = 0; j < 4; ++j) {
            const auto& q = tets[t + j];
            const __m256d f1 = _mm256_mul_pd(mj[j], rows[j]->g1), f2 = _mm256_mul_pd(mj[j], rows[j]->g2),
                          f3 = _mm256_mul_pd(mj[j], rows[j]->g3);
            add_row<false>(f1, std::size_t(q[1]), f, own);
            add_row<false>(f2, std::size_t(q[2]), f, own);
            add_row<false>(f3, std::size_t(q[3]), f, own);
            add_row<true>(_mm256_add_pd(_mm256_add_pd(f1, f2), f3), std::size_t(q[0]), f, own);
        }
    }
    alignas(32) double lanes[4];
    _mm256_store_pd(lanes, energy);
    double e = (lanes[0] + lanes[1]) + (lanes[2] + lanes[3]);
    for (; t < last; ++t)
        e += volume_scalar(tets[t], rest_volume[t], kv[t], p, f, own);
    return e;
}

// Packing with 4-double loads of each node's x y z (the fourth lane, the next node's x, is
// zeroed): the scalar loop's energy sums chain every node through two additions, these keep
// four lanes. The last node of the arrays is done by the scalar loop (its load would run past
// the end).
__attribute__((target("avx2,fma"))) NodeEnergies pack_nodes_avx2(const NodeArrays& n, std::size_t first,
                                                                 std::size_t last, double* p, double* f)
{
    const std::size_t vec_last = std::min(last, n.count > 0 ? n.count - 1 : 0);
    const __m256d g = _mm256_setr_pd(n.gravity[0], n.gravity[1], n.gravity[2], 0);
    const __m256d alpha = _mm256_set1_pd(n.mass_damping);
    const __m256d zero = _mm256_setzero_pd();
    __m256d eg = zero, ek = zero;
    std::size_t i = first;
    for (; i < vec_last; ++i) {
        const __m256d m = _mm256_set1_pd(n.mass[i]);
        const __m256d xi = _mm256_blend_pd(_mm256_loadu_pd(n.x + 3 * i), zero, 0b1000);
        const __m256d vi = _mm256_blend_pd(_mm256_loadu_pd(n.v + 3 * i), zero, 0b1000);
        const __m256d ri = _mm256_blend_pd(_mm256_loadu_pd(n.rest + 3 * i), zero, 0b1000);
        _mm256_store_pd(p + 8 * i, xi);
        _mm256_store_pd(p + 8 * i + 4, vi);
        _mm256_store_pd(f + 4 * i, _mm256_mul_pd(m, _mm256_fnmadd_pd(alpha, vi, g)));
        eg = _mm256_fnmadd_pd(_mm256_mul_pd(m, g), _mm256_sub_pd(xi, ri), eg);
        ek = _mm256_fmadd_pd(_mm256_mul_pd(m, vi), vi, ek);
    }
    alignas(32) double lg[4], lk[4];
    _mm256_store_pd(lg, eg);
    _mm256_store_pd(lk, ek);
    NodeEnergies e = pack_nodes_scalar(n, i, last, p, f);
    e.gravity += (lg[0] + lg[1]) + (lg[2] + lg[3]);
    e.kinetic += 0.5 * ((lk[0] + lk[1]) + (lk[2] + lk[3]));
    return e;
}

// Unpacking with 4-double stores: node i's store also writes 0 over node i + 1's x, which
// node i + 1's store then overwrites, so the range's last node is done alone.
__attribute__((target("avx2,fma"))) void unpack_forces_avx2(const double* f, std::size_t first, std::size_t last,
                                                            double* out)
{
    std::size_t i = first;
    for (; i + 1 < last; ++i)
        _mm256_storeu_pd(out + 3 * i, _mm256_load_pd(f + 4 * i));
    unpack_forces_scalar(f, i, last, out);
}

bool cpu_has_avx2()
{
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
}
#endif

} // namespace

bool cpu_has_simd_kernel()
{
#ifdef LOBE_FORCE_AVX2
    static const bool simd = cpu_has_avx2();
    return simd;
#else
    return false;
#endif
}

namespace {

template <bool Check>
double springs_dispatch(const SpringArrays& s, std::size_t first, std::size_t last, const double* packed, double* f,
                        const Owned<Check>& own, bool simd)
{
#ifdef LOBE_FORCE_AVX2
    if (simd && cpu_has_simd_kernel())
        return spring_forces_avx2(s, first, last, packed, f, own);
#endif
    return spring_forces_scalar(s, first, last, packed, f, own);
}

template <bool Check>
double volume_dispatch(const std::array<std::int32_t, 4>* tets, const double* rest_volume, const double* kv,
                       std::size_t first, std::size_t last, const double* packed, double* f, const Owned<Check>& own,
                       bool simd)
{
#ifdef LOBE_FORCE_AVX2
    if (simd && cpu_has_simd_kernel())
        return volume_forces_avx2(tets, rest_volume, kv, first, last, packed, f, own);
#endif
    double e = 0;
    for (std::size_t t = first; t < last; ++t)
        e += volume_scalar(tets[t], rest_volume[t], kv[t], packed, f, own);
    return e;
}

} // namespace

double spring_forces(const SpringArrays& s, std::size_t first, std::size_t last, const double* packed, double* f,
                     std::int32_t lo, std::int32_t hi, Spill* spill, bool simd)
{
    const std::size_t span = std::size_t(hi) - std::size_t(lo);
    if (!spill)
        return springs_dispatch(s, first, last, packed, f, Owned<false>{std::size_t(lo), span, nullptr}, simd);
    return springs_dispatch(s, first, last, packed, f, Owned<true>{std::size_t(lo), span, spill}, simd);
}

double volume_forces(const std::array<std::int32_t, 4>* tets, const double* rest_volume, const double* kv,
                     std::size_t first, std::size_t last, const double* packed, double* f, std::int32_t lo,
                     std::int32_t hi, Spill* spill, bool simd)
{
    const std::size_t span = std::size_t(hi) - std::size_t(lo);
    if (!spill)
        return volume_dispatch(tets, rest_volume, kv, first, last, packed, f,
                               Owned<false>{std::size_t(lo), span, nullptr}, simd);
    return volume_dispatch(tets, rest_volume, kv, first, last, packed, f, Owned<true>{std::size_t(lo), span, spill},
                           simd);
}

NodeEnergies pack_nodes(const NodeArrays& nodes, std::size_t first, std::size_t last, double* packed, double* f,
                        bool simd)
{
#ifdef LOBE_FORCE_AVX2
    if (simd && cpu_has_simd_kernel())
        return pack_nodes_avx2(nodes, first, last, packed, f);
#endif
    return pack_nodes_scalar(nodes, first, last, packed, f);
}

void unpack_forces(const double* f, std::size_t first, std::size_t last, double* out, bool simd)
{
#ifdef LOBE_FORCE_AVX2
    if (simd && cpu_has_simd_kernel())
        return unpack_forces_avx2(f, first, last, out);
#endif
    unpack_forces_scalar(f, first, last, out);
}

} // namespace lobe::mss::detail
