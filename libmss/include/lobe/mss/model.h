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

//! Springs in structure-of-arrays layout, sorted by their first node (then the second) so that
//! the force loop streams through memory.
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

//! The mass-spring system. Built once from a mesh; rebuild it (and carry the state over by
//! node index) when the topology changes.
class Model {
public:
    //! \throw core::InvalidInputError if core::mesh_problem() rejects the mesh, a tet label has no
    //!        TissueMaterial, a material or parameter is not positive/finite, or the mesh is empty
    explicit Model(const core::TetMesh& mesh, const ModelParams& params = {});

    const ModelParams& params() const { return params_; }
    const core::TetMesh& mesh() const { return mesh_; }
    std::size_t node_count() const { return mass_.size(); }
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
    bool is_fixed(std::size_t i) const { return inv_mass_[i] == 0; }
    //! Fixes every node inside the box [lo, hi] (mm); returns how many.
    std::size_t fix_box(const core::Vec3& lo_mm, const core::Vec3& hi_mm);

    //! Nodes on the boundary (in a face that belongs to one tet only), ascending.
    const std::vector<std::int32_t>& surface_nodes() const { return surface_nodes_; }
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
    double critical_time_step() const { return dt_critical_; }
    //! A guaranteed bound for the linearised undamped system at rest: 2 / sqrt(max_i sum_j
    //! |K_ij| / m_i) (Gershgorin on M^-1 K, springs and volume terms) [s].
    double gershgorin_time_step() const { return dt_gershgorin_; }
    //! Shortest rest edge [m].
    double min_edge_length() const { return min_edge_; }

private:
    void build();

    core::TetMesh mesh_;
    ModelParams params_;
    std::vector<double> rest_, mass_, inv_mass_;
    Springs springs_;
    std::vector<std::int32_t> spring_first_; // springs of first node a: [first[a], first[a+1])
    std::vector<double> tet_e_, tet_v0_, tet_kv_;
    std::vector<double> fem_k_;      // FEM: zero spring stiffness (the springs only damp)
    std::vector<double> tet_dm_inv_; // FEM: 9 per tet, the inverse rest edge matrix, row-major
    std::vector<std::int32_t> surface_nodes_;
    std::vector<std::array<std::int32_t, 3>> surface_faces_;
    std::vector<std::int32_t> surface_face_tets_;
    double dt_critical_ = 0, dt_gershgorin_ = 0, min_edge_ = 0;
};

} // namespace lobe::mss
