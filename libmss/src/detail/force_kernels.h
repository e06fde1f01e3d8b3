// The spring and HAVP volume passes of Model::forces on a packed node layout (docs/algorithms/mass_spring.md,
// "The step's cost"): one 64-byte record per node, x y z 0 vx vy vz 0, so a spring's two ends
// cost two cache lines and one vector load each for position and velocity; forces accumulate
// as x y z 0 records of 32 bytes.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

namespace lobe::mss::detail {

//! The springs of Model::springs() as raw arrays, and the stiffness actually used (fem_k_ for
//! the FEM formulations).
struct SpringArrays {
    const std::int32_t* a = nullptr;
    const std::int32_t* b = nullptr;
    const double* rest_length = nullptr;
    const double* stiffness = nullptr;
    const double* damping = nullptr;
    std::size_t count = 0;
};

//! Sizes buf for n doubles starting on a 64-byte boundary and returns that start (the
//! vector's own storage: it lives in the model, so its capacity is kept between steps).
double* aligned64(std::vector<double>& buf, std::size_t n);

//! Forces a pass hands to another thread's nodes: (node, force on it).
using Spill = std::vector<std::pair<std::int32_t, std::array<double, 3>>>;

//! Adds each spring k's elastic and damping force to f at a and (negated) at b, over springs
//! [first, last), in spring order (so each node's sum is that of the plain loop), and returns
//! sum k ext^2 over them. packed: 8 doubles per node; f: 4 doubles per node. Only nodes in
//! [lo, hi) are written; a force on another node is appended to spill (the threaded pass). With
//! no spill the pass owns every node (the serial pass: nothing is checked).
//! simd: use the AVX2 + FMA kernel if the CPU has them (checked once), else the scalar loop.
double spring_forces(const SpringArrays& s, std::size_t first, std::size_t last, const double* packed, double* f,
                     std::int32_t lo, std::int32_t hi, Spill* spill, bool simd);

//! HAVP's volume terms (Model::forces): tets [first, last), each adding f_i = -(k_V / 6)
//! (V - V0) 6 grad_i V to its four nodes (second, third, fourth, then first node), the same
//! ownership rule as spring_forces. Returns sum k_V (V - V0)^2 over them.
double volume_forces(const std::array<std::int32_t, 4>* tets, const double* rest_volume, const double* kv,
                     std::size_t first, std::size_t last, const double* packed, double* f, std::int32_t lo,
                     std::int32_t hi, Spill* spill, bool simd);

//! The per-node inputs of the packing pass.
struct NodeArrays {
    const double* x = nullptr;    //!< positions, x y z per node
    const double* v = nullptr;    //!< velocities
    const double* mass = nullptr; //!< lumped masses
    const double* rest = nullptr; //!< rest positions (the gravitational energy's zero)
    double gravity[3] = {0, 0, 0};
    double mass_damping = 0;
    std::size_t count = 0; //!< nodes in all (loads past a range's end stay inside the arrays)
};

//! Energies the packing pass takes on the way [J].
struct NodeEnergies {
    double gravity = 0, kinetic = 0;
};

//! Packs nodes [first, last): packed gets x y z 0 vx vy vz 0, f starts each node's sum with
//! m (g - alpha v), x y z 0. Returns their gravitational and kinetic energies.
NodeEnergies pack_nodes(const NodeArrays& nodes, std::size_t first, std::size_t last, double* packed, double* f,
                        bool simd);

//! Copies the force records of nodes [first, last) into out, x y z per node. Writes nothing
//! outside those nodes (ranges of different threads may meet).
void unpack_forces(const double* f, std::size_t first, std::size_t last, double* out, bool simd);

//! Whether this CPU runs spring_forces' AVX2 kernel.
bool cpu_has_simd_kernel();

} // namespace lobe::mss::detail
