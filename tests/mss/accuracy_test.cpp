// Static accuracy of every stiffness law against the analytic solutions and the library's own FEM,
// in the same run: 1 % compression of a clamped column and a cantilever bent by its own weight
// (issue 7, "Accuracy"; docs/algorithms/mass_spring.md). Equilibria come from mss/statics.h.
#include "mss/statics.h"

#include "lobe/mss/block_mesh.h"
#include "lobe/mss/simulator.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <map>
#include <string>

using namespace lobe;

namespace {

using mss::statics::cantilever;
using mss::statics::tip_deflection;
using mss::statics::Variant;
using mss::statics::variants;
constexpr double kE = mss::statics::kLiverE;
constexpr double kTip = mss::statics::kBeamTip;

// The force on the column's top plate at equilibrium [N].
double compression_force(const Variant& v, int n)
{
    const auto [m, s] = mss::statics::compression_column(v, n);
    const auto r = mss::statics::solve_static(m, s);
    EXPECT_TRUE(r.converged) << v.name << " n=" << n << " residual " << r.residual;
    return mss::statics::top_plate_force(m, r.state);
}

double cantilever_deflection(const Variant& v, int n)
{
    const mss::Model m = cantilever(v, n);
    const auto r = mss::statics::solve_static(m, m.rest_state());
    EXPECT_TRUE(r.converged) << v.name << " n=" << n << " residual " << r.residual;
    return tip_deflection(m, r.state);
}

} // namespace

TEST(MssAccuracy, StaticSolverMatchesTheSimulatorsEquilibrium)
{
    // The Newton equilibrium is the state the library's own dynamics settle to. HAVP cantilever
    // (n = 2): backward Euler with CG at 0.5 s steps (about half the first bending period, so
    // each step damps the motion strongly) for 20 s. The two agree to 0.1 %: the simulator stops
    // where its own linear solve (CG to 1e-8) and its leftover motion allow, which is far below that.
    const Variant havp = variants()[5];
    const mss::Model m = cantilever(havp, 2);
    const double newton = tip_deflection(m, mss::statics::solve_static(m, m.rest_state()).state);
    mss::SimulatorParams sp;
    sp.integrator = mss::Integrator::BackwardEuler;
    sp.solver = mss::LinearSolver::ConjugateGradient;
    sp.time_step.policy = mss::StepPolicy::Fixed;
    sp.time_step.dt = 0.5;
    mss::Simulator sim(m, sp);
    sim.advance_to(20);
    const double dynamic = tip_deflection(m, sim.state());
    std::printf("HAVP cantilever n=2: Newton %.6f mm, backward Euler after 20 s %.6f mm\n", newton * 1e3,
                dynamic * 1e3);
    EXPECT_NEAR(dynamic, newton, 1e-3 * newton);
}

TEST(MssAccuracy, StaticCompressionEveryLawAgainstAnalyticAndFem)
{
    const double analytic = kE * 400e-6 * 0.01; // uniaxial stress: E A strain = 0.044 N
    std::map<std::string, std::array<double, 2>> force;
    for (const auto& v : variants())
        for (int k = 0; k < 2; ++k)
            force[v.name][std::size_t(k)] = compression_force(v, 3 * (k + 1));
    const auto& fem = force["linear-fem"];
    std::printf("compression 1 %%, analytic %.5f N; force at 3 / 6 cells across [N] (vs linear FEM):\n", analytic);
    for (const auto& v : variants()) {
        const auto& f = force[v.name];
        std::printf("  %-17s %.5f (%+6.1f %%)  %.5f (%+6.1f %%)\n", v.name.c_str(), f[0], (f[0] / fem[0] - 1) * 100,
                    f[1], (f[1] / fem[1] - 1) * 100);
    }
    // FEM: the clamped ends stop the Poisson expansion near them, stiffening the 4:1 column by a
    // few per cent over E A strain; linear tets in pure compression are nearly exact, so the two
    // resolutions agree to 1 % and the corotational one equals the linear one (no rotation).
    for (int k = 0; k < 2; ++k) {
        EXPECT_GT(fem[k], analytic);
        EXPECT_LT(fem[k], 1.06 * analytic);
        EXPECT_NEAR(force["corotational-fem"][k], fem[k], 1e-3 * fem[k]);
    }
    EXPECT_NEAR(fem[1], fem[0], 0.01 * fem[0]);
    // Van Gelder and HAVP scale k with the element (E V / l^2, c E l), so the network's modulus
    // does not depend on the resolution: both within 3 % of themselves across the two meshes and
    // stiffer than the FEM by a mesh-independent factor (measured below; the bounds leave a few
    // per cent either side).
    for (const char* law : {"van-gelder", "havp"})
        EXPECT_NEAR(force[law][1], force[law][0], 0.03 * force[law][0]) << law;
    EXPECT_GT(force["havp"][1], 1.05 * fem[1]);
    EXPECT_LT(force["havp"][1], 1.20 * fem[1]);
    EXPECT_GT(force["van-gelder"][1], 1.10 * fem[1]);
    EXPECT_LT(force["van-gelder"][1], 1.25 * fem[1]);
    // Constant and 1/l keep k per spring as the mesh refines: a section of area A is crossed by
    // ~A/h^2 springs, each stretched by ~strain x h, so the force goes as k/h: halving h doubles
    // it for the constant law (k = E L_ref) and quadruples it for 1/l (k = E L_ref^2 / l). They
    // match the FEM only at one resolution, set by reference_length.
    // Every edge gets the full k, surface ones too (the element laws give them the share of their
    // fewer tets), so the coarser mesh, with more of its springs on the surface, is relatively
    // stiffer and the ratios stay below 2 and 4 (measured 1.64 and 3.23).
    const double constant = force["constant"][1] / force["constant"][0];
    const double inverse = force["inverse-length"][1] / force["inverse-length"][0];
    EXPECT_GT(constant, 1.5);
    EXPECT_LT(constant, 2.0);
    EXPECT_GT(inverse, 3.0);
    EXPECT_LT(inverse, 4.0);
}

TEST(MssAccuracy, CantileverBendingEveryLawAgainstEulerBernoulliAndFem)
{
    // Tip deflection at 2 and 4 cells across the 10 mm beam (80 / 16 and 80 / 32 cells along).
    std::map<std::string, std::array<double, 2>> tip;
    for (const auto& v : variants())
        for (int k = 0; k < 2; ++k)
            tip[v.name][std::size_t(k)] = cantilever_deflection(v, 2 * (k + 1));
    const auto& fem = tip["linear-fem"];
    std::printf("cantilever, Euler-Bernoulli tip %.4f mm; at 2 / 4 cells across [mm] (vs EB, vs linear FEM)\n",
                kTip * 1e3);
    for (const auto& v : variants()) {
        const auto& d = tip[v.name];
        std::printf("  %-17s", v.name.c_str());
        for (int k = 0; k < 2; ++k)
            std::printf("  %.4f (%+5.1f %%, %+5.1f %%)", d[k] * 1e3, (d[k] / kTip - 1) * 100,
                        (d[k] / fem[k] - 1) * 100);
        std::printf("\n");
    }
    // FEM: linear tets are too stiff in bending (shear locking), more so the fewer across the
    // thickness, and converge to the beam solution from below (Timoshenko's shear term adds 1.5 %
    // to Euler-Bernoulli at L/b = 8). Measured -32 % at 2 cells and -10 % at 4 (error ~ h^1.6).
    // The deflection is 0.5 % of the length, so the corotational FEM equals the linear one (its
    // rotation correction is of second order, ~1e-5 here).
    for (int k = 0; k < 2; ++k) {
        EXPECT_LT(fem[k], kTip);
        EXPECT_NEAR(tip["corotational-fem"][k], fem[k], 1e-3 * fem[k]);
    }
    EXPECT_GT(fem[1], 0.85 * kTip);
    EXPECT_LT(kTip - fem[1], 0.5 * (kTip - fem[0]));
    // In Euler-Bernoulli theory the deflection is inversely proportional to the axial modulus of
    // the fibres, so a law that is X % stiffer than the FEM in compression (the test above: HAVP
    // +11 %, Van Gelder +17 %) should bend 1/(1 + X) as far once the mesh resolves the bending;
    // both also share the coarse mesh's bending error. Measured at 4 cells: HAVP -4.9 % and Van
    // Gelder -10.5 % from the FEM on the same mesh (-14.7 % and -19.7 % from Euler-Bernoulli);
    // bounds: HAVP within 10 %, Van Gelder within 15 % of the FEM, both below it.
    EXPECT_LT(tip["havp"][1], fem[1]);
    EXPECT_GT(tip["havp"][1], 0.90 * fem[1]);
    EXPECT_LT(tip["van-gelder"][1], fem[1]);
    EXPECT_GT(tip["van-gelder"][1], 0.85 * fem[1]);
    // Constant and 1/l: k = E L_ref with L_ref = 10 mm, 2 to 4 times these cells' edges, makes them
    // an order of magnitude too stiff (measured 8.3 % and 2.3 % of the FEM deflection at 4 cells,
    // 13 % and 7 % at 2); 1/l stiffens as the mesh refines (its modulus goes as 1/h^2, so the
    // deflection would fall to a quarter when h halves, less the coarser mesh's stiffer surface
    // layer: measured 0.43).
    for (const char* law : {"constant", "inverse-length"})
        for (int k = 0; k < 2; ++k)
            EXPECT_LT(tip[law][k], 0.15 * fem[k]) << law;
    EXPECT_GT(tip["inverse-length"][1], 0.25 * tip["inverse-length"][0]);
    EXPECT_LT(tip["inverse-length"][1], 0.5 * tip["inverse-length"][0]);
}
