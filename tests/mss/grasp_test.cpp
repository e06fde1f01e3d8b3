// Forceps: grasp, pull, hold, release; the force balance at rest and the slip limit.
#include "lobe/mss/block_mesh.h"
#include "lobe/mss/simulator.h"

#include "lobe/core/errors.h"

#include <gtest/gtest.h>

#include <cmath>

using namespace lobe;

namespace {

// A 40 mm liver cube in 4 mm cells, bottom face fixed; mass damping 30/s so that it settles
// within a few tenths of a second (transients e^{-30 t / 2}).
mss::Model cube()
{
    mss::BlockMeshParams bp;
    bp.cells = {10, 10, 10};
    bp.size = {40, 40, 40};
    mss::ModelParams mp;
    mp.mass_damping = 30;
    mss::Model m(mss::make_block_mesh(bp), mp);
    m.fix_box({-1, -1, -1}, {41, 41, 1e-6});
    return m;
}

// Forceps at the top centre: close at 0.05 s, pull up by `lift` mm by 0.35 s, hold, open at
// `open` s.
mss::GraspParams forceps(double lift, double open, double max_force = 5)
{
    mss::GraspParams g;
    g.jaw_radius_mm = 6;
    g.close_time = 0.05;
    g.open_time = open;
    g.max_force_n = max_force;
    g.path = {{0.05, {20, 20, 40}}, {0.35, {20, 20, 40 + lift}}};
    return g;
}

core::Vec3 support_force(const mss::Simulator& sim)
{
    std::vector<double> f;
    sim.model().forces(sim.state(), f);
    core::Vec3 s{0, 0, 0};
    for (std::size_t i = 0; i < sim.model().node_count(); ++i)
        if (sim.model().is_fixed(i))
            s += core::Vec3{f[3 * i], f[3 * i + 1], f[3 * i + 2]};
    return s;
}

} // namespace

TEST(MssGrasp, PullHoldAndReleaseWithTheForceBalancedAtRest)
{
    // The jaws take the top nodes within 6 mm (a 4 mm grid: at least the 9 nodes of a 3 x 3
    // patch), lift them 5 mm and hold. After settling, the tissue pulls the jaws down (force of
    // the tissue on them: -z) and that force balances the supports' within 5 % (the rest is the
    // residual motion at e^{-30 x 0.45 / 2}). Then the jaws open: nothing is held, the grasp force
    // is zero, and the cube springs back to within 0.5 mm of its rest shape.
    mss::Simulator sim(cube());
    sim.add_grasp(forceps(5, 0.8));
    mss::StepInfo last;
    int held = 0;
    sim.advance_to(0.8, [&](const mss::StepInfo& i) {
        last = i;
        held = std::max(held, i.held);
    });
    EXPECT_GE(held, 9);
    EXPECT_EQ(sim.statistics().grasp_slips, 0);
    const core::Vec3 grasp = last.grasp_force, support = support_force(sim);
    std::printf("held %d nodes; grasp force (%.4f %.4f %.4f) N, supports (%.4f %.4f %.4f) N\n", held, grasp.x, grasp.y,
                grasp.z, support.x, support.y, support.z);
    EXPECT_LT(grasp.z, 0);
    EXPECT_LT(norm(grasp + support), 0.05 * norm(grasp));
    // The held nodes sit 5 mm above their rest height, within 0.01 mm: the jaws close at the
    // first step boundary after 0.05 s, by when they have risen by at most one step (< 1 ms)
    // x 5 mm / 0.3 s.
    for (auto i : sim.held_nodes(0))
        EXPECT_NEAR(sim.state().position_mm(std::size_t(i)).z - sim.model().mesh().vertices[std::size_t(i)].z, 5, 0.01);
    sim.advance_to(1.4, [&](const mss::StepInfo& i) { last = i; });
    EXPECT_EQ(last.held, 0);
    EXPECT_EQ(norm(last.grasp_force), 0.0);
    double worst = 0;
    for (std::size_t i = 0; i < sim.model().node_count(); ++i)
        worst = std::max(worst, norm(sim.state().position_mm(i) - sim.model().mesh().vertices[i]));
    EXPECT_LT(worst, 0.5);
}

TEST(MssGrasp, TheTissueSlipsOutAboveTheMaximumForce)
{
    // A 20 mm pull needs far more than 0.05 N: the most loaded nodes slip out one by one, the
    // force stays at or under the limit at every step, and the nodes still held are fewer.
    mss::Simulator sim(cube());
    sim.add_grasp(forceps(20, 1.0, 0.05));
    double worst = 0;
    int first = 0, last_held = 0;
    sim.advance_to(0.6, [&](const mss::StepInfo& i) {
        worst = std::max(worst, norm(i.grasp_force));
        if (first == 0)
            first = i.held;
        last_held = i.held;
    });
    EXPECT_LE(worst, 0.05 + 1e-12);
    EXPECT_GT(sim.statistics().grasp_slips, 0);
    EXPECT_LT(last_held, first);
}

TEST(MssGrasp, JawsClosingOnNothingHoldNothing)
{
    mss::Simulator sim(cube());
    mss::GraspParams g = forceps(5, 0.3);
    for (auto& p : g.path)
        p.position_mm.z += 30; // 30 mm above the cube
    sim.add_grasp(g);
    int held = 0;
    sim.advance_to(0.4, [&](const mss::StepInfo& i) { held = std::max(held, i.held); });
    EXPECT_EQ(held, 0);
}

TEST(MssGrasp, BadForcepsAreRefused)
{
    mss::Simulator sim(cube());
    mss::GraspParams g;
    EXPECT_THROW(sim.add_grasp(g), core::InvalidInputError); // no path
    g = forceps(5, 0.5);
    g.jaw_radius_mm = 0;
    EXPECT_THROW(sim.add_grasp(g), core::InvalidInputError);
    g = forceps(5, 0.5);
    g.max_force_n = -1;
    EXPECT_THROW(sim.add_grasp(g), core::InvalidInputError);
    g = forceps(5, 0.01); // opens before it closes
    EXPECT_THROW(sim.add_grasp(g), core::InvalidInputError);
    EXPECT_TRUE(sim.grasps().empty());
}
