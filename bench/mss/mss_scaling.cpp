// Mass-spring step on liver meshes (issue 7, "Speed"): time per step and steps per second for each
// integrator and stiffness law (and the FEM formulations), heap memory per node of the model and
// of the simulator with its solver, scaling with the node count, and two independent simulations
// on two threads against one. bench/mss/run.sh makes the meshes (lphantom + lmesh) and the chart.
//
//   mss_scaling OUT.csv MESH...       every configuration on every mesh
//   mss_scaling --single MESH CONFIG STEPS   CONFIG's steps only (for `perf stat -r`; prints
//                                            the wall time per step; bench/mss/run_kernels.sh)
// MSS_THREADS=n and MSS_SIMD=0|1 set ModelParams::threads and ::simd.
// MESH: FILE.h5 (its /meshes/liver), FILE.h5+morton (the same, nodes renumbered along a Morton
// curve: the order's effect on the spring loop's gathers), or cube:C (mss_bench's 100 mm cube
// of C^3 cells, 6 tets each: the reference of the earlier figures, in the same run).
//
// One simulation's step runs on one thread (libmss has no parallel loop); the two-thread rows run
// two simulations of the same mesh at once, one per thread, which is what a second core buys today.
#include "lobe/core/errors.h"
#include "lobe/io/hdf5.h"
#include "lobe/mss/block_mesh.h"
#include "lobe/mss/simulator.h"

#include <malloc.h>
#include <pthread.h>
#include <time.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <string>
#include <thread>
#include <tuple>
#include <vector>

using namespace lobe;

namespace {

struct Config {
    const char* name;
    mss::Integrator integrator;
    mss::Formulation formulation;
    mss::Stiffness stiffness;
    mss::LinearSolver solver;
    std::size_t max_nodes; // skipped above (CHOLMOD with the reference BLAS takes ~1 s at 10k)
    bool two_threads;      // also measured as two simulations on two threads
};

constexpr std::size_t kAll = std::numeric_limits<std::size_t>::max();
constexpr auto SE = mss::Integrator::SymplecticEuler, VV = mss::Integrator::VelocityVerlet,
               BE = mss::Integrator::BackwardEuler;
constexpr auto MS = mss::Formulation::MassSpring;
constexpr auto CHOL = mss::LinearSolver::Cholmod, CG = mss::LinearSolver::ConjugateGradient;
constexpr auto K0 = mss::Stiffness::Constant, K1 = mss::Stiffness::InverseLength, VG = mss::Stiffness::VanGelder,
               HV = mss::Stiffness::Havp;

const Config kConfigs[] = {
    {"symplectic/constant", SE, MS, K0, CG, kAll, false},
    {"symplectic/inverse-length", SE, MS, K1, CG, kAll, false},
    {"symplectic/van-gelder", SE, MS, VG, CG, kAll, true},
    {"symplectic/havp", SE, MS, HV, CG, kAll, true},
    {"symplectic/linear-fem", SE, mss::Formulation::LinearFem, VG, CG, kAll, false},
    {"symplectic/corotational-fem", SE, mss::Formulation::CorotationalFem, VG, CG, kAll, true},
    {"verlet/constant", VV, MS, K0, CG, kAll, false},
    {"verlet/inverse-length", VV, MS, K1, CG, kAll, false},
    {"verlet/van-gelder", VV, MS, VG, CG, kAll, false},
    {"verlet/havp", VV, MS, HV, CG, kAll, false},
    {"implicit-cg/constant", BE, MS, K0, CG, kAll, false},
    {"implicit-cg/inverse-length", BE, MS, K1, CG, kAll, false},
    {"implicit-cg/van-gelder", BE, MS, VG, CG, kAll, false},
    {"implicit-cg/havp", BE, MS, HV, CG, kAll, true},
    {"implicit-cholmod/van-gelder", BE, MS, VG, CHOL, 20000, false},
    {"implicit-cholmod/havp", BE, MS, HV, CHOL, 20000, false},
};

// Heap bytes in use (every arena, mmapped blocks included): CHOLMOD and Eigen allocate with malloc.
double heap_bytes()
{
    const struct mallinfo2 mi = mallinfo2();
    return double(mi.uordblks) + double(mi.hblkhd);
}

// The 1-minute load average, recorded with every row: this is a shared machine.
double load_average()
{
    double load = -1;
    if (FILE* f = std::fopen("/proc/loadavg", "r")) {
        if (std::fscanf(f, "%lf", &load) != 1)
            load = -1;
        std::fclose(f);
    }
    return load;
}

double thread_cpu_seconds()
{
    timespec ts{};
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return double(ts.tv_sec) + 1e-9 * double(ts.tv_nsec);
}

double wall_seconds()
{
    return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

// The liver hangs from its superior 10 mm (a stand-in for the ligaments) under gravity (supine,
// LPS: +y), damping 0.1, as in lsim's defaults.
mss::Model make_model(const core::TetMesh& mesh, const Config& c)
{
    mss::ModelParams mp;
    mp.formulation = c.formulation;
    mp.stiffness = c.stiffness;
    mp.gravity = {0, 9.81, 0};
    if (const char* t = std::getenv("MSS_THREADS")) // threads of the spring pass (ModelParams::threads)
        mp.threads = std::atoi(t);
    if (const char* simd = std::getenv("MSS_SIMD")) // 0: the scalar spring loop (ModelParams::simd)
        mp.simd = std::atoi(simd) != 0;
    mss::Model m(mesh, mp);
    double zmax = -std::numeric_limits<double>::infinity();
    for (const auto& v : mesh.vertices)
        zmax = std::max(zmax, v.z);
    m.fix_box({-1e9, -1e9, zmax - 10}, {1e9, 1e9, 1e9});
    return m;
}

mss::SimulatorParams sim_params(const Config& c)
{
    mss::SimulatorParams sp;
    sp.integrator = c.integrator;
    sp.solver = c.solver;
    sp.time_step.policy = mss::StepPolicy::Critical;
    if (c.integrator == BE) {
        // A fixed 2 ms on every mesh (10x the explicit step of the 10k-node mesh): the critical
        // step of lmesh's finer meshes collapses on nodes of nearly no mass (docs/benchmarks.md),
        // and a step tied to it would leave the implicit system nearly the mass matrix.
        sp.time_step.policy = mss::StepPolicy::Fixed;
        sp.time_step.dt = 2e-3;
    }
    return sp;
}

struct Timing {
    double wall_best = 0, wall_median = 0, cpu_best = 0; // seconds per step
};

// Batches of at least min_seconds of steps; per-step wall and thread-CPU time.
Timing time_steps(mss::Simulator& sim, int batches, double min_seconds)
{
    std::vector<double> wall, cpu;
    for (int b = 0; b < batches; ++b) {
        const double w0 = wall_seconds(), c0 = thread_cpu_seconds();
        long steps = 0;
        double w = 0;
        do {
            sim.step();
            ++steps;
            w = wall_seconds() - w0;
        } while (w < min_seconds);
        wall.push_back(w / double(steps));
        cpu.push_back((thread_cpu_seconds() - c0) / double(steps));
    }
    Timing t;
    std::sort(wall.begin(), wall.end());
    t.wall_best = wall.front();
    t.wall_median = wall[wall.size() / 2];
    t.cpu_best = *std::min_element(cpu.begin(), cpu.end());
    return t;
}

// Wall time of `steps` steps on each of the simulations, one thread each, started together;
// `cpu` gets the threads' CPU time summed (below wall x threads when other jobs took the cores).
double concurrent_wall(std::vector<mss::Simulator>& sims, long steps, double& cpu)
{
    std::atomic<int> ready{0};
    std::atomic<bool> go{false};
    std::vector<double> used(sims.size(), 0.0);
    std::vector<std::thread> threads;
    for (std::size_t k = 0; k < sims.size(); ++k)
        threads.emplace_back([&, k] {
            ++ready;
            while (!go.load())
                std::this_thread::yield();
            const double c0 = thread_cpu_seconds();
            for (long i = 0; i < steps; ++i)
                sims[k].step();
            used[k] = thread_cpu_seconds() - c0;
        });
    while (ready.load() < int(sims.size()))
        std::this_thread::yield();
    const double w0 = wall_seconds();
    go = true;
    for (auto& t : threads)
        t.join();
    const double wall = wall_seconds() - w0;
    cpu = 0;
    for (double u : used)
        cpu += u;
    return wall;
}

// Nodes renumbered in the order of the Morton (Z-order) code of their position on a 2^21 grid.
core::TetMesh morton_order(const core::TetMesh& in)
{
    core::Vec3 lo = in.vertices.front(), hi = lo;
    for (const auto& v : in.vertices)
        for (int c = 0; c < 3; ++c) {
            lo[c] = std::min(lo[c], v[c]);
            hi[c] = std::max(hi[c], v[c]);
        }
    auto spread = [](std::uint64_t x) { // 21 bits to every third of 63
        std::uint64_t r = 0;
        for (int b = 0; b < 21; ++b)
            r |= ((x >> b) & 1u) << (3 * b);
        return r;
    };
    std::vector<std::pair<std::uint64_t, std::int32_t>> key(in.vertices.size());
    for (std::size_t i = 0; i < key.size(); ++i) {
        std::uint64_t code = 0;
        for (int c = 0; c < 3; ++c) {
            const double t = hi[c] > lo[c] ? (in.vertices[i][c] - lo[c]) / (hi[c] - lo[c]) : 0;
            code |= spread(std::uint64_t(t * ((1 << 21) - 1))) << c;
        }
        key[i] = {code, std::int32_t(i)};
    }
    std::sort(key.begin(), key.end());
    std::vector<std::int32_t> to(key.size());
    core::TetMesh out = in;
    for (std::size_t i = 0; i < key.size(); ++i) {
        to[std::size_t(key[i].second)] = std::int32_t(i);
        out.vertices[i] = in.vertices[std::size_t(key[i].second)];
    }
    for (auto& t : out.tets)
        for (auto& v : t)
            v = to[std::size_t(v)];
    return out;
}

core::TetMesh load(const std::string& spec)
{
    if (spec.rfind("cube:", 0) == 0) {
        const int c = std::atoi(spec.c_str() + 5);
        mss::BlockMeshParams bp;
        bp.cells = {c, c, c};
        bp.size = {100, 100, 100};
        return mss::make_block_mesh(bp);
    }
    const std::string suffix = "+morton";
    const bool morton =
        spec.size() > suffix.size() && spec.compare(spec.size() - suffix.size(), suffix.size(), suffix) == 0;
    const std::string path = morton ? spec.substr(0, spec.size() - suffix.size()) : spec;
    core::TetMesh mesh = io::Hdf5Reader(path).read_tet_mesh("liver").mesh;
    return morton ? morton_order(mesh) : mesh;
}

int single(const char* path, const char* config, long steps)
{
    const core::TetMesh mesh = load(path);
    for (const auto& c : kConfigs)
        if (std::strcmp(c.name, config) == 0) {
            mss::Simulator sim(make_model(mesh, c), sim_params(c));
            const double t0 = wall_seconds();
            for (long i = 0; i < steps; ++i)
                sim.step();
            const double seconds = wall_seconds() - t0;
            std::printf("%s %s: %ld steps, %zu nodes, %zu springs, %.4f ms per step\n", path, config, steps,
                        sim.model().node_count(), sim.model().springs().size(), 1e3 * seconds / double(std::max(1L, steps)));
            return 0;
        }
    std::fprintf(stderr, "unknown configuration %s\n", config);
    return 1;
}

} // namespace

int main(int argc, char** argv)
{
    if (argc == 5 && std::strcmp(argv[1], "--single") == 0)
        return single(argv[2], argv[3], std::atol(argv[4]));
    if (argc < 3) {
        std::fprintf(stderr, "usage: mss_scaling OUT.csv MESH.h5... | mss_scaling --single MESH.h5 CONFIG STEPS\n");
        return 1;
    }
    // MSS_CONFIGS=a,b: only the configurations whose name contains a or b (e.g. "implicit").
    std::vector<std::string> only;
    if (const char* env = std::getenv("MSS_CONFIGS"))
        for (std::string list = env; !list.empty();) {
            const auto comma = list.find(',');
            only.push_back(list.substr(0, comma));
            list = comma == std::string::npos ? "" : list.substr(comma + 1);
        }
    auto selected = [&](const char* name) {
        return only.empty() || std::any_of(only.begin(), only.end(), [&](const std::string& o) {
                   return std::string(name).find(o) != std::string::npos;
               });
    };
    FILE* out = std::fopen(argv[1], "w");
    if (!out) {
        std::perror(argv[1]);
        return 2;
    }
    std::fprintf(out, "mesh,nodes,tets,springs,config,run,threads,step_us_best,step_us_median,cpu_us_best,"
                      "steps_per_second,ns_per_spring,model_bytes_per_node,simulator_bytes_per_node,"
                      "cg_iterations_per_step,factorizations_per_step,dt_s,cores_busy,load,status\n");
    for (int a = 2; a < argc; ++a) {
        const std::string path = argv[a];
        const core::TetMesh mesh = load(path);
        const std::string name = path.substr(path.find_last_of('/') + 1);
        // The reordered and cube meshes answer one question each: the springs-only and HAVP step.
        const bool reference = name.find("+morton") != std::string::npos || name.rfind("cube:", 0) == 0;
        for (const auto& c : kConfigs) {
            if (mesh.vertices.size() > c.max_nodes || !selected(c.name))
                continue;
            if (reference && std::strcmp(c.name, "symplectic/van-gelder") != 0 &&
                std::strcmp(c.name, "symplectic/havp") != 0)
                continue;
            try { // a solver that fails (CG out of iterations) is a result too: recorded, not fatal
                const bool implicit = c.integrator == BE;
                const double h0 = heap_bytes();
                mss::Model model = make_model(mesh, c);
                const double h1 = heap_bytes();
                mss::Simulator sim(std::move(model), sim_params(c));
                for (int i = 0; i < (implicit ? 3 : 20); ++i)
                    sim.step(); // warm-up: first factorisation, caches, lazily sized buffers
                const double h2 = heap_bytes();
                const auto s0 = sim.statistics();
                const Timing t = time_steps(sim, implicit ? 3 : 5, implicit ? 0.5 : 0.2);
                const auto& s1 = sim.statistics();
                const double n = double(sim.model().node_count()), springs = double(sim.model().springs().size());
                const double timed = double(s1.steps - s0.steps);
                const double cg = double(s1.cg_iterations - s0.cg_iterations) / timed;
                const double fact = double(s1.factorizations - s0.factorizations) / timed;
                std::fprintf(out,
                             "%s,%zu,%zu,%zu,%s,single,1,%.4f,%.4f,%.4f,%.2f,%.3f,%.0f,%.0f,%.1f,%.3f,%.6g,,%.2f,ok\n",
                             name.c_str(), sim.model().node_count(), sim.model().tet_count(),
                             sim.model().springs().size(), c.name, t.wall_best * 1e6, t.wall_median * 1e6,
                             t.cpu_best * 1e6, 1 / t.cpu_best, t.cpu_best / springs * 1e9, (h1 - h0) / n, (h2 - h1) / n,
                             cg, fact, sim.time_step(), load_average());
                std::fflush(out);
                std::fprintf(stderr, "%s %s: %.1f us/step (median %.1f, cpu %.1f), %.0f + %.0f B/node\n", name.c_str(),
                             c.name, t.wall_best * 1e6, t.wall_median * 1e6, t.cpu_best * 1e6, (h1 - h0) / n,
                             (h2 - h1) / n);
                if (!c.two_threads)
                    continue;
                // One simulation on one thread against two on two threads, each running the same
                // number of steps (about 1 s), alternated, best of 3 rounds.
                std::vector<mss::Simulator> one, two;
                one.emplace_back(make_model(mesh, c), sim_params(c));
                for (int i = 0; i < 2; ++i)
                    two.emplace_back(make_model(mesh, c), sim_params(c));
                const long steps = std::max(3L, long(1.0 / t.wall_best));
                double w1 = std::numeric_limits<double>::infinity(), w2 = w1, c1 = 0, c2 = 0;
                for (int round = 0; round < 3; ++round) {
                    double cpu = 0;
                    if (const double w = concurrent_wall(one, steps, cpu); w < w1) {
                        w1 = w;
                        c1 = cpu;
                    }
                    if (const double w = concurrent_wall(two, steps, cpu); w < w2) {
                        w2 = w;
                        c2 = cpu;
                    }
                }
                for (const auto& [threads, w, cpu] : {std::tuple{1, w1, c1}, std::tuple{2, w2, c2}})
                    std::fprintf(out, "%s,%zu,%zu,%zu,%s,concurrent,%d,%.4f,,%.4f,%.2f,%.3f,,,,,,%.3f,%.2f,ok\n",
                                 name.c_str(), sim.model().node_count(), sim.model().tet_count(),
                                 sim.model().springs().size(), c.name, threads, w / double(steps) * 1e6,
                                 cpu / threads / double(steps) * 1e6, threads * double(steps) / w,
                                 w / double(steps) / springs * 1e9, cpu / w, load_average());
                std::fflush(out);
                std::fprintf(
                    stderr,
                    "  two simulations on two threads: %.2f x the steps per second of one (%.2f and %.2f cores busy)\n",
                    2 * w1 / w2, c1 / w1, c2 / w2);
            } catch (const core::Error& e) {
                std::string why = e.what();
                std::replace(why.begin(), why.end(), ',', ';');
                std::fprintf(out, "%s,%zu,%zu,,%s,single,1,,,,,,,,,,,,%.2f,failed: %s\n", name.c_str(),
                             mesh.vertices.size(), mesh.tets.size(), c.name, load_average(), why.c_str());
                std::fflush(out);
                std::fprintf(stderr, "%s %s: failed: %s\n", name.c_str(), c.name, e.what());
            }
        }
    }
    std::fclose(out);
    return 0;
}
