// Baraff-Witkin backward Euler: assembly of the 3n x 3n system into a fixed sparsity pattern
// (lower triangle) and its solution by CHOLMOD or conjugate gradients.
#include "detail/implicit.h"

#include "lobe/core/errors.h"

#include <Eigen/CholmodSupport>
#include <Eigen/IterativeLinearSolvers>
#include <Eigen/Sparse>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <string>

namespace lobe::mss::detail {
namespace {

using SpMat = Eigen::SparseMatrix<double, Eigen::ColMajor, int>;

struct Vec {
    double x, y, z;
};
Vec sub(const double* p, std::size_t b, std::size_t a) { return {p[b] - p[a], p[b + 1] - p[a + 1], p[b + 2] - p[a + 2]}; }
Vec crossv(const Vec& u, const Vec& v) { return {u.y * v.z - u.z * v.y, u.z * v.x - u.x * v.z, u.x * v.y - u.y * v.x}; }

} // namespace

struct ImplicitSolver::Impl {
    const Model& model;
    SimulatorParams params;
    SpMat a;
    std::vector<int> diag_off;   // 6 per node: lower entries (r >= c) of block (i, i), r-major
    std::vector<int> spring_off; // 9 per spring: block (b, a), rows of b, columns of a
    std::vector<std::array<int, 6>> tet_spring; // the spring of each tet edge (kTetEdges order)
    Eigen::CholmodDecomposition<SpMat, Eigen::Lower> cholmod;
    Eigen::ConjugateGradient<SpMat, Eigen::Lower, Eigen::DiagonalPreconditioner<double>> cg;
    Eigen::VectorXd guess;
    bool analysed = false, factored = false;
    std::int64_t factorizations = 0;
    int since_factor = 0;

    static constexpr int kEdges[6][2] = {{0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}};

    Impl(const Model& m, const SimulatorParams& p) : model(m), params(p)
    {
        const std::size_t n = m.node_count();
        const Springs& s = m.springs();
        std::vector<Eigen::Triplet<double, int>> trip;
        trip.reserve(6 * n + 9 * s.size());
        for (std::size_t i = 0; i < n; ++i)
            for (int r = 0; r < 3; ++r)
                for (int c = 0; c <= r; ++c)
                    trip.emplace_back(int(3 * i + r), int(3 * i + c), 0.0);
        for (std::size_t k = 0; k < s.size(); ++k)
            for (int r = 0; r < 3; ++r)
                for (int c = 0; c < 3; ++c)
                    trip.emplace_back(3 * s.b[k] + r, 3 * s.a[k] + c, 0.0);
        a.resize(int(3 * n), int(3 * n));
        a.setFromTriplets(trip.begin(), trip.end());
        a.makeCompressed();
        const double* base = a.valuePtr();
        diag_off.resize(6 * n);
        for (std::size_t i = 0; i < n; ++i) {
            int q = 0;
            for (int r = 0; r < 3; ++r)
                for (int c = 0; c <= r; ++c)
                    diag_off[6 * i + q++] = int(&a.coeffRef(int(3 * i + r), int(3 * i + c)) - base);
        }
        spring_off.resize(9 * s.size());
        for (std::size_t k = 0; k < s.size(); ++k)
            for (int r = 0; r < 3; ++r)
                for (int c = 0; c < 3; ++c)
                    spring_off[9 * k + 3 * r + c] = int(&a.coeffRef(3 * s.b[k] + r, 3 * s.a[k] + c) - base);
        const auto& tets = m.mesh().tets;
        tet_spring.resize(tets.size());
        for (std::size_t t = 0; t < tets.size(); ++t)
            for (int e = 0; e < 6; ++e) {
                const auto u = std::min(tets[t][kEdges[e][0]], tets[t][kEdges[e][1]]);
                const auto v = std::max(tets[t][kEdges[e][0]], tets[t][kEdges[e][1]]);
                // Springs are sorted by (a, b): find (u, v) by binary search.
                std::size_t lo = 0, hi = s.size();
                while (lo < hi) {
                    const std::size_t mid = (lo + hi) / 2;
                    if (s.a[mid] < u || (s.a[mid] == u && s.b[mid] < v))
                        lo = mid + 1;
                    else
                        hi = mid;
                }
                tet_spring[t][e] = int(lo);
            }
        // CHOLMOD's own choice (supernodal above a fill-in threshold): simplicial LL^T took 7 s
        // per step at 9k nodes against well under a second supernodal (docs/benchmarks.md).
        cholmod.setMode(Eigen::CholmodAuto);
        cg.setTolerance(p.cg_tolerance);
        cg.setMaxIterations(p.cg_max_iterations);
    }

    // Adds the symmetric 3x3 block b (row-major) to the lower part of diagonal block i.
    void add_diag(double* val, std::size_t i, const double* b, double scale)
    {
        int q = 0;
        for (int r = 0; r < 3; ++r)
            for (int c = 0; c <= r; ++c)
                val[diag_off[6 * i + q++]] += scale * b[3 * r + c];
    }
    void add_off(double* val, std::size_t spring, const double* b, double scale)
    {
        for (int q = 0; q < 9; ++q)
            val[spring_off[9 * spring + q]] += scale * b[q];
    }

    int solve(const State& st, const std::vector<double>& f, double h, std::vector<double>& dv)
    {
        const std::size_t n = model.node_count();
        const Springs& s = model.springs();
        const auto& mass = model.masses();
        const auto& inv = model.inverse_masses();
        const double* x = st.x.data();
        const double* v = st.v.data();
        double* val = a.valuePtr();
        std::fill(val, val + a.nonZeros(), 0.0);
        Eigen::VectorXd rhs(3 * n);
        for (std::size_t i = 0; i < 3 * n; ++i)
            rhs[Eigen::Index(i)] = f[i]; // becomes f + h J v below, times h at the end

        const double alpha = model.params().mass_damping;
        for (std::size_t i = 0; i < n; ++i) {
            const double d = mass[i] * (1 + h * alpha);
            val[diag_off[6 * i + 0]] += d;
            val[diag_off[6 * i + 2]] += d;
            val[diag_off[6 * i + 5]] += d;
        }
        for (std::size_t k = 0; k < s.size(); ++k) {
            const std::size_t pa = 3 * std::size_t(s.a[k]), pb = 3 * std::size_t(s.b[k]);
            const Vec d = sub(x, pb, pa);
            const double l = std::sqrt(d.x * d.x + d.y * d.y + d.z * d.z);
            const double u[3] = {d.x / l, d.y / l, d.z / l};
            // Transverse term k (1 - l0/l) (I - u u^T) only when stretched: dropping it in
            // compression keeps the matrix positive definite (Choi and Ko 2002).
            const double kt = s.stiffness[k] * std::max(0.0, 1 - s.rest_length[k] / l);
            const double ka = s.stiffness[k], c = s.damping[k];
            double stiff[9], block[9];
            for (int r = 0; r < 3; ++r)
                for (int q = 0; q < 3; ++q) {
                    const double uu = u[r] * u[q];
                    stiff[3 * r + q] = ka * uu + kt * ((r == q ? 1.0 : 0.0) - uu);
                    block[3 * r + q] = h * c * uu + h * h * stiff[3 * r + q];
                }
            add_diag(val, s.a[k], block, 1);
            add_diag(val, s.b[k], block, 1);
            add_off(val, k, block, -1);
            // J v: the force on a grows by S (v_b - v_a).
            const double w[3] = {v[pb] - v[pa], v[pb + 1] - v[pa + 1], v[pb + 2] - v[pa + 2]};
            for (int r = 0; r < 3; ++r) {
                const double jv = h * (stiff[3 * r] * w[0] + stiff[3 * r + 1] * w[1] + stiff[3 * r + 2] * w[2]);
                rhs[Eigen::Index(pa + r)] += jv;
                rhs[Eigen::Index(pb + r)] -= jv;
            }
        }
        const auto& kv = model.volume_stiffness();
        const auto& tets = model.mesh().tets;
        for (std::size_t t = 0; t < tets.size(); ++t) {
            if (kv[t] == 0)
                continue;
            const auto& q = tets[t];
            std::size_t p[4];
            for (int i = 0; i < 4; ++i)
                p[i] = 3 * std::size_t(q[i]);
            const Vec g[4] = {crossv(sub(x, p[3], p[1]), sub(x, p[2], p[1])), crossv(sub(x, p[2], p[0]), sub(x, p[3], p[0])),
                              crossv(sub(x, p[3], p[0]), sub(x, p[1], p[0])), crossv(sub(x, p[1], p[0]), sub(x, p[2], p[0]))};
            double gv[4][3];
            for (int i = 0; i < 4; ++i) {
                gv[i][0] = g[i].x / 6;
                gv[i][1] = g[i].y / 6;
                gv[i][2] = g[i].z / 6;
            }
            const double scale = h * h * kv[t];
            double block[9];
            for (int i = 0; i < 4; ++i) {
                for (int r = 0; r < 3; ++r)
                    for (int c = 0; c < 3; ++c)
                        block[3 * r + c] = gv[i][r] * gv[i][c];
                add_diag(val, q[i], block, scale);
            }
            for (int e = 0; e < 6; ++e) {
                int i = kEdges[e][0], j = kEdges[e][1];
                if (q[i] < q[j])
                    std::swap(i, j); // the block's row node is the larger index
                for (int r = 0; r < 3; ++r)
                    for (int c = 0; c < 3; ++c)
                        block[3 * r + c] = gv[i][r] * gv[j][c];
                add_off(val, std::size_t(tet_spring[t][e]), block, scale);
            }
            // J v = -k_V g (g . v) (Gauss-Newton).
            double gdotv = 0;
            for (int i = 0; i < 4; ++i)
                gdotv += gv[i][0] * v[p[i]] + gv[i][1] * v[p[i] + 1] + gv[i][2] * v[p[i] + 2];
            for (int i = 0; i < 4; ++i)
                for (int r = 0; r < 3; ++r)
                    rhs[Eigen::Index(p[i] + r)] -= h * kv[t] * gv[i][r] * gdotv;
        }
        rhs *= h;
        // Fixed nodes: identity rows and columns, zero right-hand side.
        for (std::size_t k = 0; k < s.size(); ++k)
            if (inv[s.a[k]] == 0 || inv[s.b[k]] == 0)
                for (int q = 0; q < 9; ++q)
                    val[spring_off[9 * k + q]] = 0;
        for (std::size_t i = 0; i < n; ++i)
            if (inv[i] == 0) {
                for (int q = 0; q < 6; ++q)
                    val[diag_off[6 * i + q]] = 0;
                val[diag_off[6 * i + 0]] = val[diag_off[6 * i + 2]] = val[diag_off[6 * i + 5]] = 1;
                rhs.segment(Eigen::Index(3 * i), 3).setZero();
            }

        Eigen::VectorXd sol;
        int iterations = 0;
        if (params.solver == LinearSolver::Cholmod) {
            if (!analysed) {
                cholmod.analyzePattern(a);
                analysed = true;
            }
            // Reuse the last factorisation while it still solves the current system: iterative
            // refinement with the old factor converges when the matrix has changed little (the
            // same dt, moderate deformation); otherwise factorise again.
            bool solved = false;
            if (factored && since_factor < params.refactor_interval) {
                const SpMat full = a.selfadjointView<Eigen::Lower>();
                sol = cholmod.solve(rhs);
                const double norm_b = std::max(rhs.norm(), 1e-300);
                for (int it = 0; it < 8 && !solved; ++it) {
                    const Eigen::VectorXd r = rhs - full * sol;
                    if (r.norm() <= params.cg_tolerance * norm_b)
                        solved = true;
                    else
                        sol += cholmod.solve(r);
                }
                ++since_factor;
            }
            if (!solved) {
                cholmod.factorize(a);
                ++factorizations;
                factored = cholmod.info() == Eigen::Success;
                since_factor = 0;
                if (!factored)
                    throw core::SolverError("backward Euler: CHOLMOD could not factorise the system matrix (not "
                                            "positive definite: a tet inverted?)");
                sol = cholmod.solve(rhs);
            }
        } else {
            cg.compute(a);
            if (guess.size() != rhs.size())
                guess = Eigen::VectorXd::Zero(rhs.size());
            sol = cg.solveWithGuess(rhs, guess);
            iterations = int(cg.iterations());
            if (cg.info() != Eigen::Success)
            {
                char tol[32];
                std::snprintf(tol, sizeof tol, "%.3g", params.cg_tolerance);
                throw core::SolverError(std::string("backward Euler: conjugate gradients did not reach the tolerance ") +
                                        tol + " in " + std::to_string(iterations) + " iterations");
            }
            guess = sol;
        }
        if (!sol.allFinite())
            throw core::SolverError("backward Euler: the linear solve returned non-finite values");
        dv.assign(sol.data(), sol.data() + sol.size());
        return iterations;
    }
};

ImplicitSolver::ImplicitSolver(const Model& model, const SimulatorParams& params)
    : impl_(std::make_unique<Impl>(model, params))
{
}
ImplicitSolver::~ImplicitSolver() = default;

int ImplicitSolver::solve(const State& s, const std::vector<double>& f, double h, std::vector<double>& dv)
{
    return impl_->solve(s, f, h, dv);
}

std::int64_t ImplicitSolver::factorizations() const { return impl_->factorizations; }

} // namespace lobe::mss::detail
