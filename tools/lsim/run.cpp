// lsim: run a scene; make a block mesh.
#include "lsim/run.h"

#include "common/files.h"
#include "common/picture.h"
#include "lsim/render.h"
#include "lsim/scene.h"

#include "lobe/core/errors.h"
#include "lobe/io/hdf5.h"
#include "lobe/mesh/quality.h"
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

// What a picture needs of the simulation at one frame: the boundary, coloured by tissue, and
// where the instruments are.
Snapshot snapshot(const mss::Simulator& sim, double t)
{
    Snapshot out;
    out.time = t;
    const auto& m = sim.model();
    out.faces = m.surface_faces();
    for (auto tet : m.surface_face_tets())
        out.labels.push_back(m.mesh().tet_labels[std::size_t(tet)]);
    out.positions = sim.state().positions_mm();
    for (const auto& p : sim.probes())
        out.spheres.push_back({mss::probe_position(p, t), p.radius_mm, false});
    for (std::size_t g = 0; g < sim.grasps().size(); ++g) {
        const auto& gp = sim.grasps()[g];
        const bool closed = !sim.held_nodes(g).empty();
        out.spheres.push_back({mss::grasp_position(gp, t), gp.jaw_radius_mm, true, closed});
    }
    for (const auto& b : sim.blades())
        out.blades.push_back(mss::blade_position(b, t));
    const auto& cut = sim.cut_faces();
    out.cut_faces.assign(cut.begin(), cut.end());
    return out;
}

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
        mss::SimulatorParams params = scene.simulator;
        if (params.refine.enabled)
            // The thesis's fast measure (eq 6.17) from libmesh: libmss takes the quality check as a
            // function so that it need not link libmesh.
            params.refine.quality = mesh::fast_measure;
        sim.emplace(std::move(model), params);
        try {
            for (const auto& p : scene.probes)
                sim->add_probe(p);
            for (const auto& g : scene.grasps)
                sim->add_grasp(g);
            for (const auto& b : scene.blades)
                sim->add_blade(b);
        } catch (const core::InvalidInputError& e) {
            throw core::InvalidInputError(o.scene_file.string() + ": " + e.what());
        }
    });
    const mss::Model& model = sim->model();
    const std::size_t model_nodes0 = model.node_count(), model_springs0 = model.springs().size(), model_tets0 = model.tet_count();
    const double critical0 = model.critical_time_step();

    io::Hdf5Writer out(o.out);
    out.copy_provenance(*in);
    out.write_tet_mesh(mesh_name, mesh_data.mesh, mesh_data.quality, mesh_data.tissues.empty() ? kTissueTable : mesh_data.tissues);
    out.begin_simulation("run", mesh_name);
    out.append_frame("run", 0, sim->state().positions_mm());

    std::vector<io::SimulationStep> all_steps, pending;
    std::vector<Snapshot> picture_frames;
    const std::vector<core::Vec3> framing = model.mesh().vertices; // the rest mesh frames every picture
    std::int64_t topology_written = 0; // the simulator's topology_changes that the file has
    std::vector<double> png_times = scene.png_times;
    if (png_times.empty())
        png_times = {0, scene.duration / 2, scene.duration};
    // Each requested time takes the first frame within half a frame interval of it (frames lie
    // on multiples of the interval, so a time between two frames takes the earlier one).
    std::vector<char> taken(png_times.size(), 0);
    auto want_picture = [&](double t) {
        bool want = false;
        for (std::size_t i = 0; i < png_times.size(); ++i)
            if (!taken[i] && std::abs(png_times[i] - t) <= 0.5 * scene.frame_interval * (1 + 1e-9)) {
                taken[i] = 1;
                want = true;
            }
        return want;
    };
    if (!o.png_dir.empty() && want_picture(0))
        picture_frames.push_back(snapshot(*sim, 0));

    std::string status = "completed";
    int frames = 1, next_report = 1;
    double max_force = 0;
    const int last_frame = int(frame_count(scene)); // bounded by the parser
    const auto t_sim = std::chrono::steady_clock::now();
    try {
        for (int f = 1; f <= last_frame; ++f) {
            const double t = std::min(scene.duration, f * scene.frame_interval);
            sim->advance_to(t, [&](const mss::StepInfo& s) {
                pending.push_back({s.time, s.dt, s.force, s.energy.total()});
                max_force = std::max(max_force, norm(s.force));
            });
            out.append_steps("run", pending);
            all_steps.insert(all_steps.end(), pending.begin(), pending.end());
            pending.clear();
            if (sim->statistics().topology_changes != topology_written) {
                // A cut or a refinement changed the mesh: the frames from here use its topology.
                out.begin_topology("run", sim->model().mesh());
                topology_written = sim->statistics().topology_changes;
            }
            out.append_frame("run", t, sim->state().positions_mm());
            ++frames;
            if (!o.png_dir.empty() && want_picture(t))
                picture_frames.push_back(snapshot(*sim, t));
            if (f * 10 >= next_report * last_frame) {
                progress.message("t = " + num(t) + " s (" + std::to_string(next_report * 10) + " %), " +
                                 std::to_string(sim->statistics().steps) + " steps, dt " + num(sim->time_step() * 1e3) +
                                 " ms, force " + num(all_steps.empty() ? 0 : norm(all_steps.back().force)) + " N");
                next_report = int(f * 10 / last_frame) + 1;
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
    const mss::Model& final_model = sim->model();
    std::vector<std::pair<std::string, double>> stats = {
        {"nodes", double(model_nodes0)},
        {"springs", double(model_springs0)},
        {"tets", double(model_tets0)},
        {"final_nodes", double(final_model.node_count())},
        {"final_tets", double(final_model.tet_count())},
        {"topology_updates", double(st.topology_updates)},
        {"topology_changes", double(st.topology_changes)},
        {"cut_splits", double(st.cut_splits)},
        {"cut_snaps", double(st.cut_snaps)},
        {"cut_separations", double(st.cut_separations)},
        {"refine_splits", double(st.refine_splits)},
        {"coarsen_merges", double(st.coarsen_merges)},
        {"grasp_slips", double(st.grasp_slips)},
        {"lip_corrections", double(st.lip_corrections)},
        {"topology_wall_time_s", st.topology_seconds},
        {"max_topology_update_s", st.max_topology_seconds},
        {"frames", double(frames)},
        {"steps", double(all_steps.size())},           // kept in steps/ (up to the last good state)
        {"steps_integrated", double(st.steps)},        // including any undone by a blow-up
        {"simulated_time_s", sim->state().time},
        {"critical_dt_s", final_model.critical_time_step()},
        {"gershgorin_dt_s", final_model.gershgorin_time_step()},
        {"min_dt_s", st.min_dt},
        {"max_dt_s", st.max_dt},
        {"floor_dt_s", scene.simulator.time_step.floor_factor * critical0},
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
    prov.parameters.emplace_back("spring_kernel", scene.model.simd && mss::simd_spring_kernel_available() ? "avx2" : "scalar");
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
        for (const auto& shot : picture_frames) {
            char name[64];
            std::snprintf(name, sizeof name, "frame_%07.3fs.png", shot.time);
            tools::write_png(o.png_dir / name, render_mesh(shot, framing, "lsim t = " + num(shot.time) + " s, " +
                                                                             std::to_string(shot.positions.size()) + " nodes"));
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
