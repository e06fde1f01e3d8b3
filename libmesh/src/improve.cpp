// Quality improvement on the combined measure inside a region of interest, and on the smallest
// dihedral angle over the whole mesh: flips, smoothing and vertex insertion that never touch a
// face between two tissues or on the outer boundary (but for the interface flip of a sliver).
// Why it is done this way: docs/algorithms/meshing.md ("Quality improvement", "Slivers").
#include "lobe/mesh/improve.h"

#include "lobe/core/errors.h"
#include "lobe/core/geometry.h"
#include "lobe/mesh/quality.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <limits>
#include <vector>

namespace lobe::mesh {

using core::Vec3;

double distance_to_region(const RegionOfInterest& roi, const Vec3& p)
{
    switch (roi.kind) {
    case RegionOfInterest::Kind::None:
        return 0;
    case RegionOfInterest::Kind::Box: {
        double d2 = 0;
        for (int a = 0; a < 3; ++a) {
            const double e = std::max({roi.box_lo[a] - p[a], 0.0, p[a] - roi.box_hi[a]});
            d2 += e * e;
        }
        return std::sqrt(d2);
    }
    case RegionOfInterest::Kind::Spheres: {
        double d = std::numeric_limits<double>::infinity();
        for (const auto& c : roi.centres)
            d = std::min(d, core::distance(p, c) - roi.radius);
        return std::max(d, 0.0);
    }
    }
    return 0;
}

namespace {

using Tet = std::array<std::int32_t, 4>;

// The face of tet t opposite its local vertex i, its other three vertices in order.
std::array<std::int32_t, 3> face_opposite(const Tet& t, int i)
{
    std::array<std::int32_t, 3> f{};
    for (int k = 0, n = 0; k < 4; ++k)
        if (k != i)
            f[static_cast<std::size_t>(n++)] = t[static_cast<std::size_t>(k)];
    return f;
}

// What a pass raises: the thesis's combined measure, or the smallest dihedral angle [deg].
enum class Objective { Combined, Dihedral };

// The combined measure's threshold of the goal, reported before and after.
constexpr double kGoal = 0.3;
// An interface flip moves the interface by the distance between the sliver's two diagonals
// (its thickness); it must stay below this fraction of the sliver's mean edge.
constexpr double kMaxFlipThickness = 0.3;
constexpr double kDeg = 180 / 3.14159265358979323846;

// Smallest dihedral angle [deg]; an inverted or flat tet scores -1, below any angle.
double min_dihedral_deg(const std::array<Vec3, 4>& q)
{
    if (!(core::signed_volume(q[0], q[1], q[2], q[3]) > 0))
        return -1;
    const auto a = dihedral_angles(q[0], q[1], q[2], q[3]);
    return *std::min_element(a.begin(), a.end()) * kDeg;
}
// A change must raise the worst measure of the tets it replaces by at least this much: it keeps
// the passes from cycling on rounding-level gains.
constexpr double kMinGain = 1e-6;
// Edge removal triangulates the ring of tets around an edge; rings longer than this are rare in
// Delaunay meshes (the mean is about 5) and never improve in practice.
constexpr int kMaxRing = 12;

// The mesh while it changes: tets die and are born, every vertex knows its live tets.
class Work {
  public:
    Work(const core::TetMesh& m, Objective o, double goal_, double weight, double guard)
        : pos(m.vertices), orig(m.vertices), tets(m.tets), label(m.tet_labels), objective(o), target(goal_),
          guard_deg(guard)
    {
        qp.weight = weight;
        alive.assign(tets.size(), 1);
        q.resize(tets.size());
        star.resize(pos.size());
        for (std::size_t t = 0; t < tets.size(); ++t) {
            q[t] = quality(tets[t]);
            for (auto v : tets[t])
                star[static_cast<std::size_t>(v)].push_back(static_cast<std::int32_t>(t));
        }
        pin_surface_vertices();
    }

    // The objective of the tet with corners c.
    double measure(const std::array<Vec3, 4>& c) const
    {
        return objective == Objective::Combined ? combined_measure(c[0], c[1], c[2], c[3], qp) : min_dihedral_deg(c);
    }
    std::array<Vec3, 4> corners(const Tet& t) const { return {p(t[0]), p(t[1]), p(t[2]), p(t[3])}; }
    double quality(const Tet& t) const { return measure(corners(t)); }
    // The smallest dihedral angle of tets `ts` [deg], for the guard.
    template <class C> double worst_angle(const C& ts) const
    {
        double mn = std::numeric_limits<double>::infinity();
        for (const Tet& t : ts)
            mn = std::min(mn, min_dihedral_deg(corners(t)));
        return mn;
    }
    // Whether a change whose new tets' worst angle is `after` (the old ones' `before`) keeps
    // the dihedral floor (ImproveParams::min_dihedral).
    bool guard_ok(double after, double before) const { return guard_deg <= 0 || after >= std::min(guard_deg, before); }
    const Vec3& p(std::int32_t v) const { return pos[static_cast<std::size_t>(v)]; }
    Vec3 centroid(std::int32_t t) const
    {
        const auto& q4 = tets[static_cast<std::size_t>(t)];
        return (p(q4[0]) + p(q4[1]) + p(q4[2]) + p(q4[3])) / 4;
    }

    // Live tets holding every vertex of `vs`.
    template <std::size_t N> std::vector<std::int32_t> common(const std::array<std::int32_t, N>& vs) const
    {
        std::vector<std::int32_t> out;
        for (auto t : star[static_cast<std::size_t>(vs[0])]) {
            const auto& q4 = tets[static_cast<std::size_t>(t)];
            bool all = true;
            for (std::size_t i = 1; i < N && all; ++i)
                all = std::find(q4.begin(), q4.end(), vs[i]) != q4.end();
            if (all)
                out.push_back(t);
        }
        return out;
    }

    void kill(std::int32_t t)
    {
        alive[static_cast<std::size_t>(t)] = 0;
        for (auto v : tets[static_cast<std::size_t>(t)]) {
            auto& s = star[static_cast<std::size_t>(v)];
            s.erase(std::find(s.begin(), s.end(), t));
        }
        free_slots.push_back(t);
    }

    std::int32_t add(const Tet& t, int lab, double qual)
    {
        std::int32_t id;
        if (!free_slots.empty()) {
            id = free_slots.back();
            free_slots.pop_back();
            tets[static_cast<std::size_t>(id)] = t;
            label[static_cast<std::size_t>(id)] = lab;
            q[static_cast<std::size_t>(id)] = qual;
            alive[static_cast<std::size_t>(id)] = 1;
        } else {
            id = static_cast<std::int32_t>(tets.size());
            tets.push_back(t);
            label.push_back(lab);
            q.push_back(qual);
            alive.push_back(1);
        }
        for (auto v : t)
            star[static_cast<std::size_t>(v)].push_back(id);
        return id;
    }

    core::TetMesh mesh() const
    {
        core::TetMesh m;
        m.vertices = pos;
        for (std::size_t t = 0; t < tets.size(); ++t)
            if (alive[t]) {
                m.tets.push_back(tets[t]);
                m.tet_labels.push_back(label[t]);
            }
        return m;
    }

    std::vector<Vec3> pos;
    std::vector<Vec3> orig; // the input's positions: the surfaces that surface vertices slide on
    std::vector<Tet> tets;
    std::vector<std::int32_t> label;
    std::vector<char> alive;
    std::vector<double> q;
    std::vector<std::vector<std::int32_t>> star; // live tets of each vertex
    std::vector<char> pinned;                    // on the outer boundary or on an interface
    std::vector<std::int32_t> free_slots;        // dead tets' indices, reused so that an
                                                 // unchanged mesh keeps its tet order
    QualityParams qp;
    Objective objective;
    double target = 0;    // the goal: 0.3 combined, or SliverParams::goal degrees
    double guard_deg = 0; // ImproveParams::min_dihedral for the combined objective, else 0
    bool guard_count = true;

    // The faces around v that lie on a surface (outer boundary or interface), once each, with the
    // key of their surface: the two labels (0 outside). Face (v, f[1], f[2]).
    struct SurfaceFace {
        std::int64_t key;
        std::array<std::int32_t, 3> f;
    };
    std::vector<SurfaceFace> surface_faces(std::int32_t v) const
    {
        std::vector<SurfaceFace> out;
        for (auto t : star[static_cast<std::size_t>(v)]) {
            const auto& T = tets[static_cast<std::size_t>(t)];
            const int lt = label[static_cast<std::size_t>(t)];
            for (int i = 0; i < 4; ++i) {
                if (T[static_cast<std::size_t>(i)] == v)
                    continue;
                auto f = face_opposite(T, i);
                int other = 0;
                for (auto u : common(f))
                    if (u != t)
                        other = label[static_cast<std::size_t>(u)];
                if (other == lt)
                    continue;
                std::rotate(f.begin(), std::find(f.begin(), f.end(), v), f.end());
                if (f[1] > f[2])
                    std::swap(f[1], f[2]);
                const std::int64_t key = static_cast<std::int64_t>(std::min(lt, other)) << 32 |
                                         static_cast<std::uint32_t>(std::max(lt, other));
                if (std::none_of(out.begin(), out.end(), [&](const SurfaceFace& sf) { return sf.f == f; }))
                    out.push_back({key, f});
            }
        }
        return out;
    }
    // Whether a vertex whose surface faces are `fs` may slide along its surface: all of them on one
    // surface, forming one closed fan (each neighbour in exactly two of them), so that the vertex
    // lies inside a surface patch, not on a curve where surfaces meet.
    static bool slides(const std::vector<SurfaceFace>& fs)
    {
        if (fs.size() < 3)
            return false;
        std::vector<std::int32_t> ends;
        for (const auto& f : fs) {
            if (f.key != fs[0].key)
                return false;
            ends.push_back(f.f[1]);
            ends.push_back(f.f[2]);
        }
        std::sort(ends.begin(), ends.end());
        for (std::size_t i = 0; i < ends.size(); i += 2)
            if (ends[i] != ends[i + 1] || (i + 2 < ends.size() && ends[i + 2] == ends[i]))
                return false;
        return true;
    }

    // Tets of `ids` (live, by index) as vertex quadruples.
    std::vector<Tet> tets_of(const std::vector<std::int32_t>& ids) const
    {
        std::vector<Tet> out;
        for (auto t : ids)
            out.push_back(tets[static_cast<std::size_t>(t)]);
        return out;
    }

    // How many of `qs` lie below the goal: a change may not add to them.
    template <class C> int below(const C& qs) const
    {
        if (!guard_count)
            return 0;
        return static_cast<int>(std::count_if(qs.begin(), qs.end(), [&](double x) { return x < target; }));
    }

  private:
    // A vertex is pinned when a face of its star lies on the outer boundary (one tet) or its
    // tets carry more than one label (it lies on an interface). Flips inside one tissue never
    // change either, so this is computed once.
    void pin_surface_vertices()
    {
        pinned.assign(pos.size(), 0);
        // Every face once per tet, sorted: a face seen once is on the outer boundary. (A sorted
        // vector: a map of the faces took most of the pass's time on a 240 k-tet mesh.)
        std::vector<std::array<std::int32_t, 3>> faces;
        faces.reserve(4 * tets.size());
        constexpr int kFace[4][3] = {{1, 2, 3}, {0, 2, 3}, {0, 1, 3}, {0, 1, 2}};
        for (const auto& t : tets)
            for (const auto& f : kFace) {
                std::array<std::int32_t, 3> k{t[f[0]], t[f[1]], t[f[2]]};
                std::sort(k.begin(), k.end());
                faces.push_back(k);
            }
        std::sort(faces.begin(), faces.end());
        for (std::size_t i = 0; i < faces.size();) {
            std::size_t j = i + 1;
            while (j < faces.size() && faces[j] == faces[i])
                ++j;
            if (j - i == 1)
                for (auto v : faces[i])
                    pinned[static_cast<std::size_t>(v)] = 1;
            i = j;
        }
        for (std::size_t v = 0; v < pos.size(); ++v)
            for (auto t : star[v])
                if (label[static_cast<std::size_t>(t)] != label[static_cast<std::size_t>(star[v][0])])
                    pinned[v] = 1;
    }
};

// A change found for a bad tet: the tets it replaces and those it makes.
struct Change {
    std::vector<std::int32_t> old_tets;
    std::vector<Tet> new_tets;
    std::vector<double> new_q;
    int lab = 0;
    double old_min = 0, new_min = -std::numeric_limits<double>::infinity();
    bool edge_removal = false;
    std::int32_t relabelled = -1; // the interface flip's sliver, among old_tets
};

// 2-3 flip of the face of tet t opposite its local vertex i: the two tets sharing the face
// become three around the edge between the apexes. Only inside one tissue.
bool try_flip23(const Work& w, std::int32_t t, int i, Change& best)
{
    const auto& T = w.tets[static_cast<std::size_t>(t)];
    auto f = face_opposite(T, i); // oriented below
    const auto across = w.common(f);
    if (across.size() != 2)
        return false; // outer boundary
    const std::int32_t u = across[0] == t ? across[1] : across[0];
    const int lab = w.label[static_cast<std::size_t>(t)];
    if (w.label[static_cast<std::size_t>(u)] != lab)
        return false; // an interface face stays
    const std::int32_t d = T[static_cast<std::size_t>(i)];
    std::int32_t e = -1;
    for (auto v : w.tets[static_cast<std::size_t>(u)])
        if (std::find(f.begin(), f.end(), v) == f.end())
            e = v;
    if (!w.common(std::array<std::int32_t, 2>{d, e}).empty())
        return false; // the new edge exists already (only in an invalid mesh)
    // Orient the face so that d lies on its positive side; e is then on the other.
    if (core::signed_volume(w.p(f[0]), w.p(f[1]), w.p(f[2]), w.p(d)) < 0)
        std::swap(f[0], f[1]);
    Change c;
    c.old_tets = {t, u};
    c.lab = lab;
    c.old_min = std::min(w.q[static_cast<std::size_t>(t)], w.q[static_cast<std::size_t>(u)]);
    c.new_min = std::numeric_limits<double>::infinity();
    for (int k = 0; k < 3; ++k) {
        // Around edge (e, d) with the ring f0, f1, f2 counter-clockwise seen from d.
        const Tet n{e, d, f[static_cast<std::size_t>(k)], f[static_cast<std::size_t>((k + 1) % 3)]};
        const double qn = w.quality(n);
        c.new_tets.push_back(n);
        c.new_q.push_back(qn);
        c.new_min = std::min(c.new_min, qn);
    }
    const std::array<double, 2> old_q{w.q[static_cast<std::size_t>(t)], w.q[static_cast<std::size_t>(u)]};
    if (c.new_min > c.old_min + kMinGain && c.new_min > best.new_min && w.below(c.new_q) <= w.below(old_q) &&
        (w.guard_deg <= 0 || w.guard_ok(w.worst_angle(c.new_tets), w.worst_angle(w.tets_of(c.old_tets))))) {
        best = std::move(c);
        return true;
    }
    return false;
}

// Edge removal (Shewchuk 2002): the n tets around edge (a, b) are replaced by the 2n - 4 tets
// joining a and b to the best triangulation of the ring polygon, found by Klincsek's dynamic
// programme maximising the worst tet. Only for an edge inside one tissue (closed ring, one label).
bool try_edge_removal(const Work& w, std::int32_t a, std::int32_t b, Change& best)
{
    const auto ring_tets = w.common(std::array<std::int32_t, 2>{a, b});
    const int n = static_cast<int>(ring_tets.size());
    if (n < 3 || n > kMaxRing)
        return false;
    const int lab = w.label[static_cast<std::size_t>(ring_tets[0])];
    double old_min = std::numeric_limits<double>::infinity();
    std::vector<std::array<std::int32_t, 2>> links;
    for (auto t : ring_tets) {
        if (w.label[static_cast<std::size_t>(t)] != lab)
            return false; // the edge lies on an interface
        old_min = std::min(old_min, w.q[static_cast<std::size_t>(t)]);
        std::array<std::int32_t, 2> l{};
        int k = 0;
        for (auto v : w.tets[static_cast<std::size_t>(t)])
            if (v != a && v != b)
                l[static_cast<std::size_t>(k++)] = v;
        links.push_back(l);
    }
    // Chain the link edges into a closed polygon; an open chain means the edge is on the boundary.
    std::vector<std::int32_t> ring{links[0][0], links[0][1]};
    std::vector<char> used(links.size(), 0);
    used[0] = 1;
    for (int step = 1; step < n; ++step) {
        const auto last = ring.back();
        bool found = false;
        for (std::size_t k = 0; k < links.size() && !found; ++k)
            if (!used[k] && (links[k][0] == last || links[k][1] == last)) {
                used[k] = 1;
                ring.push_back(links[k][0] == last ? links[k][1] : links[k][0]);
                found = true;
            }
        if (!found)
            return false;
    }
    if (ring.back() != ring.front())
        return false;
    ring.pop_back();
    // Counter-clockwise seen from b: then (a, b, r_i, r_i+1) is positive, like the old tets.
    if (core::signed_volume(w.p(a), w.p(b), w.p(ring[0]), w.p(ring[1])) < 0)
        std::reverse(ring.begin(), ring.end());
    // Triangle (i, k, j), i < k < j, counter-clockwise from b: tets (r_i, r_k, r_j, b) and
    // (r_i, r_j, r_k, a) are positive.
    const auto nu = static_cast<std::size_t>(n);
    auto tri_q = [&](int i, int k, int j) {
        const auto ri = ring[static_cast<std::size_t>(i)], rk = ring[static_cast<std::size_t>(k)],
                   rj = ring[static_cast<std::size_t>(j)];
        return std::min(w.quality({ri, rk, rj, b}), w.quality({ri, rj, rk, a}));
    };
    const double inf = std::numeric_limits<double>::infinity();
    std::vector<double> Q(nu * nu, inf);
    std::vector<int> K(nu * nu, -1);
    for (int len = 2; len < n; ++len)
        for (int i = 0; i + len < n; ++i) {
            const int j = i + len;
            double bestq = -inf;
            for (int k = i + 1; k < j; ++k) {
                const double v = std::min(
                    {Q[static_cast<std::size_t>(i * n + k)], Q[static_cast<std::size_t>(k * n + j)], tri_q(i, k, j)});
                if (v > bestq) {
                    bestq = v;
                    K[static_cast<std::size_t>(i * n + j)] = k;
                }
            }
            Q[static_cast<std::size_t>(i * n + j)] = bestq;
        }
    const double new_min = Q[static_cast<std::size_t>(n - 1)];
    if (!(new_min > old_min + kMinGain && new_min > best.new_min))
        return false;
    Change c;
    c.old_tets = ring_tets;
    c.lab = lab;
    c.old_min = old_min;
    c.new_min = new_min;
    c.edge_removal = true;
    std::vector<std::array<int, 2>> todo{{0, n - 1}};
    while (!todo.empty()) {
        const auto [i, j] = todo.back();
        todo.pop_back();
        if (j - i < 2)
            continue;
        const int k = K[static_cast<std::size_t>(i * n + j)];
        const auto ri = ring[static_cast<std::size_t>(i)], rk = ring[static_cast<std::size_t>(k)],
                   rj = ring[static_cast<std::size_t>(j)];
        for (const Tet& t : {Tet{ri, rk, rj, b}, Tet{ri, rj, rk, a}}) {
            c.new_tets.push_back(t);
            c.new_q.push_back(w.quality(t));
        }
        todo.push_back({i, k});
        todo.push_back({k, j});
    }
    std::vector<double> old_q;
    for (auto t : ring_tets)
        old_q.push_back(w.q[static_cast<std::size_t>(t)]);
    if (w.below(c.new_q) > w.below(old_q))
        return false;
    if (w.guard_deg > 0 && !w.guard_ok(w.worst_angle(c.new_tets), w.worst_angle(w.tets_of(ring_tets))))
        return false;
    best = std::move(c);
    return true;
}

// The distance between the lines through p0 p1 and q0 q1 (infinite when parallel).
double line_distance(const Vec3& p0, const Vec3& p1, const Vec3& q0, const Vec3& q1)
{
    const Vec3 n = cross(p1 - p0, q1 - q0);
    const double nn = norm(n);
    return nn > 0 ? std::abs(dot(q0 - p0, n)) / nn : std::numeric_limits<double>::infinity();
}

// Interface flip: bad tet t of tissue A has two faces, sharing edge (a, b), on its interface
// with one tissue B, and its other two faces, sharing (c, d), against tets of A. Given to B, t
// joins B's tets around (a, b), which edge removal then replaces: the interface's triangles
// (a, b, c), (a, b, d) become (c, d, a), (c, d, b), a 2-2 flip of the interface surface. Only
// when (c, d) lies inside A (not yet on a surface, so the surface stays a manifold) and t is
// thin across its diagonals (the interface moves by that thickness).
bool try_interface_flip(Work& w, std::int32_t t, Change& best)
{
    const auto tu = static_cast<std::size_t>(t);
    const Tet T = w.tets[tu];
    const int A = w.label[tu];
    auto across = [&](int i) -> std::int32_t {
        for (auto u : w.common(face_opposite(T, i)))
            if (u != t)
                return u;
        return -1; // outer boundary
    };
    double mean_edge = 0;
    for (int i = 0; i < 4; ++i)
        for (int j = i + 1; j < 4; ++j)
            mean_edge += core::distance(w.p(T[static_cast<std::size_t>(i)]), w.p(T[static_cast<std::size_t>(j)])) / 6;
    bool found = false;
    for (int i = 0; i < 4; ++i)
        for (int j = i + 1; j < 4; ++j) {
            int k = 0;
            while (k == i || k == j)
                ++k;
            const int l = 6 - i - j - k;
            // Faces opposite k and l hold edge (a, b) = (T[i], T[j]); those opposite i and j hold (c, d).
            const auto uk = across(k), ul = across(l), ui = across(i), uj = across(j);
            if (uk < 0 || ul < 0 || ui < 0 || uj < 0)
                continue;
            const int B = w.label[static_cast<std::size_t>(uk)];
            if (B == A || w.label[static_cast<std::size_t>(ul)] != B || w.label[static_cast<std::size_t>(ui)] != A ||
                w.label[static_cast<std::size_t>(uj)] != A)
                continue;
            const auto a = T[static_cast<std::size_t>(i)], b = T[static_cast<std::size_t>(j)];
            const auto c = T[static_cast<std::size_t>(k)], d = T[static_cast<std::size_t>(l)];
            if (line_distance(w.p(a), w.p(b), w.p(c), w.p(d)) > kMaxFlipThickness * mean_edge)
                continue;
            // (c, d) inside A: every tet around it is A's and every face around it has two tets.
            bool inside = true;
            for (auto u : w.common(std::array<std::int32_t, 2>{c, d})) {
                const auto& U = w.tets[static_cast<std::size_t>(u)];
                inside = inside && w.label[static_cast<std::size_t>(u)] == A;
                for (int m = 0; m < 4 && inside; ++m)
                    if (U[static_cast<std::size_t>(m)] != c && U[static_cast<std::size_t>(m)] != d)
                        inside = w.common(face_opposite(U, m)).size() == 2;
            }
            if (!inside)
                continue;
            Change ch;
            w.label[tu] = B;
            const bool ok = try_edge_removal(w, a, b, ch);
            w.label[tu] = A;
            if (ok && ch.new_min > best.new_min) {
                ch.relabelled = t;
                best = std::move(ch);
                found = true;
            }
        }
    return found;
}

void apply(Work& w, const Change& c)
{
    for (auto t : c.old_tets)
        w.kill(t);
    for (std::size_t k = 0; k < c.new_tets.size(); ++k)
        w.add(c.new_tets[k], c.lab, c.new_q[k]);
}

// The worst tet of v's star with v at x, and its index in the star.
double star_min(const Work& w, std::int32_t v, const Vec3& x, std::vector<double>* each = nullptr)
{
    double mn = std::numeric_limits<double>::infinity();
    const auto& s = w.star[static_cast<std::size_t>(v)];
    if (each)
        each->resize(s.size());
    for (std::size_t k = 0; k < s.size(); ++k) {
        std::array<Vec3, 4> q4;
        const auto& T = w.tets[static_cast<std::size_t>(s[k])];
        for (std::size_t i = 0; i < 4; ++i)
            q4[i] = T[i] == v ? x : w.p(T[i]);
        const double qk = w.measure(q4);
        if (each)
            (*each)[k] = qk;
        mn = std::min(mn, qk);
    }
    return mn;
}

// Gradient of one star tet's measure with respect to v's position, by central differences.
Vec3 tet_gradient(const Work& w, std::int32_t t, std::int32_t v, const Vec3& x, double h)
{
    const auto& T = w.tets[static_cast<std::size_t>(t)];
    Vec3 g;
    for (int a = 0; a < 3; ++a) {
        std::array<Vec3, 4> lo, hi;
        for (std::size_t i = 0; i < 4; ++i)
            lo[i] = hi[i] = T[i] == v ? x : w.p(T[i]);
        for (std::size_t i = 0; i < 4; ++i)
            if (T[i] == v) {
                lo[i][a] -= h;
                hi[i][a] += h;
            }
        g[a] = (w.measure(hi) - w.measure(lo)) / (2 * h);
    }
    return g;
}

// The point of smallest norm in the convex hull of `g` (Gilbert's algorithm, a few steps):
// the steepest ascent direction of the minimum of several measures (Freitag et al.'s
// non-smooth smoothing), zero when no direction raises them all.
Vec3 min_norm_in_hull(const std::vector<Vec3>& g)
{
    Vec3 x = g[0];
    for (int it = 0; it < 50; ++it) {
        std::size_t best = 0;
        for (std::size_t k = 1; k < g.size(); ++k)
            if (dot(g[k], x) < dot(g[best], x))
                best = k;
        const Vec3 d = g[best] - x;
        const double dd = dot(d, d);
        if (dd <= 0)
            break;
        const double s = std::clamp(-dot(x, d) / dd, 0.0, 1.0);
        if (s <= 0)
            break;
        x += d * s;
    }
    return x;
}

// Moves vertex v where the worst tet of its star is better: the neighbours' centroid if that is
// better, then steps along the ascent direction of the worst tets, halving each step until it
// helps. A vertex on a surface, given its surface faces `fan` (Work::slides), moves along it:
// every position is projected onto those triangles at the input's positions, so it stays on the
// surface the mesher made (the new triangles are its chords; an interface flip nearby has
// replaced some by chords of its own), and the direction onto the patch's tangent plane.
// `moved_volume` gets the volume that changed tissue. Returns whether v moved.
bool smooth_vertex(Work& w, std::int32_t v, int steps, const std::vector<Work::SurfaceFace>* fan = nullptr,
                   double* moved_volume = nullptr)
{
    const auto& s = w.star[static_cast<std::size_t>(v)];
    if (s.empty())
        return false;
    Vec3 x = w.p(v);
    const bool on_surface = fan != nullptr;
    std::vector<std::array<Vec3, 3>> patch;
    Vec3 normal;
    Vec3 centre;
    if (on_surface) {
        std::vector<std::int32_t> ring;
        const auto o = [&](std::int32_t u) { return w.orig[static_cast<std::size_t>(u)]; };
        for (const auto& sf : *fan) {
            patch.push_back({o(v), o(sf.f[1]), o(sf.f[2])});
            Vec3 n = cross(w.p(sf.f[1]) - x, w.p(sf.f[2]) - x);
            normal += dot(n, normal) < 0 ? n * -1.0 : n; // the faces' order gives no orientation
            ring.push_back(sf.f[1]);
            ring.push_back(sf.f[2]);
        }
        normal = normalized(normal);
        std::sort(ring.begin(), ring.end());
        ring.erase(std::unique(ring.begin(), ring.end()), ring.end());
        for (auto u : ring)
            centre += w.p(u);
        centre /= static_cast<double>(ring.size());
    }
    auto place = [&](const Vec3& y) {
        if (!on_surface)
            return y;
        Vec3 best = x;
        double bd = std::numeric_limits<double>::infinity();
        for (const auto& tri : patch) {
            const Vec3 c = core::closest_on_triangle(y, tri[0], tri[1], tri[2]);
            if (const double d = core::distance(c, y); d < bd) {
                bd = d;
                best = c;
            }
        }
        return best;
    };
    std::vector<double> each;
    double f = star_min(w, v, x, &each);
    const double f0 = f;
    const int below0 = w.below(each);
    double mean_edge = 0;
    int count = 0;
    Vec3 all_centre;
    for (auto t : s)
        for (auto u : w.tets[static_cast<std::size_t>(t)])
            if (u != v) {
                mean_edge += core::distance(w.p(u), x);
                all_centre += w.p(u);
                ++count;
            }
    mean_edge /= count;
    if (!on_surface)
        centre = all_centre / count;
    {
        std::vector<double> ec;
        centre = place(centre);
        if (const double fc = star_min(w, v, centre, &ec); fc > f + kMinGain && w.below(ec) <= below0) {
            x = centre;
            f = fc;
            each = std::move(ec);
        }
    }
    const double h = 1e-4 * mean_edge;
    for (int step = 0; step < steps; ++step) {
        // The active set: tets within a small band of the worst.
        std::vector<Vec3> grads;
        for (std::size_t k = 0; k < s.size(); ++k)
            if (each[k] <= f + 1e-3)
                grads.push_back(tet_gradient(w, s[k], v, x, h));
        Vec3 d = min_norm_in_hull(grads);
        if (on_surface)
            d -= normal * dot(d, normal);
        const double dn = norm(d);
        if (!(dn > 1e-12))
            break;
        const Vec3 dir = d / dn;
        bool moved = false;
        for (double alpha = 0.25 * mean_edge; alpha > 1e-4 * mean_edge; alpha /= 2) {
            const Vec3 y = place(x + dir * alpha);
            std::vector<double> e2;
            const double fy = star_min(w, v, y, &e2);
            if (fy > f + kMinGain && w.below(e2) <= below0) {
                x = y;
                f = fy;
                each = std::move(e2);
                moved = true;
                break;
            }
        }
        if (!moved)
            break;
    }
    if (!(f > f0 + kMinGain))
        return false;
    const Vec3 x0 = w.p(v);
    if (w.guard_deg > 0) {
        const double before = w.worst_angle(w.tets_of(s));
        w.pos[static_cast<std::size_t>(v)] = x;
        const double after = w.worst_angle(w.tets_of(s));
        w.pos[static_cast<std::size_t>(v)] = x0;
        if (!w.guard_ok(after, before))
            return false;
    }
    if (on_surface && moved_volume) {
        // Each tissue's volume change in the star; what one gains another (or the outside) loses.
        std::vector<std::pair<int, double>> change;
        for (auto t : s) {
            const auto& T = w.tets[static_cast<std::size_t>(t)];
            std::array<Vec3, 4> a = w.corners(T), b = a;
            for (std::size_t i = 0; i < 4; ++i)
                if (T[i] == v)
                    b[i] = x;
            const double dv = core::signed_volume(b[0], b[1], b[2], b[3]) - core::signed_volume(a[0], a[1], a[2], a[3]);
            const int lab = w.label[static_cast<std::size_t>(t)];
            auto it = std::find_if(change.begin(), change.end(), [&](const auto& c) { return c.first == lab; });
            if (it == change.end())
                change.emplace_back(lab, dv);
            else
                it->second += dv;
        }
        double sum = 0;
        for (const auto& c : change)
            sum += std::abs(c.second);
        *moved_volume += change.size() > 1 ? sum / 2 : sum;
    }
    w.pos[static_cast<std::size_t>(v)] = x;
    for (auto t : s)
        w.q[static_cast<std::size_t>(t)] = w.quality(w.tets[static_cast<std::size_t>(t)]);
    return true;
}

// Vertex insertion (Klingner and Shewchuk 2007): the bad tet and its neighbours of the same
// tissue across its faces form a cavity, which is replaced by the tets joining a new vertex to
// the cavity's boundary faces; the vertex is then moved where the worst of them is best, and the
// whole is undone unless that beats the cavity's worst. It can fix a tet whose four vertices
// lie on surfaces when no flip does (the apex of its surface faces moves off them into the new
// vertex), which smoothing cannot; the cavity's boundary keeps every surface face. It did not
// fix the phantom's last two (docs/algorithms/meshing.md, step 7).
bool try_insertion(Work& w, std::int32_t t, int steps)
{
    const auto tu = static_cast<std::size_t>(t);
    const int lab = w.label[tu];
    std::vector<std::int32_t> neighbours;
    for (int i = 0; i < 4; ++i) {
        const auto f = face_opposite(w.tets[tu], i);
        for (auto u : w.common(f))
            if (u != t && w.label[static_cast<std::size_t>(u)] == lab)
                neighbours.push_back(u);
    }
    // Every cavity of the bad tet and a non-empty subset of those neighbours (a point inside one
    // tet only splits it, no better than the tet itself); the new vertex must see every boundary
    // face of the cavity, which the smaller cavities allow more often. The best start wins.
    std::vector<std::vector<std::int32_t>> cavities;
    for (unsigned mask = 1; mask < (1u << neighbours.size()); ++mask) {
        std::vector<std::int32_t> cav{t};
        for (std::size_t k = 0; k < neighbours.size(); ++k)
            if (mask & (1u << k))
                cav.push_back(neighbours[k]);
        cavities.push_back(cav);
    }
    // And the tets of the tissue two faces away: a larger cavity lets the new vertex sit further
    // from the bad tet's surface faces.
    if (!neighbours.empty()) {
        auto cav = cavities.back();
        for (auto u : neighbours)
            for (int i = 0; i < 4; ++i) {
                const auto& U = w.tets[static_cast<std::size_t>(u)];
                const auto f = face_opposite(U, i);
                for (auto z : w.common(f))
                    if (w.label[static_cast<std::size_t>(z)] == lab &&
                        std::find(cav.begin(), cav.end(), z) == cav.end())
                        cav.push_back(z);
            }
        cavities.push_back(cav);
    }
    std::vector<std::int32_t> cavity;
    std::vector<Tet> shells;
    Vec3 x;
    // The start must give positive tets (the dihedral objective scores an inverted tet -1).
    double best = w.objective == Objective::Combined ? 0 : -0.5;
    for (const auto& cav : cavities) {
        auto in_cav = [&](std::int32_t u) { return std::find(cav.begin(), cav.end(), u) != cav.end(); };
        // The cavity's boundary faces, as the tet with the vertex opposite the face replaced by
        // the new one (-1): it keeps its orientation when the new vertex lies inside the cavity.
        std::vector<Tet> sh;
        for (auto c : cav)
            for (int i = 0; i < 4; ++i) {
                const auto& T = w.tets[static_cast<std::size_t>(c)];
                const auto f = face_opposite(T, i);
                bool inner = false;
                for (auto u : w.common(f))
                    inner = inner || (u != c && in_cav(u));
                if (!inner) {
                    Tet n = T;
                    n[static_cast<std::size_t>(i)] = -1;
                    sh.push_back(n);
                }
            }
        // Every vertex of the cavity must stay in a tet (none may lie inside the cavity).
        bool ok = true;
        for (auto c : cav)
            for (auto v : w.tets[static_cast<std::size_t>(c)]) {
                bool kept = false;
                for (const auto& n : sh)
                    kept = kept || std::find(n.begin(), n.end(), v) != n.end();
                ok = ok && kept;
            }
        if (!ok)
            continue;
        auto worst_at = [&](const Vec3& y) {
            double mn = std::numeric_limits<double>::infinity();
            for (const auto& n : sh) {
                std::array<Vec3, 4> q4;
                for (std::size_t i = 0; i < 4; ++i)
                    q4[i] = n[i] < 0 ? y : w.p(n[i]);
                mn = std::min(mn, w.measure(q4));
            }
            return mn;
        };
        // Starts: the centroid of each cavity tet, of the bad tet with each neighbour's centroid,
        // and of the cavity's vertices.
        std::vector<Vec3> starts;
        Vec3 vc;
        for (auto c : cav) {
            starts.push_back(w.centroid(c));
            starts.push_back((w.centroid(t) + w.centroid(c)) / 2);
            vc += w.centroid(c);
        }
        starts.push_back(vc / static_cast<double>(cav.size()));
        for (const auto& y : starts)
            if (const double q = worst_at(y); q > best) {
                best = q;
                x = y;
                cavity = cav;
                shells = sh;
            }
    }
    if (cavity.empty())
        return false;
    double old_min = std::numeric_limits<double>::infinity();
    for (auto c : cavity)
        old_min = std::min(old_min, w.q[static_cast<std::size_t>(c)]);
    const auto v = static_cast<std::int32_t>(w.pos.size());
    w.pos.push_back(x);
    w.star.emplace_back();
    w.pinned.push_back(0);
    std::vector<std::pair<Tet, double>> old;
    for (auto c : cavity) {
        old.emplace_back(w.tets[static_cast<std::size_t>(c)], w.q[static_cast<std::size_t>(c)]);
        w.kill(c);
    }
    for (auto n : shells) {
        std::replace(n.begin(), n.end(), -1, v);
        w.add(n, lab, w.quality(n));
    }
    smooth_vertex(w, v, 2 * steps);
    double new_min = std::numeric_limits<double>::infinity();
    for (auto u : w.star[static_cast<std::size_t>(v)])
        new_min = std::min(new_min, w.q[static_cast<std::size_t>(u)]);
    std::vector<double> new_q, old_q;
    for (auto u : w.star[static_cast<std::size_t>(v)])
        new_q.push_back(w.q[static_cast<std::size_t>(u)]);
    std::vector<Tet> old_tets;
    for (const auto& o : old) {
        old_q.push_back(o.second);
        old_tets.push_back(o.first);
    }
    if (new_min > old_min + kMinGain && w.below(new_q) <= w.below(old_q) &&
        (w.guard_deg <= 0 ||
         w.guard_ok(w.worst_angle(w.tets_of(w.star[static_cast<std::size_t>(v)])), w.worst_angle(old_tets))))
        return true;
    const auto made = w.star[static_cast<std::size_t>(v)];
    for (auto u : made)
        w.kill(u);
    for (const auto& [T, q] : old)
        w.add(T, lab, q);
    w.pos.pop_back();
    w.star.pop_back();
    w.pinned.pop_back();
    return false;
}

// What a pass works on and how, from ImproveParams or SliverParams.
struct PassOptions {
    double target = 0; // tets below this are worked on
    double margin = 0; // ... when their centroid lies within this of the region
    int max_rounds = 0;
    bool raise_worst_last = true;
    int smoothing_steps = 0;
    bool interface_flips = false;
    bool surface_moves = false;
};

// Rounds of flips, smoothing and insertion on the bad tets of `w` near `roi`; fills `st`.
void run_pass(Work& w, const RegionOfInterest& roi, const PassOptions& o, ImproveStats& st)
{
    st.ran = true;
    st.goal = w.target;
    // Surface vertices that slid already (at most once per pass). Only input vertices lie on
    // surfaces, so the input's count sizes it.
    std::vector<char> slid(w.pos.size(), 0);
    auto in_region = [&](std::int32_t t, double margin) { return distance_to_region(roi, w.centroid(t)) <= margin; };
    auto tally = [&](std::int64_t& count, std::int64_t& below, double& worst) {
        count = below = 0;
        worst = std::numeric_limits<double>::infinity();
        for (std::size_t t = 0; t < w.tets.size(); ++t)
            if (w.alive[t] && in_region(static_cast<std::int32_t>(t), 0)) {
                ++count;
                below += w.q[t] < w.target;
                worst = std::min(worst, w.q[t]);
            }
        if (count == 0)
            worst = 0;
    };
    tally(st.tets_in_region_before, st.below_before, st.worst_before);
    // The tets to work on, worst first.
    auto bad_tets = [&] {
        std::vector<std::pair<double, std::int32_t>> bad;
        for (std::size_t t = 0; t < w.tets.size(); ++t)
            if (w.alive[t] && w.q[t] < o.target && in_region(static_cast<std::int32_t>(t), o.margin))
                bad.emplace_back(w.q[t], static_cast<std::int32_t>(t));
        std::sort(bad.begin(), bad.end());
        return bad;
    };
    // Rounds that may not add tets below the goal, then (raise_worst_last) rounds that only raise
    // the worst; a stage ends after max_rounds or a round without change.
    const int stages = o.raise_worst_last ? 2 : 1;
    for (int round = 0; round < stages * o.max_rounds; ++round) {
        if (round == o.max_rounds)
            w.guard_count = false;
        std::int64_t changes = 0;
        // Flips: for each bad tet still alive, the best of the 2-3 flips of its faces, the
        // removals of its edges and its interface flips.
        for (const auto& [qt, t] : bad_tets()) {
            const auto tu = static_cast<std::size_t>(t);
            if (!w.alive[tu] || w.q[tu] != qt)
                continue; // replaced, or a vertex moved, since the list was made
            Change best;
            for (int i = 0; i < 4; ++i)
                try_flip23(w, t, i, best);
            const auto T = w.tets[tu];
            for (int i = 0; i < 4; ++i)
                for (int j = i + 1; j < 4; ++j)
                    try_edge_removal(w, T[static_cast<std::size_t>(i)], T[static_cast<std::size_t>(j)], best);
            // The interface flip changes the tissues' volumes: only when nothing inside one helps.
            if (o.interface_flips && best.old_tets.empty())
                try_interface_flip(w, t, best);
            if (best.old_tets.empty())
                continue;
            if (best.relabelled >= 0) {
                ++st.interface_flips;
                st.interface_flip_volume += std::abs(core::signed_volume(w.p(T[0]), w.p(T[1]), w.p(T[2]), w.p(T[3])));
            } else {
                ++(best.edge_removal ? st.edge_removals : st.flips23);
            }
            apply(w, best);
            ++changes;
        }
        // Smoothing: each free vertex of a bad tet, once per round.
        std::vector<char> tried(w.pos.size(), 0);
        for (const auto& [qt, t] : bad_tets())
            for (auto v : w.tets[static_cast<std::size_t>(t)]) {
                const auto vu = static_cast<std::size_t>(v);
                if (tried[vu])
                    continue;
                tried[vu] = 1;
                // A surface vertex slides at most once per pass: enough to free the slivers it
                // pins, and the pass cannot wander along the surface.
                std::vector<Work::SurfaceFace> fan;
                if (w.pinned[vu]) {
                    if (!o.surface_moves || slid[vu])
                        continue;
                    fan = w.surface_faces(v);
                    if (!Work::slides(fan))
                        continue;
                }
                if (smooth_vertex(w, v, o.smoothing_steps, w.pinned[vu] ? &fan : nullptr, &st.surface_move_volume)) {
                    if (w.pinned[vu]) {
                        slid[vu] = 1;
                        ++st.surface_moves;
                    } else {
                        ++st.vertex_moves;
                    }
                    ++changes;
                }
            }
        // Vertex insertion for the tets still bad after flips and smoothing.
        for (const auto& [qt, t] : bad_tets())
            if (w.alive[static_cast<std::size_t>(t)] && w.q[static_cast<std::size_t>(t)] == qt &&
                try_insertion(w, t, o.smoothing_steps)) {
                ++st.vertices_inserted;
                ++changes;
            }
        st.rounds = round + 1;
        if (changes == 0) {
            if (!w.guard_count || stages == 1)
                break;
            round = o.max_rounds - 1; // the next round starts the second stage
        }
    }
    tally(st.tets_in_region_after, st.below_after, st.worst_after);
    // What is left, and why: a tet with its four vertices on surfaces cannot be smoothed, one
    // with a face on a surface keeps that face whatever the flips.
    for (std::size_t t = 0; t < w.tets.size(); ++t) {
        if (!w.alive[t] || !(w.q[t] < w.target) || !in_region(static_cast<std::int32_t>(t), 0))
            continue;
        const auto& T = w.tets[t];
        st.below_after_pinned +=
            std::all_of(T.begin(), T.end(), [&](auto v) { return w.pinned[static_cast<std::size_t>(v)] != 0; });
        for (int i = 0; i < 4; ++i) {
            const auto f = face_opposite(T, i);
            const auto across = w.common(f);
            if (across.size() == 1 || w.label[across[0]] != w.label[across[1]]) {
                ++st.below_after_surface_face;
                break;
            }
        }
    }
}

} // namespace

ImproveResult improve_quality(const core::TetMesh& mesh, const RegionOfInterest& roi, const ImproveParams& params)
{
    if (const auto problem = core::mesh_problem(mesh); !problem.empty())
        throw core::InvalidInputError("improve_quality: the mesh " + problem);
    if (!(params.margin >= 0) || params.max_rounds < 0 || params.smoothing_steps < 0 ||
        !(params.weight >= 0 && params.weight <= 1) || !std::isfinite(params.target) ||
        !(params.min_dihedral >= 0 && params.min_dihedral < 70))
        throw core::InvalidInputError("improve_quality: margin must be >= 0 mm, rounds and steps >= 0, weight in "
                                      "[0, 1], min_dihedral in [0, 70) degrees");
    const auto t0 = std::chrono::steady_clock::now();
    Work w(mesh, Objective::Combined, kGoal, params.weight, params.min_dihedral);
    ImproveResult r;
    run_pass(w, roi,
             {params.target, params.margin, params.max_rounds, params.raise_worst_last, params.smoothing_steps,
              params.interface_flips, params.surface_moves},
             r.stats);
    r.mesh = w.mesh();
    r.stats.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return r;
}

ImproveResult remove_slivers(const core::TetMesh& mesh, const SliverParams& params)
{
    if (const auto problem = core::mesh_problem(mesh); !problem.empty())
        throw core::InvalidInputError("remove_slivers: the mesh " + problem);
    // A regular tet's dihedral angle is 70.5 degrees: no tet has a smallest angle above it.
    if (!(params.goal >= 0 && params.goal < 70) || !(params.target >= params.goal && params.target < 70) ||
        params.max_rounds < 0 || params.smoothing_steps < 0)
        throw core::InvalidInputError(
            "remove_slivers: goal and target must satisfy 0 <= goal <= target < 70 degrees, rounds and steps >= 0");
    const auto t0 = std::chrono::steady_clock::now();
    Work w(mesh, Objective::Dihedral, params.goal, 0.6, 0);
    ImproveResult r;
    run_pass(w, RegionOfInterest{},
             {params.target, 0, params.max_rounds, true, params.smoothing_steps, params.interface_flips,
              params.surface_moves},
             r.stats);
    r.mesh = w.mesh();
    r.stats.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return r;
}

} // namespace lobe::mesh
