// The mass-spring model: masses, springs, volume terms, forces and energies
// (docs/algorithms/mass_spring.md).
#include "lobe/mss/model.h"

#include "detail/force_kernels.h"
#include "detail/tet_tables.h"
#include "lobe/core/errors.h"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <limits>
#include <tuple>

#include <omp.h>

namespace lobe::mss {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kMmToM = 1e-3;

bool positive_finite(double v) { return std::isfinite(v) && v > 0; }

// Below this many springs (about 15 k nodes) the spring pass stays serial whatever
// ModelParams::threads says: the fork and joins cost more than a second thread saves.
constexpr std::size_t kThreadedSprings = 100000;

using detail::kTetEdges;
using detail::kTetFaces;

} // namespace

const char* stiffness_name(Stiffness s)
{
    switch (s) {
    case Stiffness::Constant: return "constant";
    case Stiffness::InverseLength: return "inverse-length";
    case Stiffness::VanGelder: return "van-gelder";
    case Stiffness::Havp: return "havp";
    }
    return "?";
}

Stiffness parse_stiffness(const std::string& name)
{
    for (Stiffness s : {Stiffness::Constant, Stiffness::InverseLength, Stiffness::VanGelder, Stiffness::Havp})
        if (name == stiffness_name(s))
            return s;
    throw core::InvalidInputError("unknown stiffness law '" + name + "' (constant, inverse-length, van-gelder, havp)");
}

bool simd_spring_kernel_available() { return detail::cpu_has_simd_kernel(); }

const char* formulation_name(Formulation f)
{
    switch (f) {
    case Formulation::MassSpring: return "mass-spring";
    case Formulation::LinearFem: return "linear-fem";
    case Formulation::CorotationalFem: return "corotational-fem";
    }
    return "?";
}

Formulation parse_formulation(const std::string& name)
{
    for (Formulation f : {Formulation::MassSpring, Formulation::LinearFem, Formulation::CorotationalFem})
        if (name == formulation_name(f))
            return f;
    throw core::InvalidInputError("unknown formulation '" + name + "' (mass-spring, linear-fem, corotational-fem)");
}

std::vector<TissueMaterial> default_tissues()
{
    const double e = 11000;
    return {{1, e, 1060}, {2, 5 * e, 1060}, {3, 5 * e, 1060}, {4, 10 * e, 1060}};
}

std::vector<core::Vec3> State::positions_mm() const
{
    std::vector<core::Vec3> p(node_count());
    for (std::size_t i = 0; i < p.size(); ++i)
        p[i] = position_mm(i);
    return p;
}

Model::Model(const core::TetMesh& mesh, const ModelParams& params) : mesh_(mesh), params_(params)
{
    if (const std::string problem = core::mesh_problem(mesh_); !problem.empty())
        throw core::InvalidInputError("mass-spring model: the tet mesh " + problem);
    if (mesh_.tets.empty())
        throw core::InvalidInputError("mass-spring model: the tet mesh has no tets");
    for (const auto& t : params_.tissues)
        if (!positive_finite(t.youngs_modulus) || !positive_finite(t.density))
            throw core::InvalidInputError("mass-spring model: tissue " + std::to_string(t.label) +
                                          " needs a positive Young's modulus and density");
    if (!(params_.havp_c > 0) || !(params_.volume_coefficient >= 0) || !positive_finite(params_.reference_length_mm) ||
        !(params_.damping_ratio >= 0) || !(params_.mass_damping >= 0) || !std::isfinite(params_.havp_c) ||
        !std::isfinite(params_.volume_coefficient) || !std::isfinite(params_.damping_ratio) ||
        !std::isfinite(params_.mass_damping) || !(params_.poisson_ratio > -1 && params_.poisson_ratio < 0.5))
        throw core::InvalidInputError("mass-spring model: havp_c and reference_length must be positive, "
                                      "volume_coefficient, damping_ratio and mass_damping non-negative and finite, "
                                      "poisson_ratio in (-1, 0.5)");
    for (int c = 0; c < 3; ++c)
        if (!std::isfinite(params_.gravity[c]))
            throw core::InvalidInputError("mass-spring model: gravity is not finite");
    build();
}

void Model::build()
{
    const std::size_t n = mesh_.vertices.size(), nt = mesh_.tets.size();
    rest_.resize(3 * n);
    for (std::size_t i = 0; i < n; ++i)
        for (int c = 0; c < 3; ++c)
            rest_[3 * i + c] = mesh_.vertices[i][c] * kMmToM;
    fixed_.assign(n, 0);
    tet_e_.assign(nt, 0);
    tet_v0_.assign(nt, 0);
    tet_kv_.assign(nt, 0);
    tet_density_.assign(nt, 0);
    tet_dm_inv_.assign(params_.formulation == Formulation::MassSpring ? 0 : 9 * nt, 0.0);
    mass_.assign(n, 0);
    for (std::size_t t = 0; t < nt; ++t) {
        set_tet(t);
        for (auto i : mesh_.tets[t])
            mass_[i] += tet_density_[t] * tet_v0_[t] / 4;
    }
    for (std::size_t i = 0; i < n; ++i)
        if (mass_[i] <= 0)
            throw core::InvalidInputError("mass-spring model: vertex " + std::to_string(i) + " belongs to no tet");
    inv_mass_.resize(n);
    for (std::size_t i = 0; i < n; ++i)
        inv_mass_[i] = 1 / mass_[i];

    // Edges with the tets around them: sorting (a, b) pairs gives the springs in node order.
    struct EdgeRef {
        std::int32_t a, b;
        std::int32_t tet;
    };
    std::vector<EdgeRef> refs;
    refs.reserve(6 * nt);
    for (std::size_t t = 0; t < nt; ++t) {
        const auto& q = mesh_.tets[t];
        for (const auto& e : kTetEdges) {
            const auto a = q[e[0]], b = q[e[1]];
            refs.push_back({std::min(a, b), std::max(a, b), static_cast<std::int32_t>(t)});
        }
    }
    std::sort(refs.begin(), refs.end(), [](const EdgeRef& x, const EdgeRef& y) { return std::tie(x.a, x.b) < std::tie(y.a, y.b); });
    springs_ = {};
    spring_sum_e_.clear();
    spring_sum_ev_.clear();
    spring_count_.clear();
    for (std::size_t r = 0; r < refs.size();) {
        std::size_t e = r;
        double sum_e = 0, sum_ev = 0;
        int count = 0;
        for (; e < refs.size() && refs[e].a == refs[r].a && refs[e].b == refs[r].b; ++e) {
            sum_e += tet_e_[refs[e].tet];
            sum_ev += tet_e_[refs[e].tet] * tet_v0_[refs[e].tet];
            ++count;
        }
        const auto a = refs[r].a, b = refs[r].b;
        double l2 = 0;
        for (int c = 0; c < 3; ++c)
            l2 += (rest_[3 * b + c] - rest_[3 * a + c]) * (rest_[3 * b + c] - rest_[3 * a + c]);
        springs_.a.push_back(a);
        springs_.b.push_back(b);
        springs_.rest_length.push_back(std::sqrt(l2));
        springs_.stiffness.push_back(0);
        springs_.damping.push_back(0);
        spring_sum_e_.push_back(sum_e);
        spring_sum_ev_.push_back(sum_ev);
        spring_count_.push_back(count);
        set_spring(springs_.size() - 1);
        r = e;
    }
    fem_k_.assign(params_.formulation == Formulation::MassSpring ? 0 : springs_.size(), 0.0);
    // push_back leaves up to twice the capacity: about 200 bytes per node on a liver mesh.
    for (auto* v : {&springs_.rest_length, &springs_.stiffness, &springs_.damping, &spring_sum_e_, &spring_sum_ev_})
        v->shrink_to_fit();
    springs_.a.shrink_to_fit();
    springs_.b.shrink_to_fit();
    spring_count_.shrink_to_fit();

    // Boundary faces: faces met once. Sorted vertex triples identify a face.
    struct FaceRef {
        std::array<std::int32_t, 3> key;
        std::array<std::int32_t, 3> face;
        std::int32_t tet;
    };
    std::vector<FaceRef> faces;
    faces.reserve(4 * nt);
    for (std::size_t t = 0; t < nt; ++t)
        for (const auto& f : kTetFaces) {
            const auto& q = mesh_.tets[t];
            FaceRef ref{{q[f[0]], q[f[1]], q[f[2]]}, {q[f[0]], q[f[1]], q[f[2]]}, static_cast<std::int32_t>(t)};
            std::sort(ref.key.begin(), ref.key.end());
            faces.push_back(ref);
        }
    std::sort(faces.begin(), faces.end(), [](const FaceRef& x, const FaceRef& y) { return x.key < y.key; });
    surface_faces_.clear();
    surface_face_tets_.clear();
    for (std::size_t r = 0; r < faces.size();) {
        std::size_t e = r;
        while (e < faces.size() && faces[e].key == faces[r].key)
            ++e;
        if (e - r == 1) {
            surface_faces_.push_back(faces[r].face);
            surface_face_tets_.push_back(faces[r].tet);
        }
        r = e;
    }
    surface_nodes_stale_ = true;
    bounds_stale_ = true;
}

void Model::set_tet(std::size_t t)
{
    const auto label = mesh_.tet_labels[t];
    const TissueMaterial* mat = nullptr;
    for (const auto& m : params_.tissues)
        if (m.label == label)
            mat = &m;
    if (!mat)
        throw core::InvalidInputError("mass-spring model: tet " + std::to_string(t) + " has tissue label " +
                                      std::to_string(label) + ", which has no material");
    const double v = core::signed_volume(mesh_, t) * kMmToM * kMmToM * kMmToM;
    tet_e_[t] = mat->youngs_modulus;
    tet_density_[t] = mat->density;
    tet_v0_[t] = v;
    tet_kv_[t] = params_.formulation == Formulation::MassSpring && params_.stiffness == Stiffness::Havp &&
                         params_.volume_coefficient > 0
                     ? params_.volume_coefficient * tet_e_[t] * v / (v * v)
                     : 0;
    // FEM: the inverse rest edge matrix; the springs stay for damping and the time step estimate
    // (Van Gelder k, the stiffness of the same element to within a factor ~1), with no elastic
    // force of their own (fem_k_).
    if (params_.formulation != Formulation::MassSpring) {
        const auto& q = mesh_.tets[t];
        Eigen::Matrix3d dm;
        for (int c = 0; c < 3; ++c)
            for (int r = 0; r < 3; ++r)
                dm(r, c) = rest_[3 * std::size_t(q[std::size_t(c) + 1]) + std::size_t(r)] - rest_[3 * std::size_t(q[0]) + std::size_t(r)];
        const Eigen::Matrix3d inv = dm.inverse();
        for (int r = 0; r < 3; ++r)
            for (int c = 0; c < 3; ++c)
                tet_dm_inv_[9 * t + 3 * std::size_t(r) + std::size_t(c)] = inv(r, c);
    }
}

void Model::set_spring(std::size_t k)
{
    const double l = springs_.rest_length[k];
    const double sum_e = spring_sum_e_[k], sum_ev = spring_sum_ev_[k];
    const int count = spring_count_[k];
    const double lref = params_.reference_length_mm * kMmToM;
    double stiff = 0;
    switch (params_.formulation == Formulation::MassSpring ? params_.stiffness : Stiffness::VanGelder) {
    case Stiffness::Constant: stiff = sum_e / count * lref; break;
    case Stiffness::InverseLength: stiff = sum_e / count * lref * lref / l; break;
    case Stiffness::VanGelder: stiff = sum_ev / (l * l); break;
    case Stiffness::Havp: stiff = params_.havp_c * sum_e * l; break;
    }
    const double ma = mass_[std::size_t(springs_.a[k])], mb = mass_[std::size_t(springs_.b[k])];
    const double mu = ma * mb / (ma + mb);
    springs_.stiffness[k] = stiff;
    springs_.damping[k] = 2 * params_.damping_ratio * std::sqrt(mu * stiff);
}

void Model::update_bounds() const
{
    const std::size_t n = mass_.size();
    dt_critical_ = std::numeric_limits<double>::infinity();
    min_edge_ = std::numeric_limits<double>::infinity();
    std::vector<double> row(3 * n, 0.0);
    double ratio = std::numeric_limits<double>::infinity(); // min m / k: one square root at the end
    for (std::size_t s = 0; s < springs_.size(); ++s) {
        const auto a = std::size_t(springs_.a[s]), b = std::size_t(springs_.b[s]);
        const double k = springs_.stiffness[s];
        ratio = std::min(ratio, std::min(mass_[a], mass_[b]) / k);
        min_edge_ = std::min(min_edge_, springs_.rest_length[s]);
        double d[3], sum = 0;
        for (std::size_t c = 0; c < 3; ++c) {
            d[c] = (rest_[3 * b + c] - rest_[3 * a + c]) / springs_.rest_length[s];
            sum += std::abs(d[c]);
        }
        for (std::size_t c = 0; c < 3; ++c) {
            // |k d d^T| row c, once in the diagonal block and once in the off-diagonal one.
            row[3 * a + c] += 2 * k * std::abs(d[c]) * sum;
            row[3 * b + c] += 2 * k * std::abs(d[c]) * sum;
        }
    }
    dt_critical_ = kPi * std::sqrt(ratio);
    for (std::size_t t = 0; t < mesh_.tets.size(); ++t) {
        if (tet_kv_[t] == 0)
            continue;
        const auto& q = mesh_.tets[t];
        core::Vec3 x[4];
        for (std::size_t i = 0; i < 4; ++i)
            x[i] = {rest_[3 * std::size_t(q[i])], rest_[3 * std::size_t(q[i]) + 1], rest_[3 * std::size_t(q[i]) + 2]};
        const core::Vec3 g[4] = {cross(x[3] - x[1], x[2] - x[1]) / 6, cross(x[2] - x[0], x[3] - x[0]) / 6,
                                 cross(x[3] - x[0], x[1] - x[0]) / 6, cross(x[1] - x[0], x[2] - x[0]) / 6};
        double all = 0;
        for (const auto& gi : g)
            all += std::abs(gi.x) + std::abs(gi.y) + std::abs(gi.z);
        for (std::size_t i = 0; i < 4; ++i)
            for (int c = 0; c < 3; ++c)
                row[3 * std::size_t(q[i]) + std::size_t(c)] += tet_kv_[t] * std::abs(g[i][c]) * all;
    }
    double lambda = 0;
    for (std::size_t i = 0; i < 3 * n; ++i)
        lambda = std::max(lambda, row[i] / mass_[i / 3]);
    dt_gershgorin_ = 2 / std::sqrt(lambda);
    bounds_stale_ = false;
    gershgorin_stale_ = false;
}

double Model::critical_time_step() const
{
    if (bounds_stale_)
        update_bounds();
    return dt_critical_;
}
double Model::gershgorin_time_step() const
{
    if (bounds_stale_ || gershgorin_stale_)
        update_bounds();
    return dt_gershgorin_;
}
double Model::min_edge_length() const
{
    if (bounds_stale_)
        update_bounds();
    return min_edge_;
}

const std::vector<std::int32_t>& Model::surface_nodes() const
{
    if (surface_nodes_stale_) {
        std::vector<char> on(mass_.size(), 0);
        for (const auto& f : surface_faces_)
            for (auto v : f)
                on[std::size_t(v)] = 1;
        surface_nodes_.clear();
        for (std::size_t i = 0; i < on.size(); ++i)
            if (on[i])
                surface_nodes_.push_back(static_cast<std::int32_t>(i));
        surface_nodes_stale_ = false;
    }
    return surface_nodes_;
}

double Model::total_mass() const
{
    double m = 0;
    for (double v : mass_)
        m += v;
    return m;
}

double Model::rest_volume() const
{
    double v = 0;
    for (double t : tet_v0_)
        v += t;
    return v;
}

void Model::set_fixed(std::size_t i, bool fixed)
{
    if (i >= mass_.size())
        throw core::InvalidInputError("mass-spring model: node " + std::to_string(i) + " does not exist");
    fixed_[i] = fixed ? 1 : 0;
    inv_mass_[i] = fixed ? 0 : 1 / mass_[i];
}

std::size_t Model::fix_box(const core::Vec3& lo, const core::Vec3& hi)
{
    std::size_t count = 0;
    for (std::size_t i = 0; i < mesh_.vertices.size(); ++i) {
        const auto& p = mesh_.vertices[i];
        if (p.x >= lo.x && p.x <= hi.x && p.y >= lo.y && p.y <= hi.y && p.z >= lo.z && p.z <= hi.z) {
            inv_mass_[i] = 0;
            fixed_[i] = 1;
            ++count;
        }
    }
    return count;
}

State Model::rest_state() const
{
    State s;
    s.x = rest_;
    s.v.assign(rest_.size(), 0.0);
    return s;
}

void Model::forces(const State& s, std::vector<double>& f, Energy* energy) const
{
    const std::size_t n = mass_.size();
    f.resize(3 * n);
    const double* x = s.x.data();
    const double* v = s.v.data();
    double* F = f.data();
    double e_springs = 0;

    // The springs in their stored order (sorted by first node when built, so positions
    // stream; a flat list lets edits append and remove springs), on positions and velocities
    // packed per node (detail/force_kernels.h): the packing costs a pass over the nodes and
    // spares the spring pass most of its scattered loads.
    const std::size_t ns = springs_.size();
    const detail::SpringArrays arrays{springs_.a.data(),
                                      springs_.b.data(),
                                      springs_.rest_length.data(),
                                      params_.formulation == Formulation::MassSpring ? springs_.stiffness.data()
                                                                                     : fem_k_.data(),
                                      springs_.damping.data(),
                                      ns};
    double* p = detail::aligned64(packed_, 8 * n);
    double* fp = detail::aligned64(packed_f_, 4 * n);
    // Packing starts each node's force sum with gravity and mass damping and takes the kinetic
    // and gravitational energies on the way.
    detail::NodeArrays nodes;
    nodes.x = x;
    nodes.v = v;
    nodes.mass = mass_.data();
    nodes.rest = rest_.data();
    nodes.gravity[0] = params_.gravity.x;
    nodes.gravity[1] = params_.gravity.y;
    nodes.gravity[2] = params_.gravity.z;
    nodes.mass_damping = params_.mass_damping;
    nodes.count = n;
    auto pack = [&](std::size_t i0, std::size_t i1, double& e_gravity, double& e_kinetic) {
        const detail::NodeEnergies e = detail::pack_nodes(nodes, i0, i1, p, fp, params_.simd);
        e_gravity += e.gravity;
        e_kinetic += e.kinetic;
    };
    auto unpack = [&](std::size_t i0, std::size_t i1) { detail::unpack_forces(fp, i0, i1, F, params_.simd); };
    // HAVP's volume terms (tet_kv_ is zero for the other laws and for the FEM, which would pay
    // the pass for nothing).
    const std::size_t nt = params_.formulation == Formulation::MassSpring && params_.stiffness == Stiffness::Havp &&
                                   params_.volume_coefficient > 0
                               ? mesh_.tets.size()
                               : 0;
    const auto volume = [&](std::size_t t0, std::size_t t1, std::int32_t lo, std::int32_t hi, detail::Spill* spill) {
        return detail::volume_forces(mesh_.tets.data(), tet_v0_.data(), tet_kv_.data(), t0, t1, p, fp, lo, hi, spill,
                                     params_.simd);
    };
    double e_gravity = 0, e_kinetic = 0, e_vol_sum = 0;
    const int threads = ns < kThreadedSprings ? 1 : std::max(1, params_.threads);
    if (threads == 1) {
        pack(0, n, e_gravity, e_kinetic);
        e_springs = detail::spring_forces(arrays, 0, ns, p, fp, 0, std::int32_t(n), nullptr, params_.simd);
        e_vol_sum = volume(0, nt, 0, std::int32_t(n), nullptr);
        unpack(0, n);
    } else {
        // Thread t takes springs [ns t / T, ns (t + 1) / T) and owns the nodes [bound[t],
        // bound[t + 1]): the first node of its first spring on (springs are sorted by first node
        // when built, so nearly every write is its own; edits append springs out of order, which
        // costs more hand-overs, never a wrong sum). Each node's sum is its owner's springs in
        // spring order, then the hand-overs in thread order: the same whatever the scheduling.
        std::vector<std::int32_t> bound(std::size_t(threads) + 1, 0);
        bound[std::size_t(threads)] = std::int32_t(n);
        for (int t = 1; t < threads; ++t)
            bound[std::size_t(t)] =
                std::max(bound[std::size_t(t) - 1], arrays.a[ns * std::size_t(t) / std::size_t(threads)]);
        spill_.resize(std::size_t(threads));
        const auto shares = std::size_t(threads);
        double e_sum = 0;
#pragma omp parallel num_threads(threads) reduction(+ : e_sum, e_gravity, e_kinetic, e_vol_sum)
        {
            // The runtime may give fewer threads than asked (OMP_THREAD_LIMIT, nesting): each one
            // then takes several shares, so every node and spring is still done once.
            const auto first = std::size_t(omp_get_thread_num()), stride = std::size_t(omp_get_num_threads());
            for (std::size_t t = first; t < shares; t += stride)
                pack(std::size_t(bound[t]), std::size_t(bound[t + 1]), e_gravity, e_kinetic);
#pragma omp barrier
            for (std::size_t t = first; t < shares; t += stride) {
                spill_[t].clear();
                e_sum += detail::spring_forces(arrays, ns * t / shares, ns * (t + 1) / shares, p, fp, bound[t],
                                               bound[t + 1], &spill_[t], params_.simd);
                // The tets split the same way: lmesh sorts them by lowest node, so most of their
                // writes fall on the thread's own nodes too.
                e_vol_sum += volume(nt * t / shares, nt * (t + 1) / shares, bound[t], bound[t + 1], &spill_[t]);
            }
#pragma omp barrier
            for (std::size_t t = first; t < shares; t += stride) {
                for (const auto& spill : spill_)
                    for (const auto& [node, g] : spill)
                        if (node >= bound[t] && node < bound[t + 1])
                            for (std::size_t c = 0; c < 3; ++c)
                                fp[4 * std::size_t(node) + c] += g[c];
                unpack(std::size_t(bound[t]), std::size_t(bound[t + 1]));
            }
        }
        e_springs = e_sum;
    }
    e_springs *= 0.5;

    double e_volume = 0.5 * e_vol_sum;

    if (params_.formulation != Formulation::MassSpring) {
        const double nu = params_.poisson_ratio;
        const bool corotational = params_.formulation == Formulation::CorotationalFem;
        for (std::size_t t = 0; t < mesh_.tets.size(); ++t) {
            const auto& q = mesh_.tets[t];
            const double e = tet_e_[t], vol = tet_v0_[t];
            const double lambda = e * nu / ((1 + nu) * (1 - 2 * nu)), mu = e / (2 * (1 + nu));
            Eigen::Matrix3d ds, dminv;
            for (int c = 0; c < 3; ++c)
                for (int r = 0; r < 3; ++r) {
                    ds(r, c) = x[3 * q[c + 1] + r] - x[3 * q[0] + r];
                    dminv(c, r) = tet_dm_inv_[9 * t + 3 * c + r];
                }
            const Eigen::Matrix3d grad = ds * dminv; // deformation gradient F
            Eigen::Matrix3d rot = Eigen::Matrix3d::Identity();
            if (corotational) {
                const Eigen::JacobiSVD<Eigen::Matrix3d> svd(grad, Eigen::ComputeFullU | Eigen::ComputeFullV);
                Eigen::Matrix3d u = svd.matrixU();
                rot = u * svd.matrixV().transpose();
                if (rot.determinant() < 0) { // an inverted element: the nearest rotation, not a reflection
                    u.col(2) *= -1;
                    rot = u * svd.matrixV().transpose();
                }
            }
            const Eigen::Matrix3d s_mat = rot.transpose() * grad;
            const Eigen::Matrix3d eps = 0.5 * (s_mat + s_mat.transpose()) - Eigen::Matrix3d::Identity();
            const double tr = eps.trace();
            const Eigen::Matrix3d stress = lambda * tr * Eigen::Matrix3d::Identity() + 2 * mu * eps;
            const Eigen::Matrix3d h = -vol * rot * stress * dminv.transpose();
            for (int j = 0; j < 3; ++j)
                for (int r = 0; r < 3; ++r) {
                    F[3 * q[j + 1] + r] += h(r, j);
                    F[3 * q[0] + r] -= h(r, j);
                }
            e_volume += vol * (mu * eps.squaredNorm() + 0.5 * lambda * tr * tr);
        }
    }

    if (energy) {
        energy->kinetic = e_kinetic;
        energy->springs = e_springs;
        energy->volume = e_volume;
        energy->gravity = e_gravity;
    }
}

Energy Model::energy(const State& s) const
{
    Energy e;
    std::vector<double> f;
    forces(s, f, &e);
    return e;
}

} // namespace lobe::mss
