// Static error against time per step (issue 7, "chart error against time per step"): for every
// stiffness law and both FEM formulations, at several resolutions, in one run, the static error
// of a 1 % compression of a clamped column and of a cantilever bent by its own weight (the
// problems of tests/mss/accuracy_test.cpp, made finer), and the cost of one explicit step on the
// same mesh.
//
//   build-bench/bench/mss_accuracy [OUT.csv]     (default: stdout)
//   /usr/bin/python3 bench/mss/plot_accuracy.py OUT.csv OUT.png
//
// Equilibria come from tests/mss/statics.h (Newton on Model::forces). Time per step: one
// Simulator::step() (symplectic Euler, critical policy, alpha = 0.2, damping 0.1), the best of 5
// batches of at least 0.1 s of thread CPU time each, so that other users of the machine cost as
// little as possible.
#include "mss/statics.h"

#include "lobe/mss/block_mesh.h"
#include "lobe/mss/simulator.h"

#include <time.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <limits>
#include <string>
#include <vector>

using namespace lobe;

namespace {

using mss::statics::Variant;
using mss::statics::tip_deflection;
constexpr double kE = mss::statics::kLiverE;

// The prepared problem: a model with its fixed nodes and the state to start from
// (tests/mss/statics.h: the column and the cantilever the accuracy tests use).
using Problem = mss::statics::Column;

Problem beam(const Variant& v, int n)
{
    mss::Model m = mss::statics::cantilever(v, n);
    mss::State s = m.rest_state();
    return {std::move(m), std::move(s)};
}

double seconds_since(std::chrono::steady_clock::time_point t0)
{
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

double thread_cpu_seconds()
{
    timespec ts{};
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return double(ts.tv_sec) + 1e-9 * double(ts.tv_nsec);
}

// Seconds per explicit step from `start`: the best of 5 batches of >= 0.1 s of this thread's CPU
// time (time spent descheduled by other users' jobs is not counted; their cache traffic is).
double time_per_step(const Problem& p, double& dt)
{
    mss::SimulatorParams sp;
    sp.time_step.policy = mss::StepPolicy::Critical;
    mss::Simulator sim(p.model, sp);
    sim.set_state(p.start);
    dt = sim.time_step();
    for (int i = 0; i < 20; ++i)
        sim.step();
    double best = std::numeric_limits<double>::infinity();
    for (int batch = 0; batch < 5; ++batch) {
        const double t0 = thread_cpu_seconds();
        long steps = 0;
        double t = 0;
        do {
            for (int i = 0; i < 10; ++i)
                sim.step();
            steps += 10;
            t = thread_cpu_seconds() - t0;
        } while (t < 0.1);
        best = std::min(best, t / double(steps));
    }
    return best;
}

} // namespace

int main(int argc, char** argv)
{
    FILE* out = argc > 1 ? std::fopen(argv[1], "w") : stdout;
    if (!out) {
        std::perror(argv[1]);
        return 2;
    }
    std::fprintf(out, "problem,variant,cells_across,nodes,springs,tets,value,analytic,error_vs_analytic,linear_fem,"
                      "error_vs_linear_fem,newton_iterations,jacobians,colours,residual,static_seconds,step_us,dt_s,"
                      "cpu_per_simulated_second\n");
    const double analytic_force = kE * 400e-6 * 0.01;
    for (const char* problem : {"compression", "cantilever"}) {
        const bool compression = std::string(problem) == "compression";
        for (int n : {2, 3, 4, 6, 8}) {
            double fem = 0;
            for (const auto& v : mss::statics::variants()) {
                const Problem p = compression ? mss::statics::compression_column(v, n) : beam(v, n);
                const auto t0 = std::chrono::steady_clock::now();
                const auto r = mss::statics::solve_static(p.model, p.start);
                const double t_static = seconds_since(t0);
                const double value =
                    compression ? mss::statics::top_plate_force(p.model, r.state) : tip_deflection(p.model, r.state);
                if (v.formulation == mss::Formulation::LinearFem)
                    fem = value;
                const double analytic = compression ? analytic_force : mss::statics::kBeamTip;
                double dt = 0;
                const double step = time_per_step(p, dt);
                std::fprintf(out, "%s,%s,%d,%zu,%zu,%zu,%.8g,%.8g,%.6f,%.8g,%.6f,%d,%d,%d,%.3g,%.3f,%.3f,%.6g,%.4f\n",
                             problem, v.name.c_str(), n, p.model.node_count(), p.model.springs().size(), p.model.tet_count(),
                             value, analytic, value / analytic - 1, fem, value / fem - 1, r.iterations, r.jacobians,
                             r.colours, r.residual, t_static, step * 1e6, dt, step / dt);
                std::fflush(out);
                std::fprintf(stderr, "%s n=%d %-17s %.5g (%+.1f %% analytic, %+.1f %% FEM) %s, %.1f us/step\n", problem,
                             n, v.name.c_str(), value, (value / analytic - 1) * 100, (value / fem - 1) * 100,
                             r.converged ? "converged" : "NOT CONVERGED", step * 1e6);
                std::fprintf(stderr, "    newton %d iterations, %d jacobians, residual %.2g, last step %.2g\n",
                             r.iterations, r.jacobians, r.residual, r.last_step);
            }
        }
    }
    if (out != stdout)
        std::fclose(out);
    return 0;
}
