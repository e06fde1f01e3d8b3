#include "lobe/mesh/quality.h"

#include "lobe/core/errors.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>

#include <cmath>
#include <random>

using namespace lobe;
using core::Vec3;
using mesh::Measure;

namespace {

const double kPi = std::acos(-1.0);

// Regular tet of edge 1 (alternate corners of a cube of side 1/sqrt2), positively oriented.
std::array<Vec3, 4> regular_tet()
{
    const double s = 1 / std::sqrt(8.0);
    return {Vec3{s, s, s}, Vec3{s, -s, -s}, Vec3{-s, -s, s}, Vec3{-s, s, -s}};
}

mesh::TetMeasures measures(const std::array<Vec3, 4>& p, double h = 1.0, mesh::QualityParams params = {})
{
    return mesh::tet_measures(p[0], p[1], p[2], p[3], h, params);
}

// Rotation about an arbitrary axis (Rodrigues) then scale and shift.
Vec3 transform(const Vec3& p, double scale)
{
    const Vec3 k = core::normalized(Vec3{1, 2, 3});
    const double a = 0.7;
    const Vec3 r = p * std::cos(a) + core::cross(k, p) * std::sin(a) + k * (core::dot(k, p) * (1 - std::cos(a)));
    return r * scale + Vec3{10, -4, 7};
}

} // namespace

TEST(TetQuality, RegularTetScoresOneOnEveryMeasure)
{
    // Every measure is divided by its regular-tet value, so only rounding separates it from 1.
    const auto m = measures(regular_tet());
    for (int i = 0; i < mesh::kMeasureCount; ++i)
        EXPECT_NEAR(m.values[i], 1.0, 1e-12) << mesh::measure_name(static_cast<Measure>(i));
    EXPECT_NEAR(m.min_dihedral_deg, std::acos(1.0 / 3) * 180 / kPi, 1e-9);
    EXPECT_NEAR(m.radius_edge_ratio, std::sqrt(6.0) / 4, 1e-12); // R = sqrt6/4 l, l_min = l
    EXPECT_NEAR(m.lambda_max, 1 / (3 * std::sqrt(2.0)), 1e-12);  // the spec's l/(3 sqrt2)
}

TEST(TetQuality, RightCornerTetMatchesHandComputedValues)
{
    // (0,0,0), (1,0,0), (0,1,0), (0,0,1): V = 1/6, three edges 1 and three sqrt2 (sum l^2 = 9),
    // face areas sqrt3/2 (opposite the corner) and 1/2. Values derived by hand; the tolerance is
    // rounding (1e-9) since each is a closed form.
    const std::array<Vec3, 4> p{Vec3{0, 0, 0}, Vec3{1, 0, 0}, Vec3{0, 1, 0}, Vec3{0, 0, 1}};
    const auto m = measures(p, 1.0);
    const double tol = 1e-9;
    // Dihedral angles: 90 deg at the corner's edges, arccos(1/sqrt3) = 54.7356 deg at the others.
    EXPECT_NEAR(m.min_dihedral_deg, std::acos(1 / std::sqrt(3.0)) * 180 / kPi, tol);
    EXPECT_NEAR(m.max_dihedral_deg, 90.0, tol);
    EXPECT_NEAR(m[Measure::MinDihedral], std::acos(1 / std::sqrt(3.0)) / std::acos(1.0 / 3), tol);
    EXPECT_NEAR(m[Measure::MaxDihedral], (kPi / 2) / (kPi - std::acos(1.0 / 3)), tol);
    // Circumcentre (1/2,1/2,1/2), R = sqrt3/2, l_min = 1: B = 0.866; 1/B normalised = (sqrt6/4)/(sqrt3/2) = 1/sqrt2.
    EXPECT_NEAR(m.radius_edge_ratio, std::sqrt(3.0) / 2, tol);
    EXPECT_NEAR(m[Measure::RadiusEdgeInverse], 1 / std::sqrt(2.0), tol);
    // The circumcentre lies outside (x+y+z = 3/2 > 1), so r_mc is the slanted face's circumcircle,
    // sqrt6/3. Size-and-shape: (r_reg/r_mc)^2 = ((sqrt6/4)/(sqrt6/3))^2 = 9/16. Scale-invariant:
    // (V/r_mc^3) / (V_reg/r_reg^3) = (3/(4 sqrt6)) / (8/(9 sqrt3)) = 27/(32 sqrt2).
    EXPECT_NEAR(m[Measure::InterpolationSizeShape], 9.0 / 16, tol);
    EXPECT_NEAR(m[Measure::Interpolation], 27 / (32 * std::sqrt(2.0)), tol);
    // Stiffness V grad grad^T with gradients (-1,-1,-1), e1, e2, e3: eigenvalues 0, V, V, 4V.
    EXPECT_NEAR(m.lambda_max, 4.0 / 6, tol);
    // V^(1/3)/lambda against the regular (6 sqrt2)^(-1/3) / (1/(3 sqrt2)): 2^(-4/3).
    EXPECT_NEAR(m[Measure::Conditioning], std::pow(2.0, -4.0 / 3), tol);
    // V/(sum A^2)^(3/4): sum A^2 = 3/2 against 3/4 for the regular tet: 2^(-1/4).
    EXPECT_NEAR(m[Measure::ConditioningSmooth], std::pow(2.0, -0.25), tol);
    // (72 sqrt3 V / 9^(3/2))^3 = (4 sqrt3 / 9)^3.
    EXPECT_NEAR(m[Measure::Fast], std::pow(4 * std::sqrt(3.0) / 9, 3), tol);
    // Gradient factor g = (sum A_i A_j l_ij^2 + 6V max_i sum_j A_j l_ij) / (V sum A):
    // right corner (3 sqrt3/4 + 3/2 + sqrt3/2 + sqrt2) / ((sqrt3/2 + 3/2)/6); regular
    // (9/8 + 6 (1/(6 sqrt2)) (3 sqrt3/4)) / (sqrt3/(6 sqrt2)).
    const double s3 = std::sqrt(3.0), s2 = std::sqrt(2.0);
    const double g = (3 * s3 / 4 + 1.5 + s3 / 2 + s2) / ((s3 / 2 + 1.5) / 6);
    const double g_reg = (9.0 / 8 + (1 / s2) * (3 * s3 / 4)) / (s3 / (6 * s2));
    EXPECT_NEAR(m[Measure::GradientSizeShape], g_reg / g, tol);
    EXPECT_NEAR(m[Measure::Gradient], std::pow(2.0, 1.0 / 6) * g_reg / g, tol); // (V/V_reg)^(1/3) = 2^(1/6)
    // Combined, eq 6.16 with lambda ~ sum A^2/(18V): conditioning ratio 2^(1/4), interpolation
    // ratio 2^(-1/6) g/g_reg; Q = 1/(0.6 r_c + 0.4 r_i)^2.
    const double den = 0.6 * std::pow(2.0, 0.25) + 0.4 * std::pow(2.0, -1.0 / 6) * g / g_reg;
    EXPECT_NEAR(m[Measure::Combined], 1 / (den * den), tol);
    EXPECT_NEAR(m[Measure::Combined], 0.72801, 1e-5); // the same, evaluated by hand
}

TEST(TetQuality, InvariantUnderRotationTranslationAndScale)
{
    // Shape measures do not depend on placement or size (the size-and-shape ones are given a
    // reference edge scaled alike); only rounding separates the values.
    const std::array<Vec3, 4> p{Vec3{0, 0, 0}, Vec3{1.3, 0.1, 0}, Vec3{0.2, 0.9, 0.1}, Vec3{0.3, 0.4, 0.8}};
    const double scale = 37.5;
    std::array<Vec3, 4> q;
    for (int i = 0; i < 4; ++i)
        q[i] = transform(p[i], scale);
    mesh::QualityParams exact;
    exact.exact_lambda = true;
    for (const auto& params : {mesh::QualityParams{}, exact}) {
        const auto a = measures(p, 1.0, params);
        const auto b = measures(q, scale, params);
        for (int i = 0; i < mesh::kMeasureCount; ++i)
            EXPECT_NEAR(a.values[i], b.values[i], 1e-9) << mesh::measure_name(static_cast<Measure>(i));
        EXPECT_NEAR(b.lambda_max, scale * a.lambda_max, 1e-9 * scale); // lambda_max scales as a length
    }
}

TEST(TetQuality, InvertedTetIsNegativeOnSignedMeasures)
{
    auto p = regular_tet();
    std::swap(p[0], p[1]);
    const auto m = measures(p);
    // An odd permutation flips the volume's sign only: |value| stays 1.
    for (auto k : {Measure::Interpolation, Measure::Gradient, Measure::Conditioning, Measure::Combined, Measure::Fast})
        EXPECT_NEAR(m[k], -1.0, 1e-12) << mesh::measure_name(k);
}

TEST(TetQuality, DegenerateShapesReachTheirLimits)
{
    const double eps = 1e-7;
    // Sliver: a unit square with the diagonal corners lifted by +-eps. All volume measures -> 0
    // (they scale like eps); the dihedral angles go to 0 and 180 deg; but the circumsphere tends to
    // the square's circle (R = sqrt2/2, l_min = 1) so 1/B tends to (sqrt6/4)/(sqrt2/2) = sqrt3/2:
    // the radius-edge measure's known blindness to slivers.
    const std::array<Vec3, 4> sliver{Vec3{0, 0, eps}, Vec3{1, 0, -eps}, Vec3{1, 1, eps}, Vec3{0, 1, -eps}};
    auto m = measures(sliver);
    if (m.volume < 0) {
        auto s = sliver;
        std::swap(s[0], s[1]);
        m = measures(s);
    }
    for (auto k : {Measure::Interpolation, Measure::Conditioning, Measure::ConditioningSmooth, Measure::Combined,
                   Measure::Fast, Measure::GradientSizeShape, Measure::MinDihedral, Measure::MaxDihedral})
        EXPECT_LT(m[k], 1e-5) << mesh::measure_name(k); // each is O(eps) or smaller
    EXPECT_NEAR(m[Measure::RadiusEdgeInverse], std::sqrt(3.0) / 2, 1e-6);

    // Needle: an equilateral triangle of side eps and an apex at distance 1. Conditioning and
    // the combined measure -> 0, but no angle is bad for the gradient: the dihedral angles tend
    // to 60 deg (long edges) and 90 deg (short edges).
    const double h = std::sqrt(3.0) / 2;
    std::array<Vec3, 4> needle{Vec3{0, 0, 0}, Vec3{eps, 0, 0}, Vec3{eps / 2, eps * h, 0}, Vec3{eps / 2, eps * h / 3, 1}};
    m = measures(needle);
    ASSERT_GT(m.volume, 0);
    EXPECT_NEAR(m.min_dihedral_deg, 60.0, 1e-3); // the triangle's angles, to O(eps)
    EXPECT_NEAR(m.max_dihedral_deg, 90.0, 1e-3);
    EXPECT_LT(m[Measure::Combined], 1e-6);
    EXPECT_LT(m[Measure::Fast], 1e-6);
    EXPECT_LT(m[Measure::Conditioning], 1e-3);

    // Cap: apex eps above the centre of an equilateral base: three dihedral angles -> 180 deg,
    // three -> 0.
    std::array<Vec3, 4> cap{Vec3{0, 0, 0}, Vec3{1, 0, 0}, Vec3{0.5, h, 0}, Vec3{0.5, h / 3, eps}};
    m = measures(cap);
    ASSERT_GT(m.volume, 0);
    EXPECT_GT(m.max_dihedral_deg, 179.99); // 180 - O(eps) degrees
    EXPECT_LT(m.min_dihedral_deg, 0.01);
    EXPECT_LT(m[Measure::Gradient], 1e-5); // a near-180 angle ruins the gradient bound
    EXPECT_LT(m[Measure::Combined], 1e-6);

    // Wedge: a short edge of length eps (two vertices together), the other two far apart:
    // the dihedral angle at the opposite edge -> 0.
    std::array<Vec3, 4> wedge{Vec3{0, 0, 0}, Vec3{eps, 0, 0}, Vec3{0.5, 1, 0}, Vec3{0.5, 0, 1}};
    m = measures(wedge);
    ASSERT_GT(m.volume, 0);
    EXPECT_LT(m.min_dihedral_deg, 1e-3);
    EXPECT_LT(m[Measure::Combined], 1e-6);
    EXPECT_LT(m[Measure::Fast], 1e-6);

    // Exactly flat: every volume measure is exactly 0 and 1/B is reported as 0.
    const std::array<Vec3, 4> flat{Vec3{0, 0, 0}, Vec3{1, 0, 0}, Vec3{0, 1, 0}, Vec3{0.3, 0.3, 0}};
    m = measures(flat);
    for (auto k : {Measure::Interpolation, Measure::Combined, Measure::Fast, Measure::RadiusEdgeInverse})
        EXPECT_EQ(m[k], 0.0) << mesh::measure_name(k);
}

TEST(TetQuality, LambdaEstimateLiesWithinTheThesisBounds)
{
    // eq 6.13: sum A^2/(27V) <= lambda_max <= sum A^2/(9V), i.e. the estimate sum A^2/(18V) is
    // within a factor 2 (upper) and 1.5 (lower) of the exact value, for any tet.
    std::uint32_t seed = 12345;
    auto rnd = [&] {
        seed = seed * 1664525u + 1013904223u;
        return (seed >> 8) / double(1 << 24);
    };
    for (int n = 0; n < 200; ++n) {
        std::array<Vec3, 4> p;
        for (auto& v : p)
            v = {rnd(), rnd(), rnd()};
        if (std::abs(core::signed_volume(p[0], p[1], p[2], p[3])) < 1e-6)
            continue;
        const double exact = mesh::stiffness_lambda_max(p[0], p[1], p[2], p[3]);
        const double est = mesh::stiffness_lambda_max_estimate(p[0], p[1], p[2], p[3]);
        EXPECT_LE(est / exact, 1.5 * (1 + 1e-9));
        EXPECT_GE(est / exact, 0.5 * (1 - 1e-9));
    }
}

TEST(TriangleQuality, EquilateralIsOneAndRightIsoscelesKnown)
{
    EXPECT_NEAR(mesh::triangle_quality({0, 0, 0}, {1, 0, 0}, {0.5, std::sqrt(3.0) / 2, 0}), 1.0, 1e-12);
    // (0,0),(1,0),(0,1): A = 1/2, sum l^2 = 4: (4 sqrt3 / 8)^4 = (sqrt3/2)^4 = 9/16.
    EXPECT_NEAR(mesh::triangle_quality({0, 0, 0}, {1, 0, 0}, {0, 1, 0}), 9.0 / 16, 1e-12);
    EXPECT_EQ(mesh::triangle_quality({0, 0, 0}, {1, 0, 0}, {2, 0, 0}), 0.0); // collinear
}

TEST(MeshQuality, SummariesBandsAndWorstElements)
{
    // Two tissues: a regular tet (label 1) and a right-corner tet (label 2, combined 0.728),
    // plus a flattened tet in label 2 (combined < 0.3).
    core::TetMesh m;
    const auto r = regular_tet();
    m.vertices = {r[0], r[1], r[2], r[3], {10, 0, 0}, {11, 0, 0}, {10, 1, 0}, {10, 0, 1},
                  {20, 0, 0}, {21, 0, 0}, {20, 1, 0}, {20.3, 0.3, 0.02}};
    m.tets = {{0, 1, 2, 3}, {4, 5, 6, 7}, {8, 9, 10, 11}};
    m.tet_labels = {1, 2, 2};
    mesh::QualityParams params;
    params.worst_count = 2;
    const auto q = mesh::evaluate_quality(m, params);
    ASSERT_EQ(q.tissues.size(), 2u);
    EXPECT_EQ(q.tissues[0].label, 1);
    EXPECT_EQ(q.tissues[1].tets, 2);
    const auto& comb = q.tissues[1].measures[int(Measure::Combined)];
    EXPECT_EQ(comb.bands[0], 1); // the flat tet
    EXPECT_EQ(comb.bands[3], 1); // the right-corner tet (0.728 >= 0.7)
    EXPECT_NEAR(comb.max, 0.72801, 1e-5);
    EXPECT_NEAR(q.all.measures[int(Measure::Combined)].max, 1.0, 1e-12);
    std::int64_t in_hist = 0;
    for (auto c : q.all.measures[0].histogram)
        in_hist += c;
    EXPECT_EQ(in_hist, 3); // every tet lands in exactly one bin
    ASSERT_EQ(q.worst.size(), 2u);
    EXPECT_EQ(q.worst[0].tet, 2); // the flat one first
    EXPECT_EQ(q.worst[1].tet, 1);
    EXPECT_NEAR(q.all.volume, 1 / (6 * std::sqrt(2.0)) + 1.0 / 6 + 0.02 / 6, 1e-12);
    EXPECT_FALSE(mesh::format_quality_report(q).empty());
}

TEST(MeshQuality, RefusesMalformedMeshes)
{
    core::TetMesh m;
    EXPECT_THROW(mesh::evaluate_quality(m), core::InvalidInputError); // empty
    m.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    m.tets = {{0, 2, 1, 3}}; // negatively oriented
    m.tet_labels = {1};
    EXPECT_THROW(mesh::evaluate_quality(m), core::InvalidInputError);
}

namespace {

// n^3 cubes of side 1, each split into the 6 Kuhn tets (all positively oriented).
core::TetMesh kuhn_cube(int n)
{
    core::TetMesh m;
    auto id = [n](int i, int j, int k) { return i + (n + 1) * (j + (n + 1) * k); };
    for (int k = 0; k <= n; ++k)
        for (int j = 0; j <= n; ++j)
            for (int i = 0; i <= n; ++i)
                m.vertices.push_back({double(i), double(j), double(k)});
    const int perms[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
    for (int k = 0; k < n; ++k)
        for (int j = 0; j < n; ++j)
            for (int i = 0; i < n; ++i)
                for (const auto& p : perms) {
                    int c[3] = {i, j, k};
                    std::array<std::int32_t, 4> t{};
                    t[0] = id(c[0], c[1], c[2]);
                    for (int s = 0; s < 3; ++s) {
                        ++c[p[s]];
                        t[static_cast<std::size_t>(s + 1)] = id(c[0], c[1], c[2]);
                    }
                    if (core::signed_volume(m.vertices[t[0]], m.vertices[t[1]], m.vertices[t[2]], m.vertices[t[3]]) < 0)
                        std::swap(t[0], t[1]);
                    m.tets.push_back(t);
                    m.tet_labels.push_back(1);
                }
    return m;
}

// Condition number of the P1 Laplacian stiffness matrix with the boundary vertices fixed
// (Dirichlet), so that it is positive definite: lambda_max / lambda_min.
double stiffness_condition(const core::TetMesh& m, int n)
{
    std::vector<int> free(m.vertices.size(), -1);
    int nf = 0;
    for (std::size_t v = 0; v < m.vertices.size(); ++v) {
        const int iv = static_cast<int>(v), i = iv % (n + 1), j = (iv / (n + 1)) % (n + 1), k = iv / ((n + 1) * (n + 1));
        if (i > 0 && j > 0 && k > 0 && i < n && j < n && k < n)
            free[v] = nf++;
    }
    Eigen::MatrixXd K = Eigen::MatrixXd::Zero(nf, nf);
    for (const auto& t : m.tets) {
        Eigen::Matrix3d J;
        for (int c = 0; c < 3; ++c)
            for (int r = 0; r < 3; ++r)
                J(r, c) = m.vertices[t[c + 1]][r] - m.vertices[t[0]][r];
        const Eigen::Matrix3d inv = J.inverse();
        Eigen::Matrix<double, 4, 3> g;
        g.row(1) = inv.row(0);
        g.row(2) = inv.row(1);
        g.row(3) = inv.row(2);
        g.row(0) = -(inv.row(0) + inv.row(1) + inv.row(2));
        const Eigen::Matrix4d ke = std::abs(J.determinant()) / 6 * g * g.transpose();
        for (int a = 0; a < 4; ++a)
            for (int b = 0; b < 4; ++b)
                if (free[t[a]] >= 0 && free[t[b]] >= 0)
                    K(free[t[a]], free[t[b]]) += ke(a, b);
    }
    Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(K, Eigen::EigenvaluesOnly);
    return es.eigenvalues().maxCoeff() / es.eigenvalues().minCoeff();
}

} // namespace

TEST(MeshQuality, ConditioningMeasurePredictsTheStiffnessConditionNumber)
{
    // Shewchuk: lambda_min of the assembled matrix hardly depends on element shape while
    // lambda_max lies between the largest element lambda_max and the largest sum of them over
    // a vertex's elements. The element lambda_max is V^(1/3) / (conditioning x c_reg), so a mesh
    // whose worst conditioning measure drops k-fold should see lambda_max, hence the condition
    // number, grow about k-fold once that element dominates. Degrade a 4^3 Kuhn mesh by pushing
    // one interior vertex along a diagonal edge, and compare the growth from t = 0.9 on.
    const int n = 4;
    const auto good = kuhn_cube(n);
    const double c_reg = std::cbrt(1 / (6 * std::sqrt(2.0))) * 3 * std::sqrt(2.0); // V^(1/3)/lambda of the regular tet
    auto predicted_lambda = [&](const core::TetMesh& m) {
        const auto q = mesh::evaluate_quality(m);
        double worst = 0;
        for (std::size_t t = 0; t < m.tets.size(); ++t)
            worst = std::max(worst, std::cbrt(core::signed_volume(m, t)) /
                                        (q.per_tet[int(Measure::Conditioning)][t] * c_reg));
        return worst;
    };
    const std::int32_t v = 1 + (n + 1) * (1 + (n + 1) * 1); // vertex (1,1,1)
    double kappa_ref = 0, lam_ref = 0, kappa_prev = stiffness_condition(good, n);
    for (double t : {0.9, 0.95, 0.97, 0.99, 0.995}) {
        auto bad = good;
        bad.vertices[v] = Vec3{1, 1, 1} * (1 + t); // towards (2,2,2), along a mesh edge
        ASSERT_EQ(core::mesh_problem(bad), "") << t;
        const double kappa = stiffness_condition(bad, n), lam = predicted_lambda(bad);
        if (kappa_ref == 0)
            kappa_ref = kappa, lam_ref = lam;
        std::printf("t %.3f: predicted lambda_max x%.2f, condition number x%.2f (from t = 0.9)\n", t, lam / lam_ref,
                    kappa / kappa_ref);
        EXPECT_GT(kappa, kappa_prev); // worse element, worse conditioning
        kappa_prev = kappa;
        // Growth predicted within a factor 1.5: the neighbours' share of lambda_max and
        // lambda_min's small change are what separate them (measured 0.81 at t = 0.99).
        EXPECT_GT(kappa / kappa_ref, lam / lam_ref / 1.5);
        EXPECT_LT(kappa / kappa_ref, lam / lam_ref * 1.5);
    }
}

TEST(TetQuality, FastMeasureAloneEqualsTheFullEvaluation)
{
    // fast_measure skips every other measure's work but must give the same number: random tets,
    // half of them inverted, agree with tet_measures to 1e-12 (the same operations, summed in
    // another order), and the regular tet scores exactly 1.
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> u(-10, 10);
    for (int i = 0; i < 200; ++i) {
        const Vec3 a{u(rng), u(rng), u(rng)}, b{u(rng), u(rng), u(rng)}, c{u(rng), u(rng), u(rng)}, d{u(rng), u(rng), u(rng)};
        const double full = mesh::tet_measures(a, b, c, d, 1.0)[mesh::Measure::Fast];
        EXPECT_NEAR(mesh::fast_measure(a, b, c, d), full, 1e-12 * std::max(1.0, std::abs(full))) << i;
    }
    auto r = regular_tet();
    for (auto& v : r)
        v = v * 2.5; // the measure is scale-free
    EXPECT_NEAR(mesh::fast_measure(r[0], r[1], r[2], r[3]), 1.0, 1e-12);
}
