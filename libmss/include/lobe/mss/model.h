#pragma once
//! \file
//! \brief The multi-tissue mass-spring model built from a tetrahedral mesh: lumped masses, one
//! spring per edge with a choice of stiffness laws (constant, 1/l, Van Gelder, Lloyd's HAVP),
//! HAVP's volume-preserving forces, axial spring damping, fixed nodes and gravity
//! (docs/algorithms/mass_spring.md).
//!
//! Units: the model works in SI internally (m, kg, s, N, Pa, J). Positions come in and go out in
//! millimetres, as everywhere in lobe; forces are in newtons, energies in joules, times in seconds.

#include "lobe/core/tet_mesh.h"
#include "lobe/core/types.h"

#include <array>
#include <cstdint>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

namespace lobe::mss {

//! How a spring's stiffness follows from the mesh and the material.
enum class Stiffness {
    Constant,      //!< k = E_edge * reference_length (the same for every edge of a tissue)
    InverseLength, //!< k = E_edge * reference_length^2 / l
    VanGelder,     //!< k = sum over the tets t sharing the edge of E_t V_t / l^2 (Van Gelder 1998)
    Havp,          //!< k = sum over the tets t sharing the edge of c E_t l (Lloyd et al. 2007), plus
                   //!< volume forces of stiffness k_V = volume_coefficient * E_t * V0_t per tet
};

//! What produces the elastic forces. The FEM formulations are the accuracy reference for the
//! mass-spring laws (docs/algorithms/mass_spring.md, "FEM reference"): linear tetrahedra with
//! the tissue's E and poisson_ratio, small-strain (Linear) or with the element rotation removed
//! by a polar decomposition (Corotational). Explicit integrators only.
enum class Formulation {
    MassSpring,     //!< springs (and HAVP volume forces) as chosen by Stiffness
    LinearFem,      //!< f = -K_e (x - X) per tet
    CorotationalFem //!< f = -R K_e (R^T x - X) per tet, R from the polar decomposition of F
};
//! "mass-spring", "linear-fem", "corotational-fem"
const char* formulation_name(Formulation f);
//! \throw core::InvalidInputError for another name
Formulation parse_formulation(const std::string& name);

//! "constant", "inverse-length", "van-gelder", "havp".
const char* stiffness_name(Stiffness s);
//! Inverse of stiffness_name. \throw core::InvalidInputError for another name
Stiffness parse_stiffness(const std::string& name);

//! Whether this CPU runs the spring pass's AVX2 + FMA kernel (ModelParams::simd).
bool simd_spring_kernel_available();

//! One tissue: the tet label it applies to and its material.
struct TissueMaterial {
    std::int32_t label = 1;
    double youngs_modulus = 11000; //!< E [Pa]
    double density = 1060;         //!< [kg/m^3]
};

//! The thesis's tissues (docs/algorithms/mass_spring.md): liver parenchyma E = 11 kPa, portal and
//! hepatic veins 5 x, tumour 10 x; density 1060 kg/m^3 for all (a literature value; the thesis
//! gives none).
std::vector<TissueMaterial> default_tissues();

//! The HAVP spring constant c of k = c E l: the Frobenius least-squares fit of the spring-only
//! stiffness matrix of a regular tetrahedron to its linear FEM matrix with Poisson ratio 1/4
//! (Lloyd et al. 2007; re-derived in tests/mss/model_test.cpp).
inline constexpr double kHavpSpringOnly = 0.11313708498984761; // 2 sqrt(2) / 25
//! The spring constant c of the joint fit of springs and the volume term (same test).
inline constexpr double kHavpWithVolume = 0.10775;
//! The volume stiffness coefficient of that joint fit: k_V = (2/35) E V0.
inline constexpr double kHavpVolumeCoefficient = 2.0 / 35.0;

//! Parameters of the model. Defaults are the thesis's "modified HAVP" liver.
struct ModelParams {
    Formulation formulation = Formulation::MassSpring;
    Stiffness stiffness = Stiffness::Havp;
    //! Poisson ratio of the FEM formulations (the mass-spring laws imply 1/4).
    double poisson_ratio = 0.25;
    std::vector<TissueMaterial> tissues = default_tissues(); //!< one entry per tet label used
    //! HAVP spring constant c (k = c E l). Default: the joint fit with volume forces.
    double havp_c = kHavpWithVolume;
    //! Volume-force stiffness k_V = volume_coefficient * E * V0 per tet [dimensionless factor];
    //! applied with Havp only; 0 turns volume forces off (then use havp_c = kHavpSpringOnly).
    double volume_coefficient = kHavpVolumeCoefficient;
    //! Length scale of the Constant and InverseLength laws [mm]: they match Van Gelder's
    //! magnitude for a mesh of about this edge length.
    double reference_length_mm = 10;
    //! Axial damping ratio zeta of each spring: c_ij = 2 zeta sqrt(mu_ij k_ij), mu_ij the reduced
    //! mass of its two nodes. 1 = a lone spring critically damped; 0 = undamped.
    double damping_ratio = 0.1;
    //! Mass-proportional (air) damping alpha [1/s]: f_i = -alpha m_i v_i.
    double mass_damping = 0;
    core::Vec3 gravity{0, 0, 0}; //!< [m/s^2], e.g. {0, 9.81, 0} for a supine patient in LPS
    //! Threads of the force pass (OpenMP): packing, springs and HAVP's volume terms. Each
    //! thread takes a contiguous share of the nodes, springs and tets and adds forces only to
    //! the nodes of its own range, handing the few others over, so the sums do not depend on
    //! scheduling. 1 (the default) runs serially; below 100 k springs (about 15 k nodes) the pass
    //! stays serial whatever this says (the fork and joins cost more than a thread saves). Two
    //! threads took a 107 k-node liver's Van Gelder step from 5.4 to 3.0 ms on a quiet machine;
    //! OpenMP's barriers make them much slower when the other core is busy (docs/benchmarks.md,
    //! "Kernels"; OMP_WAIT_POLICY=passive helps there).
    int threads = 1;
    //! Run the spring pass with the AVX2 + FMA kernel when the CPU has them (checked at run
    //! time; the scalar loop otherwise). The forces agree with the scalar loop's to rounding.
    bool simd = true;
};

//! Node positions and velocities; what an integrator advances. Node i of the state is vertex i
//! of the mesh the model was built from.
struct State {
    std::vector<double> x; //!< positions, xyz interleaved [m]
    std::vector<double> v; //!< velocities, xyz interleaved [m/s]
    double time = 0;       //!< [s]

    std::size_t node_count() const { return x.size() / 3; }
    core::Vec3 position_mm(std::size_t i) const { return {x[3 * i] * 1e3, x[3 * i + 1] * 1e3, x[3 * i + 2] * 1e3}; }
    std::vector<core::Vec3> positions_mm() const;
};

//! Springs in structure-of-arrays layout, built sorted by their first node (then the second) so
//! that the force loop streams through memory; local edits append and move springs (Model::apply).
struct Springs {
    std::vector<std::int32_t> a, b;  //!< node indices, a < b
    std::vector<double> rest_length; //!< [m]
    std::vector<double> stiffness;   //!< k [N/m]
    std::vector<double> damping;     //!< c [N s/m]
    std::size_t size() const { return a.size(); }
};

//! Energies of a state [J].
struct Energy {
    double kinetic = 0;
    double springs = 0;
    double volume = 0;  //!< HAVP volume terms, or the FEM strain energy
    double gravity = 0; //!< potential relative to the rest positions: -sum m g.(x - X)
    double total() const { return kinetic + springs + volume + gravity; }
};

//! A vertex that a MeshEdit adds: a point of the segment between two vertices, in the rest
//! shape and in the current state alike (a = b, t = 0: a copy of vertex a, as a cut needs).
struct NewVertex {
    std::int32_t a = 0, b = 0;
    double t = 0; //!< (1 - t) a + t b, in [0, 1]
};

//! A local change of the mesh, applied by Model::apply in this order: the new vertices are
//! appended (indices node_count(), node_count() + 1, ...); the removed tets go (the last tets
//! move into their slots); the added tets are appended; the removed vertices go (the last
//! vertices move into their slots). Cutting and refinement are built from such edits
//! (lobe/mss/topology.h, docs/algorithms/instruments.md).
struct MeshEdit {
    std::vector<NewVertex> new_vertices;
    std::vector<std::int32_t> removed_tets;
    std::vector<std::array<std::int32_t, 4>> added_tets; //!< may refer to the new vertices
    std::vector<std::int32_t> added_labels;              //!< one tissue label per added tet
    std::vector<std::int32_t> removed_vertices;          //!< each must be in no tet after the edit
};

//! How Model::apply renumbered what it kept: (old index, new index) pairs in the order the
//! moves happened (a later move may move an index that an earlier one produced).
struct EditResult {
    std::vector<std::pair<std::int32_t, std::int32_t>> moved_vertices;
    std::vector<std::pair<std::int32_t, std::int32_t>> moved_tets;
    std::int32_t first_new_vertex = 0; //!< index of the edit's first new vertex
    std::int32_t first_new_tet = 0;    //!< index of the edit's first added tet (they are contiguous)
};

//! The mass-spring system, built from a mesh. Local mesh changes (cuts, refinement) go through
//! apply(), which updates masses, springs, volume terms and the surface locally and carries the
//! state over.
class Model {
public:
    //! \throw core::InvalidInputError if core::mesh_problem() rejects the mesh, a tet label has no
    //!        TissueMaterial, a material or parameter is not positive/finite, or the mesh is empty
    explicit Model(const core::TetMesh& mesh, const ModelParams& params = {});

    const ModelParams& params() const { return params_; }
    const core::TetMesh& mesh() const { return mesh_; }
    std::size_t node_count() const { return mass_.size(); }
    //! Springs: sorted by (a, b) when built; edits append new springs and move the last spring
    //! into the slot of a removed one.
    const Springs& springs() const { return springs_; }
    std::size_t tet_count() const { return mesh_.tets.size(); }

    const std::vector<double>& masses() const { return mass_; }         //!< lumped [kg]
    const std::vector<double>& inverse_masses() const { return inv_mass_; } //!< 0 for fixed nodes
    double total_mass() const;                                           //!< [kg]
    double rest_volume() const;                                          //!< [m^3]
    const std::vector<double>& rest_positions() const { return rest_; }  //!< xyz [m]
    //! Volume-force coefficient k_V / V0^2 of each tet [J/m^6], 0 without volume forces.
    const std::vector<double>& volume_stiffness() const { return tet_kv_; }
    const std::vector<double>& tet_rest_volumes() const { return tet_v0_; } //!< [m^3]

    //! Fixes node i in place (a ligament attachment) or frees it.
    void set_fixed(std::size_t i, bool fixed);
    bool is_fixed(std::size_t i) const { return fixed_[i] != 0; }
    //! Fixes every node inside the box [lo, hi] (mm); returns how many.
    std::size_t fix_box(const core::Vec3& lo_mm, const core::Vec3& hi_mm);

    //! Nodes on the boundary (in a face that belongs to one tet only), ascending.
    const std::vector<std::int32_t>& surface_nodes() const;
    //! Boundary faces, oriented outward.
    const std::vector<std::array<std::int32_t, 3>>& surface_faces() const { return surface_faces_; }
    //! The tet each boundary face belongs to.
    const std::vector<std::int32_t>& surface_face_tets() const { return surface_face_tets_; }

    //! The state at rest: rest positions, zero velocities, time 0.
    State rest_state() const;

    //! Internal plus external (gravity, mass damping) forces at state s [N], xyz interleaved,
    //! written into f (resized). Fixed nodes get their forces too (the integrator ignores them).
    //! If energy is not null, fills it (kinetic and potential energies of s).
    void forces(const State& s, std::vector<double>& f, Energy* energy = nullptr) const;

    //! All energies of s.
    Energy energy(const State& s) const;

    //! Paloc's per-spring critical time step pi sqrt(m/k) with m the smaller node mass of the
    //! spring (the thesis's eq. 3.1 with this model's k), minimised over springs [s]. Without a
    //! safety factor: the symplectic Euler limit is lower (docs/algorithms/mass_spring.md).
    //! After an edit it is the smaller of the previous value and that of the springs the edit
    //! changed (never above the exact minimum: removed springs can only raise it); an edit that
    //! removes vertices recomputes it over the whole mesh.
    double critical_time_step() const;
    //! A guaranteed bound for the linearised undamped system at rest: 2 / sqrt(max_i sum_j
    //! |K_ij| / m_i) (Gershgorin on M^-1 K, springs and volume terms) [s].
    double gershgorin_time_step() const;
    //! Shortest rest edge [m] (after edits: kept like critical_time_step()).
    double min_edge_length() const;

    // ---- local mesh changes ----------------------------------------------------------------

    //! Builds the adjacency that apply() and vertex_tets() use (done by the first apply()
    //! otherwise): tets per vertex, an edge table and a boundary face table, O(tets) once.
    //! \throw core::InvalidInputError above 2^21 - 1 vertices (the face keys pack 21 bits each)
    void enable_editing();
    bool editing_enabled() const { return editing_; }
    //! Tets around vertex v. \pre enable_editing() was called
    const std::vector<std::int32_t>& vertex_tets(std::int32_t v) const { return vertex_tets_[std::size_t(v)]; }

    //! Applies a local edit: new vertices get their rest position, position and velocity
    //! interpolated (a vertex is fixed if both parents are); masses, springs (stiffness from the
    //! tets around each edge, damping from the masses), volume terms and boundary faces are
    //! updated for the touched tets, edges and nodes only; the time step bounds follow. `state`
    //! (of this model) is carried over and stays valid.
    //! \throw core::InvalidInputError for an index out of range, a repeated removal, an added tet
    //!        without material, with a repeated vertex or not positively oriented in the rest
    //!        shape, a vertex left without tets and not removed, or a removed vertex still in a
    //!        tet; the model and the state are then unchanged
    EditResult apply(const MeshEdit& edit, State& state);

    //! Unit outward normal of the boundary around vertex v in state s: the area-weighted mean of
    //! the normals of the boundary faces holding v; zero for an interior vertex.
    //! \pre editing_enabled()
    core::Vec3 boundary_normal(std::int32_t v, const State& s) const;

private:
    void build();
    void set_tet(std::size_t t);              // material, V0, volume and FEM terms of tet t
    void set_spring(std::size_t k);           // stiffness and damping of spring k from its sums
    void update_bounds() const;               // time step bounds and shortest edge
    void add_tet_terms(std::size_t t, double sign, std::vector<std::uint64_t>& edges,
                       std::vector<std::int32_t>& nodes);
    void update_faces(const std::array<std::int32_t, 4>& q, std::vector<std::uint64_t>& faces) const;
    void refresh_face(std::uint64_t key);
    void remove_spring(std::size_t k);

    core::TetMesh mesh_;
    ModelParams params_;
    std::vector<double> rest_, mass_, inv_mass_;
    std::vector<char> fixed_;
    Springs springs_;
    std::vector<double> tet_e_, tet_v0_, tet_kv_, tet_density_;
    std::vector<double> fem_k_;      // FEM: zero spring stiffness (the springs only damp)
    std::vector<double> tet_dm_inv_; // FEM: 9 per tet, the inverse rest edge matrix, row-major
    std::vector<std::array<std::int32_t, 3>> surface_faces_;
    std::vector<std::int32_t> surface_face_tets_;
    mutable std::vector<std::int32_t> surface_nodes_;
    mutable bool surface_nodes_stale_ = false;
    mutable double dt_critical_ = 0, dt_gershgorin_ = 0, min_edge_ = 0;
    mutable bool bounds_stale_ = false;
    mutable bool gershgorin_stale_ = false; // after edits (the critical step is kept up to date)
    // Threaded spring pass: per thread, the forces it hands over (node, fx, fy, fz).
    mutable std::vector<std::vector<std::pair<std::int32_t, std::array<double, 3>>>> spill_;
    // forces()' packed nodes (x y z 0 vx vy vz 0) and force records (x y z 0): scratch, so one
    // forces() call at a time per model.
    mutable std::vector<double> packed_, packed_f_;

    // Editing (enable_editing): per spring the sums its stiffness law needs over the tets around
    // its edge; edge and boundary-face tables keyed by packed vertex indices.
    bool editing_ = false;
    std::vector<std::vector<std::int32_t>> vertex_tets_;
    std::vector<double> spring_sum_e_, spring_sum_ev_;
    std::vector<std::int32_t> spring_count_;
    std::unordered_map<std::uint64_t, std::int32_t> edge_slot_; // edge -> spring
    std::unordered_map<std::uint64_t, std::int32_t> face_slot_; // boundary face -> surface_faces_ slot
};

} // namespace lobe::mss
