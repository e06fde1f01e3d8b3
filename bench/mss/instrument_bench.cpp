// Step time with cutting and with refinement against the same scene without them, on liver
// meshes (issue 8; docs/benchmarks.md, "Instruments"). Run by bench/mss/run_instruments.sh:
//   instrument_bench SUMMARY.csv SERIES.csv MESH.h5 ...   (SCENES=a,b: only those scenes)
// For each mesh (its only tet mesh; HAVP springs with volume forces, the back fifth of the liver
// fixed, critical step policy so that runs with and without instruments take comparable steps;
// 0.2 s of simulated time or 2000 steps, whichever is less):
//   probe       a 10 mm probe presses 8 mm into the front of the liver and holds
//   probe+refine   the same with on-the-fly refinement (libmesh's fast measure)
//   plain       no instrument (the same number of simulated seconds)
//   cut         a scalpel cuts into the front half of the liver, its edge across the liver's height
// and writes per-run step statistics (mean, median, 99th percentile and largest step time, the
// topology updates and what they cost) and, for the cut, the time of every step.
#include "lobe/io/hdf5.h"
#include "lobe/mesh/quality.h"
#include "lobe/mss/simulator.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <string>
#include <vector>

using namespace lobe;

namespace {

struct Box {
    core::Vec3 lo{1e300, 1e300, 1e300}, hi{-1e300, -1e300, -1e300};
};

Box bounds(const core::TetMesh& m)
{
    Box b;
    for (const auto& v : m.vertices)
        for (int c = 0; c < 3; ++c) {
            b.lo[c] = std::min(b.lo[c], v[c]);
            b.hi[c] = std::max(b.hi[c], v[c]);
        }
    return b;
}

struct Result {
    std::string mesh, scene;
    std::size_t nodes0 = 0, tets0 = 0, nodes1 = 0, tets1 = 0;
    std::int64_t steps = 0, updates = 0, changes = 0;
    double mean_us = 0, median_us = 0, p99_us = 0, max_us = 0, topology_s = 0, max_update_ms = 0, wall_s = 0;
    double simulated_s = 0;
};

// Where a sphere of radius r coming from the front (-y) along the line through the liver's
// centre first touches a vertex: its centre's y then.
double first_contact_y(const core::TetMesh& m, const Box& b, double r)
{
    const double cx = (b.lo.x + b.hi.x) / 2, cz = (b.lo.z + b.hi.z) / 2;
    double y = b.hi.y;
    for (const auto& v : m.vertices) {
        const double d2 = (v.x - cx) * (v.x - cx) + (v.z - cz) * (v.z - cz);
        if (d2 < r * r)
            y = std::min(y, v.y - std::sqrt(r * r - d2));
    }
    return y;
}

Result run(const std::string& name, const core::TetMesh& mesh, const std::string& scene, double seconds,
           std::vector<std::pair<double, double>>* series)
{
    const Box b = bounds(mesh);
    mss::Model model(mesh);
    model.fix_box({b.lo.x - 1, b.hi.y - 0.2 * (b.hi.y - b.lo.y), b.lo.z - 1}, {b.hi.x + 1, b.hi.y + 1, b.hi.z + 1});
    mss::SimulatorParams sp;
    sp.time_step.policy = mss::StepPolicy::Critical;
    if (scene == "probe+refine") {
        sp.refine.enabled = true;
        sp.refine.quality = mesh::fast_measure;
    }
    Result r;
    r.mesh = name;
    r.scene = scene;
    r.nodes0 = model.node_count();
    r.tets0 = model.tet_count();
    mss::Simulator sim(std::move(model), sp);
    if (scene.rfind("probe", 0) == 0) {
        mss::ProbeParams p;
        p.radius_mm = 10;
        const double y = first_contact_y(mesh, b, p.radius_mm);
        const double cx = (b.lo.x + b.hi.x) / 2, cz = (b.lo.z + b.hi.z) / 2;
        p.path = {{0, {cx, y - 2, cz}}, {0.6 * seconds, {cx, y + 8, cz}}}; // 8 mm past the first contact
        sim.add_probe(p);
    } else if (scene == "cut") {
        mss::BladeParams bl;
        const double x = (b.lo.x + b.hi.x) / 2 + 1.3;
        bl.path = {{0, {x, b.lo.y - 5, b.lo.z - 5}, {x, b.lo.y - 5, b.hi.z + 5}},
                   {seconds, {x, (b.lo.y + b.hi.y) / 2, b.lo.z - 5}, {x, (b.lo.y + b.hi.y) / 2, b.hi.z + 5}}};
        sim.add_blade(bl);
    }
    std::vector<double> us;
    const auto t0 = std::chrono::steady_clock::now();
    while (sim.state().time < seconds) {
        const auto s0 = std::chrono::steady_clock::now();
        const mss::StepInfo info = sim.step_until(seconds);
        const double dt = std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - s0).count();
        us.push_back(dt);
        if (series)
            series->emplace_back(info.time, dt);
    }
    r.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    r.simulated_s = sim.state().time;
    const auto& st = sim.statistics();
    r.steps = st.steps;
    r.updates = st.topology_updates;
    r.changes = st.topology_changes;
    r.topology_s = st.topology_seconds;
    r.max_update_ms = 1e3 * st.max_topology_seconds;
    r.nodes1 = sim.model().node_count();
    r.tets1 = sim.model().tet_count();
    double sum = 0;
    for (double v : us)
        sum += v;
    r.mean_us = sum / double(us.size());
    std::sort(us.begin(), us.end());
    r.median_us = us[us.size() / 2];
    r.p99_us = us[std::min(us.size() - 1, std::size_t(0.99 * double(us.size())))];
    r.max_us = us.back();
    return r;
}

} // namespace

int main(int argc, char** argv)
{
    if (argc < 4) {
        std::cerr << "usage: instrument_bench SUMMARY.csv SERIES.csv MESH.h5 ...\n";
        return 1;
    }
    std::ofstream summary(argv[1]), series_csv(argv[2]);
    summary << "mesh,scene,nodes,tets,final_nodes,final_tets,simulated_s,steps,mean_us,median_us,p99_us,max_us,"
               "topology_updates,topology_changes,topology_s,max_update_ms,wall_s\n";
    series_csv << "mesh,time_s,step_us\n";
    for (int i = 3; i < argc; ++i) {
        const std::string file = argv[i];
        io::Hdf5Reader in(file);
        const core::TetMesh mesh = in.read_tet_mesh(in.tet_meshes().at(0)).mesh;
        const std::string name = std::to_string(mesh.vertices.size() / 1000) + "k";
        // 0.2 s of simulated time, or 2000 steps at the critical policy's step if that is less
        // (lmesh's finest meshes have micrometre edges and a critical step of microseconds): the
        // instruments then move faster, but do the same work, in the same number of steps.
        double seconds = 0.2;
        {
            mss::Model m(mesh);
            seconds = std::min(seconds, 2000 * mss::TimeStepParams{}.safety * m.critical_time_step());
        }
        for (const std::string scene : {"plain", "probe", "probe+refine", "cut"}) {
            // SCENES=cut,probe+refine runs only those (e.g. under perf record).
            const char* only = std::getenv("SCENES");
            if (only && ("," + std::string(only) + ",").find("," + scene + ",") == std::string::npos)
                continue;
            std::vector<std::pair<double, double>> series;
            const Result r = run(name, mesh, scene, seconds, scene == "cut" ? &series : nullptr);
            char line[512];
            std::snprintf(line, sizeof line, "%s,%s,%zu,%zu,%zu,%zu,%.4f,%lld,%.1f,%.1f,%.1f,%.1f,%lld,%lld,%.4f,%.2f,%.2f\n",
                          r.mesh.c_str(), r.scene.c_str(), r.nodes0, r.tets0, r.nodes1, r.tets1, r.simulated_s,
                          static_cast<long long>(r.steps), r.mean_us, r.median_us, r.p99_us, r.max_us,
                          static_cast<long long>(r.updates), static_cast<long long>(r.changes), r.topology_s,
                          r.max_update_ms, r.wall_s);
            summary << line << std::flush;
            std::cerr << line;
            for (const auto& [t, us] : series)
                series_csv << name << "," << t << "," << us << "\n";
        }
    }
    return 0;
}
