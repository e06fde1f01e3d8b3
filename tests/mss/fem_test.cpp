// The FEM reference formulations, and the static accuracy of every stiffness law against them
// and against the analytic solution.
#include "lobe/mss/block_mesh.h"
#include "lobe/mss/simulator.h"

#include "lobe/core/errors.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

using namespace lobe;

namespace {

mss::Model fem_block(mss::Formulation f)
{
    mss::BlockMeshParams bp;
    bp.cells = {3, 3, 3};
    bp.size = {30, 30, 30};
    bp.tets_per_cell = 5;
    mss::ModelParams mp;
    mp.formulation = f;
    mp.damping_ratio = 0;
    return mss::Model(mss::make_block_mesh(bp), mp);
}

// Largest force on an interior node / largest force anywhere, for positions x = map(X).
template <class Map>
std::pair<double, double> interior_and_max_force(const mss::Model& m, Map map)
{
    mss::State s = m.rest_state();
    for (std::size_t i = 0; i < s.node_count(); ++i) {
        const core::Vec3 p = map(core::Vec3{s.x[3 * i], s.x[3 * i + 1], s.x[3 * i + 2]});
        s.x[3 * i] = p.x;
        s.x[3 * i + 1] = p.y;
        s.x[3 * i + 2] = p.z;
    }
    std::vector<double> f;
    m.forces(s, f);
    std::vector<char> surface(s.node_count(), 0);
    for (auto i : m.surface_nodes())
        surface[std::size_t(i)] = 1;
    double interior = 0, all = 0;
    for (std::size_t i = 0; i < s.node_count(); ++i) {
        const double n = std::sqrt(f[3 * i] * f[3 * i] + f[3 * i + 1] * f[3 * i + 1] + f[3 * i + 2] * f[3 * i + 2]);
        all = std::max(all, n);
        if (!surface[i])
            interior = std::max(interior, n);
    }
    return {interior, all};
}

} // namespace

TEST(MssFem, PassesThePatchTestAndTheCorotationalOneIgnoresRotations)
{
    // Patch test: under a uniform strain (here 1 % stretch and 0.5 % shear) every interior node of
    // a linear-tet mesh is in equilibrium: its forces cancel to rounding, 1e-9 of the largest
    // (boundary) force. A rigid 30 degree rotation creates no force in the corotational
    // formulation (1e-9 of the stretch's force) and a large one in the linear formulation
    // (its small-strain measure reads a rotation as strain: more than the 1 % stretch's).
    for (auto f : {mss::Formulation::LinearFem, mss::Formulation::CorotationalFem}) {
        const mss::Model m = fem_block(f);
        const auto [interior, all] =
            interior_and_max_force(m, [](core::Vec3 p) { return core::Vec3{1.01 * p.x + 0.005 * p.y, p.y, p.z}; });
        EXPECT_GT(all, 0);
        EXPECT_LT(interior, 1e-9 * all) << mss::formulation_name(f);
        const double c = std::cos(0.5236), s = std::sin(0.5236);
        const auto [ri, rall] = interior_and_max_force(m, [&](core::Vec3 p) { return core::Vec3{c * p.x - s * p.y, s * p.x + c * p.y, p.z}; });
        (void)ri;
        if (f == mss::Formulation::CorotationalFem)
            EXPECT_LT(rall, 1e-9 * all);
        else
            EXPECT_GT(rall, all);
    }
}

TEST(MssFem, ForcesAreMinusTheGradientOfTheStrainEnergy)
{
    // Central differences (step 1e-9 m on 10 mm elements) of the strain energy agree with the
    // forces to 1e-6 of the largest force, for a random deformation with rotation.
    for (auto f : {mss::Formulation::LinearFem, mss::Formulation::CorotationalFem}) {
        const mss::Model m = fem_block(f);
        mss::State s = m.rest_state();
        for (std::size_t i = 0; i < s.x.size(); ++i)
            s.x[i] += 2e-4 * std::sin(double(7 * i + 1)) + (i % 3 == 0 ? 0.3 * s.x[i + 1] : 0);
        std::vector<double> force;
        m.forces(s, force);
        double fmax = 0;
        for (double v : force)
            fmax = std::max(fmax, std::abs(v));
        for (std::size_t i = 0; i < s.x.size(); i += 7) {
            mss::State a = s, b = s;
            a.x[i] += 1e-9;
            b.x[i] -= 1e-9;
            EXPECT_NEAR(force[i], -(m.energy(a).total() - m.energy(b).total()) / 2e-9, 1e-6 * fmax)
                << mss::formulation_name(f) << " " << i;
        }
    }
}

namespace {

// Force needed to hold a 20 x 20 x 80 mm column (3 x 3 x 12 cells, 5 tets each) compressed by
// 1 % between clamped ends, quasi-statically (0.3 s ramp, 0.3 s hold, mass damping 30/s) [N].
double compression_force(mss::ModelParams mp)
{
    mss::BlockMeshParams bp;
    bp.cells = {3, 3, 12};
    bp.size = {20, 20, 80};
    bp.tets_per_cell = 5;
    mp.mass_damping = 30;
    mss::Model model(mss::make_block_mesh(bp), mp);
    model.fix_box({-1, -1, -1}, {21, 21, 1e-6});
    model.fix_box({-1, -1, 80 - 1e-6}, {21, 21, 81});
    mss::Simulator sim(model, {});
    for (int frame = 1; frame <= 600; ++frame) {
        const double t = frame * 1e-3;
        mss::State s = sim.state();
        for (std::size_t i = 0; i < s.node_count(); ++i)
            if (model.mesh().vertices[i].z > 80 - 1e-6)
                s.x[3 * i + 2] = 80e-3 * (1 - 0.01 * std::min(1.0, t / 0.3));
        sim.set_state(s);
        sim.advance_to(t);
    }
    std::vector<double> f;
    model.forces(sim.state(), f);
    double push = 0;
    for (std::size_t i = 0; i < model.node_count(); ++i)
        if (model.mesh().vertices[i].z > 80 - 1e-6)
            push += f[3 * i + 2]; // the tissue pushes the top plate up
    return push;
}

} // namespace

TEST(MssFem, StaticCompressionAgainstTheAnalyticSolutionAndFem)
{
    // Analytic: uniaxial stress, F = E A strain = 11 kPa x 400 mm^2 x 1 % = 0.044 N. The clamped
    // ends stop the lateral (Poisson) expansion near them, which stiffens a 4:1 column by a few
    // per cent, and linear tets at 6.7 mm are stiff in bending-free compression by little: the
    // FEM reference must land within 10 % of the analytic force (measured +1.8 %), the corotational one within
    // 1 % of the linear one (1 % strain, no rotation). The mass-spring laws are measured against
    // the same FEM (measured: HAVP +11 %, Van Gelder +16 %, constant +307 %, 1/l +452 %: the last
    // two depend on reference_length); HAVP, fitted to this FEM on a regular tetrahedron, must
    // stay within 20 % of it and Van Gelder within 25 %.
    const double analytic = 11000 * 400e-6 * 0.01;
    mss::ModelParams mp;
    mp.formulation = mss::Formulation::LinearFem;
    const double linear = compression_force(mp);
    mp.formulation = mss::Formulation::CorotationalFem;
    const double corot = compression_force(mp);
    EXPECT_NEAR(linear, analytic, 0.10 * analytic);
    EXPECT_NEAR(corot, linear, 0.01 * linear);
    std::printf("compression 1 %%: analytic %.5f N, linear FEM %.5f N, corotational %.5f N\n", analytic, linear, corot);
    mp.formulation = mss::Formulation::MassSpring;
    for (auto st : {mss::Stiffness::Constant, mss::Stiffness::InverseLength, mss::Stiffness::VanGelder, mss::Stiffness::Havp}) {
        mp.stiffness = st;
        const double f = compression_force(mp);
        std::printf("  %-15s %.5f N (%+.0f %% vs FEM)\n", mss::stiffness_name(st), f, (f / linear - 1) * 100);
        if (st == mss::Stiffness::Havp) {
            EXPECT_NEAR(f, linear, 0.20 * linear);
        }
        if (st == mss::Stiffness::VanGelder) {
            EXPECT_NEAR(f, linear, 0.25 * linear);
        }
    }
}

TEST(MssFem, ImplicitRefusesFem)
{
    mss::SimulatorParams sp;
    sp.integrator = mss::Integrator::BackwardEuler;
    EXPECT_THROW(mss::Simulator(fem_block(mss::Formulation::LinearFem), sp), core::InvalidInputError);
}
