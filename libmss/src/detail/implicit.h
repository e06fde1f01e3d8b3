#pragma once
// The linear solve of the Baraff-Witkin backward Euler step. Eigen and CHOLMOD stay in
// implicit.cpp.

#include "lobe/mss/model.h"
#include "lobe/mss/simulator.h"

#include <memory>
#include <vector>

namespace lobe::mss::detail {

class ImplicitSolver {
public:
    ImplicitSolver(const Model& model, const SimulatorParams& params);
    ~ImplicitSolver();

    // Solves (M + h D + h^2 S) dv = h (f + h J v) with D, S the damping and stiffness matrices
    // (S with the compressive transverse spring terms dropped and the volume terms Gauss-Newton,
    // so the matrix is positive definite) and J = -S. Fixed nodes get dv = 0.
    // f = forces at s (Model::forces). Returns the CG iterations (0 for CHOLMOD).
    int solve(const State& s, const std::vector<double>& f, double h, std::vector<double>& dv);

    std::int64_t factorizations() const;

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

} // namespace lobe::mss::detail
