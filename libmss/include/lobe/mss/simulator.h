#pragma once
//! \file
//! \brief Time integration of a mss::Model: semi-implicit (symplectic) Euler, velocity Verlet and
//! Baraff-Witkin backward Euler (CHOLMOD or conjugate gradients); fixed, critical or adaptive
//! time steps with a reported floor; blow-up detection that keeps the last good state; probes
//! (docs/algorithms/mass_spring.md).

#include "lobe/mss/instrument.h"
#include "lobe/mss/model.h"

#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace lobe::mss {

enum class Integrator {
    SymplecticEuler, //!< v += dt a(x, v); x += dt v. Conditionally stable.
    VelocityVerlet,  //!< second order; damping uses the predicted velocity. Conditionally stable.
    BackwardEuler,   //!< one Baraff-Witkin linearised implicit step per dt. Stable at large dt.
};
//! "symplectic-euler", "velocity-verlet", "backward-euler"
const char* integrator_name(Integrator i);
//! \throw core::InvalidInputError for another name
Integrator parse_integrator(const std::string& name);

enum class LinearSolver {
    Cholmod,           //!< sparse Cholesky (SuiteSparse CHOLMOD), pattern analysed once
    ConjugateGradient, //!< Jacobi-preconditioned CG, warm-started from the previous step
};
//! "cholmod", "cg"
const char* linear_solver_name(LinearSolver s);
LinearSolver parse_linear_solver(const std::string& name);

enum class StepPolicy {
    Fixed,    //!< dt as given
    Critical, //!< dt = safety * Model::critical_time_step(), recomputed when the model changes
    Adaptive, //!< starts at safety * critical (or dt if given) and adapts from an error estimate
};
//! "fixed", "critical", "adaptive"
const char* step_policy_name(StepPolicy p);
StepPolicy parse_step_policy(const std::string& name);

//! The time step policy. The critical step is Paloc's pi sqrt(m/k) per spring, minimised.
struct TimeStepParams {
    StepPolicy policy = StepPolicy::Adaptive;
    double dt = 0;              //!< Fixed: the step [s] (required); Adaptive: the first step (0 = safety * critical)
    double safety = 0.2;        //!< alpha of dt = alpha * critical (the thesis's step needs one)
    double max_factor = 1.0;    //!< Adaptive: dt never exceeds max_factor * critical
    double floor_factor = 0.01; //!< Adaptive: dt never goes below floor_factor * critical (reported)
    //! Adaptive: allowed local error per step, as a fraction of the shortest rest edge. The
    //! estimate is dt^2/2 max_i |a_i(t+dt) - a_i(t)| (the Euler/trapezoid difference).
    double tolerance = 1e-4;
};

//! Integration parameters.
struct SimulatorParams {
    Integrator integrator = Integrator::SymplecticEuler;
    LinearSolver solver = LinearSolver::Cholmod;
    TimeStepParams time_step;
    double cg_tolerance = 1e-8;  //!< relative residual of CG, and of CHOLMOD solves that reuse a factor
    int cg_max_iterations = 1000;
    //! CHOLMOD: steps a factorisation may be reused for (by iterative refinement against the
    //! current matrix, refactorising whenever that does not reach cg_tolerance); 1 = every step.
    int refactor_interval = 100;
    //! Blow-up: any node faster than this [m/s] (tissue under an instrument moves at mm/s to cm/s).
    double max_speed = 50;
    //! Blow-up: over one check interval the total energy (gravity included) rose, beyond the
    //! work of the instruments, by more than (energy_growth - 1) x the energy magnitude
    //! (kinetic + elastic + |gravity|, at least the elastic energy of a 0.1 % strain of the body).
    double energy_growth = 2;
    int check_interval = 20; //!< steps between blow-up checks on the energy and saved good states
    //! Simulated time between topology updates (cuts, refinement) [s]: 2 ms, 500 updates per
    //! simulated second, well above the 10 Hz of published cutting simulators, while the
    //! instrument force is still reported at every step.
    double topology_interval = 2e-3;
    RefineParams refine; //!< on-the-fly refinement around the instruments (off by default)
};

//! What one step did.
struct StepInfo {
    double time = 0;           //!< time at the end of the step [s]
    double dt = 0;             //!< the step taken [s]
    core::Vec3 force{0, 0, 0}; //!< force of the tissue on the instruments, summed [N]
    Energy energy;             //!< energies at the end of the step [J]
    int contacts = 0;          //!< nodes projected out of instruments in this step
    bool at_floor = false;     //!< the adaptive step sat at its floor
    core::Vec3 grasp_force{0, 0, 0}; //!< force of the held tissue on the forceps, summed [N] (also in force)
    int held = 0;                    //!< nodes the forceps hold
    bool topology_changed = false;   //!< a cut or a refinement changed the mesh before this step
};

//! Run statistics.
struct SimulatorStatistics {
    std::int64_t steps = 0;
    std::int64_t rollbacks = 0;     //!< blow-ups caught by the adaptive policy and undone
    std::int64_t floor_hits = 0;    //!< steps taken at the adaptive floor
    std::int64_t step_cuts = 0;     //!< adaptive reductions from the error estimate
    std::int64_t factorizations = 0;
    std::int64_t cg_iterations = 0;
    double min_dt = 0, max_dt = 0;  //!< [s]
    double max_error = 0;           //!< largest error estimate seen [m]
    std::int64_t topology_updates = 0;  //!< topology updates run (cuts and refinement checks)
    std::int64_t topology_changes = 0;  //!< of those, the ones that changed the mesh
    std::int64_t cut_splits = 0;        //!< edges split by blades
    std::int64_t cut_snaps = 0;         //!< blade crossings moved onto a vertex
    std::int64_t cut_separations = 0;   //!< vertex copies made along cut faces
    std::int64_t refine_splits = 0;     //!< edges bisected by refinement
    std::int64_t coarsen_merges = 0;    //!< bisections undone
    std::int64_t grasp_slips = 0;       //!< nodes that slipped out of the forceps
    std::int64_t lip_corrections = 0;   //!< projections keeping cut lips apart
    double topology_seconds = 0;        //!< wall time spent in topology updates [s]
    double max_topology_seconds = 0;    //!< the longest one [s]
};

//! A model, its state, instruments and integrator. Stateful: the implicit integrator keeps its
//! symbolic factorisation between steps.
class Simulator {
public:
    //! \throw core::InvalidInputError for bad parameters (e.g. Fixed without dt)
    explicit Simulator(Model model, const SimulatorParams& params = {});
    ~Simulator();
    Simulator(Simulator&&) noexcept;
    Simulator& operator=(Simulator&&) noexcept;

    const Model& model() const;
    const SimulatorParams& params() const;
    const State& state() const;
    //! Replaces the state (same node count). \throw core::InvalidInputError otherwise
    void set_state(const State& s);
    //! Adds forceps; returns their index. \throw core::InvalidInputError via validate_grasp
    std::size_t add_grasp(const GraspParams& grasp);
    const std::vector<GraspParams>& grasps() const;
    //! Adds a scalpel blade; returns its index. \throw core::InvalidInputError via validate_blade
    std::size_t add_blade(const BladeParams& blade);
    const std::vector<BladeParams>& blades() const;
    //! Nodes the forceps g hold now.
    const std::vector<std::int32_t>& held_nodes(std::size_t g) const;
    //! The boundary faces that cuts made (outward), kept from passing through each other.
    const std::vector<std::array<std::int32_t, 3>>& cut_faces() const;
    //! Adds a probe; returns its index. \throw core::InvalidInputError via validate_probe, or
    //!        if a surface node lies inside the probe at the current time
    std::size_t add_probe(const ProbeParams& probe);
    const std::vector<ProbeParams>& probes() const;

    //! The step the next step() will take [s].
    double time_step() const;

    //! One step. \throw core::SolverError on a blow-up the policy cannot undo; state() is then
    //! the last good state (checked at most check_interval steps before).
    StepInfo step();
    //! One step, shortened if needed so that it ends at t_end. A step that ends at t_end gets
    //! every blow-up check and becomes the last good state (so frames written at such times are
    //! never undone).
    StepInfo step_until(double t_end);

    //! Steps until time t_end, the last step shortened to land on it; calls on_step after each.
    void advance_to(double t_end, const std::function<void(const StepInfo&)>& on_step = {});

    const SimulatorStatistics& statistics() const;

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

} // namespace lobe::mss
