#include "lobe/mesh/quality.h"

#include "lobe/core/errors.h"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <numeric>
#include <sstream>

namespace lobe::mesh {

using core::Vec3;

namespace {

constexpr double kPi = 3.14159265358979323846;
// The regular tet's dihedral angle, arccos(1/3).
const double kRegularDihedral = std::acos(1.0 / 3.0);

// Local vertex pairs of the six edges, and for edge e the two other vertices.
constexpr int kEdge[6][2] = {{0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}};
constexpr int kOpposite[6][2] = {{2, 3}, {1, 3}, {1, 2}, {0, 3}, {0, 2}, {0, 1}};

double sq(double x) { return x * x; }

double sign_of(double v) { return v > 0 ? 1.0 : (v < 0 ? -1.0 : 0.0); }

struct Ball {
    Vec3 centre;
    double radius = std::numeric_limits<double>::infinity();
};

// Circumcircle of triangle (a, b, c), centred in its plane; infinite for a degenerate triangle.
Ball circumcircle(const Vec3& a, const Vec3& b, const Vec3& c)
{
    const Vec3 ab = b - a, ac = c - a, n = cross(ab, ac);
    const double n2 = dot(n, n);
    if (!(n2 > 0))
        return {};
    const Vec3 off = (dot(ac, ac) * cross(n, ab) + dot(ab, ab) * cross(ac, n)) / (2 * n2);
    return {a + off, norm(off)};
}

// Circumsphere of the tet; infinite when it is flat.
Ball circumsphere(const std::array<Vec3, 4>& p)
{
    const Vec3 ba = p[1] - p[0], ca = p[2] - p[0], da = p[3] - p[0];
    const double den = 2 * dot(ba, cross(ca, da));
    if (den == 0)
        return {};
    const Vec3 off = (dot(ba, ba) * cross(ca, da) + dot(ca, ca) * cross(da, ba) + dot(da, da) * cross(ba, ca)) / den;
    return {p[0] + off, norm(off)};
}

// Radius of the smallest ball holding the four points: the smallest candidate (edge diametral
// ball, face circumcircle ball, circumsphere) that holds them all. The minimum enclosing ball is
// the circumball of its support set, which is one of these.
double min_containment_radius(const std::array<Vec3, 4>& p, double scale)
{
    const double tol = 1e-9 * scale;
    auto holds_all = [&](const Ball& b) {
        for (const auto& q : p)
            if (distance(q, b.centre) > b.radius + tol)
                return false;
        return true;
    };
    double best = std::numeric_limits<double>::infinity();
    for (const auto& e : kEdge) {
        const Ball b{(p[e[0]] + p[e[1]]) / 2, distance(p[e[0]], p[e[1]]) / 2};
        if (b.radius < best && holds_all(b))
            best = b.radius;
    }
    for (int i = 0; i < 4; ++i) {
        const Ball b = circumcircle(p[(i + 1) % 4], p[(i + 2) % 4], p[(i + 3) % 4]);
        if (b.radius < best && holds_all(b))
            best = b.radius;
    }
    const Ball s = circumsphere(p);
    if (s.radius < best && holds_all(s))
        best = s.radius;
    return best;
}

double triangle_area(const Vec3& a, const Vec3& b, const Vec3& c) { return norm(cross(b - a, c - a)) / 2; }

// Everything the measures need, computed once per tet.
struct Geometry {
    std::array<Vec3, 4> p;
    double l[6]{};   // edge lengths, kEdge order
    double area[4]{}; // area of the face opposite vertex i
    double volume = 0;
    bool flat = false;
};

Geometry geometry(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d)
{
    Geometry g;
    g.p = {a, b, c, d};
    for (int e = 0; e < 6; ++e)
        g.l[e] = distance(g.p[kEdge[e][0]], g.p[kEdge[e][1]]);
    for (int i = 0; i < 4; ++i)
        g.area[i] = triangle_area(g.p[(i + 1) % 4], g.p[(i + 2) % 4], g.p[(i + 3) % 4]);
    g.volume = core::signed_volume(a, b, c, d);
    const double lmax = *std::max_element(g.l, g.l + 6);
    // Relative threshold: a tet whose volume is at rounding level of its size is flat.
    g.flat = !(std::abs(g.volume) > 1e-13 * lmax * lmax * lmax);
    return g;
}

int edge_index(int i, int j)
{
    if (i > j)
        std::swap(i, j);
    for (int e = 0; e < 6; ++e)
        if (kEdge[e][0] == i && kEdge[e][1] == j)
            return e;
    return -1;
}

// Shewchuk's gradient-error factor (the parenthesis of eq 6.15 over V sum A):
// (sum_{i<j} A_i A_j l_ij^2 + 6|V| max_i sum_{j!=i} A_j l_ij) / (|V| sum A) [mm].
double gradient_factor(const Geometry& g)
{
    const double v = std::abs(g.volume);
    double s = 0;
    for (int e = 0; e < 6; ++e)
        s += g.area[kEdge[e][0]] * g.area[kEdge[e][1]] * sq(g.l[e]);
    double mx = 0;
    for (int i = 0; i < 4; ++i) {
        double t = 0;
        for (int j = 0; j < 4; ++j)
            if (j != i)
                t += g.area[j] * g.l[edge_index(i, j)];
        mx = std::max(mx, t);
    }
    const double sum_a = g.area[0] + g.area[1] + g.area[2] + g.area[3];
    return (s + 6 * v * mx) / (v * sum_a);
}

double lambda_max_exact(const Geometry& g)
{
    Eigen::Matrix3d j;
    for (int c = 0; c < 3; ++c)
        for (int r = 0; r < 3; ++r)
            j(r, c) = g.p[c + 1][r] - g.p[0][r];
    const Eigen::Matrix3d inv = j.inverse(); // rows: gradients of the barycentric coordinates 1..3
    Eigen::Matrix<double, 4, 3> grad;
    grad.row(1) = inv.row(0);
    grad.row(2) = inv.row(1);
    grad.row(3) = inv.row(2);
    grad.row(0) = -(inv.row(0) + inv.row(1) + inv.row(2));
    const Eigen::Matrix4d k = std::abs(g.volume) * grad * grad.transpose();
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix4d> es(k, Eigen::EigenvaluesOnly);
    return es.eigenvalues().maxCoeff();
}

double lambda_max_estimate(const Geometry& g)
{
    double s = 0;
    for (double a : g.area)
        s += a * a;
    return s / (18 * std::abs(g.volume));
}

// The two terms of eq 6.15 before normalisation: conditioning lambda^(3/4)/V^(1/4) and
// interpolation c_t * gradient_factor with c_t = V^(-1/3).
struct CombinedTerms {
    double conditioning = 0, interpolation = 0;
};

CombinedTerms combined_terms(const Geometry& g, bool exact)
{
    const double v = std::abs(g.volume);
    const double lam = exact ? lambda_max_exact(g) : lambda_max_estimate(g);
    return {std::pow(lam, 0.75) / std::pow(v, 0.25), gradient_factor(g) / std::cbrt(v)};
}

// Unnormalised measures, with the signs applied; combined is filled in by the caller.
struct Raw {
    std::array<double, kMeasureCount> v{};
    double radius_edge = 0, min_dihedral = 0, max_dihedral = 0, lambda = 0;
};

Raw raw_measures(const Geometry& g, double h)
{
    Raw r;
    const double lmin = *std::min_element(g.l, g.l + 6), lmax = *std::max_element(g.l, g.l + 6);
    const auto dih = dihedral_angles(g.p[0], g.p[1], g.p[2], g.p[3]);
    r.min_dihedral = *std::min_element(dih.begin(), dih.end());
    r.max_dihedral = *std::max_element(dih.begin(), dih.end());
    r.v[int(Measure::MinDihedral)] = r.min_dihedral;
    r.v[int(Measure::MaxDihedral)] = kPi - r.max_dihedral;
    if (g.flat) {
        // Volume-based measures are 0; the circumsphere of a flat tet is undefined (infinite, or
        // any sphere through a circle): report 1/B = 0 and B = infinity.
        r.radius_edge = std::numeric_limits<double>::infinity();
        return r;
    }
    const double s = sign_of(g.volume), v = std::abs(g.volume);
    const double rmc = min_containment_radius(g.p, lmax);
    const double rc = circumsphere(g.p).radius;
    r.radius_edge = rc / lmin;
    r.lambda = lambda_max_exact(g);
    double sum_a2 = 0;
    for (double a : g.area)
        sum_a2 += a * a;
    double sum_l2 = 0;
    for (double l : g.l)
        sum_l2 += l * l;
    const double gf = gradient_factor(g);
    r.v[int(Measure::InterpolationSizeShape)] = s * sq(h / rmc);
    r.v[int(Measure::Interpolation)] = s * v / (rmc * rmc * rmc);
    r.v[int(Measure::GradientSizeShape)] = s * h / gf;
    r.v[int(Measure::Gradient)] = s * std::cbrt(v) / gf;
    r.v[int(Measure::Conditioning)] = s * std::cbrt(v) / r.lambda;
    r.v[int(Measure::ConditioningSmooth)] = s * v / std::pow(sum_a2, 0.75);
    r.v[int(Measure::RadiusEdgeInverse)] = lmin / rc;
    r.v[int(Measure::Fast)] = s * std::pow(v / std::pow(sum_l2, 1.5), 3);
    return r;
}

Geometry regular_unit_tet()
{
    const double s = 1 / std::sqrt(8.0); // vertices of a cube of side 2s: edge 2 s sqrt2 = 1
    return geometry({s, s, s}, {s, -s, -s}, {-s, -s, s}, {-s, s, -s}); // positively oriented
}

struct Normalisers {
    Raw regular;
    CombinedTerms terms_estimate, terms_exact;
};

const Normalisers& normalisers()
{
    static const Normalisers n = [] {
        const Geometry g = regular_unit_tet();
        return Normalisers{raw_measures(g, 1.0), combined_terms(g, false), combined_terms(g, true)};
    }();
    return n;
}

// Eq 6.16 normalised by the regular tet's terms; g must not be flat.
double combined_value(const Geometry& g, const QualityParams& params)
{
    const Normalisers& n = normalisers();
    const CombinedTerms t = combined_terms(g, params.exact_lambda);
    const CombinedTerms& reg = params.exact_lambda ? n.terms_exact : n.terms_estimate;
    const double den =
        params.weight * t.conditioning / reg.conditioning + (1 - params.weight) * t.interpolation / reg.interpolation;
    return sign_of(g.volume) / (den * den);
}

} // namespace

const char* measure_name(Measure m)
{
    switch (m) {
    case Measure::InterpolationSizeShape: return "interpolation_size_shape";
    case Measure::Interpolation: return "interpolation";
    case Measure::GradientSizeShape: return "gradient_size_shape";
    case Measure::Gradient: return "gradient";
    case Measure::Conditioning: return "conditioning";
    case Measure::ConditioningSmooth: return "conditioning_smooth";
    case Measure::RadiusEdgeInverse: return "radius_edge_inverse";
    case Measure::MinDihedral: return "min_dihedral";
    case Measure::MaxDihedral: return "max_dihedral";
    case Measure::Combined: return "combined";
    case Measure::Fast: return "fast";
    }
    return "unknown";
}

std::array<double, 6> dihedral_angles(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d)
{
    const std::array<Vec3, 4> p{a, b, c, d};
    std::array<double, 6> out{};
    for (int e = 0; e < 6; ++e) {
        const Vec3& o = p[kEdge[e][0]];
        const Vec3 axis = normalized(p[kEdge[e][1]] - o);
        // The angle between the two other vertices seen along the edge = the interior angle.
        Vec3 u = p[kOpposite[e][0]] - o, w = p[kOpposite[e][1]] - o;
        u -= axis * dot(u, axis);
        w -= axis * dot(w, axis);
        out[e] = std::atan2(norm(cross(u, w)), dot(u, w));
    }
    return out;
}

double stiffness_lambda_max(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d)
{
    const Geometry g = geometry(a, b, c, d);
    if (g.flat)
        return std::numeric_limits<double>::infinity();
    return lambda_max_exact(g);
}

double stiffness_lambda_max_estimate(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d)
{
    const Geometry g = geometry(a, b, c, d);
    if (g.flat)
        return std::numeric_limits<double>::infinity();
    return lambda_max_estimate(g);
}

double triangle_quality(const Vec3& a, const Vec3& b, const Vec3& c)
{
    const double sum_l2 = dot(b - a, b - a) + dot(c - b, c - b) + dot(a - c, a - c);
    if (!(sum_l2 > 0))
        return 0;
    return std::pow(4 * std::sqrt(3.0) * triangle_area(a, b, c) / sum_l2, 4);
}

double fast_measure(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d)
{
    // The same raw value as raw_measures, without the other measures' work (circumsphere,
    // containment sphere, exact lambda_max): s (V / (sum l^2)^(3/2))^3, normalised like the rest.
    const double v = core::signed_volume(a, b, c, d);
    const double sum_l2 = dot(b - a, b - a) + dot(c - a, c - a) + dot(d - a, d - a) + dot(c - b, c - b) + dot(d - b, d - b) +
                          dot(d - c, d - c);
    if (!(sum_l2 > 0))
        return 0;
    const double raw = sign_of(v) * std::pow(std::abs(v) / std::pow(sum_l2, 1.5), 3);
    return raw / normalisers().regular.v[int(Measure::Fast)];
}

double combined_measure(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d, const QualityParams& params)
{
    const Geometry g = geometry(a, b, c, d);
    return g.flat ? 0.0 : combined_value(g, params);
}

TetMeasures tet_measures(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d, double reference_edge,
                         const QualityParams& params)
{
    if (!(reference_edge > 0) || !std::isfinite(reference_edge))
        throw core::InvalidInputError("tet_measures: the reference edge must be a positive length, got " +
                                      std::to_string(reference_edge));
    if (!(params.weight >= 0 && params.weight <= 1))
        throw core::InvalidInputError("tet_measures: the weight w must lie in [0, 1], got " +
                                      std::to_string(params.weight));
    const Geometry g = geometry(a, b, c, d);
    const Normalisers& n = normalisers();
    const Raw r = raw_measures(g, reference_edge);
    TetMeasures m;
    for (int i = 0; i < kMeasureCount; ++i)
        m.values[i] = n.regular.v[i] != 0 ? r.v[i] / n.regular.v[i] : 0;
    if (!g.flat)
        m.values[int(Measure::Combined)] = combined_value(g, params);
    m.volume = g.volume;
    m.radius_edge_ratio = r.radius_edge;
    m.min_dihedral_deg = r.min_dihedral * 180 / kPi;
    m.max_dihedral_deg = r.max_dihedral * 180 / kPi;
    m.lambda_max = g.flat ? std::numeric_limits<double>::infinity() : r.lambda;
    return m;
}

namespace {

void add_to_summary(MeasureSummary& s, double v, int bins)
{
    if (s.count == 0) {
        s.min = s.max = v;
        s.histogram.assign(static_cast<std::size_t>(bins), 0);
    }
    s.min = std::min(s.min, v);
    s.max = std::max(s.max, v);
    s.mean += v; // divided by count at the end
    ++s.count;
    const int bin = std::clamp(static_cast<int>(std::floor(v * bins)), 0, bins - 1);
    ++s.histogram[static_cast<std::size_t>(bin)];
    const int band = v < 0.3 ? 0 : (v < 0.5 ? 1 : (v < 0.7 ? 2 : 3));
    ++s.bands[static_cast<std::size_t>(band)];
}

void add_tet(TissueQuality& t, const TetMeasures& m, int bins)
{
    if (t.tets == 0) {
        t.min_dihedral_deg = m.min_dihedral_deg;
        t.max_dihedral_deg = m.max_dihedral_deg;
    }
    ++t.tets;
    t.volume += m.volume;
    t.min_dihedral_deg = std::min(t.min_dihedral_deg, m.min_dihedral_deg);
    t.max_dihedral_deg = std::max(t.max_dihedral_deg, m.max_dihedral_deg);
    t.max_radius_edge_ratio = std::max(t.max_radius_edge_ratio, m.radius_edge_ratio);
    for (int i = 0; i < kMeasureCount; ++i)
        add_to_summary(t.measures[static_cast<std::size_t>(i)], m.values[static_cast<std::size_t>(i)], bins);
}

void finish(TissueQuality& t)
{
    for (auto& s : t.measures)
        if (s.count > 0)
            s.mean /= static_cast<double>(s.count);
}

} // namespace

MeshQuality evaluate_quality(const core::TetMesh& mesh, const QualityParams& params)
{
    if (mesh.tets.empty())
        throw core::InvalidInputError("evaluate_quality: the mesh has no tets");
    if (const auto problem = core::mesh_problem(mesh); !problem.empty())
        throw core::InvalidInputError("evaluate_quality: the mesh " + problem);
    if (params.histogram_bins < 1 || params.histogram_bins > 10000)
        throw core::InvalidInputError("evaluate_quality: histogram_bins must be in [1, 10000], got " +
                                      std::to_string(params.histogram_bins));
    MeshQuality q;
    double h = params.reference_edge;
    if (!(h > 0)) {
        double sum = 0;
        for (const auto& t : mesh.tets)
            for (const auto& e : kEdge)
                sum += distance(mesh.vertices[t[e[0]]], mesh.vertices[t[e[1]]]);
        h = sum / (6.0 * static_cast<double>(mesh.tets.size()));
    }
    q.reference_edge = h;
    const std::size_t n = mesh.tets.size();
    for (auto& v : q.per_tet)
        v.resize(n);
    q.min_dihedral_deg.resize(n);
    q.max_dihedral_deg.resize(n);
    q.radius_edge_ratio.resize(n);
    std::map<int, TissueQuality> tissues;
    for (std::size_t t = 0; t < n; ++t) {
        const auto& tet = mesh.tets[t];
        const TetMeasures m = tet_measures(mesh.vertices[tet[0]], mesh.vertices[tet[1]], mesh.vertices[tet[2]],
                                           mesh.vertices[tet[3]], h, params);
        for (int i = 0; i < kMeasureCount; ++i)
            q.per_tet[static_cast<std::size_t>(i)][t] = m.values[static_cast<std::size_t>(i)];
        q.min_dihedral_deg[t] = m.min_dihedral_deg;
        q.max_dihedral_deg[t] = m.max_dihedral_deg;
        q.radius_edge_ratio[t] = m.radius_edge_ratio;
        add_tet(q.all, m, params.histogram_bins);
        auto& tissue = tissues[mesh.tet_labels[t]];
        tissue.label = mesh.tet_labels[t];
        add_tet(tissue, m, params.histogram_bins);
    }
    finish(q.all);
    for (auto& [label, t] : tissues) {
        finish(t);
        q.tissues.push_back(t);
    }
    const auto& comb = q.per_tet[int(Measure::Combined)];
    std::vector<std::size_t> order(n);
    std::iota(order.begin(), order.end(), std::size_t{0});
    const std::size_t k = std::min<std::size_t>(n, static_cast<std::size_t>(std::max(0, params.worst_count)));
    std::partial_sort(order.begin(), order.begin() + static_cast<std::ptrdiff_t>(k), order.end(),
                      [&](std::size_t a, std::size_t b) { return comb[a] < comb[b]; });
    for (std::size_t i = 0; i < k; ++i) {
        const std::size_t t = order[i];
        const auto& tet = mesh.tets[t];
        WorstElement w;
        w.tet = static_cast<std::int64_t>(t);
        w.label = mesh.tet_labels[t];
        w.combined = comb[t];
        w.min_dihedral_deg = q.min_dihedral_deg[t];
        w.max_dihedral_deg = q.max_dihedral_deg[t];
        w.centroid = (mesh.vertices[tet[0]] + mesh.vertices[tet[1]] + mesh.vertices[tet[2]] + mesh.vertices[tet[3]]) / 4;
        q.worst.push_back(w);
    }
    return q;
}

std::string format_quality_report(const MeshQuality& quality)
{
    std::ostringstream os;
    char buf[256];
    auto tissue_block = [&](const TissueQuality& t) {
        std::snprintf(buf, sizeof buf, "%s: %lld tets, volume %.1f mm^3, dihedral angles %.2f-%.2f deg, max B %.2f\n",
                      t.label == 0 ? "all tissues" : ("tissue " + std::to_string(t.label)).c_str(),
                      static_cast<long long>(t.tets), t.volume, t.min_dihedral_deg, t.max_dihedral_deg,
                      t.max_radius_edge_ratio);
        os << buf;
        os << "  measure                    min    mean     max   <0.3  0.3-0.5  0.5-0.7  >=0.7\n";
        for (int i = 0; i < kMeasureCount; ++i) {
            const auto& s = t.measures[static_cast<std::size_t>(i)];
            std::snprintf(buf, sizeof buf, "  %-24s %6.3f  %6.3f  %6.3f %6lld  %7lld  %7lld  %6lld\n",
                          measure_name(static_cast<Measure>(i)), s.min, s.mean, s.max,
                          static_cast<long long>(s.bands[0]), static_cast<long long>(s.bands[1]),
                          static_cast<long long>(s.bands[2]), static_cast<long long>(s.bands[3]));
            os << buf;
        }
    };
    std::snprintf(buf, sizeof buf, "Tetrahedron quality (1 = regular tet; reference edge h = %.3f mm)\n",
                  quality.reference_edge);
    os << buf;
    tissue_block(quality.all);
    for (const auto& t : quality.tissues)
        tissue_block(t);
    os << "worst elements (combined measure):\n";
    for (const auto& w : quality.worst) {
        std::snprintf(buf, sizeof buf, "  tet %lld tissue %d: combined %.4f, dihedral %.2f-%.2f deg, at (%.2f, %.2f, %.2f) mm\n",
                      static_cast<long long>(w.tet), w.label, w.combined, w.min_dihedral_deg, w.max_dihedral_deg,
                      w.centroid.x, w.centroid.y, w.centroid.z);
        os << buf;
    }
    return os.str();
}

} // namespace lobe::mesh
