// The spring pass on packed nodes (detail/spring_kernel.h). The AVX2 kernel takes four springs
// at a time: it loads each end's position and velocity records whole (no gathers, which this
// CPU family does slowly), forms the differences as one row per spring, sums the rows' products
// across into one lane per spring for the length and the closing speed, computes the four
// magnitudes with vector sqrt and division, and adds each magnitude times its own row to the
// spring's two nodes in spring order. docs/benchmarks.md ("Mass-spring step") measures it
// against the scalar loop.
#include "detail/spring_kernel.h"

#include <cmath>
#include <cstdint>
#include <cstdlib>

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define LOBE_SPRING_AVX2 1
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
struct Owned {
    std::size_t lo, span;
    Spill* spill;
    bool owns(std::size_t i) const { return i - lo < span; } // unsigned: below lo wraps round
};

// One spring, in the formula of the plain loop.
inline double spring_scalar(const SpringArrays& s, std::size_t k, const double* p, double* f, const Owned& own)
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
    if (own.owns(a)) {
        double* fa = f + 4 * a;
        fa[0] += m * dx;
        fa[1] += m * dy;
        fa[2] += m * dz;
    } else {
        own.spill->push_back({std::int32_t(a), {m * dx, m * dy, m * dz}});
    }
    if (own.owns(b)) {
        double* fb = f + 4 * b;
        fb[0] -= m * dx;
        fb[1] -= m * dy;
        fb[2] -= m * dz;
    } else {
        own.spill->push_back({std::int32_t(b), {-m * dx, -m * dy, -m * dz}});
    }
    return s.stiffness[k] * ext * ext;
}

double spring_forces_scalar(const SpringArrays& s, std::size_t first, std::size_t last, const double* p, double* f,
                            const Owned& own)
{
    double e = 0;
    for (std::size_t k = first; k < last; ++k)
        e += spring_scalar(s, k, p, f, own);
    return e;
}

#ifdef LOBE_SPRING_AVX2
// Adds a spring's force row g to f[a] and takes it from f[b]: 32-byte records, one load, add
// and store each. (Keeping a run of one a's sum in a register instead, to spare the store and
// reload between consecutive springs of the run, measured 5 % slower.)
__attribute__((target("avx2,fma"), always_inline)) inline void add_spring(__m256d g, std::size_t a, std::size_t b,
                                                                         double* f, const Owned& own)
{
    if (own.owns(a)) {
        double* fa = f + 4 * a;
        _mm256_store_pd(fa, _mm256_add_pd(_mm256_load_pd(fa), g));
    } else {
        alignas(32) double r[4];
        _mm256_store_pd(r, g);
        own.spill->push_back({std::int32_t(a), {r[0], r[1], r[2]}});
    }
    if (own.owns(b)) {
        double* fb = f + 4 * b;
        _mm256_store_pd(fb, _mm256_sub_pd(_mm256_load_pd(fb), g));
    } else {
        alignas(32) double r[4];
        _mm256_store_pd(r, g);
        own.spill->push_back({std::int32_t(b), {-r[0], -r[1], -r[2]}});
    }
}

// Lane j = the sum of row j's four lanes.
__attribute__((target("avx2,fma"), always_inline)) inline __m256d sum_rows(__m256d r0, __m256d r1, __m256d r2, __m256d r3)
{
    const __m256d h01 = _mm256_hadd_pd(r0, r1); // r0 01, r1 01, r0 23, r1 23
    const __m256d h23 = _mm256_hadd_pd(r2, r3);
    return _mm256_add_pd(_mm256_blend_pd(h01, h23, 0b1100), _mm256_permute2f128_pd(h01, h23, 0x21));
}

__attribute__((target("avx2,fma"))) double spring_forces_avx2(const SpringArrays& s, std::size_t first,
                                                                std::size_t last, const double* p, double* f,
                                                                const Owned& own)
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
        const __m256d l2 = sum_rows(_mm256_mul_pd(d0, d0), _mm256_mul_pd(d1, d1), _mm256_mul_pd(d2, d2),
                                    _mm256_mul_pd(d3, d3));
        const __m256d dot = sum_rows(_mm256_mul_pd(w0, d0), _mm256_mul_pd(w1, d1), _mm256_mul_pd(w2, d2),
                                     _mm256_mul_pd(w3, d3));
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

bool cpu_has_avx2()
{
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
}
#endif

} // namespace

bool cpu_has_simd_kernel()
{
#ifdef LOBE_SPRING_AVX2
    static const bool simd = cpu_has_avx2();
    return simd;
#else
    return false;
#endif
}

double spring_forces(const SpringArrays& s, std::size_t first, std::size_t last, const double* packed, double* f,
                     std::int32_t lo, std::int32_t hi, Spill* spill, bool simd)
{
    const Owned own{std::size_t(lo), std::size_t(hi) - std::size_t(lo), spill};
#ifdef LOBE_SPRING_AVX2
    if (simd && cpu_has_simd_kernel())
        return spring_forces_avx2(s, first, last, packed, f, own);
#endif
    return spring_forces_scalar(s, first, last, packed, f, own);
}

} // namespace lobe::mss::detail
