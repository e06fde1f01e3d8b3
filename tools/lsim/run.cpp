// lsim: run a scene; make a block mesh.
#include "lsim/run.h"

#include "common/files.h"
#include "common/picture.h"
#include "lsim/render.h"
#include "lsim/scene.h"

#include "lobe/core/errors.h"
#include "lobe/io/hdf5.h"
#include "lobe/mss/simulator.h"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <optional>

namespace lobe::lsim {
namespace fs = std::filesystem;

namespace {

std::string num(double v)
{
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.4g", v);
    return buf;
}

const io::LabelTable kTissueTable = {{1, "liver"}, {2, "portal_vein"}, {3, "hepatic_veins"}, {4, "tumour"}};

} // namespace

int run_scene(const RunOptions& o, const tools::Progress& progress, tools::RunRecord& record)
{
    auto& timings = record.timings;
    std::optional<io::Hdf5Reader> in;
    io::TetMeshData mesh_data;
    std::string mesh_name = o.mesh_name;
    timings.time("read", [&] {
        in.emplace(o.mesh_file);
        const auto names = in->tet_meshes();
        if (mesh_name.empty()) {
            if (names.size() != 1)
                throw core::InvalidInputError(o.mesh_file.string() + ": holds " + std::to_string(names.size()) +
                                              " tet meshes; choose one with --mesh");
            mesh_name = names[0];
        }
        mesh_data = in->read_tet_mesh(mesh_name);
    });
    const Scene scene = read_scene(o.scene_file);

    std::optional<mss::Simulator> sim;
    timings.time("build", [&] {
        mss::Model model = [&] {
            try {
                return mss::Model(mesh_data.mesh, scene.model);
            } catch (const core::InvalidInputError& e) {
                throw core::InvalidInputError(o.mesh_file.string() + ": /meshes/" + mesh_name + ": " + e.what());
            }
        }();
        std::size_t fixed = 0;
        for (const auto& b : scene.fixed)
            fixed += model.fix_box(b.lo, b.hi);
        if (!scene.fixed.empty() && fixed == 0)
            throw core::InvalidInputError(o.scene_file.string() + ": the [fixed] boxes hold no mesh vertex");
        progress.message("model: " + std::to_string(model.node_count()) + " nodes (" + std::to_string(fixed) + " fixed), " +
                         std::to_string(model.springs().size()) + " springs, " + std::to_string(model.tet_count()) +
                         " tets, " + mss::stiffness_name(scene.model.stiffness) + " stiffness; critical step " +
                         num(model.critical_time_step() * 1e3) + " ms");
        sim.emplace(std::move(model), scene.simulator);
        for (const auto& p : scene.probes)
            try {
                sim->add_probe(p);
            } catch (const core::InvalidInputError& e) {
                throw core::InvalidInputError(o.scene_file.string() + ": " + e.what());
            }
    });
    const mss::Model& model = sim->model();

    io::Hdf5Writer out(o.out);
    out.copy_provenance(*in);
    out.write_tet_mesh(mesh_name, mesh_data.mesh, mesh_data.quality, mesh_data.tissues.empty() ? kTissueTable : mesh_data.tissues);
    out.begin_simulation("run", mesh_name);
    out.append_frame("run", 0, sim->state().positions_mm());

    std::vector<io::SimulationStep> all_steps, pending;
    std::vector<std::pair<double, std::vector<core::Vec3>>> picture_frames;
    std::vector<double> png_times = scene.png_times;
    if (png_times.empty())
        png_times = {0, scene.duration / 2, scene.duration};
    auto want_picture = [&](double t) {
        for (double p : png_times)
            if (std::abs(p - t) <= 0.5 * scene.frame_interval)
                return true;
        return false;
    };
    if (!o.png_dir.empty() && want_picture(0))
        picture_frames.emplace_back(0, sim->state().positions_mm());

    std::string status = "completed";
    int frames = 1, next_report = 1;
    double max_force = 0;
    const int frame_count = int(std::ceil(scene.duration / scene.frame_interval - 1e-9));
    const auto t_sim = std::chrono::steady_clock::now();
    try {
        for (int f = 1; f <= frame_count; ++f) {
            const double t = std::min(scene.duration, f * scene.frame_interval);
            sim->advance_to(t, [&](const mss::StepInfo& s) {
                pending.push_back({s.time, s.dt, s.force, s.energy.total()});
                max_force = std::max(max_force, norm(s.force));
            });
            out.append_steps("run", pending);
            all_steps.insert(all_steps.end(), pending.begin(), pending.end());
            pending.clear();
            out.append_frame("run", t, sim->state().positions_mm());
            ++frames;
            if (!o.png_dir.empty() && want_picture(t))
                picture_frames.emplace_back(t, sim->state().positions_mm());
            if (f * 10 >= next_report * frame_count) {
                progress.message("t = " + num(t) + " s (" + std::to_string(next_report * 10) + " %), " +
                                 std::to_string(sim->statistics().steps) + " steps, dt " + num(sim->time_step() * 1e3) +
                                 " ms, force " + num(all_steps.empty() ? 0 : norm(all_steps.back().force)) + " N");
                next_report = int(f * 10 / frame_count) + 1;
            }
        }
    } catch (const core::SolverError& e) {
        status = e.what();
        // The steps since the last frame may include the bad ones: keep only those up to the
        // last good state, which the simulator went back to.
        const double t_good = sim->state().time;
        while (!pending.empty() && pending.back().time > t_good)
            pending.pop_back();
        out.append_steps("run", pending);
        all_steps.insert(all_steps.end(), pending.begin(), pending.end());
    }
    const double sim_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_sim).count();

    const auto& st = sim->statistics();
    std::vector<std::pair<std::string, double>> stats = {
        {"nodes", double(model.node_count())},
        {"springs", double(model.springs().size())},
        {"tets", double(model.tet_count())},
        {"frames", double(frames)},
        {"steps", double(all_steps.size())},           // kept in steps/ (up to the last good state)
        {"steps_integrated", double(st.steps)},        // including any undone by a blow-up
        {"simulated_time_s", sim->state().time},
        {"critical_dt_s", model.critical_time_step()},
        {"gershgorin_dt_s", model.gershgorin_time_step()},
        {"min_dt_s", st.min_dt},
        {"max_dt_s", st.max_dt},
        {"floor_dt_s", scene.simulator.time_step.floor_factor * model.critical_time_step()},
        {"floor_hits", double(st.floor_hits)},
        {"step_cuts", double(st.step_cuts)},
        {"rollbacks", double(st.rollbacks)},
        {"factorizations", double(st.factorizations)},
        {"cg_iterations", double(st.cg_iterations)},
        {"max_force_n", max_force},
        {"wall_time_s", sim_seconds},
        {"wall_time_per_step_us", st.steps > 0 ? 1e6 * sim_seconds / double(st.steps) : 0},
    };
    out.finish_simulation("run", stats, status);
    io::Provenance prov = record.provenance();
    prov.timings.emplace_back("simulate", sim_seconds);
    prov.parameters.emplace_back("scene", scene.text);
    prov.parameters.emplace_back("result.status", status);
    prov.parameters.emplace_back("result.steps", std::to_string(st.steps));
    out.write_provenance(prov);
    out.commit();
    progress.message("wrote " + o.out.string() + ": " + std::to_string(frames) + " frames, " + std::to_string(all_steps.size()) +
                     " steps in " + num(sim_seconds) + " s (" + num(st.steps > 0 ? 1e6 * sim_seconds / double(st.steps) : 0) +
                     " us per step), dt " + num(st.min_dt * 1e3) + ".." + num(st.max_dt * 1e3) + " ms" +
                     (st.floor_hits ? ", " + std::to_string(st.floor_hits) + " steps at the dt floor" : "") +
                     ", largest force " + num(max_force) + " N");

    if (!o.png_dir.empty()) {
        fs::create_directories(o.png_dir);
        for (const auto& [t, pos] : picture_frames) {
            std::vector<Sphere> spheres;
            for (const auto& p : sim->probes())
                spheres.push_back({mss::probe_position(p, t), p.radius_mm});
            char name[64];
            std::snprintf(name, sizeof name, "frame_%07.3fs.png", t);
            tools::write_png(o.png_dir / name, render_mesh(model, pos, spheres, "lsim t = " + num(t) + " s"));
        }
        tools::write_png(o.png_dir / "force.png",
                         plot_force(all_steps, "force of the tissue on the instruments [N] against time [s]"));
        progress.message("pictures in " + o.png_dir.string());
    }
    if (status != "completed") {
        throw core::SolverError(status + " (" + o.out.string() + " keeps the frames up to t = " + num(sim->state().time) +
                                " s)");
    }
    return tools::kExitOk;
}

int make_block(const BlockOptions& o, const tools::Progress& progress, tools::RunRecord& record)
{
    core::TetMesh mesh = mss::make_block_mesh(o.block);
    std::size_t tumour = 0;
    if (o.tumour.size() == 4)
        tumour = mss::label_sphere(mesh, {o.tumour[0], o.tumour[1], o.tumour[2]}, o.tumour[3], 4);
    io::Hdf5Writer out(o.out);
    out.write_tet_mesh("block", mesh, {}, kTissueTable);
    out.write_provenance(record.provenance());
    out.commit();
    progress.message("wrote " + o.out.string() + ": /meshes/block, " + std::to_string(mesh.vertices.size()) + " vertices, " +
                     std::to_string(mesh.tets.size()) + " tets" +
                     (o.tumour.size() == 4 ? " (" + std::to_string(tumour) + " tumour)" : ""));
    return tools::kExitOk;
}

} // namespace lobe::lsim
