// Mass-spring step cost (issue 7): one integration step of a liver cube of about 1k, 10k and 100k
// nodes, per integrator and stiffness law. Run: build-bench/bench/mss_bench (docs/benchmarks.md).
#include "lobe/mss/block_mesh.h"
#include "lobe/mss/simulator.h"

#include <benchmark/benchmark.h>

using namespace lobe;

namespace {

// A cube of c^3 cells (6 tets each), (c+1)^3 nodes, bottom fixed.
mss::Model cube(int c, mss::Stiffness stiffness)
{
    mss::BlockMeshParams bp;
    bp.cells = {c, c, c};
    bp.size = {100, 100, 100};
    mss::ModelParams mp;
    mp.stiffness = stiffness;
    mp.gravity = {0, 0, -9.81};
    mss::Model m(mss::make_block_mesh(bp), mp);
    m.fix_box({-1, -1, -1}, {101, 101, 1e-6});
    return m;
}

void step(benchmark::State& st, mss::Integrator integrator, mss::Stiffness stiffness, mss::LinearSolver solver)
{
    const int c = int(st.range(0));
    mss::SimulatorParams sp;
    sp.integrator = integrator;
    sp.solver = solver;
    sp.time_step.policy = mss::StepPolicy::Critical;
    if (integrator == mss::Integrator::BackwardEuler)
        sp.time_step.safety = 2; // ten times the explicit step
    mss::Simulator sim(cube(c, stiffness), sp);
    for (int i = 0; i < 10; ++i)
        sim.step(); // warm up (first factorisation, caches)
    for (auto _ : st)
        benchmark::DoNotOptimize(sim.step());
    const auto& m = sim.model();
    st.counters["nodes"] = double(m.node_count());
    st.counters["springs"] = double(m.springs().size());
    st.counters["ns_per_spring"] =
        benchmark::Counter(double(m.springs().size()) * 1e-9, benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
}

} // namespace

// 10, 20, 45 cells: 1331, 9261, 97336 nodes.
BENCHMARK_CAPTURE(step, symplectic_havp, mss::Integrator::SymplecticEuler, mss::Stiffness::Havp, mss::LinearSolver::Cholmod)
    ->Arg(10)->Arg(20)->Arg(45)->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(step, symplectic_vangelder, mss::Integrator::SymplecticEuler, mss::Stiffness::VanGelder, mss::LinearSolver::Cholmod)
    ->Arg(10)->Arg(20)->Arg(45)->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(step, verlet_havp, mss::Integrator::VelocityVerlet, mss::Stiffness::Havp, mss::LinearSolver::Cholmod)
    ->Arg(10)->Arg(20)->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(step, implicit_cholmod_havp, mss::Integrator::BackwardEuler, mss::Stiffness::Havp, mss::LinearSolver::Cholmod)
    ->Arg(10)->Arg(20)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(step, implicit_cg_havp, mss::Integrator::BackwardEuler, mss::Stiffness::Havp, mss::LinearSolver::ConjugateGradient)
    ->Arg(10)->Arg(20)->Unit(benchmark::kMillisecond);

BENCHMARK_MAIN();
