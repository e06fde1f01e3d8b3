#pragma once
// Static equilibrium of a mss::Model, for the accuracy tests (tests/mss/accuracy_test.cpp) and
// the accuracy benchmark (bench/mss/mss_accuracy.cpp). Newton's method on Model::forces alone,
// with the stiffness matrix assembled from coloured finite differences of the forces (Curtis,
// Powell and Reid 1974: nodes two edges apart never share a tet, so one forward difference
// perturbs a whole colour at once). Using only the public forces, it treats every stiffness law
// and both FEM formulations alike, and reaches the equilibrium that damped dynamics would reach
// after many periods of the slowest (bending) mode in a handful of solves.
#include "lobe/mss/block_mesh.h"
#include "lobe/mss/model.h"

#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

namespace lobe::mss::statics {

// ---- what the accuracy tests and bench/mss/mss_accuracy compare ----------------------------
constexpr double kLiverE = 11000;  //!< liver Young's modulus [Pa]
constexpr double kLiverRho = 1060; //!< liver density [kg/m^3]

//! One stiffness law or formulation under comparison.
struct Variant {
    std::string name;
    Formulation formulation;
    Stiffness stiffness;
};

//! The two FEM references, then the four mass-spring laws.
inline const std::vector<Variant>& variants()
{
    static const std::vector<Variant> v = {
        {"linear-fem", Formulation::LinearFem, Stiffness::VanGelder},
        {"corotational-fem", Formulation::CorotationalFem, Stiffness::VanGelder},
        {"constant", Formulation::MassSpring, Stiffness::Constant},
        {"inverse-length", Formulation::MassSpring, Stiffness::InverseLength},
        {"van-gelder", Formulation::MassSpring, Stiffness::VanGelder},
        {"havp", Formulation::MassSpring, Stiffness::Havp},
    };
    return v;
}

//! One tissue (label 1) of liver under variant v.
inline ModelParams liver_params(const Variant& v)
{
    ModelParams mp;
    mp.formulation = v.formulation;
    mp.stiffness = v.stiffness;
    mp.tissues = {{1, kLiverE, kLiverRho}};
    return mp;
}

//! The compression problem: a 20 x 20 x 80 mm column of n x n x 4n cells (5 tets each), both
//! ends clamped, and the state with the top moved down 1 % (uniform strain: the top plate's
//! move, and a start near the solution).
struct Column {
    Model model;
    State start;
};
inline Column compression_column(const Variant& v, int n)
{
    BlockMeshParams bp;
    bp.cells = {n, n, 4 * n};
    bp.size = {20, 20, 80};
    bp.tets_per_cell = 5;
    Model m(make_block_mesh(bp), liver_params(v));
    m.fix_box({-1, -1, -1}, {21, 21, 1e-6});
    m.fix_box({-1, -1, 80 - 1e-6}, {21, 21, 81});
    State s = m.rest_state();
    for (std::size_t i = 0; i < m.node_count(); ++i)
        s.x[3 * i + 2] *= 0.99;
    return {std::move(m), std::move(s)};
}

//! Force of the column on its top plate (z = 80 mm) in state s [N].
inline double top_plate_force(const Model& m, const State& s)
{
    std::vector<double> f;
    m.forces(s, f);
    double push = 0;
    for (std::size_t i = 0; i < m.node_count(); ++i)
        if (m.mesh().vertices[i].z > 80 - 1e-6)
            push += f[3 * i + 2];
    return push;
}

//! The cantilever: an 80 x 10 x 10 mm beam along x, 8n x n x n cells (5 tets each), clamped at
//! x = 0, bent by its own weight along -z, the gravity scaled so that Euler-Bernoulli gives a tip
//! deflection of kBeamTip (0.5 % of the length: the linear regime both theories assume).
constexpr double kBeamLength = 0.08, kBeamSide = 0.01, kBeamTip = 4e-4; // [m]
inline double beam_gravity()
{
    const double area = kBeamSide * kBeamSide, inertia = area * area / 12;
    return 8 * kLiverE * inertia * kBeamTip / (kLiverRho * area * kBeamLength * kBeamLength * kBeamLength * kBeamLength);
}
inline Model cantilever(const Variant& v, int n)
{
    BlockMeshParams bp;
    bp.cells = {8 * n, n, n};
    bp.size = {80, 10, 10};
    bp.tets_per_cell = 5;
    ModelParams mp = liver_params(v);
    mp.gravity = {0, 0, -beam_gravity()};
    Model m(make_block_mesh(bp), mp);
    m.fix_box({-1, -1, -1}, {1e-6, 11, 11});
    return m;
}

//! Mean downward (-z) displacement of the beam's free end face (x > 80 mm) [m].
inline double tip_deflection(const Model& m, const State& s)
{
    double sum = 0;
    int count = 0;
    for (std::size_t i = 0; i < m.node_count(); ++i)
        if (m.mesh().vertices[i].x > 80 - 1e-6) {
            sum += m.rest_positions()[3 * i + 2] - s.x[3 * i + 2];
            ++count;
        }
    return sum / count;
}

struct StaticParams {
    //! Converged when the largest force on a free node is below tolerance x the largest one at
    //! the start (the load: gravity, or the reaction to the prescribed displacements). Rounding
    //! in the elastic forces (k x ulp(x)) sets a floor near 1e-9..1e-8 of a small gravity load;
    //! 1e-6 leaves displacements wrong by about that fraction, far below the errors measured.
    double tolerance = 1e-6;
    //! Also converged when a Newton step moves no node by more than step_tolerance x the largest
    //! displacement from the start: very stiff laws (1/l on fine meshes) reach their rounding
    //! floor above `tolerance` of a small load while the displacements have long stopped moving.
    double step_tolerance = 1e-9;
    int max_iterations = 40;
    double fd_step = 1e-9; //!< finite-difference step [m]; the forces are smooth at this scale
};

struct StaticResult {
    State state;
    int iterations = 0;
    int jacobians = 0;   //!< stiffness matrices assembled
    int colours = 0;     //!< colours of the last assembly (force evaluations per component)
    double residual = 0; //!< largest free force at the end / at the start
    double last_step = 0; //!< largest move of the last Newton step / largest displacement
    bool converged = false;
};

namespace detail {

// Closed neighbourhoods (the node and every node it shares an edge, hence a tet, with).
inline std::vector<std::vector<std::int32_t>> neighbourhoods(const Model& m)
{
    std::vector<std::vector<std::int32_t>> nb(m.node_count());
    for (std::size_t i = 0; i < nb.size(); ++i)
        nb[i].push_back(std::int32_t(i));
    const auto& s = m.springs();
    for (std::size_t k = 0; k < s.size(); ++k) {
        nb[std::size_t(s.a[k])].push_back(s.b[k]);
        nb[std::size_t(s.b[k])].push_back(s.a[k]);
    }
    return nb;
}

// Greedy distance-2 colouring: no node sees two nodes of one colour in its neighbourhood.
inline std::vector<int> colour(const std::vector<std::vector<std::int32_t>>& nb, int& count)
{
    std::vector<int> c(nb.size(), -1), seen;
    count = 0;
    for (std::size_t i = 0; i < nb.size(); ++i) {
        seen.assign(std::size_t(count) + 1, 0);
        for (auto j : nb[i])
            for (auto k : nb[std::size_t(j)])
                if (c[std::size_t(k)] >= 0)
                    seen[std::size_t(c[std::size_t(k)])] = 1;
        int pick = 0;
        while (seen[std::size_t(pick)])
            ++pick;
        c[i] = pick;
        count = std::max(count, pick + 1);
    }
    return c;
}

} // namespace detail

// K = -df/dx over the free degrees of freedom (dof[3i + r] >= 0), symmetrised.
inline Eigen::SparseMatrix<double> stiffness(const Model& m, const State& s, const std::vector<int>& dof, int free,
                                             double h, int* colours = nullptr)
{
    const auto nb = detail::neighbourhoods(m);
    int count = 0;
    const std::vector<int> col = detail::colour(nb, count);
    if (colours)
        *colours = count;
    std::vector<double> f0, f1;
    m.forces(s, f0);
    std::vector<Eigen::Triplet<double>> t;
    State p = s;
    for (int c = 0; c < count; ++c)
        for (int d = 0; d < 3; ++d) {
            p.x = s.x;
            bool any = false;
            for (std::size_t i = 0; i < nb.size(); ++i)
                if (col[i] == c && dof[3 * i + std::size_t(d)] >= 0) {
                    p.x[3 * i + std::size_t(d)] += h;
                    any = true;
                }
            if (!any)
                continue;
            m.forces(p, f1);
            for (std::size_t i = 0; i < nb.size(); ++i) {
                if (col[i] != c || dof[3 * i + std::size_t(d)] < 0)
                    continue;
                const int column = dof[3 * i + std::size_t(d)];
                for (auto j : nb[i])
                    for (std::size_t r = 0; r < 3; ++r) {
                        const std::size_t row = 3 * std::size_t(j) + r;
                        if (dof[row] >= 0)
                            t.emplace_back(dof[row], column, -(f1[row] - f0[row]) / h);
                    }
            }
        }
    Eigen::SparseMatrix<double> k(free, free);
    k.setFromTriplets(t.begin(), t.end());
    const Eigen::SparseMatrix<double> kt = k.transpose();
    return 0.5 * (k + kt);
}

//! Equilibrium of the free nodes, the fixed ones (inverse mass 0) held where `start` puts them.
//! Modified Newton: the stiffness matrix is reassembled only when a step fails to shrink the
//! residual tenfold (the linear FEM converges in one step, the others in a few).
inline StaticResult solve_static(const Model& m, const State& start, const StaticParams& params = {})
{
    StaticResult r;
    r.state = start;
    std::fill(r.state.v.begin(), r.state.v.end(), 0.0); // no damping force at rest
    const std::size_t n = m.node_count();
    std::vector<int> dof(3 * n, -1);
    int free = 0;
    for (std::size_t i = 0; i < n; ++i)
        if (!m.is_fixed(i))
            for (std::size_t d = 0; d < 3; ++d)
                dof[3 * i + d] = free++;
    auto largest = [&](const std::vector<double>& f) {
        double v = 0;
        for (std::size_t k = 0; k < f.size(); ++k)
            if (dof[k] >= 0)
                v = std::max(v, std::abs(f[k]));
        return v;
    };
    std::vector<double> f;
    m.forces(r.state, f);
    const double load = largest(f);
    if (!(load > 0)) {
        r.converged = true;
        return r;
    }
    Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver;
    bool fresh = false;
    double previous = load;
    Eigen::VectorXd rhs(free);
    for (r.iterations = 0; r.iterations < params.max_iterations; ++r.iterations) {
        const double now = largest(f);
        r.residual = now / load;
        if (r.residual <= params.tolerance) {
            r.converged = true;
            break;
        }
        if (r.iterations == 0 || (now > 0.1 * previous && !fresh)) {
            solver.compute(stiffness(m, r.state, dof, free, params.fd_step, &r.colours));
            ++r.jacobians;
            if (solver.info() != Eigen::Success)
                break;
            fresh = true;
        } else {
            fresh = false;
        }
        previous = now;
        for (std::size_t k = 0; k < f.size(); ++k)
            if (dof[k] >= 0)
                rhs[dof[k]] = f[k];
        const Eigen::VectorXd dx = solver.solve(rhs); // K dx = f: the step that cancels the force
        double moved = 0, displaced = 0;
        for (std::size_t k = 0; k < f.size(); ++k)
            if (dof[k] >= 0) {
                r.state.x[k] += dx[dof[k]];
                moved = std::max(moved, std::abs(dx[dof[k]]));
                displaced = std::max(displaced, std::abs(r.state.x[k] - start.x[k]));
            }
        m.forces(r.state, f);
        r.last_step = displaced > 0 ? moved / displaced : 0;
        if (r.last_step <= params.step_tolerance) {
            r.residual = largest(f) / load;
            r.converged = true;
            ++r.iterations;
            break;
        }
    }
    return r;
}

} // namespace lobe::mss::statics
