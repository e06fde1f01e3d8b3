// Manifold repair of a labelled tetrahedralisation. A label's region is a manifold solid iff,
// at every vertex v, the cells of that label around v form one disc in v's link (the sphere
// of faces opposite v): connected, with a connected complement. A region touching itself
// along an edge or at a vertex breaks one of the two, so checking vertices finds both kinds
// of defect. See docs/algorithms/meshing.md, "Manifold repair".
#include "detail/manifold_repair.h"

#include "lobe/core/tet_mesh.h"
#include "lobe/mesh/quality.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <map>
#include <optional>
#include <queue>
#include <utility>

namespace lobe::mesh::detail {

namespace {

// The star of one vertex as a small graph: nodes are the cells around v plus, for a vertex on
// the hull, one node standing for everything outside the hull (label 0, fixed); edges join
// cells that share a face through v.
struct Star {
    std::vector<std::int32_t> cell; // global cell, -1 = outside the hull
    std::vector<int> label;
    std::vector<char> fixed;
    std::vector<double> volume;
    std::vector<std::vector<int>> adj;

    std::size_t size() const { return cell.size(); }
};

// A cell may change label this many times: enough for a fix to undo an earlier one nearby, and
// a bound on the total work.
constexpr std::uint8_t kMaxChanges = 4;

class Repairer {
public:
    explicit Repairer(LabelledCells& m) : m_(m)
    {
        const std::size_t nv = m.vertices.size();
        start_.assign(nv + 1, 0);
        for (const auto& c : m.cells)
            for (auto v : c)
                ++start_[static_cast<std::size_t>(v) + 1];
        for (std::size_t v = 0; v < nv; ++v)
            start_[v + 1] += start_[v];
        incident_.resize(start_[nv]);
        auto fill = start_;
        for (std::size_t c = 0; c < m.cells.size(); ++c)
            for (auto v : m.cells[c])
                incident_[fill[static_cast<std::size_t>(v)]++] = static_cast<std::int32_t>(c);
        local_.assign(m.cells.size(), -1);
        changes_.assign(m.cells.size(), 0);
        volume_.resize(m.cells.size());
        for (std::size_t c = 0; c < m.cells.size(); ++c) {
            const auto& q = m.cells[c];
            volume_[c] = std::abs(core::signed_volume(m.vertices[static_cast<std::size_t>(q[0])],
                                                      m.vertices[static_cast<std::size_t>(q[1])],
                                                      m.vertices[static_cast<std::size_t>(q[2])],
                                                      m.vertices[static_cast<std::size_t>(q[3])]));
        }
    }

    bool bad(std::size_t v)
    {
        build(v);
        return !star_.cell.empty() && first_bad_label().has_value();
    }

    std::int64_t count_bad()
    {
        std::int64_t n = 0;
        for (std::size_t v = 0; v < m_.vertices.size(); ++v)
            n += bad(v) ? 1 : 0;
        return n;
    }

    ManifoldRepairStats run()
    {
        ManifoldRepairStats s;
        std::vector<char> queued(m_.vertices.size(), 0);
        std::queue<std::size_t> work;
        for (std::size_t v = 0; v < m_.vertices.size(); ++v)
            if (bad(v)) {
                ++s.bad_vertices_before;
                work.push(v);
                queued[v] = 1;
            }
        std::vector<std::int32_t> changed;
        while (!work.empty()) {
            const std::size_t v = work.front();
            work.pop();
            queued[v] = 0;
            changed.clear();
            fix(v, s, changed);
            for (auto c : changed)
                for (auto w : m_.cells[static_cast<std::size_t>(c)]) {
                    const auto wu = static_cast<std::size_t>(w);
                    if (!queued[wu]) {
                        queued[wu] = 1;
                        work.push(wu);
                    }
                }
        }
        s.bad_vertices_after = count_bad();
        return s;
    }

private:
    struct Option {
        double cost = std::numeric_limits<double>::infinity();
        std::vector<std::pair<int, int>> relabel; // (star node, new label)
    };

    void build(std::size_t v)
    {
        Star& s = star_;
        s.cell.clear();
        s.label.clear();
        s.fixed.clear();
        s.volume.clear();
        for (auto& a : s.adj)
            a.clear();
        const auto b = start_[v], e = start_[v + 1];
        for (auto i = b; i < e; ++i) {
            const auto c = incident_[i];
            local_[static_cast<std::size_t>(c)] = static_cast<int>(i - b);
            s.cell.push_back(c);
            s.label.push_back(m_.labels[static_cast<std::size_t>(c)]);
            s.fixed.push_back(m_.fixed[static_cast<std::size_t>(c)] || changes_[static_cast<std::size_t>(c)] >= kMaxChanges);
            s.volume.push_back(volume_[static_cast<std::size_t>(c)]);
        }
        if (s.adj.size() < s.cell.size() + 1)
            s.adj.resize(s.cell.size() + 1);
        int outside = -1;
        const auto n = static_cast<int>(s.cell.size());
        for (int i = 0; i < n; ++i) {
            const auto c = static_cast<std::size_t>(s.cell[static_cast<std::size_t>(i)]);
            for (int f = 0; f < 4; ++f) {
                if (m_.cells[c][static_cast<std::size_t>(f)] == static_cast<std::int32_t>(v))
                    continue; // the face opposite v does not contain v
                const auto nb = m_.neighbours[c][static_cast<std::size_t>(f)];
                int j = nb >= 0 ? local_[static_cast<std::size_t>(nb)] : -1;
                if (j < 0) {
                    if (outside < 0) {
                        outside = n;
                        s.cell.push_back(-1);
                        s.label.push_back(0);
                        s.fixed.push_back(1);
                        s.volume.push_back(0);
                    }
                    j = outside;
                    s.adj[static_cast<std::size_t>(j)].push_back(i);
                }
                s.adj[static_cast<std::size_t>(i)].push_back(j);
            }
        }
        for (int i = 0; i < n; ++i)
            local_[static_cast<std::size_t>(s.cell[static_cast<std::size_t>(i)])] = -1;
    }

    // Connected components of the star nodes for which `in` holds; returns their count.
    int components(const std::function<bool(int)>& in, std::vector<int>& comp) const
    {
        const auto n = star_.size();
        comp.assign(n, -1);
        int count = 0;
        std::vector<int> stack;
        for (std::size_t i = 0; i < n; ++i) {
            if (comp[i] >= 0 || !in(static_cast<int>(i)))
                continue;
            comp[i] = count;
            stack.assign(1, static_cast<int>(i));
            while (!stack.empty()) {
                const int a = stack.back();
                stack.pop_back();
                for (int b : star_.adj[static_cast<std::size_t>(a)])
                    if (comp[static_cast<std::size_t>(b)] < 0 && in(b)) {
                        comp[static_cast<std::size_t>(b)] = count;
                        stack.push_back(b);
                    }
            }
            ++count;
        }
        return count;
    }

    std::optional<int> first_bad_label()
    {
        std::vector<int> labels = star_.label;
        std::sort(labels.begin(), labels.end());
        labels.erase(std::unique(labels.begin(), labels.end()), labels.end());
        if (labels.size() < 2)
            return std::nullopt;
        for (int x : labels) {
            if (components([&](int i) { return star_.label[static_cast<std::size_t>(i)] == x; }, comp_) > 1 ||
                components([&](int i) { return star_.label[static_cast<std::size_t>(i)] != x; }, comp_) > 1)
                return x;
        }
        return std::nullopt;
    }

    // Keeps one component (the only one holding fixed nodes, else the largest) and relabels
    // the others, each to `to(component)`. Blocked if two components hold fixed nodes.
    Option drop_pieces(const std::vector<int>& comp, int count, const std::function<int(int)>& to) const
    {
        Option o;
        std::vector<double> vol(static_cast<std::size_t>(count), 0);
        std::vector<char> has_fixed(static_cast<std::size_t>(count), 0);
        for (std::size_t i = 0; i < comp.size(); ++i)
            if (comp[i] >= 0) {
                vol[static_cast<std::size_t>(comp[i])] += star_.volume[i];
                has_fixed[static_cast<std::size_t>(comp[i])] |= star_.fixed[i];
            }
        int keep = -1, fixed_count = 0;
        for (int c = 0; c < count; ++c)
            if (has_fixed[static_cast<std::size_t>(c)]) {
                keep = c;
                ++fixed_count;
            }
        if (fixed_count > 1)
            return o;
        if (keep < 0)
            keep = static_cast<int>(std::max_element(vol.begin(), vol.end()) - vol.begin());
        o.cost = 0;
        for (int c = 0; c < count; ++c) {
            if (c == keep)
                continue;
            const int label = to(c);
            if (label < 0)
                return Option{};
            for (std::size_t i = 0; i < comp.size(); ++i)
                if (comp[i] == c) {
                    o.relabel.emplace_back(static_cast<int>(i), label);
                    o.cost += star_.volume[i];
                }
        }
        return o;
    }

    // Joins the components of `comp` by relabelling shortest paths (by volume) of non-fixed
    // nodes outside them; a path takes the label `label_of(start node)` of the node it leaves.
    Option bridge(const std::vector<int>& comp, int count, const std::function<int(int)>& label_of) const
    {
        Option o;
        const auto n = star_.size();
        std::vector<char> joined(n, 0);
        for (std::size_t i = 0; i < n; ++i)
            joined[i] = comp[i] == 0;
        std::vector<char> comp_joined(static_cast<std::size_t>(count), 0);
        comp_joined[0] = 1;
        std::vector<int> new_label(n, -1); // label of a node already on a path
        double cost = 0;
        for (int round = 1; round < count; ++round) {
            std::vector<double> dist(n, std::numeric_limits<double>::infinity());
            std::vector<int> prev(n, -1), origin(n, -1);
            using Item = std::pair<double, int>;
            std::priority_queue<Item, std::vector<Item>, std::greater<>> pq;
            for (std::size_t i = 0; i < n; ++i)
                if (joined[i]) {
                    dist[i] = 0;
                    origin[i] = new_label[i] >= 0 ? new_label[i] : label_of(static_cast<int>(i));
                    pq.emplace(0.0, static_cast<int>(i));
                }
            int target = -1;
            while (!pq.empty()) {
                const auto [d, a] = pq.top();
                pq.pop();
                const auto au = static_cast<std::size_t>(a);
                if (d > dist[au])
                    continue;
                if (comp[au] >= 0 && !comp_joined[static_cast<std::size_t>(comp[au])]) {
                    target = a;
                    break;
                }
                for (int b : star_.adj[au]) {
                    const auto bu = static_cast<std::size_t>(b);
                    double nd;
                    if (comp[bu] >= 0)
                        nd = joined[bu] ? 0 : d; // reaching another component ends the path
                    else if (!star_.fixed[bu] && !joined[bu])
                        nd = d + star_.volume[bu];
                    else
                        continue;
                    if (nd < dist[bu]) {
                        dist[bu] = nd;
                        prev[bu] = a;
                        origin[bu] = origin[au];
                        pq.emplace(nd, b);
                    }
                }
            }
            if (target < 0)
                return Option{};
            const int c = comp[static_cast<std::size_t>(target)];
            comp_joined[static_cast<std::size_t>(c)] = 1;
            for (std::size_t i = 0; i < n; ++i)
                if (comp[i] == c)
                    joined[i] = 1;
            for (int a = prev[static_cast<std::size_t>(target)]; a >= 0 && !joined[static_cast<std::size_t>(a)];
                 a = prev[static_cast<std::size_t>(a)]) {
                const auto au = static_cast<std::size_t>(a);
                joined[au] = 1;
                new_label[au] = origin[static_cast<std::size_t>(target)];
                o.relabel.emplace_back(a, new_label[au]);
                cost += star_.volume[au];
            }
        }
        o.cost = cost;
        return o;
    }

    // The most frequent label among the neighbours of component c that are not labelled x.
    int neighbour_label(const std::vector<int>& comp, int c, int x) const
    {
        std::map<int, int> votes;
        for (std::size_t i = 0; i < comp.size(); ++i)
            if (comp[i] == c)
                for (int b : star_.adj[i]) {
                    const int l = star_.label[static_cast<std::size_t>(b)];
                    if (l != x)
                        ++votes[l];
                }
        int best = -1, n = 0;
        for (const auto& [l, k] : votes)
            if (k > n)
                best = l, n = k;
        return best;
    }

    void fix(std::size_t v, ManifoldRepairStats& s, std::vector<std::int32_t>& changed)
    {
        for (int iteration = 0; iteration < 32; ++iteration) {
            build(v);
            if (star_.cell.empty())
                return;
            const auto bad_label = first_bad_label();
            if (!bad_label)
                return;
            const int x = *bad_label;
            const auto& lab = star_.label;
            std::vector<int> cx, cn;
            const int kx = components([&](int i) { return lab[static_cast<std::size_t>(i)] == x; }, cx);
            const int kn = components([&](int i) { return lab[static_cast<std::size_t>(i)] != x; }, cn);
            Option best;
            auto consider = [&](Option o) {
                if (o.cost < best.cost)
                    best = std::move(o);
            };
            if (kx > 1) {
                // x in pieces: drop the stray pieces into their neighbours, or join them.
                consider(drop_pieces(cx, kx, [&](int c) { return neighbour_label(cx, c, x); }));
                consider(bridge(cx, kx, [&](int) { return x; }));
            } else if (kn > 1) {
                // x surrounds a pocket: fill the pockets with x, or open a way between them.
                consider(drop_pieces(cn, kn, [&](int) { return x; }));
                consider(bridge(cn, kn, [&](int i) { return lab[static_cast<std::size_t>(i)]; }));
            }
            if (best.relabel.empty())
                return; // every fix is blocked: left for the report
            for (const auto& [node, label] : best.relabel) {
                const auto c = static_cast<std::size_t>(star_.cell[static_cast<std::size_t>(node)]);
                if (m_.labels[c] == label)
                    continue;
                m_.labels[c] = label;
                ++changes_[c]; // bounded: the repair terminates
                ++s.relabelled;
                s.removed += label == 0 ? 1 : 0;
                s.volume += volume_[c];
                changed.push_back(static_cast<std::int32_t>(c));
            }
        }
    }

    LabelledCells& m_;
    std::vector<std::size_t> start_;
    std::vector<std::int32_t> incident_;
    std::vector<int> local_;
    std::vector<std::uint8_t> changes_;
    std::vector<double> volume_;
    Star star_;
    std::vector<int> comp_;
};

} // namespace

std::int64_t count_non_manifold_vertices(const LabelledCells& m)
{
    LabelledCells copy = m; // Repairer's queries do not modify, but it holds a mutable reference
    return Repairer(copy).count_bad();
}

ManifoldRepairStats repair_manifold(LabelledCells& m)
{
    return Repairer(m).run();
}

PeelStats peel_boundary_slivers(LabelledCells& m, double min_angle_deg)
{
    auto across = [&](std::size_t c, std::size_t f) {
        const auto n = m.neighbours[c][f];
        return n < 0 ? 0 : m.labels[static_cast<std::size_t>(n)];
    };
    std::vector<char> on_surface(m.vertices.size(), 0);
    for (std::size_t c = 0; c < m.cells.size(); ++c)
        if (m.labels[c] != 0)
            for (std::size_t f = 0; f < 4; ++f)
                if (across(c, f) != m.labels[c])
                    for (std::size_t i = 0; i < 4; ++i)
                        if (i != f)
                            on_surface[static_cast<std::size_t>(m.cells[c][i])] = 1;
    PeelStats s;
    const double pi = std::acos(-1.0);
    for (std::size_t c = 0; c < m.cells.size(); ++c) {
        if (m.labels[c] == 0)
            continue;
        const auto& q = m.cells[c];
        bool outside = false, all = true;
        for (std::size_t f = 0; f < 4; ++f) {
            outside = outside || across(c, f) == 0;
            all = all && on_surface[static_cast<std::size_t>(q[f])];
        }
        if (!outside || !all)
            continue;
        const auto& a = m.vertices[static_cast<std::size_t>(q[0])];
        const auto& b = m.vertices[static_cast<std::size_t>(q[1])];
        const auto& cc = m.vertices[static_cast<std::size_t>(q[2])];
        const auto& d = m.vertices[static_cast<std::size_t>(q[3])];
        const auto angles = dihedral_angles(a, b, cc, d);
        if (*std::min_element(angles.begin(), angles.end()) * 180 / pi >= min_angle_deg)
            continue;
        m.labels[c] = 0;
        m.fixed[c] = 1;
        ++s.tets;
        s.volume += std::abs(core::signed_volume(a, b, cc, d));
    }
    return s;
}

} // namespace lobe::mesh::detail
