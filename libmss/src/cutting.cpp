// Progressive cutting (docs/algorithms/instruments.md, "Cutting").
#include "detail/cutting.h"

#include "detail/tet_tables.h"
#include "lobe/core/geometry.h"
#include "lobe/mss/topology.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <unordered_map>
#include <unordered_set>

namespace lobe::mss::detail {
namespace {

struct Box {
    core::Vec3 lo{std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity(),
                  std::numeric_limits<double>::infinity()};
    core::Vec3 hi{-std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity(),
                  -std::numeric_limits<double>::infinity()};
    void add(const core::Vec3& p)
    {
        for (int c = 0; c < 3; ++c) {
            lo[c] = std::min(lo[c], p[c]);
            hi[c] = std::max(hi[c], p[c]);
        }
    }
    Box grown(double m) const { return {lo - core::Vec3{m, m, m}, hi + core::Vec3{m, m, m}}; }
    bool holds(const core::Vec3& p) const
    {
        return p.x >= lo.x && p.x <= hi.x && p.y >= lo.y && p.y <= hi.y && p.z >= lo.z && p.z <= hi.z;
    }
    bool meets(const Box& o) const
    {
        return lo.x <= o.hi.x && o.lo.x <= hi.x && lo.y <= o.hi.y && o.lo.y <= hi.y && lo.z <= o.hi.z && o.lo.z <= hi.z;
    }
};

// Where a point lies against the swept surface: signed distance to the plane of the nearest
// swept triangle (positive on its normal's side) and the distance from its projection on that
// plane to the triangle (0 when the point is over the triangle).
struct Side {
    double d = 0;
    double beyond = std::numeric_limits<double>::infinity();
    double dist = std::numeric_limits<double>::infinity();
};

Side locate(const core::Vec3& p, const std::vector<const std::array<core::Vec3, 3>*>& tris)
{
    Side best;
    for (const auto* t : tris) {
        const auto& [a, b, c] = *t;
        const core::Vec3 q = core::closest_on_triangle(p, a, b, c);
        const double dist = norm(p - q);
        if (dist >= best.dist)
            continue;
        const core::Vec3 n = normalized(cross(b - a, c - a));
        const double d = dot(p - a, n);
        const core::Vec3 proj = p - n * d;
        best = {d, norm(proj - core::closest_on_triangle(proj, a, b, c)), dist};
    }
    return best;
}

bool contains(const std::array<std::int32_t, 4>& q, std::int32_t v) { return q[0] == v || q[1] == v || q[2] == v || q[3] == v; }

// Signed distance of v to face g in the rest shape when v lies over the face there (within a
// tenth of it) and within an edge of it: how deep the cut itself left v behind the face; 0 for a
// pair that was not neighbours at the cut.
double rest_depth(const Model& model, std::int32_t v, const std::array<std::int32_t, 3>& g)
{
    const auto& r = model.mesh().vertices;
    const core::Vec3 a = r[std::size_t(g[0])], b = r[std::size_t(g[1])], c = r[std::size_t(g[2])], p = r[std::size_t(v)];
    const core::Vec3 nn = cross(b - a, c - a);
    const double area2 = norm(nn);
    if (!(area2 > 0))
        return 0;
    const core::Vec3 n = nn / area2;
    const double d = dot(p - a, n);
    const double edge = std::max({norm(b - a), norm(c - b), norm(a - c)});
    if (std::abs(d) > edge)
        return 0;
    const core::Vec3 q = p - n * d;
    const double wa = dot(cross(b - q, c - q), n) / area2, wb = dot(cross(c - q, a - q), n) / area2;
    const double wc = 1 - wa - wb;
    return wa >= -0.1 && wb >= -0.1 && wc >= -0.1 ? d : 0;
}

} // namespace

CutReport Cutting::cut(Model& model, State& st, BladeState& blade, double time)
{
    CutReport report;
    const auto [a1, b1] = blade_position(blade.params, time);
    if (!blade.started) {
        blade.started = true;
        blade.last = {a1, b1};
        return report;
    }
    const auto [a0, b0] = blade.last;
    blade.last = {a1, b1};
    model.enable_editing();
    if (max_edge_mm_ == 0)
        for (double l : model.springs().rest_length)
            max_edge_mm_ = std::max(max_edge_mm_, l * 1e3); // edits only ever shorten edges
    on_cut_.resize(model.node_count(), 0);
    auto& on = blade.on; // this blade's surface: another cut's vertices are placed by geometry
    on.resize(model.node_count(), 0);

    // The quad the edge swept, as two triangles; their normals agree for a planar quad.
    std::vector<std::array<core::Vec3, 3>> fresh;
    for (const auto& tri : {std::array<core::Vec3, 3>{a0, b0, b1}, std::array<core::Vec3, 3>{a0, b1, a1}})
        if (norm(cross(tri[1] - tri[0], tri[2] - tri[0])) > 1e-9)
            fresh.push_back(tri);
    if (fresh.empty())
        return report;
    Box sweep;
    for (const auto& tri : fresh)
        for (const auto& p : tri)
            sweep.add(p);
    blade.swept.insert(blade.swept.end(), fresh.begin(), fresh.end());
    const double margin = max_edge_mm_;
    const Box region = sweep.grown(margin);
    // Swept triangles near the region: the new ones and earlier ones the front left close by.
    std::vector<const std::array<core::Vec3, 3>*> near;
    for (const auto& tri : blade.swept) {
        Box b;
        for (const auto& p : tri)
            b.add(p);
        if (b.grown(margin).meets(region))
            near.push_back(&tri);
    }

    std::vector<std::int32_t> nodes;
    for (std::size_t i = 0; i < model.node_count(); ++i)
        if (region.holds(st.position_mm(i)))
            nodes.push_back(std::int32_t(i));
    if (nodes.empty())
        return report;

    // Sign of each vertex against the swept surface (0: on a cut already).
    std::unordered_map<std::int32_t, Side> where;
    auto side_of = [&](std::int32_t v) -> const Side& {
        auto it = where.find(v);
        if (it == where.end())
            it = where.emplace(v, locate(st.position_mm(std::size_t(v)), near)).first;
        return it->second;
    };
    auto sign = [&](std::int32_t v) {
        if (on[std::size_t(v)])
            return 0;
        const double d = side_of(v).d;
        return d > 0 ? 1 : (d < 0 ? -1 : 0);
    };
    std::unordered_set<std::uint64_t> edge_set;
    for (auto v : nodes)
        for (auto t : model.vertex_tets(v)) {
            const auto& q = model.mesh().tets[std::size_t(t)];
            for (const auto& e : kTetEdges)
                edge_set.insert(edge_key(q[std::size_t(e[0])], q[std::size_t(e[1])]));
        }
    std::vector<std::uint64_t> candidate(edge_set.begin(), edge_set.end());
    std::sort(candidate.begin(), candidate.end()); // the same cut on every run

    // Crossings inside the swept surface; near an end (snap) or making a short edge (d_min) the
    // crossing moves onto the end vertex instead.
    struct Crossing {
        std::int32_t a, b;
        double s;
    };
    std::vector<Crossing> crossings;
    const double snap = blade.params.snap;
    for (auto key : candidate) {
        const auto a = edge_first(key), b = edge_second(key);
        if (sign(a) * sign(b) >= 0)
            continue;
        const double da = side_of(a).d, db = side_of(b).d;
        const double s = da / (da - db);
        const core::Vec3 pa = st.position_mm(std::size_t(a)), pb = st.position_mm(std::size_t(b));
        const core::Vec3 p = pa * (1 - s) + pb * s;
        const Side at = locate(p, near);
        const double len = norm(pb - pa);
        if (at.beyond > 1e-3 * len || std::abs(at.d) > snap * len)
            continue; // past the blade's front (or off a kink): a later sweep decides
        crossings.push_back({a, b, s});
    }
    const auto& rest = model.mesh().vertices;
    for (const auto& c : crossings) {
        bool zero_a = c.s < snap, zero_b = c.s > 1 - snap;
        if (!zero_a && !zero_b) {
            // d_min: the new vertex's edges (to both ends and around the ring) in the rest shape.
            const core::Vec3 pr = rest[std::size_t(c.a)] * (1 - c.s) + rest[std::size_t(c.b)] * c.s;
            double shortest = std::min(c.s, 1 - c.s) * norm(rest[std::size_t(c.b)] - rest[std::size_t(c.a)]);
            for (auto t : tets_around_edge(model, c.a, c.b))
                for (auto w : model.mesh().tets[std::size_t(t)])
                    if (w != c.a && w != c.b)
                        shortest = std::min(shortest, norm(rest[std::size_t(w)] - pr));
            if (shortest < blade.d_min_mm)
                (c.s < 0.5 ? zero_a : zero_b) = true;
        }
        if (zero_a || zero_b) {
            const auto v = zero_a ? c.a : c.b;
            if (!on[std::size_t(v)]) {
                on[std::size_t(v)] = 1;
                on_cut_[std::size_t(v)] = 1;
                ++report.snapped;
            }
        }
    }
    for (const auto& c : crossings) {
        if (on[std::size_t(c.a)] || on[std::size_t(c.b)])
            continue;
        const auto m = split_edge(model, st, c.a, c.b, c.s);
        on_cut_.resize(model.node_count(), 0);
        on.resize(model.node_count(), 0);
        on_cut_[std::size_t(m)] = 1;
        on[std::size_t(m)] = 1;
        nodes.push_back(m);
        ++report.splits;
    }

    // Side of a tet: +1 or -1 if its off-cut vertices all lie on that side, 0 if it straddles the
    // cut (the blade's front has not passed through it yet). A tet whose four vertices are all on
    // the cut (snapping can flatten the cut around one) goes to the side its vertices lie on on
    // average, so that it cannot bridge the two sides.
    auto tet_side = [&](const std::array<std::int32_t, 4>& q) {
        int plus = 0, minus = 0;
        for (auto v : q) {
            const int s = sign(v);
            plus += s > 0;
            minus += s < 0;
        }
        if (plus == 0 && minus == 0) {
            double d = 0;
            for (auto v : q)
                d += side_of(v).d;
            return d > 0 ? 1 : (d < 0 ? -1 : 0);
        }
        return plus > 0 && minus == 0 ? 1 : (minus > 0 && plus == 0 ? -1 : 0);
    };
    // Faces on the cut between a plus and a minus tet, over the swept surface: cut.
    std::vector<std::uint64_t> found;
    for (auto v : nodes) {
        if (!on[std::size_t(v)])
            continue;
        for (auto t : model.vertex_tets(v)) {
            const auto& q = model.mesh().tets[std::size_t(t)];
            const int s = tet_side(q);
            if (s <= 0)
                continue; // each cut face once: from its plus tet
            for (const auto& f : kTetFaces) {
                const std::array<std::int32_t, 3> g{q[std::size_t(f[0])], q[std::size_t(f[1])], q[std::size_t(f[2])]};
                if (!on[std::size_t(g[0])] || !on[std::size_t(g[1])] || !on[std::size_t(g[2])])
                    continue;
                std::int32_t other = -1;
                for (auto u : model.vertex_tets(g[0]))
                    if (u != t && contains(model.mesh().tets[std::size_t(u)], g[1]) && contains(model.mesh().tets[std::size_t(u)], g[2]))
                        other = u;
                if (other < 0 || tet_side(model.mesh().tets[std::size_t(other)]) != -1)
                    continue;
                const core::Vec3 p0 = st.position_mm(std::size_t(g[0])), p1 = st.position_mm(std::size_t(g[1])),
                                 p2 = st.position_mm(std::size_t(g[2]));
                const Side at = locate((p0 + p1 + p2) / 3, near);
                const double len = std::max({norm(p1 - p0), norm(p2 - p1), norm(p0 - p2)});
                if (at.beyond > 1e-3 * len || std::abs(at.d) > snap * len)
                    continue; // ahead of the blade
                found.push_back(face_id(g[0], g[1], g[2]));
            }
        }
    }
    std::sort(found.begin(), found.end());
    found.erase(std::unique(found.begin(), found.end()), found.end());
    std::vector<std::uint64_t> merged;
    std::set_union(blade.cut_faces.begin(), blade.cut_faces.end(), found.begin(), found.end(), std::back_inserter(merged));
    report.faces = int(merged.size() - blade.cut_faces.size());
    blade.cut_faces.swap(merged);

    // Separate the tissue at every vertex on the cut whose tets the cut now divides: the
    // vertices of the cut faces, and those in the region on this cut, whose stars the front may
    // only now have finished dividing (after their faces' other vertices were separated).
    std::vector<std::int32_t> verts;
    for (auto key : blade.cut_faces)
        for (auto v : {std::int32_t(key >> 42), std::int32_t((key >> 21) & 0x1fffff), std::int32_t(key & 0x1fffff)})
            verts.push_back(v);
    for (auto v : nodes)
        if (on[std::size_t(v)])
            verts.push_back(v);
    std::sort(verts.begin(), verts.end());
    verts.erase(std::unique(verts.begin(), verts.end()), verts.end());
    for (auto v : verts) {
        const auto copies = separate_vertex(model, st, v, blade.cut_faces);
        if (copies.empty())
            continue;
        on_cut_.resize(model.node_count(), 0);
        on.resize(model.node_count(), 0);
        for (auto c : copies) {
            on_cut_[std::size_t(c)] = 1;
            on[std::size_t(c)] = 1;
            ++report.separated;
        }
    }
    // Cut faces that are no longer shared by two tets (separated) need no more tracking.
    std::vector<std::uint64_t> still;
    for (auto key : blade.cut_faces) {
        const auto v0 = std::int32_t(key >> 42), v1 = std::int32_t((key >> 21) & 0x1fffff), v2 = std::int32_t(key & 0x1fffff);
        int n = 0;
        if (std::size_t(v0) < model.node_count())
            for (auto u : model.vertex_tets(v0))
                n += contains(model.mesh().tets[std::size_t(u)], v1) && contains(model.mesh().tets[std::size_t(u)], v2);
        if (n == 2)
            still.push_back(key);
    }
    blade.cut_faces.swap(still);
    return report;
}

void Cutting::refresh_lips(const Model& model)
{
    lips_.clear();
    lip_vertices_.clear();
    on_cut_.resize(model.node_count(), 0);
    for (const auto& f : model.surface_faces())
        if (on_cut_[std::size_t(f[0])] && on_cut_[std::size_t(f[1])] && on_cut_[std::size_t(f[2])]) {
            lips_.push_back(f);
            lip_vertices_.insert(lip_vertices_.end(), f.begin(), f.end());
        }
    std::sort(lip_vertices_.begin(), lip_vertices_.end());
    lip_vertices_.erase(std::unique(lip_vertices_.begin(), lip_vertices_.end()), lip_vertices_.end());
    lip_slots_.resize(lips_.size());
    for (std::size_t f = 0; f < lips_.size(); ++f)
        for (std::size_t j = 0; j < 3; ++j)
            lip_slots_[f][j] = std::int32_t(std::lower_bound(lip_vertices_.begin(), lip_vertices_.end(), lips_[f][j]) -
                                            lip_vertices_.begin());
    // Each lip vertex's neighbourhood (the vertices of its tets), and its lip faces.
    ring_start_.assign(1, 0);
    ring_.clear();
    for (auto v : lip_vertices_) {
        const std::size_t first = ring_.size();
        for (auto t : model.vertex_tets(v))
            for (auto w : model.mesh().tets[std::size_t(t)])
                ring_.push_back(w);
        std::sort(ring_.begin() + std::ptrdiff_t(first), ring_.end());
        ring_.erase(std::unique(ring_.begin() + std::ptrdiff_t(first), ring_.end()), ring_.end());
        ring_start_.push_back(ring_.size());
    }
}

void Cutting::refresh_candidates(const State& st)
{
    candidates_.clear();
    if (lips_.empty())
        return;
    // Lip faces in a hash grid of cells one longest edge wide, by centroid (positions in mm).
    const double cell = std::max(max_edge_mm_, 1e-3);
    auto key = [&](const core::Vec3& p) {
        return std::array<long, 3>{long(std::floor(p.x / cell)), long(std::floor(p.y / cell)), long(std::floor(p.z / cell))};
    };
    struct Hash {
        std::size_t operator()(const std::array<long, 3>& k) const
        {
            return (std::size_t(k[0]) * 73856093u) ^ (std::size_t(k[1]) * 19349663u) ^ (std::size_t(k[2]) * 83492791u);
        }
    };
    std::unordered_map<std::array<long, 3>, std::vector<std::int32_t>, Hash> grid;
    grid.reserve(lips_.size());
    std::vector<core::Vec3> centre(lips_.size()), fnormal(lips_.size());
    std::vector<double> reach2(lips_.size());
    const std::vector<core::Vec3> normal = lip_normals(st);
    for (std::size_t f = 0; f < lips_.size(); ++f) {
        const auto& g = lips_[f];
        const core::Vec3 a = st.position_mm(std::size_t(g[0])), b = st.position_mm(std::size_t(g[1])),
                         c = st.position_mm(std::size_t(g[2]));
        centre[f] = (a + b + c) / 3;
        const core::Vec3 nn = cross(b - a, c - a);
        fnormal[f] = normalized(nn);
        // A vertex can cross the face only over it and at most half an edge deep: within the
        // face's radius plus half its longest edge, plus 1 mm for what the lips may move before
        // the next refresh (a few ms at tissue speeds of mm/s to cm/s).
        const double r = std::max({norm(a - centre[f]), norm(b - centre[f]), norm(c - centre[f])}) +
                         0.5 * std::max({norm(b - a), norm(c - b), norm(a - c)}) + 1.0;
        reach2[f] = r * r;
        grid[key(centre[f])].push_back(std::int32_t(f));
    }
    // Within the face's reach, facing the vertex's lip within 80 degrees (the per-step test asks
    // 60), not of its own neighbourhood.
    for (std::size_t i = 0; i < lip_vertices_.size(); ++i) {
        const auto v = lip_vertices_[i];
        const core::Vec3 p = st.position_mm(std::size_t(v));
        const core::Vec3 nv = normalized(normal[i]);
        const auto rb = ring_.begin() + std::ptrdiff_t(ring_start_[i]), re = ring_.begin() + std::ptrdiff_t(ring_start_[i + 1]);
        const auto k = key(p);
        for (long dx = -2; dx <= 2; ++dx)
            for (long dy = -2; dy <= 2; ++dy)
                for (long dz = -2; dz <= 2; ++dz) {
                    const auto it = grid.find({k[0] + dx, k[1] + dy, k[2] + dz});
                    if (it == grid.end())
                        continue;
                    for (auto f : it->second) {
                        const core::Vec3 pc = p - centre[std::size_t(f)];
                        if (dot(pc, pc) > reach2[std::size_t(f)] || dot(fnormal[std::size_t(f)], nv) > -0.17)
                            continue;
                        const auto& g = lips_[std::size_t(f)];
                        if (std::binary_search(rb, re, g[0]) || std::binary_search(rb, re, g[1]) || std::binary_search(rb, re, g[2]))
                            continue;
                        candidates_.emplace_back(std::int32_t(i), f);
                    }
                }
    }
}

std::vector<core::Vec3> Cutting::lip_normals(const State& st) const
{
    std::vector<core::Vec3> normal(lip_vertices_.size(), core::Vec3{0, 0, 0});
    for (std::size_t f = 0; f < lips_.size(); ++f) {
        const auto& g = lips_[f];
        const core::Vec3 a = st.position_mm(std::size_t(g[0])), b = st.position_mm(std::size_t(g[1])),
                         c = st.position_mm(std::size_t(g[2]));
        const core::Vec3 nn = cross(b - a, c - a);
        for (auto slot : lip_slots_[f])
            normal[std::size_t(slot)] += nn;
    }
    return normal;
}

int Cutting::keep_apart(const Model& model, State& st, State* before)
{
    if (candidates_.empty())
        return 0;
    const std::vector<core::Vec3> normal = lip_normals(st); // the lips' directions now
    const auto& inv = model.inverse_masses();
    int count = 0;
    for (const auto& [slot, f] : candidates_) {
        const auto v = lip_vertices_[std::size_t(slot)];
        const auto& g = lips_[std::size_t(f)];
        const core::Vec3 a = st.position_mm(std::size_t(g[0])), b = st.position_mm(std::size_t(g[1])),
                         c = st.position_mm(std::size_t(g[2]));
        const core::Vec3 nn = cross(b - a, c - a);
        const double area2 = norm(nn);
        if (!(area2 > 0))
            continue;
        const core::Vec3 n = nn / area2;
        // Only a face that faces v's own lip can be crossed by it: lips of one cut face each
        // other, while two lips of one piece meeting at a corner (two cuts) do not.
        if (dot(n, normal[std::size_t(slot)]) > -0.5 * norm(normal[std::size_t(slot)]))
            continue;
        const core::Vec3 p = st.position_mm(std::size_t(v));
        const double d = dot(p - a, n);
        if (d >= 0)
            continue; // in front
        const double edge = std::max({norm(b - a), norm(c - b), norm(a - c)});
        // Snapping makes a cut surface zigzag by up to snap x the edge, so a vertex of one lip may
        // lie behind a face of the other where the cut was made: that depth, from the rest shape,
        // is allowed; only going deeper is a crossing.
        const double allowed = std::min(0.0, rest_depth(model, v, g));
        if (d >= allowed || d < allowed - 0.5 * edge)
            continue; // not deeper than the cut left it, or too deep to be a lip crossing
        // Barycentric coordinates of the projection: over the face only.
        const core::Vec3 q = p - n * d;
        const double wa = dot(cross(b - q, c - q), n) / area2, wb = dot(cross(c - q, a - q), n) / area2;
        const double wc = 1 - wa - wb;
        if (wa < 0 || wb < 0 || wc < 0)
            continue;
        const double w[3] = {wa, wb, wc};
        const double iv = inv[std::size_t(v)];
        double denom = iv;
        for (int j = 0; j < 3; ++j)
            denom += w[j] * w[j] * inv[std::size_t(g[std::size_t(j)])];
        if (!(denom > 0))
            continue;
        // Back to the allowed depth, shared in inverse proportion to the masses.
        const double lambda = (allowed - d) * 1e-3 / denom;
        double vrel = 0;
        for (std::size_t c3 = 0; c3 < 3; ++c3) {
            double vf = 0;
            for (int j = 0; j < 3; ++j)
                vf += w[j] * st.v[3 * std::size_t(g[std::size_t(j)]) + c3];
            vrel += (st.v[3 * std::size_t(v) + c3] - vf) * n[int(c3)];
        }
        const double mu = vrel < 0 ? -vrel / denom : 0; // inelastic: stop the approach
        if (before && count == 0) {
            before->x = st.x;
            before->v = st.v;
            before->time = st.time;
        }
        for (std::size_t c3 = 0; c3 < 3; ++c3) {
            st.x[3 * std::size_t(v) + c3] += lambda * iv * n[int(c3)];
            st.v[3 * std::size_t(v) + c3] += mu * iv * n[int(c3)];
            for (int j = 0; j < 3; ++j) {
                const auto u = std::size_t(g[std::size_t(j)]);
                st.x[3 * u + c3] -= lambda * w[j] * inv[u] * n[int(c3)];
                st.v[3 * u + c3] -= mu * w[j] * inv[u] * n[int(c3)];
            }
        }
        ++count;
    }
    return count;
}

void Cutting::renumber(const std::vector<std::pair<std::int32_t, std::int32_t>>& moved, std::vector<BladeState>& blades)
{
    for (const auto& [from, to] : moved) {
        if (std::size_t(from) < on_cut_.size()) {
            on_cut_[std::size_t(to)] = on_cut_[std::size_t(from)];
            on_cut_.resize(std::size_t(from)); // the last vertex moved: the list ends before it
        }
        for (auto& b : blades) {
            if (std::size_t(from) < b.on.size()) {
                b.on[std::size_t(to)] = b.on[std::size_t(from)];
                b.on.resize(std::size_t(from));
            }
        }
        for (auto& b : blades)
            for (auto& key : b.cut_faces) {
                std::int32_t v[3] = {std::int32_t(key >> 42), std::int32_t((key >> 21) & 0x1fffff), std::int32_t(key & 0x1fffff)};
                for (auto& x : v)
                    if (x == from)
                        x = to;
                key = face_id(v[0], v[1], v[2]);
            }
    }
    for (auto& b : blades)
        std::sort(b.cut_faces.begin(), b.cut_faces.end());
}

} // namespace lobe::mss::detail
