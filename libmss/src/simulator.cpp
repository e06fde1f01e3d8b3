// Time integration, the time step policy, blow-up detection and probe contact.
#include "lobe/mss/simulator.h"

#include "detail/cutting.h"
#include "detail/implicit.h"
#include "lobe/core/errors.h"
#include "lobe/mss/topology.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <optional>
#include <unordered_set>

namespace lobe::mss {
namespace {

std::string sci(double v)
{
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.3g", v);
    return buf;
}

// Kinetic + elastic + |gravity|: a magnitude that only grows without bound when the run blows up.
double magnitude(const Energy& e) { return e.kinetic + e.springs + e.volume + std::abs(e.gravity); }

} // namespace

const char* integrator_name(Integrator i)
{
    switch (i) {
    case Integrator::SymplecticEuler: return "symplectic-euler";
    case Integrator::VelocityVerlet: return "velocity-verlet";
    case Integrator::BackwardEuler: return "backward-euler";
    }
    return "?";
}
Integrator parse_integrator(const std::string& name)
{
    for (auto i : {Integrator::SymplecticEuler, Integrator::VelocityVerlet, Integrator::BackwardEuler})
        if (name == integrator_name(i))
            return i;
    throw core::InvalidInputError("unknown integrator '" + name + "' (symplectic-euler, velocity-verlet, backward-euler)");
}
const char* linear_solver_name(LinearSolver s) { return s == LinearSolver::Cholmod ? "cholmod" : "cg"; }
LinearSolver parse_linear_solver(const std::string& name)
{
    if (name == "cholmod")
        return LinearSolver::Cholmod;
    if (name == "cg")
        return LinearSolver::ConjugateGradient;
    throw core::InvalidInputError("unknown linear solver '" + name + "' (cholmod, cg)");
}
const char* step_policy_name(StepPolicy p)
{
    switch (p) {
    case StepPolicy::Fixed: return "fixed";
    case StepPolicy::Critical: return "critical";
    case StepPolicy::Adaptive: return "adaptive";
    }
    return "?";
}
StepPolicy parse_step_policy(const std::string& name)
{
    for (auto p : {StepPolicy::Fixed, StepPolicy::Critical, StepPolicy::Adaptive})
        if (name == step_policy_name(p))
            return p;
    throw core::InvalidInputError("unknown time step policy '" + name + "' (fixed, critical, adaptive)");
}

struct Simulator::Impl {
    Model model;
    SimulatorParams params;
    State state;
    std::vector<ProbeParams> probes;
    std::vector<double> force, force_next, dv, v_old, v_pred;
    State lip_before;                 // the state before a lip correction
    std::vector<double> lip_scratch; // forces of the energy passes around it
    std::vector<int> touched; // per node: the index + 1 of the probe that moved it this step (-1: held)
    // Forceps: whether the jaws are closed (or have opened again), what they hold and where.
    struct Grasp {
        GraspParams params;
        bool closed = false, opened = false;
        std::vector<std::int32_t> held;
        std::vector<core::Vec3> offset; // held node - jaw centre at closing [mm]
    };
    std::vector<Grasp> grasps;
    std::vector<GraspParams> grasp_params;
    std::vector<BladeParams> blade_params;
    std::vector<detail::BladeState> blades;
    detail::Cutting cutting;
    struct Split {
        std::int32_t a, b, m; // edge a-b bisected at m
    };
    std::vector<Split> splits; // refinement bisections not yet undone, oldest first
    double next_topology = 0;
    double mean_edge_mm = 0, d_min_mm = 0;
    Energy energy; // of `state`
    double dt = 0, dt_max = 0, dt_floor = 0, dt_cap = 0;
    double tolerance = 0, energy_floor = 0;
    std::unique_ptr<detail::ImplicitSolver> implicit;
    SimulatorStatistics stats;
    // Last good state, for rollback.
    State good;
    std::vector<double> good_force;
    Energy good_energy;
    std::int64_t steps_since_check = 0;
    double max_speed2 = 0; // squared speed of the fastest node after the last step
    double probe_work = 0; // work of the instruments on the tissue since the last good state [J]

    Impl(Model m, const SimulatorParams& p) : model(std::move(m)), params(p)
    {
        const auto& ts = params.time_step;
        auto bad = [](double v) { return !std::isfinite(v) || v < 0; };
        if (bad(ts.dt) || !(ts.safety > 0) || bad(ts.safety) || !(ts.max_factor > 0) || bad(ts.max_factor) ||
            !(ts.floor_factor > 0) || bad(ts.floor_factor) || !(ts.tolerance > 0) || bad(ts.tolerance) ||
            !(params.max_speed > 0) || !(params.energy_growth > 1) || params.check_interval < 1 || params.refactor_interval < 1 ||
            !(params.cg_tolerance > 0) || params.cg_max_iterations < 1)
            throw core::InvalidInputError("simulator: time step factors, tolerance, max_speed, cg settings must be "
                                          "positive, energy_growth above 1, check_interval at least 1");
        if (params.integrator == Integrator::BackwardEuler && model.params().formulation != Formulation::MassSpring)
            throw core::InvalidInputError("simulator: backward Euler supports the mass-spring formulation only, not " +
                                          std::string(formulation_name(model.params().formulation)));
        if (ts.policy == StepPolicy::Fixed && !(ts.dt > 0))
            throw core::InvalidInputError("simulator: the fixed time step policy needs dt > 0");
        state = model.rest_state();
        setup();
    }

    // Everything derived from the model: recomputed when the model changes.
    void setup()
    {
        const auto& ts = params.time_step;
        const double crit = model.critical_time_step();
        dt_max = ts.max_factor * crit;
        dt_floor = ts.floor_factor * crit; // fixed for the run: topology changes may not lower it
        dt_cap = dt_max;
        double sum = 0;
        for (double l : model.springs().rest_length)
            sum += l;
        mean_edge_mm = 1e3 * sum / double(model.springs().size());
        d_min_mm = 0.5e3 * model.min_edge_length();
        switch (ts.policy) {
        case StepPolicy::Fixed: dt = ts.dt; break;
        case StepPolicy::Critical: dt = ts.safety * crit; break;
        case StepPolicy::Adaptive: dt = ts.dt > 0 ? ts.dt : ts.safety * crit; break;
        }
        tolerance = ts.tolerance * model.min_edge_length();
        double e_min = std::numeric_limits<double>::infinity();
        for (const auto& t : model.params().tissues)
            e_min = std::min(e_min, t.youngs_modulus);
        energy_floor = 0.5 * e_min * 1e-6 * model.rest_volume();
        if (params.integrator == Integrator::BackwardEuler)
            implicit = std::make_unique<detail::ImplicitSolver>(model, params);
        evaluate(state, force, energy);
        checkpoint();
    }

    void evaluate(const State& s, std::vector<double>& f, Energy& e) const { model.forces(s, f, &e); }

    // After a cut or a refinement: the step bounds follow the new elements (the floor does not),
    // the implicit solver re-analyses its pattern, and the changed state becomes the good one.
    void after_topology_change()
    {
        const auto& ts = params.time_step;
        const double crit = model.critical_time_step();
        dt_max = ts.max_factor * crit;
        dt_cap = dt_max;
        if (ts.policy == StepPolicy::Critical)
            dt = std::max(dt_floor, ts.safety * crit);
        else if (ts.policy == StepPolicy::Adaptive)
            dt = std::max(dt_floor, std::min(dt, ts.safety * crit));
        tolerance = ts.tolerance * model.min_edge_length();
        if (params.integrator == Integrator::BackwardEuler)
            implicit = std::make_unique<detail::ImplicitSolver>(model, params);
        if (!blades.empty()) {
            cutting.refresh_lips(model);
            cutting.refresh_candidates(state);
        }
        evaluate(state, force, energy);
        checkpoint();
    }

    // Follows the renumbering of a coarsening merge in everything that names vertices.
    void renumber(const std::vector<std::pair<std::int32_t, std::int32_t>>& moved)
    {
        for (const auto& [from, to] : moved) {
            for (auto& sp : splits)
                for (auto* x : {&sp.a, &sp.b, &sp.m})
                    if (*x == from)
                        *x = to;
            for (auto& g : grasps)
                for (auto& h : g.held)
                    if (h == from)
                        h = to;
        }
        cutting.renumber(moved, blades);
    }

    // Distance from p to the nearest instrument, in units of that instrument's reach (its radius
    // or the blade's edge, plus the refinement margin): < 1 inside the refinement region.
    double reach_ratio(const core::Vec3& p, double t) const
    {
        const double margin = params.refine.margin_mm > 0 ? params.refine.margin_mm : 2 * mean_edge_mm;
        double best = std::numeric_limits<double>::infinity();
        for (const auto& pr : probes)
            best = std::min(best, norm(p - probe_position(pr, t)) / (pr.radius_mm + margin));
        for (const auto& g : grasps)
            best = std::min(best, norm(p - grasp_position(g.params, t)) / (g.params.jaw_radius_mm + margin));
        for (const auto& b : blades) {
            const auto [a, e] = blade_position(b.params, t);
            const core::Vec3 d = e - a;
            const double w = std::clamp(dot(p - a, d) / std::max(dot(d, d), 1e-300), 0.0, 1.0);
            best = std::min(best, norm(p - (a + d * w)) / margin);
        }
        return best;
    }

    // Refinement by bisection around the instruments, and the undoing of bisections (newest
    // first) once every instrument has left (docs/algorithms/instruments.md, "Refinement").
    bool refine_update()
    {
        const RefineParams& rp = params.refine;
        const double t = state.time;
        const double target = rp.edge_mm > 0 ? rp.edge_mm : 0.5 * mean_edge_mm;
        const double d_min = rp.min_edge_mm > 0 ? rp.min_edge_mm : d_min_mm;
        bool changed = false;
        // Coarsen: undo bisections whose midpoint no instrument is near any more.
        for (std::size_t i = splits.size(); i-- > 0;) {
            const Split sp = splits[i];
            if (reach_ratio(state.position_mm(std::size_t(sp.m)), t) < rp.coarsen_factor)
                continue;
            bool held = false;
            for (const auto& g : grasps)
                held = held || std::find(g.held.begin(), g.held.end(), sp.m) != g.held.end();
            if (held || cutting.on_cut(sp.m))
                continue;
            std::vector<std::pair<std::int32_t, std::int32_t>> moved;
            if (!merge_split(model, state, sp.m, sp.a, sp.b, &moved))
                continue; // its tets were split further (a later bisection still stands) or cut
            splits.erase(splits.begin() + std::ptrdiff_t(i));
            renumber(moved);
            ++stats.coarsen_merges;
            changed = true;
        }
        // Refine: the longest rest edges in the region first.
        model.enable_editing();
        std::vector<char> inside(model.node_count(), 0);
        for (std::size_t v = 0; v < model.node_count(); ++v)
            inside[v] = reach_ratio(state.position_mm(v), t) < 1;
        struct Candidate {
            double length;
            std::int32_t a, b;
        };
        std::vector<Candidate> cand;
        std::unordered_set<std::uint64_t> seen;
        const auto& rest = model.mesh().vertices;
        for (std::size_t v = 0; v < model.node_count(); ++v) {
            if (!inside[v])
                continue;
            for (auto tt : model.vertex_tets(std::int32_t(v)))
                for (auto w : model.mesh().tets[std::size_t(tt)]) {
                    const auto a = std::min(std::int32_t(v), w), b = std::max(std::int32_t(v), w);
                    if (a == b || !seen.insert((std::uint64_t(std::uint32_t(a)) << 32) | std::uint32_t(b)).second)
                        continue;
                    const double l = norm(rest[std::size_t(b)] - rest[std::size_t(a)]);
                    if (l > target && !(cutting.on_cut(a) && cutting.on_cut(b)))
                        cand.push_back({l, a, b});
                }
        }
        std::sort(cand.begin(), cand.end(), [](const Candidate& x, const Candidate& y) {
            return x.length != y.length ? x.length > y.length : std::tie(x.a, x.b) < std::tie(y.a, y.b);
        });
        int done = 0;
        for (const auto& c : cand) {
            if (done >= rp.max_splits)
                break;
            const auto ring = tets_around_edge(model, c.a, c.b);
            if (ring.empty() || c.length / 2 < d_min)
                continue;
            const core::Vec3 mid_rest = (rest[std::size_t(c.a)] + rest[std::size_t(c.b)]) / 2;
            const core::Vec3 mid_now = (state.position_mm(std::size_t(c.a)) + state.position_mm(std::size_t(c.b))) / 2;
            bool ok = true;
            for (auto r : ring) {
                const auto& q = model.mesh().tets[std::size_t(r)];
                for (auto w : q)
                    if (w != c.a && w != c.b && norm(rest[std::size_t(w)] - mid_rest) < d_min)
                        ok = false;
                if (ok && rp.quality) {
                    // Both halves, in the rest shape and as deformed now.
                    for (int half = 0; half < 2 && ok; ++half) {
                        std::array<core::Vec3, 4> pr{}, pc{};
                        for (std::size_t i = 0; i < 4; ++i) {
                            const bool swap = q[i] == (half == 0 ? c.b : c.a);
                            pr[i] = swap ? mid_rest : rest[std::size_t(q[i])];
                            pc[i] = swap ? mid_now : state.position_mm(std::size_t(q[i]));
                        }
                        ok = rp.quality(pr[0], pr[1], pr[2], pr[3]) >= rp.min_quality &&
                             rp.quality(pc[0], pc[1], pc[2], pc[3]) >= rp.min_quality;
                    }
                }
                if (!ok)
                    break;
            }
            if (!ok)
                continue;
            const auto m = split_edge(model, state, c.a, c.b, 0.5);
            splits.push_back({c.a, c.b, m});
            ++stats.refine_splits;
            ++done;
            changed = true;
        }
        return changed;
    }

    // Cuts, refinement and coarsening at the current time; returns whether the mesh changed.
    bool topology_update()
    {
        const auto t0 = std::chrono::steady_clock::now();
        bool changed = false;
        for (auto& b : blades) {
            if (b.d_min_mm == 0)
                b.d_min_mm = b.params.min_edge_mm > 0 ? b.params.min_edge_mm : b.params.snap * 2 * d_min_mm;
            const detail::CutReport r = cutting.cut(model, state, b, state.time);
            stats.cut_splits += r.splits;
            stats.cut_snaps += r.snapped;
            stats.cut_separations += r.separated;
            changed = changed || r.changed();
        }
        if (params.refine.enabled)
            changed = refine_update() || changed;
        ++stats.topology_updates;
        if (changed) {
            ++stats.topology_changes;
            after_topology_change();
        } else if (!blades.empty()) {
            cutting.refresh_candidates(state); // the lips have moved since the last look
        }
        const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        stats.topology_seconds += secs;
        stats.max_topology_seconds = std::max(stats.max_topology_seconds, secs);
        return changed;
    }

    // Forceps: close (take the free surface nodes within reach) and open at their times.
    void update_grasps(double t)
    {
        for (auto& g : grasps) {
            if (!g.closed && !g.opened && t >= g.params.close_time && t < g.params.open_time) {
                g.closed = true;
                const core::Vec3 c = grasp_position(g.params, t);
                for (const auto v : model.surface_nodes())
                    if (!model.is_fixed(std::size_t(v)) && norm(state.position_mm(std::size_t(v)) - c) <= g.params.jaw_radius_mm) {
                        g.held.push_back(v);
                        g.offset.push_back(state.position_mm(std::size_t(v)) - c);
                    }
            }
            if (g.closed && t >= g.params.open_time) {
                g.closed = false;
                g.opened = true;
                g.held.clear();
                g.offset.clear();
            }
        }
    }

    // Moves the held nodes with the jaws (position and velocity) at the state's time.
    void hold(State& s, double h)
    {
        for (auto& g : grasps) {
            const core::Vec3 c = grasp_position(g.params, s.time) * 1e-3;
            const core::Vec3 vc = (c - grasp_position(g.params, s.time - h) * 1e-3) / h;
            for (std::size_t k = 0; k < g.held.size(); ++k) {
                const auto i = std::size_t(g.held[k]);
                const core::Vec3 target = c + g.offset[k] * 1e-3;
                for (std::size_t d = 0; d < 3; ++d) {
                    s.x[3 * i + d] = target[int(d)];
                    s.v[3 * i + d] = vc[int(d)];
                }
                if (!touched.empty())
                    touched[i] = -1;
            }
        }
    }

    // The force of the held tissue on the jaws (the forces on the held nodes, which the jaws
    // cancel); above the jaws' limit the most loaded node slips out, until the rest is held.
    core::Vec3 grasp_reaction(const std::vector<double>& f, double t, double h)
    {
        core::Vec3 total{0, 0, 0};
        for (auto& g : grasps) {
            // The jaws' work on the tissue this step: they hold each node against f_i while
            // moving it with them.
            const core::Vec3 step = (grasp_position(g.params, t) - grasp_position(g.params, t - h)) * 1e-3;
            core::Vec3 sum{0, 0, 0};
            for (auto i : g.held)
                sum += core::Vec3{f[3 * std::size_t(i)], f[3 * std::size_t(i) + 1], f[3 * std::size_t(i) + 2]};
            while (!g.held.empty() && norm(sum) > g.params.max_force_n) {
                const core::Vec3 dir = normalized(sum);
                std::size_t worst = 0;
                double load = -std::numeric_limits<double>::infinity();
                for (std::size_t k = 0; k < g.held.size(); ++k) {
                    const auto i = std::size_t(g.held[k]);
                    const double l = f[3 * i] * dir.x + f[3 * i + 1] * dir.y + f[3 * i + 2] * dir.z;
                    if (l > load) {
                        load = l;
                        worst = k;
                    }
                }
                const auto i = std::size_t(g.held[worst]);
                sum -= core::Vec3{f[3 * i], f[3 * i + 1], f[3 * i + 2]};
                g.held.erase(g.held.begin() + std::ptrdiff_t(worst));
                g.offset.erase(g.offset.begin() + std::ptrdiff_t(worst));
                ++stats.grasp_slips;
            }
            probe_work -= dot(sum, step);
            total += sum;
        }
        return total;
    }

    void checkpoint()
    {
        good = state;
        good_force = force;
        good_energy = energy;
        steps_since_check = 0;
        probe_work = 0;
    }

    void rollback()
    {
        state = good;
        force = good_force;
        energy = good_energy;
        steps_since_check = 0;
        probe_work = 0;
    }

    // Pushes surface nodes out of every probe at time t; adds the reaction (force of the tissue
    // on the probes) to `reaction`, the probes' work to `work`, the position corrections to x and
    // delta / h to v. Marks each moved node with its probe's index + 1. Returns the nodes moved.
    // The reaction is the impulse the projection gave, m delta / h^2 per node: exact momentum
    // bookkeeping for the explicit integrators (implicit_reaction replaces it for backward Euler).
    int contact(State& s, double h, core::Vec3& reaction, std::vector<int>& moved, double& work) const
    {
        int count = 0;
        const auto& m = model.masses();
        const auto& inv = model.inverse_masses();
        for (std::size_t p = 0; p < probes.size(); ++p) {
            const auto& probe = probes[p];
            const core::Vec3 c = probe_position(probe, s.time) * 1e-3;
            const core::Vec3 vp = (c - probe_position(probe, s.time - h) * 1e-3) / h;
            const double r = probe.radius_mm * 1e-3;
            for (const auto i : model.surface_nodes()) {
                if (inv[std::size_t(i)] == 0)
                    continue;
                double* x = &s.x[3 * std::size_t(i)];
                const double d[3] = {x[0] - c.x, x[1] - c.y, x[2] - c.z};
                const double l2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
                if (l2 >= r * r)
                    continue;
                const double l = std::sqrt(l2);
                // A node at the very centre goes out along +z; any direction is as good.
                const double u[3] = {l > 0 ? d[0] / l : 0, l > 0 ? d[1] / l : 0, l > 0 ? d[2] / l : 1};
                for (int k = 0; k < 3; ++k) {
                    const double delta = (r - l) * u[k];
                    x[k] += delta;
                    s.v[3 * std::size_t(i) + k] += delta / h;
                    // The probe gave the node the momentum m delta / h over h: its force on the
                    // node was m delta / h^2, so the node pushes back with the opposite.
                    reaction[k] -= m[std::size_t(i)] * delta / (h * h);
                    work += m[std::size_t(i)] * delta / h * vp[k];
                }
                moved[std::size_t(i)] = int(p) + 1;
                ++count;
            }
        }
        return count;
    }

    // Backward Euler: the implicit solve already spread each step's motion over the whole mesh,
    // so the projection impulse no longer measures the contact force. The contact carries instead
    // the normal part of the force the rest of the tissue exerts on each touched node (exact at
    // rest, where it balances the supports).
    void implicit_reaction(const State& s, double h, const std::vector<double>& f, const std::vector<int>& moved,
                           core::Vec3& reaction, double& work) const
    {
        for (std::size_t i = 0; i < moved.size(); ++i) {
            if (!moved[i])
                continue;
            const auto& probe = probes[std::size_t(moved[i] - 1)];
            const core::Vec3 c = probe_position(probe, s.time) * 1e-3;
            const core::Vec3 vp = (c - probe_position(probe, s.time - h) * 1e-3) / h;
            const core::Vec3 n = normalized(core::Vec3{s.x[3 * i], s.x[3 * i + 1], s.x[3 * i + 2]} - c);
            const double fn = f[3 * i] * n.x + f[3 * i + 1] * n.y + f[3 * i + 2] * n.z;
            if (fn < 0) {
                reaction += n * fn;
                work -= fn * dot(n, vp) * h;
            }
        }
    }

    // The position constraints after the integrator's update: forceps hold their nodes, and
    // the lips of cuts are kept from passing each other.
    void constrain(State& s, double h)
    {
        if (!grasps.empty())
            hold(s, h);
        if (!cutting.lips().empty()) {
            // The correction moves nodes without a force, so the energy it changes is the
            // instruments' doing, like a probe's work: the blow-up check must not count it. Two
            // energy passes and a copy of the state, only on the steps that correct a crossing.
            const int corrected = cutting.keep_apart(model, s, &lip_before);
            stats.lip_corrections += corrected;
            if (corrected > 0) {
                Energy before, after;
                model.forces(lip_before, lip_scratch, &before);
                model.forces(s, lip_scratch, &after);
                probe_work += after.total() - before.total();
            }
        }
    }

    // One step of size h from `state`, with `force` = forces at `state`. Leaves the new state,
    // its forces and energy; returns the error estimate.
    double integrate(double h, StepInfo& info)
    {
        const std::size_t n = model.node_count();
        const auto& inv = model.inverse_masses();
        // In place: a blow-up goes back to the checkpoint, so the old state is not needed.
        State& next = state;
        next.time = state.time + h;
        if (!probes.empty() || !grasps.empty())
            touched.assign(n, 0);
        core::Vec3 reaction{0, 0, 0};
        int contacts = 0;
        Energy e_next;
        double* x = next.x.data();
        double* v = next.v.data();
        // The node passes share the force pass's threads on meshes large enough for them
        // (ModelParams::threads; the same 100 k-spring threshold, about 15 k nodes).
        const int team = model.springs().size() >= 100000 ? std::max(1, model.params().threads) : 1;
        switch (params.integrator) {
        case Integrator::SymplecticEuler:
#pragma omp parallel for num_threads(team) if (team > 1) schedule(static)
            for (std::size_t i = 0; i < n; ++i) {
                const double w = h * inv[i];
                for (std::size_t k = 3 * i; k < 3 * i + 3; ++k) {
                    v[k] += w * force[k];
                    x[k] += h * v[k];
                }
            }
            if (!probes.empty())
                contacts = contact(next, h, reaction, touched, probe_work);
            constrain(next, h);
            evaluate(next, force_next, e_next);
            break;
        case Integrator::VelocityVerlet: {
            v_old = next.v;
            for (std::size_t i = 0; i < n; ++i)
                for (std::size_t k = 3 * i; k < 3 * i + 3; ++k) {
                    const double a = force[k] * inv[i];
                    x[k] += h * v[k] + 0.5 * h * h * a;
                    v[k] += h * a; // predicted, for the damping forces
                }
            v_pred.clear();
            if (!probes.empty() || !grasps.empty() || !cutting.lips().empty()) {
                v_pred = next.v;
                contacts = contact(next, h, reaction, touched, probe_work);
                constrain(next, h);
            }
            model.forces(next, force_next, &e_next);
            for (std::size_t i = 0; i < n; ++i)
                for (std::size_t k = 3 * i; k < 3 * i + 3; ++k) {
                    const double correction = v_pred.empty() ? 0 : v[k] - v_pred[k];
                    v[k] = v_old[k] + 0.5 * h * (force[k] + force_next[k]) * inv[i] + correction;
                }
            e_next.kinetic = 0;
            const auto& m = model.masses();
            for (std::size_t i = 0; i < n; ++i)
                e_next.kinetic += 0.5 * m[i] * (v[3 * i] * v[3 * i] + v[3 * i + 1] * v[3 * i + 1] + v[3 * i + 2] * v[3 * i + 2]);
            // Damping forces were evaluated with the predicted velocity; refresh them.
            if (model.params().damping_ratio > 0 || model.params().mass_damping > 0)
                model.forces(next, force_next);
            break;
        }
        case Integrator::BackwardEuler: {
            stats.cg_iterations += implicit->solve(state, force, h, dv);
            for (std::size_t i = 0; i < n; ++i)
                for (std::size_t k = 3 * i; k < 3 * i + 3; ++k) {
                    v[k] += inv[i] == 0 ? 0 : dv[k];
                    x[k] += h * v[k];
                }
            if (!probes.empty()) {
                double ignored = 0;
                contacts = contact(next, h, reaction, touched, ignored);
                reaction = {0, 0, 0};
            }
            constrain(next, h);
            evaluate(next, force_next, e_next);
            if (contacts > 0)
                implicit_reaction(next, h, force_next, touched, reaction, probe_work);
            stats.factorizations = implicit->factorizations();
            break;
        }
        }
        if (!grasps.empty()) {
            info.grasp_force = grasp_reaction(force_next, next.time, h);
            reaction += info.grasp_force;
            for (const auto& g : grasps)
                info.held += int(g.held.size());
        }
        // Error estimate: dt^2/2 |a(t+h) - a(t)|, over free nodes the instruments did not move.
        // The same pass finds the fastest node for the blow-up check.
        double err = 0, vmax2 = 0;
#pragma omp parallel for num_threads(team) if (team > 1) schedule(static) reduction(max : err, vmax2)
        for (std::size_t i = 0; i < n; ++i) {
            vmax2 = std::max(vmax2, v[3 * i] * v[3 * i] + v[3 * i + 1] * v[3 * i + 1] + v[3 * i + 2] * v[3 * i + 2]);
            if (inv[i] == 0 || (!touched.empty() && touched[i]))
                continue;
            double d2 = 0;
            for (int k = 0; k < 3; ++k) {
                const double d = (force_next[3 * i + k] - force[3 * i + k]) * inv[i];
                d2 += d * d;
            }
            err = std::max(err, d2);
        }
        err = 0.5 * h * h * std::sqrt(err);
        max_speed2 = vmax2;
        force.swap(force_next);
        energy = e_next;
        info.time = state.time;
        info.dt = h;
        info.force = reaction;
        info.energy = energy;
        info.contacts = contacts;
        return err;
    }

    // Why the current state is blown up, or empty.
    std::string blow_up(bool energy_check) const
    {
        // A non-finite position or velocity makes the energy non-finite (every node is in a
        // spring and carries kinetic energy), so no separate pass over the nodes is needed.
        if (!std::isfinite(energy.total()) || !std::isfinite(max_speed2))
            return "a node position or velocity is not finite";
        if (max_speed2 > params.max_speed * params.max_speed)
            return "a node moves at " + sci(std::sqrt(max_speed2)) + " m/s (limit " + sci(params.max_speed) + " m/s)";
        if (energy_check) {
            // Energy balance: without blow-up the total energy (gravity included) only falls by
            // damping and rises by the probes' work; allow (growth - 1) x its magnitude. The work
            // is estimated from the contact impulses, so its own size is part of the scale.
            const double excess = energy.total() - good_energy.total() - probe_work;
            const double scale = std::max({magnitude(good_energy), std::abs(probe_work), energy_floor});
            if (excess > (params.energy_growth - 1) * scale)
                return "the energy rose by " + sci(excess) + " J beyond the work of the instruments in " +
                       std::to_string(steps_since_check) + " steps (from " + sci(good_energy.total()) + " J)";
        }
        return {};
    }

    // One step of at most h_limit; `landing` = the step is meant to end at a requested time.
    StepInfo step(double h_limit, bool landing)
    {
        const bool adaptive = params.time_step.policy == StepPolicy::Adaptive;
        bool topology_changed = false;
        if ((!blades.empty() || params.refine.enabled) && state.time >= next_topology - 1e-12) {
            topology_changed = topology_update();
            next_topology = state.time + params.topology_interval;
        }
        if (!grasps.empty())
            update_grasps(state.time);
        for (;;) {
            double h = std::min(dt, h_limit);
            StepInfo info;
            info.at_floor = adaptive && dt <= dt_floor;
            info.topology_changed = topology_changed;
            // A step that lands on a requested time (an output frame) is checked in full and
            // becomes the last good state, so what is written out never has to be taken back.
            const double err = integrate(h, info);
            ++steps_since_check;
            const bool full_check = (landing && h == h_limit) || steps_since_check >= params.check_interval;
            const std::string why = blow_up(full_check);
            if (!why.empty()) {
                const double t_bad = state.time;
                rollback();
                if (adaptive && dt > dt_floor) {
                    // Paloc's empirical rule: back off below the step that failed and stay there.
                    ++stats.rollbacks;
                    dt_cap = std::max(dt_floor, 0.5 * dt);
                    dt = std::max(dt_floor, 0.25 * dt);
                    continue;
                }
                throw core::SolverError(std::string(integrator_name(params.integrator)) + " blew up at t = " + sci(t_bad) +
                                        " s with dt = " + sci(h) + " s (critical step estimate " +
                                        sci(model.critical_time_step()) + " s, Gershgorin bound " +
                                        sci(model.gershgorin_time_step()) + " s): " + why +
                                        "; the state is the last good one, at t = " + sci(state.time) + " s");
            }
            if (full_check)
                checkpoint();
            ++stats.steps;
            stats.min_dt = stats.steps == 1 ? h : std::min(stats.min_dt, h);
            stats.max_dt = std::max(stats.max_dt, h);
            stats.max_error = std::max(stats.max_error, err);
            if (info.at_floor)
                ++stats.floor_hits;
            if (adaptive && h == dt) {
                if (err > tolerance) {
                    // A large error (an instrument starting to move, a contact) shortens the
                    // step; it grows back by 5 % a step once the error is small again. Only a
                    // blow-up lowers the cap for good.
                    ++stats.step_cuts;
                    dt = std::max(dt_floor, dt * std::max(0.5, 0.9 * std::sqrt(tolerance / err)));
                } else if (err < 0.25 * tolerance) {
                    dt = std::min(dt * 1.05, dt_cap);
                }
            }
            return info;
        }
    }
};

Simulator::Simulator(Model model, const SimulatorParams& params) : impl_(std::make_unique<Impl>(std::move(model), params)) {}
Simulator::~Simulator() = default;
Simulator::Simulator(Simulator&&) noexcept = default;
Simulator& Simulator::operator=(Simulator&&) noexcept = default;

const Model& Simulator::model() const { return impl_->model; }
const SimulatorParams& Simulator::params() const { return impl_->params; }
const State& Simulator::state() const { return impl_->state; }
const std::vector<ProbeParams>& Simulator::probes() const { return impl_->probes; }
double Simulator::time_step() const { return impl_->dt; }
const SimulatorStatistics& Simulator::statistics() const { return impl_->stats; }

void Simulator::set_state(const State& s)
{
    Impl& m = *impl_;
    if (s.x.size() != 3 * m.model.node_count() || s.v.size() != s.x.size())
        throw core::InvalidInputError("simulator: the state has " + std::to_string(s.x.size() / 3) + " nodes, the model " +
                                      std::to_string(m.model.node_count()));
    m.state = s;
    m.evaluate(m.state, m.force, m.energy);
    m.checkpoint();
}

std::size_t Simulator::add_probe(const ProbeParams& probe)
{
    validate_probe(probe);
    // A probe that appears inside the tissue would be resolved by one huge projection impulse
    // (a blow-up a few steps later); refuse it with the depth instead.
    const Impl& m = *impl_;
    const core::Vec3 c = probe_position(probe, m.state.time);
    double depth = 0;
    for (const auto i : m.model.surface_nodes())
        depth = std::max(depth, probe.radius_mm - norm(m.state.position_mm(std::size_t(i)) - c));
    if (depth > 1e-3) // a micron: touching is fine
        throw core::InvalidInputError("probe '" + probe.name + "' starts " + sci(depth) +
                                      " mm inside the tissue at t = " + sci(m.state.time) +
                                      " s: start its path clear of the surface");
    impl_->probes.push_back(probe);
    return impl_->probes.size() - 1;
}

std::size_t Simulator::add_grasp(const GraspParams& grasp)
{
    validate_grasp(grasp);
    Impl::Grasp g;
    g.params = grasp;
    impl_->grasps.push_back(g);
    impl_->grasp_params.push_back(grasp);
    return impl_->grasps.size() - 1;
}
const std::vector<GraspParams>& Simulator::grasps() const { return impl_->grasp_params; }
const std::vector<std::int32_t>& Simulator::held_nodes(std::size_t g) const { return impl_->grasps.at(g).held; }

std::size_t Simulator::add_blade(const BladeParams& blade)
{
    validate_blade(blade);
    detail::BladeState b;
    b.params = blade;
    impl_->blades.push_back(b);
    impl_->blade_params.push_back(blade);
    impl_->next_topology = impl_->state.time; // the blade's first pose is taken at the next step
    return impl_->blades.size() - 1;
}
const std::vector<BladeParams>& Simulator::blades() const { return impl_->blade_params; }
const std::vector<std::array<std::int32_t, 3>>& Simulator::cut_faces() const { return impl_->cutting.lips(); }

StepInfo Simulator::step() { return impl_->step(std::numeric_limits<double>::infinity(), false); }

StepInfo Simulator::step_until(double t_end)
{
    const double left = t_end - impl_->state.time;
    if (!(left > 0))
        throw core::InvalidInputError("simulator: step_until(" + sci(t_end) + " s) is not after the current time " +
                                      sci(impl_->state.time) + " s");
    // Avoid a sliver of a step just before t_end: split what is left in two instead.
    const double dt = impl_->dt;
    const double h = left <= dt ? left : (left < 1.5 * dt ? 0.5 * left : dt);
    StepInfo info = impl_->step(h, left <= dt);
    if (left <= dt && info.dt == left)
        impl_->state.time = t_end; // exactly, despite rounding
    return info;
}

void Simulator::advance_to(double t_end, const std::function<void(const StepInfo&)>& on_step)
{
    while (impl_->state.time < t_end) {
        const StepInfo info = step_until(t_end);
        if (on_step)
            on_step(info);
    }
}

// ---- probes ----------------------------------------------------------------------------------

core::Vec3 probe_position(const ProbeParams& p, double t)
{
    const auto& path = p.path;
    if (t <= path.front().time)
        return path.front().position_mm;
    for (std::size_t i = 1; i < path.size(); ++i)
        if (t <= path[i].time) {
            const double w = (t - path[i - 1].time) / (path[i].time - path[i - 1].time);
            return path[i - 1].position_mm * (1 - w) + path[i].position_mm * w;
        }
    return path.back().position_mm;
}

void validate_probe(const ProbeParams& p)
{
    const std::string what = "probe '" + p.name + "'";
    if (!(p.radius_mm > 0) || !std::isfinite(p.radius_mm))
        throw core::InvalidInputError(what + ": the radius must be positive");
    if (p.path.empty())
        throw core::InvalidInputError(what + ": the path has no point");
    for (std::size_t i = 0; i < p.path.size(); ++i) {
        const auto& q = p.path[i];
        if (!std::isfinite(q.time) || !std::isfinite(q.position_mm.x) || !std::isfinite(q.position_mm.y) ||
            !std::isfinite(q.position_mm.z))
            throw core::InvalidInputError(what + ": path point " + std::to_string(i + 1) + " is not finite");
        if (i > 0 && !(q.time > p.path[i - 1].time))
            throw core::InvalidInputError(what + ": path times must increase (point " + std::to_string(i + 1) + ")");
    }
}

namespace {

template <class P> void check_times(const std::string& what, const std::vector<P>& path)
{
    if (path.empty())
        throw core::InvalidInputError(what + ": the path has no point");
    for (std::size_t i = 1; i < path.size(); ++i)
        if (!(path[i].time > path[i - 1].time))
            throw core::InvalidInputError(what + ": path times must increase (point " + std::to_string(i + 1) + ")");
}

bool finite(const core::Vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

// Linear interpolation along a path of timed points, clamped at both ends.
template <class P, class F> auto along(const std::vector<P>& path, double t, F get)
{
    if (t <= path.front().time)
        return get(path.front());
    for (std::size_t i = 1; i < path.size(); ++i)
        if (t <= path[i].time) {
            const double w = (t - path[i - 1].time) / (path[i].time - path[i - 1].time);
            return get(path[i - 1]) * (1 - w) + get(path[i]) * w;
        }
    return get(path.back());
}

} // namespace

void validate_grasp(const GraspParams& g)
{
    const std::string what = "forceps '" + g.name + "'";
    check_times(what, g.path);
    for (std::size_t i = 0; i < g.path.size(); ++i)
        if (!std::isfinite(g.path[i].time) || !finite(g.path[i].position_mm))
            throw core::InvalidInputError(what + ": path point " + std::to_string(i + 1) + " is not finite");
    if (!(g.jaw_radius_mm > 0) || !std::isfinite(g.jaw_radius_mm))
        throw core::InvalidInputError(what + ": the jaw radius must be positive");
    if (!(g.max_force_n > 0) || !std::isfinite(g.max_force_n))
        throw core::InvalidInputError(what + ": the maximum force must be positive");
    if (!std::isfinite(g.close_time) || std::isnan(g.open_time) || !(g.open_time > g.close_time))
        throw core::InvalidInputError(what + ": the jaws must open after they close");
}

void validate_blade(const BladeParams& b)
{
    const std::string what = "blade '" + b.name + "'";
    check_times(what, b.path);
    for (std::size_t i = 0; i < b.path.size(); ++i) {
        const auto& q = b.path[i];
        if (!std::isfinite(q.time) || !finite(q.a_mm) || !finite(q.b_mm))
            throw core::InvalidInputError(what + ": pose " + std::to_string(i + 1) + " is not finite");
        if (!(norm(q.b_mm - q.a_mm) > 0))
            throw core::InvalidInputError(what + ": pose " + std::to_string(i + 1) + " has a zero-length edge");
    }
    if (!(b.snap > 0 && b.snap < 0.5))
        throw core::InvalidInputError(what + ": snap must lie in (0, 0.5)");
    if (!(b.min_edge_mm >= 0) || !std::isfinite(b.min_edge_mm))
        throw core::InvalidInputError(what + ": min_edge must not be negative");
}

std::pair<core::Vec3, core::Vec3> blade_position(const BladeParams& b, double t)
{
    return {along(b.path, t, [](const BladePose& p) { return p.a_mm; }), along(b.path, t, [](const BladePose& p) { return p.b_mm; })};
}

core::Vec3 grasp_position(const GraspParams& g, double t)
{
    return along(g.path, t, [](const PathPoint& p) { return p.position_mm; });
}

} // namespace lobe::mss
