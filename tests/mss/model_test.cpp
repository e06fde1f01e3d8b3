// The mass-spring model: HAVP constants re-derived from linear FEM, masses, stiffness laws,
// volume forces (sign, zero net force), boundary faces, errors.
#include "lobe/mss/block_mesh.h"
#include "lobe/mss/model.h"
#include "lobe/mss/topology.h"

#include "lobe/core/errors.h"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <random>

using namespace lobe;

namespace {

using Mat12 = std::array<std::array<double, 12>, 12>;

// Linear-elastic FEM stiffness of one tet: K_ij^ab = V (lambda d_a phi_i d_b phi_j +
// mu d_b phi_i d_a phi_j + mu delta_ab grad phi_i . grad phi_j), grad phi_i = grad_i V / V.
Mat12 fem_tet(const std::array<core::Vec3, 4>& p, double e, double nu)
{
    const double lambda = e * nu / ((1 + nu) * (1 - 2 * nu)), mu = e / (2 * (1 + nu));
    const double v = core::signed_volume(p[0], p[1], p[2], p[3]);
    const core::Vec3 g[4] = {cross(p[3] - p[1], p[2] - p[1]) / 6, cross(p[2] - p[0], p[3] - p[0]) / 6,
                             cross(p[3] - p[0], p[1] - p[0]) / 6, cross(p[1] - p[0], p[2] - p[0]) / 6};
    Mat12 k{};
    for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j)
            for (int a = 0; a < 3; ++a)
                for (int b = 0; b < 3; ++b) {
                    const double gi_a = g[i][a] / v, gj_b = g[j][b] / v, gi_b = g[i][b] / v, gj_a = g[j][a] / v;
                    k[3 * i + a][3 * j + b] = v * (lambda * gi_a * gj_b + mu * gi_b * gj_a +
                                                   (a == b ? mu * dot(g[i], g[j]) / (v * v) : 0));
                }
    return k;
}

// Spring stiffness matrix of the six edges with k = l (so the HAVP constant is the fit factor).
Mat12 springs_tet(const std::array<core::Vec3, 4>& p)
{
    Mat12 k{};
    for (int i = 0; i < 4; ++i)
        for (int j = i + 1; j < 4; ++j) {
            const core::Vec3 d = p[j] - p[i];
            const double l = norm(d);
            const core::Vec3 u = d / l;
            for (int a = 0; a < 3; ++a)
                for (int b = 0; b < 3; ++b) {
                    const double s = l * u[a] * u[b];
                    k[3 * i + a][3 * i + b] += s;
                    k[3 * j + a][3 * j + b] += s;
                    k[3 * i + a][3 * j + b] -= s;
                    k[3 * j + a][3 * i + b] -= s;
                }
        }
    return k;
}

// Volume term for k_V = E V0: (k_V / V0^2) grad V grad V^T.
Mat12 volume_tet(const std::array<core::Vec3, 4>& p)
{
    const double v = core::signed_volume(p[0], p[1], p[2], p[3]);
    const core::Vec3 g[4] = {cross(p[3] - p[1], p[2] - p[1]) / 6, cross(p[2] - p[0], p[3] - p[0]) / 6,
                             cross(p[3] - p[0], p[1] - p[0]) / 6, cross(p[1] - p[0], p[2] - p[0]) / 6};
    Mat12 k{};
    for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j)
            for (int a = 0; a < 3; ++a)
                for (int b = 0; b < 3; ++b)
                    k[3 * i + a][3 * j + b] = g[i][a] * g[j][b] / v;
    return k;
}

double inner(const Mat12& a, const Mat12& b)
{
    double s = 0;
    for (int i = 0; i < 12; ++i)
        for (int j = 0; j < 12; ++j)
            s += a[i][j] * b[i][j];
    return s;
}

std::array<core::Vec3, 4> regular_tet(double l)
{
    // Alternate corners of a cube of side l / sqrt(2), positively oriented.
    const double s = l / std::sqrt(2.0);
    std::array<core::Vec3, 4> p{core::Vec3{0, 0, 0}, core::Vec3{s, s, 0}, core::Vec3{s, 0, s}, core::Vec3{0, s, s}};
    if (core::signed_volume(p[0], p[1], p[2], p[3]) < 0)
        std::swap(p[2], p[3]);
    return p;
}

core::TetMesh one_tet(const std::array<core::Vec3, 4>& p)
{
    core::TetMesh m;
    m.vertices.assign(p.begin(), p.end());
    m.tets = {{0, 1, 2, 3}};
    m.tet_labels = {1};
    return m;
}

} // namespace

TEST(MssModel, HavpSpringConstantIsTheFemFitForPoissonQuarter)
{
    // Lloyd et al. 2007: k = c E l, c from the best fit of the spring matrix to linear FEM with
    // nu = 1/4. The Frobenius least-squares c = <K_fem, K_s> / <K_s, K_s> is exact algebra on
    // doubles, so it agrees with 2 sqrt(2)/25 to rounding (1e-12); E and l scale out.
    const auto p = regular_tet(0.7);
    const double e = 3.0;
    const Mat12 kf = fem_tet(p, e, 0.25), ks = springs_tet(p);
    const double c = inner(kf, ks) / inner(ks, ks) / e;
    EXPECT_NEAR(c, mss::kHavpSpringOnly, 1e-12);
    EXPECT_NEAR(c, 2 * std::sqrt(2.0) / 25, 1e-12);

    // Joint fit of springs and the volume term: the 2x2 normal equations. The constants in
    // model.h are given to 5 digits (c) and exactly (2/35), hence the tolerances.
    const Mat12 kv = volume_tet(p);
    const double a11 = inner(ks, ks), a12 = inner(ks, kv), a22 = inner(kv, kv);
    const double b1 = inner(kf, ks), b2 = inner(kf, kv);
    const double det = a11 * a22 - a12 * a12;
    const double c_joint = (b1 * a22 - b2 * a12) / det / e, kv_joint = (a11 * b2 - a12 * b1) / det / e;
    EXPECT_NEAR(c_joint, mss::kHavpWithVolume, 5e-6);
    EXPECT_NEAR(kv_joint, mss::kHavpVolumeCoefficient, 1e-12);

    // The volume term must lower the misfit (that is why HAVP adds it).
    Mat12 r1 = kf, r2 = kf;
    for (int i = 0; i < 12; ++i)
        for (int j = 0; j < 12; ++j) {
            r1[i][j] -= c * e * ks[i][j];
            r2[i][j] -= c_joint * e * ks[i][j] + kv_joint * e * kv[i][j];
        }
    const double spring_residual = std::sqrt(inner(r1, r1) / inner(kf, kf));
    const double joint_residual = std::sqrt(inner(r2, r2) / inner(kf, kf));
    EXPECT_LT(joint_residual, spring_residual);
    std::printf("HAVP fit residual: springs only %.4f, with volume term %.4f of |K_fem|\n", spring_residual, joint_residual);
}

TEST(MssModel, LumpedMassesAddUpToTheBody)
{
    // m_i = rho/4 sum V_t: the total is rho V exactly (up to rounding, 1e-12 relative), for both
    // splits and for a box off the origin.
    for (int split : {5, 6}) {
        mss::BlockMeshParams bp;
        bp.cells = {3, 4, 5};
        bp.size = {30, 20, 50};
        bp.origin = {-7, 3, 100};
        bp.tets_per_cell = split;
        const mss::Model m(mss::make_block_mesh(bp));
        const double volume = 30e-3 * 20e-3 * 50e-3;
        EXPECT_NEAR(m.rest_volume(), volume, 1e-12 * volume) << split;
        EXPECT_NEAR(m.total_mass(), 1060 * volume, 1e-12 * 1060 * volume) << split;
        EXPECT_EQ(m.tet_count(), std::size_t(split * 60));
    }
}

TEST(MssModel, StiffnessLawsSumOverTheTetsOfEachEdge)
{
    // Each tet has six edges, so summing the per-edge laws over all springs gives exact totals:
    // Van Gelder sum k l^2 = 6 sum_t E_t V_t; HAVP sum k / l = 6 c sum_t E_t. A tumour in the block
    // makes interface springs blend two moduli; the identities hold to rounding (1e-10 relative).
    mss::BlockMeshParams bp;
    bp.cells = {4, 4, 4};
    core::TetMesh mesh = mss::make_block_mesh(bp);
    const std::size_t tumour = mss::label_sphere(mesh, {20, 20, 20}, 12, 4);
    ASSERT_GT(tumour, 0u);
    double sum_ev = 0, sum_e = 0;
    for (std::size_t t = 0; t < mesh.tets.size(); ++t) {
        const double e = mesh.tet_labels[t] == 4 ? 110000 : 11000;
        sum_ev += e * core::signed_volume(mesh, t) * 1e-9;
        sum_e += e;
    }
    mss::ModelParams p;
    p.stiffness = mss::Stiffness::VanGelder;
    const mss::Model vg(mesh, p);
    double s = 0;
    for (std::size_t k = 0; k < vg.springs().size(); ++k)
        s += vg.springs().stiffness[k] * vg.springs().rest_length[k] * vg.springs().rest_length[k];
    EXPECT_NEAR(s, 6 * sum_ev, 1e-10 * s);
    p.stiffness = mss::Stiffness::Havp;
    const mss::Model havp(mesh, p);
    s = 0;
    for (std::size_t k = 0; k < havp.springs().size(); ++k)
        s += havp.springs().stiffness[k] / havp.springs().rest_length[k];
    EXPECT_NEAR(s, 6 * p.havp_c * sum_e, 1e-10 * s);
    // Springs are sorted by node for streaming.
    for (std::size_t k = 1; k < havp.springs().size(); ++k)
        ASSERT_TRUE(havp.springs().a[k - 1] < havp.springs().a[k] ||
                    (havp.springs().a[k - 1] == havp.springs().a[k] && havp.springs().b[k - 1] < havp.springs().b[k]));
}

TEST(MssModel, VolumeForcesHaveZeroSumAndAreMinusTheEnergyGradient)
{
    // A randomly deformed tet with HAVP springs and volume forces. Internal forces sum to zero
    // (the thesis's eq. 6.8 as printed would not: rows 1 and 3 flipped); rounding leaves about
    // 1e-15 of the largest force. The force is -dE/dx: central differences with step 1e-9 m
    // (1e-4 of the edge) agree to 1e-6 relative (the O(h^2) error and rounding are far below).
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> jitter(-2, 2);
    const auto p = regular_tet(10);
    mss::ModelParams params;
    params.damping_ratio = 0;
    params.volume_coefficient = 5; // large, so volume forces dominate the check
    const mss::Model m(one_tet(p), params);
    mss::State s = m.rest_state();
    for (auto& x : s.x)
        x += jitter(rng) * 1e-3;
    std::vector<double> f;
    mss::Energy e;
    m.forces(s, f, &e);
    EXPECT_GT(e.volume, 0);
    double fmax = 0;
    for (double v : f)
        fmax = std::max(fmax, std::abs(v));
    for (int c = 0; c < 3; ++c)
        EXPECT_NEAR(f[c] + f[3 + c] + f[6 + c] + f[9 + c], 0, 1e-12 * fmax);
    const double h = 1e-9;
    for (std::size_t i = 0; i < 12; ++i) {
        mss::State a = s, b = s;
        a.x[i] += h;
        b.x[i] -= h;
        const double de = (m.energy(a).total() - m.energy(b).total()) / (2 * h);
        EXPECT_NEAR(f[i], -de, 1e-6 * fmax) << i;
    }
}

TEST(MssModel, BoundaryFacesCloseTheBoxOutward)
{
    // Outward boundary faces: areas add up to the box's surface, and the divergence theorem
    // sum p0 . (p1 x p2) / 6 gives its volume with a positive sign (exact arithmetic on a grid,
    // rounding at 1e-9 relative).
    mss::BlockMeshParams bp;
    bp.cells = {2, 3, 4};
    bp.size = {20, 30, 40};
    bp.tets_per_cell = 5;
    const mss::Model m(mss::make_block_mesh(bp));
    double area = 0, volume = 0;
    const auto& v = m.mesh().vertices;
    for (const auto& f : m.surface_faces()) {
        area += norm(cross(v[f[1]] - v[f[0]], v[f[2]] - v[f[0]])) / 2;
        volume += dot(v[f[0]], cross(v[f[1]], v[f[2]])) / 6;
    }
    EXPECT_NEAR(area, 2 * (20 * 30 + 30 * 40 + 20 * 40), 1e-9 * area);
    EXPECT_NEAR(volume, 20 * 30 * 40, 1e-9 * volume);
    // Nodes: all but the (1 x 2 x 3) interior ones.
    EXPECT_EQ(m.surface_nodes().size(), std::size_t(3 * 4 * 5 - 1 * 2 * 3));
}

TEST(MssModel, RejectsUnknownTissueAndBadParameters)
{
    core::TetMesh mesh = mss::make_block_mesh({});
    mesh.tet_labels[3] = 9;
    try {
        mss::Model m(mesh);
        FAIL() << "accepted label 9";
    } catch (const core::InvalidInputError& e) {
        EXPECT_NE(std::string(e.what()).find("label 9"), std::string::npos) << e.what();
    }
    mss::ModelParams p;
    p.damping_ratio = -1;
    EXPECT_THROW(mss::Model(mss::make_block_mesh({}), p), core::InvalidInputError);
    core::TetMesh flipped = mss::make_block_mesh({});
    std::swap(flipped.tets[0][0], flipped.tets[0][1]);
    EXPECT_THROW(mss::Model{flipped}, core::InvalidInputError);
}

namespace {

// The model's rest state with every node displaced at random by up to 0.3 mm per axis and
// moving at up to 1 cm/s.
mss::State jiggled(const mss::Model& m, unsigned seed)
{
    mss::State s = m.rest_state();
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(-1, 1);
    for (auto& x : s.x)
        x += 0.3e-3 * u(rng);
    for (auto& v : s.v)
        v = 0.01 * u(rng);
    return s;
}

// The forces of two models of one mesh on one state agree to 1e-12 of the largest (rounding
// only: the same formulas, each node's sum in a fixed order), and so do the spring and volume
// energies ((V - V0)^2 to 1e-10: V - V0 loses digits to V).
void expect_same_forces(const mss::Model& ma, const mss::Model& mb, const mss::State& st)
{
    std::vector<double> fa, fb;
    mss::Energy ea, eb;
    ma.forces(st, fa, &ea);
    mb.forces(st, fb, &eb);
    ASSERT_EQ(fa.size(), fb.size());
    double big = 0, diff = 0;
    for (std::size_t i = 0; i < fa.size(); ++i) {
        big = std::max(big, std::abs(fa[i]));
        diff = std::max(diff, std::abs(fa[i] - fb[i]));
    }
    EXPECT_GT(big, 0);
    EXPECT_LE(diff, 1e-12 * big);
    EXPECT_NEAR(ea.springs, eb.springs, 1e-12 * ea.springs);
    EXPECT_NEAR(ea.volume, eb.volume, 1e-10 * std::abs(ea.volume));
}

} // namespace

TEST(MssModel, TwoThreadSpringPassGivesTheSerialForces)
{
    // A 26^3-cell block (5 tets per cell, about 120 k springs: above the threaded pass's 100 k
    // threshold), every node displaced at random by up to 0.3 mm and moving: the two-thread
    // pass's forces equal the serial ones to 1e-12 of the largest (each node's sum is taken by
    // one thread in the serial order, the hand-overs added afterwards: rounding only), and so
    // does the spring energy. The same after edge splits, which append springs out of order.
    mss::BlockMeshParams bp;
    bp.cells = {26, 26, 26};
    bp.size = {60, 60, 60};
    bp.tets_per_cell = 5;
    const core::TetMesh mesh = mss::make_block_mesh(bp);
    mss::ModelParams two, two_scalar;
    two.threads = two_scalar.threads = 2;
    two_scalar.simd = false; // the scalar loop with the same hand-overs (CPUs without AVX2)
    mss::Model serial(mesh), threaded(mesh, two), threaded_scalar(mesh, two_scalar);
    ASSERT_GT(serial.springs().size(), 100000u);
    mss::State s = jiggled(serial, 7);
    expect_same_forces(serial, threaded, s);
    expect_same_forces(serial, threaded_scalar, s);
    // Split ten edges spread over the block in all models (the same edits, the same state).
    mss::State s2 = s, s3 = s;
    for (int i = 0; i < 10; ++i) {
        const auto q = serial.mesh().tets[std::size_t(i) * serial.mesh().tets.size() / 10]; // a copy: the split reallocates
        mss::split_edge(serial, s, q[0], q[1], 0.5);
        mss::split_edge(threaded, s2, q[0], q[1], 0.5);
        mss::split_edge(threaded_scalar, s3, q[0], q[1], 0.5);
    }
    ASSERT_EQ(s.x, s2.x);
    ASSERT_EQ(s.x, s3.x);
    expect_same_forces(serial, threaded, s);
    expect_same_forces(serial, threaded_scalar, s);
}

TEST(MssModel, SimdForcePassesGiveTheScalarForces)
{
    // The AVX2 spring and volume kernels against the scalar loops on the same packed nodes: a
    // 9^3-cell block with HAVP volume terms, gravity and mass damping, every node displaced by
    // up to 0.3 mm and moving. Forces agree to 1e-12 of the largest (the same formulas, the same
    // summation order per node; FMA contraction, products by 1/6 for divisions and the energy's
    // four partial sums differ in rounding only). Then after edge splits, which append springs
    // out of order and leave counts that are not multiples of the kernels' four.
    if (!mss::simd_spring_kernel_available())
        GTEST_SKIP() << "this CPU has no AVX2 + FMA: only the scalar loop runs here";
    mss::BlockMeshParams bp;
    bp.cells = {9, 9, 9};
    bp.size = {40, 40, 40};
    const core::TetMesh mesh = mss::make_block_mesh(bp);
    mss::ModelParams simd, scalar;
    simd.stiffness = scalar.stiffness = mss::Stiffness::Havp;
    simd.gravity = scalar.gravity = {0, 9.81, 0};
    simd.mass_damping = scalar.mass_damping = 2;
    scalar.simd = false;
    mss::Model fast(mesh, simd), plain(mesh, scalar);
    mss::State s = jiggled(fast, 11);
    const mss::Energy ef = fast.energy(s), ep = plain.energy(s);
    EXPECT_GT(ef.volume, 0); // the volume kernel has work to do
    // The packing pass's energies: four lanes against one running sum, rounding only.
    EXPECT_NEAR(ef.kinetic, ep.kinetic, 1e-12 * ep.kinetic);
    EXPECT_NEAR(ef.gravity, ep.gravity, 1e-9 * std::abs(ep.gravity)); // a sum of +- terms
    EXPECT_NE(ep.gravity, 0);
    expect_same_forces(fast, plain, s);
    mss::State s2 = s;
    for (int i = 0; i < 7; ++i) {
        const auto q = fast.mesh().tets[std::size_t(i) * fast.mesh().tets.size() / 7]; // a copy: the split reallocates
        mss::split_edge(fast, s, q[0], q[1], 0.5);
        mss::split_edge(plain, s2, q[0], q[1], 0.5);
    }
    ASSERT_EQ(s.x, s2.x);
    ASSERT_NE(fast.springs().size() % 4, 0u);
    expect_same_forces(fast, plain, s);
}
