// Edge splits, their undo, and vertex separation along cut faces (docs/algorithms/instruments.md).
#include "lobe/mss/topology.h"

#include "detail/tet_tables.h"
#include "lobe/core/errors.h"

#include <algorithm>
#include <string>

namespace lobe::mss {
namespace {

bool contains(const std::array<std::int32_t, 4>& q, std::int32_t v) { return q[0] == v || q[1] == v || q[2] == v || q[3] == v; }

double signed_volume(const State& s, const std::array<std::int32_t, 4>& q)
{
    const core::Vec3 p[4] = {s.position_mm(std::size_t(q[0])), s.position_mm(std::size_t(q[1])),
                             s.position_mm(std::size_t(q[2])), s.position_mm(std::size_t(q[3]))};
    return core::signed_volume(p[0], p[1], p[2], p[3]);
}

} // namespace

std::uint64_t face_id(std::int32_t a, std::int32_t b, std::int32_t c) { return detail::face_key(a, b, c); }

std::vector<std::int32_t> tets_around_edge(const Model& model, std::int32_t a, std::int32_t b)
{
    std::vector<std::int32_t> out;
    for (auto t : model.vertex_tets(a))
        if (contains(model.mesh().tets[std::size_t(t)], b))
            out.push_back(t);
    return out;
}

std::int32_t split_edge(Model& model, State& state, std::int32_t a, std::int32_t b, double t)
{
    model.enable_editing();
    if (!(t > 0 && t < 1))
        throw core::InvalidInputError("split_edge: t = " + std::to_string(t) + " is not inside (0, 1)");
    const auto ring = tets_around_edge(model, a, b);
    if (ring.empty())
        throw core::InvalidInputError("split_edge: " + std::to_string(a) + "-" + std::to_string(b) + " is not an edge");
    const auto m = std::int32_t(model.node_count());
    MeshEdit e;
    e.new_vertices.push_back({a, b, t});
    for (auto r : ring) {
        const auto& q = model.mesh().tets[std::size_t(r)];
        auto lower = q, upper = q; // a keeps the first half, b the second
        std::replace(lower.begin(), lower.end(), b, m);
        std::replace(upper.begin(), upper.end(), a, m);
        e.removed_tets.push_back(r);
        e.added_tets.push_back(lower);
        e.added_tets.push_back(upper);
        e.added_labels.push_back(model.mesh().tet_labels[std::size_t(r)]);
        e.added_labels.push_back(model.mesh().tet_labels[std::size_t(r)]);
    }
    model.apply(e, state);
    return m;
}

bool merge_split(Model& model, State& state, std::int32_t m, std::int32_t a, std::int32_t b,
                 std::vector<std::pair<std::int32_t, std::int32_t>>* moved)
{
    model.enable_editing();
    const auto& tets = model.mesh().tets;
    const auto& around = model.vertex_tets(m);
    // Each tet around m holds a or b (not both); pair (m, a, c, d) with (m, b, c, d).
    std::vector<std::int32_t> with_a, with_b;
    for (auto t : around) {
        const auto& q = tets[std::size_t(t)];
        const bool ha = contains(q, a), hb = contains(q, b);
        if (ha == hb)
            return false;
        (ha ? with_a : with_b).push_back(t);
    }
    if (with_a.size() != with_b.size() || with_a.empty())
        return false;
    MeshEdit e;
    std::vector<char> used(with_b.size(), 0);
    for (auto ta : with_a) {
        auto merged = tets[std::size_t(ta)];
        std::replace(merged.begin(), merged.end(), m, b); // (a, b, c, d): the tet before the split
        bool found = false;
        for (std::size_t j = 0; j < with_b.size() && !found; ++j) {
            if (used[j])
                continue;
            auto other = tets[std::size_t(with_b[j])];
            std::replace(other.begin(), other.end(), m, a);
            auto x = merged, y = other;
            std::sort(x.begin(), x.end());
            std::sort(y.begin(), y.end());
            if (x == y && model.mesh().tet_labels[std::size_t(ta)] == model.mesh().tet_labels[std::size_t(with_b[j])]) {
                used[j] = 1;
                found = true;
                e.removed_tets.push_back(with_b[j]);
            }
        }
        if (!found || !(signed_volume(state, merged) > 0))
            return false;
        e.removed_tets.push_back(ta);
        e.added_tets.push_back(merged);
        e.added_labels.push_back(model.mesh().tet_labels[std::size_t(ta)]);
    }
    e.removed_vertices.push_back(m);
    // The merged tets are the originals: their rest volumes are the sums of the halves', and the
    // masses of a, b and the ring return to what they were; m's momentum is shared by a and b in
    // the ratio of the mass they take back, which keeps the total when m lay on the edge.
    const auto& mass = model.masses();
    const double mm = mass[std::size_t(m)];
    std::array<double, 3> pm{};
    for (std::size_t c = 0; c < 3; ++c)
        pm[c] = mm * state.v[3 * std::size_t(m) + c];
    const double ma0 = mass[std::size_t(a)], mb0 = mass[std::size_t(b)];
    std::array<double, 3> pa{}, pb{};
    for (std::size_t c = 0; c < 3; ++c) {
        pa[c] = ma0 * state.v[3 * std::size_t(a) + c];
        pb[c] = mb0 * state.v[3 * std::size_t(b) + c];
    }
    const EditResult r = model.apply(e, state);
    auto where = [&](std::int32_t v) {
        for (const auto& [from, to] : r.moved_vertices)
            if (v == from)
                v = to;
        return v;
    };
    const auto na = where(a), nb = where(b);
    const double ga = model.masses()[std::size_t(na)] - ma0, gb = model.masses()[std::size_t(nb)] - mb0;
    if (ga + gb > 0)
        for (std::size_t c = 0; c < 3; ++c) {
            state.v[3 * std::size_t(na) + c] = (pa[c] + pm[c] * ga / (ga + gb)) / model.masses()[std::size_t(na)];
            state.v[3 * std::size_t(nb) + c] = (pb[c] + pm[c] * gb / (ga + gb)) / model.masses()[std::size_t(nb)];
        }
    if (moved)
        *moved = r.moved_vertices;
    return true;
}

std::vector<std::int32_t> separate_vertex(Model& model, State& state, std::int32_t v,
                                          const std::vector<std::uint64_t>& cut_faces)
{
    model.enable_editing();
    const auto around = model.vertex_tets(v); // a copy: apply() changes it
    const auto& tets = model.mesh().tets;
    // Groups of the tets around v joined through faces (holding v) that are not cut.
    std::vector<int> group(around.size(), -1);
    int groups = 0;
    for (std::size_t s = 0; s < around.size(); ++s) {
        if (group[s] >= 0)
            continue;
        std::vector<std::size_t> stack{s};
        group[s] = groups;
        while (!stack.empty()) {
            const auto i = stack.back();
            stack.pop_back();
            const auto& qi = tets[std::size_t(around[i])];
            for (std::size_t j = 0; j < around.size(); ++j) {
                if (group[j] >= 0)
                    continue;
                const auto& qj = tets[std::size_t(around[j])];
                std::int32_t shared[4];
                int n = 0;
                for (auto x : qi)
                    if (contains(qj, x))
                        shared[n++] = x;
                if (n != 3)
                    continue; // not face neighbours
                if (std::binary_search(cut_faces.begin(), cut_faces.end(), face_id(shared[0], shared[1], shared[2])))
                    continue;
                group[j] = groups;
                stack.push_back(j);
            }
        }
        ++groups;
    }
    std::vector<std::int32_t> copies;
    if (groups < 2)
        return copies;
    MeshEdit e;
    const auto n = std::int32_t(model.node_count());
    for (int g = 1; g < groups; ++g) {
        e.new_vertices.push_back({v, v, 0});
        copies.push_back(n + g - 1);
    }
    for (std::size_t i = 0; i < around.size(); ++i) {
        if (group[i] == 0)
            continue;
        auto q = tets[std::size_t(around[i])];
        std::replace(q.begin(), q.end(), v, n + group[i] - 1);
        e.removed_tets.push_back(around[i]);
        e.added_tets.push_back(q);
        e.added_labels.push_back(model.mesh().tet_labels[std::size_t(around[i])]);
    }
    model.apply(e, state);
    return copies;
}

} // namespace lobe::mss
