#include "lobe/seg/skeleton.h"

#include "detail/volume.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <map>
#include <numeric>
#include <queue>
#include <string>
#include <utility>
#include <vector>

namespace lobe::seg {
namespace {

// ---------------------------------------------------------------------------------------------
// The 3x3x3 neighbourhood: position n = (di+1) + 3 (dj+1) + 9 (dk+1), centre 13.

constexpr int kCentre = 13;

struct Cube {
    std::array<std::vector<int>, 27> adj26; // 26-adjacent positions (centre excluded)
    std::array<std::vector<int>, 27> adj6;  // 6-adjacent positions within N18 (centre excluded)
    std::array<bool, 27> in18{};            // not the centre, not a corner
    std::array<int, 6> faces{4, 10, 12, 14, 16, 22};

    Cube()
    {
        auto off = [](int n) { return std::array<int, 3>{n % 3 - 1, (n / 3) % 3 - 1, n / 9 - 1}; };
        for (int n = 0; n < 27; ++n) {
            const auto a = off(n);
            const int nz = (a[0] != 0) + (a[1] != 0) + (a[2] != 0);
            in18[std::size_t(n)] = n != kCentre && nz < 3;
        }
        for (int n = 0; n < 27; ++n) {
            if (n == kCentre)
                continue;
            const auto a = off(n);
            for (int m = 0; m < 27; ++m) {
                if (m == kCentre || m == n)
                    continue;
                const auto b = off(m);
                const int dx = std::abs(a[0] - b[0]), dy = std::abs(a[1] - b[1]), dz = std::abs(a[2] - b[2]);
                if (std::max({dx, dy, dz}) == 1)
                    adj26[std::size_t(n)].push_back(m);
                if (dx + dy + dz == 1 && in18[std::size_t(n)] && in18[std::size_t(m)])
                    adj6[std::size_t(n)].push_back(m);
            }
        }
    }
};

const Cube& cube()
{
    static const Cube c;
    return c;
}

//! (26, 6) simple-point test on a 3x3x3 configuration (centre ignored): T26 = 1 and T6̄ = 1.
bool simple(const std::array<std::uint8_t, 27>& v)
{
    const Cube& c = cube();
    std::array<std::uint8_t, 27> seen{};
    std::array<int, 27> stack{};
    // T26: 26-components of the object in N26*.
    int comps = 0;
    for (int n = 0; n < 27; ++n) {
        if (n == kCentre || !v[std::size_t(n)] || seen[std::size_t(n)])
            continue;
        if (++comps > 1)
            return false;
        int top = 0;
        stack[std::size_t(top++)] = n;
        seen[std::size_t(n)] = 1;
        while (top) {
            const int p = stack[std::size_t(--top)];
            for (int q : c.adj26[std::size_t(p)])
                if (v[std::size_t(q)] && !seen[std::size_t(q)]) {
                    seen[std::size_t(q)] = 1;
                    stack[std::size_t(top++)] = q;
                }
        }
    }
    if (comps != 1)
        return false;
    // T6̄: 6-components of the background in N18 that touch a face neighbour.
    seen.fill(0);
    comps = 0;
    for (int f : c.faces) {
        if (v[std::size_t(f)] || seen[std::size_t(f)])
            continue;
        if (++comps > 1)
            return false;
        int top = 0;
        stack[std::size_t(top++)] = f;
        seen[std::size_t(f)] = 1;
        while (top) {
            const int p = stack[std::size_t(--top)];
            for (int q : c.adj6[std::size_t(p)])
                if (!v[std::size_t(q)] && !seen[std::size_t(q)]) {
                    seen[std::size_t(q)] = 1;
                    stack[std::size_t(top++)] = q;
                }
        }
    }
    return comps == 1;
}

//! A binary volume padded by one background voxel on every side.
struct Padded {
    std::array<std::ptrdiff_t, 3> n{0, 0, 0};
    std::vector<std::uint8_t> v;
    std::array<std::ptrdiff_t, 27> offs{};

    explicit Padded(const core::LabelImage3D& m)
    {
        n = {m.size[0] + 2, m.size[1] + 2, m.size[2] + 2};
        v.assign(std::size_t(n[0] * n[1] * n[2]), 0);
        for (int k = 0; k < m.size[2]; ++k)
            for (int j = 0; j < m.size[1]; ++j)
                for (int i = 0; i < m.size[0]; ++i)
                    v[std::size_t(at(i + 1, j + 1, k + 1))] = m.at(i, j, k) ? 1 : 0;
        for (int q = 0; q < 27; ++q)
            offs[std::size_t(q)] = (q % 3 - 1) + n[0] * (((q / 3) % 3 - 1) + n[1] * (q / 9 - 1));
    }
    std::ptrdiff_t at(std::ptrdiff_t i, std::ptrdiff_t j, std::ptrdiff_t k) const { return i + n[0] * (j + n[1] * k); }
    std::array<std::uint8_t, 27> neighbourhood(std::ptrdiff_t p) const
    {
        std::array<std::uint8_t, 27> c{};
        for (int q = 0; q < 27; ++q)
            c[std::size_t(q)] = v[std::size_t(p + offs[std::size_t(q)])];
        return c;
    }
    int count26(std::ptrdiff_t p) const
    {
        int s = 0;
        for (int q = 0; q < 27; ++q)
            if (q != kCentre)
                s += v[std::size_t(p + offs[std::size_t(q)])];
        return s;
    }
    std::array<int, 3> ijk(std::ptrdiff_t p) const
    {
        return {int(p % n[0]) - 1, int((p / n[0]) % n[1]) - 1, int(p / (n[0] * n[1])) - 1};
    }
};

// ---------------------------------------------------------------------------------------------
// A mutable graph for pruning.

struct GNode {
    core::Vec3 pos;
    double radius = 0;
    bool alive = true;
};

struct GEdge {
    int a = 0, b = 0;
    std::vector<core::Vec3> pts;
    std::vector<double> rad;
    bool alive = true;
    double length() const
    {
        double l = 0;
        for (std::size_t i = 1; i < pts.size(); ++i)
            l += core::distance(pts[i - 1], pts[i]);
        return l;
    }
};

struct Work {
    std::vector<GNode> nodes;
    std::vector<GEdge> edges;

    std::vector<std::vector<int>> incidence() const
    {
        std::vector<std::vector<int>> inc(nodes.size());
        for (std::size_t e = 0; e < edges.size(); ++e)
            if (edges[e].alive) {
                inc[std::size_t(edges[e].a)].push_back(int(e));
                inc[std::size_t(edges[e].b)].push_back(int(e));
            }
        return inc;
    }
};

double median(std::vector<double> v)
{
    if (v.empty())
        return 0;
    const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
    std::nth_element(v.begin(), mid, v.end());
    return *mid;
}

//! Joins edges meeting at nodes with exactly two edges (not loops). Returns how many were joined.
std::size_t merge_degree_two(Work& w)
{
    std::size_t merged = 0;
    bool again = true;
    while (again) {
        again = false;
        const auto inc = w.incidence();
        for (std::size_t n = 0; n < w.nodes.size(); ++n) {
            if (!w.nodes[n].alive || inc[n].size() != 2)
                continue;
            GEdge& e1 = w.edges[std::size_t(inc[n][0])];
            GEdge& e2 = w.edges[std::size_t(inc[n][1])];
            if (!e1.alive || !e2.alive || &e1 == &e2 || e1.a == e1.b || e2.a == e2.b)
                continue;
            // Orient e1 to end at n and e2 to start at n, then append.
            if (e1.a == int(n)) {
                std::swap(e1.a, e1.b);
                std::reverse(e1.pts.begin(), e1.pts.end());
                std::reverse(e1.rad.begin(), e1.rad.end());
            }
            if (e2.b == int(n)) {
                std::swap(e2.a, e2.b);
                std::reverse(e2.pts.begin(), e2.pts.end());
                std::reverse(e2.rad.begin(), e2.rad.end());
            }
            if (e1.a == e2.b)
                continue; // the two edges form a loop through n: leave it to the cycle breaking
            e1.pts.insert(e1.pts.end(), e2.pts.begin() + 1, e2.pts.end());
            e1.rad.insert(e1.rad.end(), e2.rad.begin() + 1, e2.rad.end());
            e1.b = e2.b;
            e2.alive = false;
            w.nodes[n].alive = false;
            ++merged;
            again = true;
            break; // the incidence lists are stale
        }
    }
    return merged;
}

//! Removes terminal edges shorter than the spur length at their branch point.
std::size_t prune_spurs(Work& w, const CentrelineParams& p)
{
    const auto inc = w.incidence();
    std::vector<int> doomed;
    for (std::size_t e = 0; e < w.edges.size(); ++e) {
        const GEdge& ed = w.edges[e];
        if (!ed.alive || ed.a == ed.b)
            continue;
        const std::size_t da = inc[std::size_t(ed.a)].size(), db = inc[std::size_t(ed.b)].size();
        int junction = -1;
        if (da == 1 && db >= 3)
            junction = ed.b;
        else if (db == 1 && da >= 3)
            junction = ed.a;
        if (junction < 0)
            continue;
        const double limit = std::max(p.min_spur_mm, p.spur_radius_factor * w.nodes[std::size_t(junction)].radius);
        if (ed.length() < limit)
            doomed.push_back(int(e));
    }
    // Never remove every terminal edge of one branch point in one pass (a short fork would vanish
    // whole): keep the longest spur at a junction whose other edges are all doomed.
    std::vector<std::uint8_t> kill(w.edges.size(), 0);
    for (int e : doomed)
        kill[std::size_t(e)] = 1;
    for (std::size_t n = 0; n < w.nodes.size(); ++n) {
        if (!w.nodes[n].alive || inc[n].size() < 3)
            continue;
        std::size_t killed = 0;
        for (int e : inc[n])
            killed += kill[std::size_t(e)];
        if (killed == inc[n].size()) {
            int keep = inc[n][0];
            for (int e : inc[n])
                if (w.edges[std::size_t(e)].length() > w.edges[std::size_t(keep)].length())
                    keep = e;
            kill[std::size_t(keep)] = 0;
        }
    }
    std::size_t removed = 0;
    for (std::size_t e = 0; e < w.edges.size(); ++e)
        if (kill[e]) {
            GEdge& ed = w.edges[e];
            ed.alive = false;
            const int end = inc[std::size_t(ed.a)].size() == 1 ? ed.a : ed.b;
            w.nodes[std::size_t(end)].alive = false;
            ++removed;
        }
    return removed;
}

//! Contracts short edges between two branch points into one branch point.
std::size_t merge_junctions(Work& w, const CentrelineParams& p)
{
    std::size_t merged = 0;
    bool again = true;
    while (again) {
        again = false;
        const auto inc = w.incidence();
        for (std::size_t e = 0; e < w.edges.size(); ++e) {
            GEdge& ed = w.edges[e];
            if (!ed.alive || ed.a == ed.b)
                continue;
            if (inc[std::size_t(ed.a)].size() < 3 || inc[std::size_t(ed.b)].size() < 3)
                continue;
            const double r = std::max(w.nodes[std::size_t(ed.a)].radius, w.nodes[std::size_t(ed.b)].radius);
            if (ed.length() >= p.junction_merge_factor * r)
                continue;
            // Node b goes into node a, placed at the edge's midpoint.
            const int a = ed.a, b = ed.b;
            GNode& na = w.nodes[std::size_t(a)];
            const core::Vec3 mid = ed.pts[ed.pts.size() / 2];
            na.pos = mid;
            na.radius = std::max(na.radius, w.nodes[std::size_t(b)].radius);
            w.nodes[std::size_t(b)].alive = false;
            ed.alive = false;
            for (int f : inc[std::size_t(b)]) {
                GEdge& g = w.edges[std::size_t(f)];
                if (!g.alive)
                    continue;
                if (g.a == b) {
                    g.a = a;
                    g.pts.front() = mid;
                }
                if (g.b == b) {
                    g.b = a;
                    g.pts.back() = mid;
                }
                if (g.a == g.b)
                    g.alive = false; // a loop through the merged pair
            }
            for (int f : inc[std::size_t(a)]) {
                GEdge& g = w.edges[std::size_t(f)];
                if (!g.alive)
                    continue;
                if (g.a == a)
                    g.pts.front() = mid;
                if (g.b == a)
                    g.pts.back() = mid;
            }
            ++merged;
            again = true;
            break;
        }
    }
    return merged;
}

//! Keeps a maximum spanning forest by edge radius (loops come from touching vessels; the
//! thinnest edge of a loop is the likeliest false contact). Returns the edges dropped.
std::size_t break_cycles(Work& w)
{
    std::vector<int> order;
    for (std::size_t e = 0; e < w.edges.size(); ++e)
        if (w.edges[e].alive)
            order.push_back(int(e));
    std::vector<double> r(w.edges.size(), 0);
    for (int e : order)
        r[std::size_t(e)] = median(w.edges[std::size_t(e)].rad);
    std::stable_sort(order.begin(), order.end(), [&](int x, int y) { return r[std::size_t(x)] > r[std::size_t(y)]; });
    std::vector<int> parent(w.nodes.size());
    std::iota(parent.begin(), parent.end(), 0);
    auto find = [&](int x) {
        while (parent[std::size_t(x)] != x) {
            parent[std::size_t(x)] = parent[std::size_t(parent[std::size_t(x)])];
            x = parent[std::size_t(x)];
        }
        return x;
    };
    std::size_t dropped = 0;
    for (int e : order) {
        GEdge& ed = w.edges[std::size_t(e)];
        const int ra = find(ed.a), rb = find(ed.b);
        if (ra == rb) {
            ed.alive = false;
            ++dropped;
        } else {
            parent[std::size_t(ra)] = rb;
        }
    }
    return dropped;
}

} // namespace

bool is_simple_point(const core::LabelImage3D& mask, int i, int j, int k)
{
    std::array<std::uint8_t, 27> c{};
    for (int q = 0; q < 27; ++q) {
        const int ii = i + q % 3 - 1, jj = j + (q / 3) % 3 - 1, kk = k + q / 9 - 1;
        c[std::size_t(q)] = mask.contains(ii, jj, kk) && mask.at(ii, jj, kk) ? 1 : 0;
    }
    return simple(c);
}

core::LabelImage3D thin(const core::LabelImage3D& mask)
{
    detail::check_image(mask, "thin: mask");
    core::LabelImage3D out(mask.geometry(), 0);
    const detail::Box box = detail::bounding_box(mask);
    if (box.empty())
        return out;
    Padded pv(detail::crop(mask, box));
    std::vector<std::ptrdiff_t> object;
    for (std::ptrdiff_t p = 0; p < static_cast<std::ptrdiff_t>(pv.v.size()); ++p)
        if (pv.v[std::size_t(p)])
            object.push_back(p);
    // The six face directions, in Lee's order: N, S, E, W, U, B.
    const std::array<int, 6> dirs{10, 16, 14, 12, 22, 4};
    std::vector<std::ptrdiff_t> candidates;
    for (;;) {
        bool changed = false;
        for (int d : dirs) {
            const std::ptrdiff_t o = pv.offs[std::size_t(d)];
            candidates.clear();
            for (std::ptrdiff_t p : object) {
                if (!pv.v[std::size_t(p)] || pv.v[std::size_t(p + o)])
                    continue; // deleted already, or not a border voxel in this direction
                if (pv.count26(p) == 1)
                    continue; // an end point: keeps the curve's extent
                if (simple(pv.neighbourhood(p)))
                    candidates.push_back(p);
            }
            // Sequential re-check: deleting one candidate may make its neighbour non-simple.
            for (std::ptrdiff_t p : candidates) {
                if (pv.count26(p) == 1 || !simple(pv.neighbourhood(p)))
                    continue;
                pv.v[std::size_t(p)] = 0;
                changed = true;
            }
        }
        object.erase(std::remove_if(object.begin(), object.end(), [&](std::ptrdiff_t p) { return !pv.v[std::size_t(p)]; }),
                     object.end());
        if (!changed)
            break;
    }
    for (std::ptrdiff_t p : object) {
        const auto c = pv.ijk(p);
        out.at(c[0] + box.lo[0], c[1] + box.lo[1], c[2] + box.lo[2]) = 1;
    }
    return out;
}

core::CentrelineGraph centreline_graph(const core::LabelImage3D& skeleton, const core::ImageF& distance_mm,
                                       const CentrelineParams& params, CentrelineStats* stats)
{
    detail::check_image(skeleton, "centreline_graph: skeleton");
    detail::check_same_grid(skeleton, distance_mm, "centreline_graph: the distance map");
    if (!(params.min_spur_mm >= 0) || !(params.spur_radius_factor >= 0) || !(params.junction_merge_factor >= 0) ||
        !(params.min_component_length_mm >= 0) || params.max_prune_passes < 0)
        throw core::InvalidInputError("centreline_graph: the pruning parameters must be >= 0");
    CentrelineStats st;
    core::CentrelineGraph out;
    const detail::Box box = detail::bounding_box(skeleton);
    if (box.empty()) {
        if (stats)
            *stats = st;
        return out;
    }
    const Padded pv(detail::crop(skeleton, box));
    const double half = 0.5 * std::min({skeleton.spacing[0], skeleton.spacing[1], skeleton.spacing[2]});
    auto position = [&](std::ptrdiff_t p) {
        const auto c = pv.ijk(p);
        return skeleton.index_to_physical(c[0] + box.lo[0], c[1] + box.lo[1], c[2] + box.lo[2]);
    };
    auto radius = [&](std::ptrdiff_t p) {
        const auto c = pv.ijk(p);
        const double d = distance_mm.at(c[0] + box.lo[0], c[1] + box.lo[1], c[2] + box.lo[2]);
        return std::isfinite(d) ? std::max(0.0, d - half) : 0.0;
    };

    // Voxels with other than two skeleton neighbours are node voxels; 26-adjacent node voxels
    // form one node (a branch point is often a small cluster).
    std::vector<std::ptrdiff_t> vox;
    for (std::ptrdiff_t p = 0; p < static_cast<std::ptrdiff_t>(pv.v.size()); ++p)
        if (pv.v[std::size_t(p)])
            vox.push_back(p);
    st.skeleton_voxels = vox.size();
    std::map<std::ptrdiff_t, int> node_of; // node voxel -> node index
    Work w;
    for (std::ptrdiff_t p : vox) {
        if (pv.count26(p) == 2 || node_of.count(p))
            continue;
        const int id = static_cast<int>(w.nodes.size());
        std::vector<std::ptrdiff_t> cluster{p}, stack{p};
        node_of[p] = id;
        while (!stack.empty()) {
            const std::ptrdiff_t q = stack.back();
            stack.pop_back();
            for (int s = 0; s < 27; ++s) {
                const std::ptrdiff_t r = q + pv.offs[std::size_t(s)];
                if (s == kCentre || !pv.v[std::size_t(r)] || pv.count26(r) == 2 || node_of.count(r))
                    continue;
                node_of[r] = id;
                cluster.push_back(r);
                stack.push_back(r);
            }
        }
        GNode n;
        for (std::ptrdiff_t q : cluster) {
            n.pos += position(q);
            n.radius = std::max(n.radius, radius(q));
        }
        n.pos /= static_cast<double>(cluster.size());
        w.nodes.push_back(n);
    }

    // Trace the runs of two-neighbour voxels between nodes.
    std::vector<std::uint8_t> walked(pv.v.size(), 0);
    for (const auto& [p, id] : node_of) {
        for (int s = 0; s < 27; ++s) {
            const std::ptrdiff_t q = p + pv.offs[std::size_t(s)];
            // 26-adjacent node voxels belong to one cluster, so a neighbour is a run's first voxel
            if (s == kCentre || !pv.v[std::size_t(q)] || node_of.count(q))
                continue;
            if (walked[std::size_t(q)])
                continue;
            GEdge e;
            e.a = id;
            e.pts = {w.nodes[std::size_t(id)].pos};
            e.rad = {w.nodes[std::size_t(id)].radius};
            std::ptrdiff_t prev = p, cur = q;
            int end = -1;
            for (;;) {
                walked[std::size_t(cur)] = 1;
                e.pts.push_back(position(cur));
                e.rad.push_back(radius(cur));
                std::ptrdiff_t next = -1;
                for (int t = 0; t < 27 && end < 0; ++t) {
                    const std::ptrdiff_t r = cur + pv.offs[std::size_t(t)];
                    if (t == kCentre || r == prev || !pv.v[std::size_t(r)])
                        continue;
                    const auto nit = node_of.find(r);
                    if (nit != node_of.end()) {
                        // Reaching a node voxel other than where we started ends the run; the
                        // start's own cluster ends it only once we have left it.
                        if (nit->second != id || e.pts.size() > 2)
                            end = nit->second;
                        continue;
                    }
                    if (!walked[std::size_t(r)])
                        next = r;
                }
                if (end >= 0 || next < 0)
                    break;
                prev = cur;
                cur = next;
            }
            if (end < 0)
                continue; // a run that dead-ends without a node (cannot happen on a thin curve)
            e.b = end;
            e.pts.push_back(w.nodes[std::size_t(end)].pos);
            e.rad.push_back(w.nodes[std::size_t(end)].radius);
            if (e.a == e.b) {
                ++st.cycles_broken; // a loop on one node
                continue;
            }
            w.edges.push_back(std::move(e));
        }
    }

    st.cycles_broken += break_cycles(w);
    for (int pass = 0; pass < params.max_prune_passes; ++pass) {
        const std::size_t spurs = prune_spurs(w, params);
        merge_degree_two(w);
        const std::size_t joined = merge_junctions(w, params);
        merge_degree_two(w);
        st.spurs_pruned += spurs;
        st.junctions_merged += joined;
        if (spurs == 0 && joined == 0)
            break;
    }

    // Drop small parts (noise).
    {
        std::vector<int> parent(w.nodes.size());
        std::iota(parent.begin(), parent.end(), 0);
        auto find = [&](int x) {
            while (parent[std::size_t(x)] != x)
                x = parent[std::size_t(x)] = parent[std::size_t(parent[std::size_t(x)])];
            return x;
        };
        for (const auto& e : w.edges)
            if (e.alive)
                parent[std::size_t(find(e.a))] = find(e.b);
        std::vector<double> len(w.nodes.size(), 0);
        for (const auto& e : w.edges)
            if (e.alive)
                len[std::size_t(find(e.a))] += e.length();
        std::vector<std::uint8_t> has_edge(w.nodes.size(), 0);
        for (const auto& e : w.edges)
            if (e.alive)
                has_edge[std::size_t(e.a)] = has_edge[std::size_t(e.b)] = 1;
        std::vector<std::uint8_t> counted(w.nodes.size(), 0);
        for (std::size_t n = 0; n < w.nodes.size(); ++n) {
            if (!w.nodes[n].alive)
                continue;
            const int r = find(int(n));
            if (!has_edge[n] || len[std::size_t(r)] < params.min_component_length_mm) {
                if (!counted[std::size_t(r)] && has_edge[n])
                    ++st.components_dropped;
                counted[std::size_t(r)] = 1;
                w.nodes[n].alive = false;
            }
        }
        for (auto& e : w.edges)
            if (e.alive && (!w.nodes[std::size_t(e.a)].alive || !w.nodes[std::size_t(e.b)].alive))
                e.alive = false;
    }

    // Compact, with every edge running from its thicker end.
    std::vector<int> newid(w.nodes.size(), -1);
    for (std::size_t n = 0; n < w.nodes.size(); ++n)
        if (w.nodes[n].alive) {
            newid[n] = static_cast<int>(out.nodes.size());
            out.nodes.push_back({w.nodes[n].pos, w.nodes[n].radius});
        }
    for (auto& e : w.edges) {
        if (!e.alive)
            continue;
        const std::size_t m = std::max<std::size_t>(1, e.rad.size() / 4);
        const double ra = std::accumulate(e.rad.begin(), e.rad.begin() + static_cast<std::ptrdiff_t>(m), 0.0);
        const double rb = std::accumulate(e.rad.end() - static_cast<std::ptrdiff_t>(m), e.rad.end(), 0.0);
        if (rb > ra) {
            std::swap(e.a, e.b);
            std::reverse(e.pts.begin(), e.pts.end());
            std::reverse(e.rad.begin(), e.rad.end());
        }
        core::CentrelineEdge ce;
        ce.from = newid[std::size_t(e.a)];
        ce.to = newid[std::size_t(e.b)];
        ce.radius_mm = median(e.rad);
        ce.length_mm = e.length();
        ce.points = std::move(e.pts);
        ce.point_radius = std::move(e.rad);
        out.edges.push_back(std::move(ce));
    }
    if (stats)
        *stats = st;
    return out;
}

std::vector<std::vector<int>> graph_components(const core::CentrelineGraph& graph)
{
    std::vector<int> parent(graph.nodes.size());
    std::iota(parent.begin(), parent.end(), 0);
    auto find = [&](int x) {
        while (parent[std::size_t(x)] != x)
            x = parent[std::size_t(x)] = parent[std::size_t(parent[std::size_t(x)])];
        return x;
    };
    for (const auto& e : graph.edges)
        parent[std::size_t(find(e.from))] = find(e.to);
    std::map<int, std::vector<int>> parts;
    for (std::size_t n = 0; n < graph.nodes.size(); ++n)
        parts[find(int(n))].push_back(int(n));
    std::vector<std::vector<int>> out;
    for (auto& [root, nodes] : parts)
        out.push_back(std::move(nodes));
    return out;
}

void assign_branch_levels(core::CentrelineGraph& graph, int root, int label, double min_branch_mm)
{
    if (root < 0 || root >= static_cast<int>(graph.nodes.size()))
        throw core::InvalidInputError("assign_branch_levels: root " + std::to_string(root) + " is not a node");
    std::vector<std::vector<int>> inc(graph.nodes.size());
    for (std::size_t e = 0; e < graph.edges.size(); ++e) {
        inc[std::size_t(graph.edges[e].from)].push_back(int(e));
        inc[std::size_t(graph.edges[e].to)].push_back(int(e));
    }
    // Orient the tree away from the root (breadth first), remembering the visiting order.
    std::vector<std::uint8_t> seen_edge(graph.edges.size(), 0), seen_node(graph.nodes.size(), 0);
    std::vector<int> order; // edges, parents before children
    std::queue<int> q;
    q.push(root);
    seen_node[std::size_t(root)] = 1;
    while (!q.empty()) {
        const int n = q.front();
        q.pop();
        for (int e : inc[std::size_t(n)]) {
            if (seen_edge[std::size_t(e)])
                continue;
            seen_edge[std::size_t(e)] = 1;
            auto& ed = graph.edges[std::size_t(e)];
            if (ed.from != n) {
                std::swap(ed.from, ed.to);
                std::reverse(ed.points.begin(), ed.points.end());
                std::reverse(ed.point_radius.begin(), ed.point_radius.end());
            }
            ed.label = label;
            order.push_back(e);
            if (!seen_node[std::size_t(ed.to)]) {
                seen_node[std::size_t(ed.to)] = 1;
                q.push(ed.to);
            }
        }
    }
    // Children of each node and subtree lengths (children after parents in `order`).
    std::vector<std::vector<int>> children(graph.nodes.size());
    for (int e : order)
        children[std::size_t(graph.edges[std::size_t(e)].from)].push_back(e);
    std::vector<double> subtree(graph.edges.size(), 0.0);
    for (auto it = order.rbegin(); it != order.rend(); ++it) {
        const auto& ed = graph.edges[std::size_t(*it)];
        double s = ed.length_mm;
        for (int c : children[std::size_t(ed.to)])
            s += subtree[std::size_t(c)];
        subtree[std::size_t(*it)] = s;
    }
    auto set_children = [&](int node, int parent_level) {
        const auto& kids = children[std::size_t(node)];
        int significant = 0, main = -1;
        for (int c : kids)
            if (subtree[std::size_t(c)] >= min_branch_mm) {
                ++significant;
                main = c;
            }
        for (int c : kids) {
            int lvl;
            if (parent_level == 0)
                lvl = 1;
            else if (kids.size() < 2)
                lvl = parent_level; // a node with one child is no branch point
            else if (significant == 1 && c == main)
                lvl = parent_level; // the continuation past a side spur
            else
                lvl = parent_level + 1;
            graph.edges[std::size_t(c)].level = lvl;
        }
    };
    set_children(root, 0);
    for (int e : order)
        set_children(graph.edges[std::size_t(e)].to, graph.edges[std::size_t(e)].level);
}

} // namespace lobe::seg
