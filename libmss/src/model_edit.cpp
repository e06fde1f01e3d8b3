// Local mesh edits of the mass-spring model: the tables they need and Model::apply
// (docs/algorithms/instruments.md, "Local updates").
#include "lobe/mss/model.h"

#include "detail/tet_tables.h"
#include "lobe/core/errors.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <unordered_map>
#include <unordered_set>

namespace lobe::mss {
namespace {

constexpr double kPi = 3.14159265358979323846;

using detail::edge_first;
using detail::edge_key;
using detail::edge_second;
using detail::face_key;
using detail::kTetEdges;
using detail::kTetFaces;

constexpr double kMmToM = 1e-3;

[[noreturn]] void refuse(const std::string& what) { throw core::InvalidInputError("mesh edit: " + what); }

bool contains(const std::array<std::int32_t, 4>& q, std::int32_t v) { return q[0] == v || q[1] == v || q[2] == v || q[3] == v; }

void replace(std::array<std::int32_t, 4>& q, std::int32_t from, std::int32_t to)
{
    for (auto& v : q)
        if (v == from)
            v = to;
}

template <class T> void unique_sorted(std::vector<T>& v)
{
    std::sort(v.begin(), v.end());
    v.erase(std::unique(v.begin(), v.end()), v.end());
}

} // namespace

void Model::enable_editing()
{
    if (editing_)
        return;
    const std::size_t n = mass_.size();
    if (n > std::size_t(detail::kMaxEditableVertices))
        throw core::InvalidInputError("mass-spring model: " + std::to_string(n) + " vertices, above the " +
                                      std::to_string(detail::kMaxEditableVertices) + " that local edits support");
    vertex_tets_.assign(n, {});
    for (std::size_t t = 0; t < mesh_.tets.size(); ++t)
        for (auto v : mesh_.tets[t])
            vertex_tets_[std::size_t(v)].push_back(std::int32_t(t));
    edge_slot_.clear();
    edge_slot_.reserve(2 * springs_.size());
    for (std::size_t k = 0; k < springs_.size(); ++k)
        edge_slot_.emplace(edge_key(springs_.a[k], springs_.b[k]), std::int32_t(k));
    face_slot_.clear();
    face_slot_.reserve(2 * surface_faces_.size());
    for (std::size_t f = 0; f < surface_faces_.size(); ++f)
        face_slot_.emplace(face_key(surface_faces_[f][0], surface_faces_[f][1], surface_faces_[f][2]), std::int32_t(f));
    editing_ = true;
}

void Model::remove_spring(std::size_t k)
{
    edge_slot_.erase(edge_key(springs_.a[k], springs_.b[k]));
    const std::size_t last = springs_.size() - 1;
    if (k != last) {
        springs_.a[k] = springs_.a[last];
        springs_.b[k] = springs_.b[last];
        springs_.rest_length[k] = springs_.rest_length[last];
        springs_.stiffness[k] = springs_.stiffness[last];
        springs_.damping[k] = springs_.damping[last];
        spring_sum_e_[k] = spring_sum_e_[last];
        spring_sum_ev_[k] = spring_sum_ev_[last];
        spring_count_[k] = spring_count_[last];
        edge_slot_[edge_key(springs_.a[k], springs_.b[k])] = std::int32_t(k);
    }
    springs_.a.pop_back();
    springs_.b.pop_back();
    springs_.rest_length.pop_back();
    springs_.stiffness.pop_back();
    springs_.damping.pop_back();
    spring_sum_e_.pop_back();
    spring_sum_ev_.pop_back();
    spring_count_.pop_back();
    if (!fem_k_.empty())
        fem_k_.pop_back();
}

// Re-derives whether face `key` is a boundary face (exactly one tet has it) from the tets
// around its first vertex, and updates the surface tables.
void Model::refresh_face(std::uint64_t key)
{
    const auto v0 = std::int32_t(key >> 42), v1 = std::int32_t((key >> 21) & 0x1fffff), v2 = std::int32_t(key & 0x1fffff);
    int count = 0;
    std::int32_t tet = -1;
    if (std::size_t(v0) < vertex_tets_.size())
        for (auto t : vertex_tets_[std::size_t(v0)]) {
            const auto& q = mesh_.tets[std::size_t(t)];
            if (contains(q, v1) && contains(q, v2)) {
                ++count;
                tet = t;
            }
        }
    const auto it = face_slot_.find(key);
    if (count == 1) {
        const auto& q = mesh_.tets[std::size_t(tet)];
        std::array<std::int32_t, 3> face{};
        for (const auto& f : kTetFaces) {
            const std::array<std::int32_t, 3> g{q[std::size_t(f[0])], q[std::size_t(f[1])], q[std::size_t(f[2])]};
            if (face_key(g[0], g[1], g[2]) == key)
                face = g;
        }
        if (it != face_slot_.end()) {
            surface_faces_[std::size_t(it->second)] = face;
            surface_face_tets_[std::size_t(it->second)] = tet;
        } else {
            face_slot_.emplace(key, std::int32_t(surface_faces_.size()));
            surface_faces_.push_back(face);
            surface_face_tets_.push_back(tet);
        }
    } else if (it != face_slot_.end()) {
        const std::size_t slot = std::size_t(it->second), last = surface_faces_.size() - 1;
        face_slot_.erase(it);
        if (slot != last) {
            surface_faces_[slot] = surface_faces_[last];
            surface_face_tets_[slot] = surface_face_tets_[last];
            const auto& f = surface_faces_[slot];
            face_slot_[face_key(f[0], f[1], f[2])] = std::int32_t(slot);
        }
        surface_faces_.pop_back();
        surface_face_tets_.pop_back();
    }
}

EditResult Model::apply(const MeshEdit& e, State& st)
{
    enable_editing();
    const auto n0 = std::int32_t(node_count());
    const auto nn = std::int32_t(e.new_vertices.size());
    const std::int32_t n1 = n0 + nn;
    const auto t0 = std::int32_t(tet_count());
    if (st.x.size() != 3 * std::size_t(n0) || st.v.size() != st.x.size())
        refuse("the state has " + std::to_string(st.x.size() / 3) + " nodes, the model " + std::to_string(n0));
    if (n1 > detail::kMaxEditableVertices)
        refuse("more than " + std::to_string(detail::kMaxEditableVertices) + " vertices");

    // ---- validation: nothing changes until every check has passed -------------------------
    std::vector<core::Vec3> new_rest(std::size_t(nn), core::Vec3{0, 0, 0});
    auto rest_mm = [&](std::int32_t v) { return v < n0 ? mesh_.vertices[std::size_t(v)] : new_rest[std::size_t(v - n0)]; };
    for (std::int32_t i = 0; i < nn; ++i) {
        const auto& nv = e.new_vertices[std::size_t(i)];
        if (nv.a < 0 || nv.b < 0 || nv.a >= n0 + i || nv.b >= n0 + i)
            refuse("new vertex " + std::to_string(i) + " has a parent out of range");
        if (!(nv.t >= 0 && nv.t <= 1))
            refuse("new vertex " + std::to_string(i) + " has t outside [0, 1]");
        new_rest[std::size_t(i)] = rest_mm(nv.a) * (1 - nv.t) + rest_mm(nv.b) * nv.t;
    }
    std::vector<std::int32_t> removed = e.removed_tets;
    std::sort(removed.begin(), removed.end());
    for (std::size_t i = 0; i < removed.size(); ++i) {
        if (removed[i] < 0 || removed[i] >= t0)
            refuse("removed tet " + std::to_string(removed[i]) + " out of range");
        if (i > 0 && removed[i] == removed[i - 1])
            refuse("tet " + std::to_string(removed[i]) + " removed twice");
    }
    if (e.added_labels.size() != e.added_tets.size())
        refuse(std::to_string(e.added_tets.size()) + " added tets but " + std::to_string(e.added_labels.size()) + " labels");
    std::unordered_map<std::int32_t, int> delta; // change of each vertex's tet count
    for (auto t : removed)
        for (auto v : mesh_.tets[std::size_t(t)])
            --delta[v];
    for (std::size_t i = 0; i < e.added_tets.size(); ++i) {
        const auto& q = e.added_tets[i];
        for (int a = 0; a < 4; ++a) {
            if (q[std::size_t(a)] < 0 || q[std::size_t(a)] >= n1)
                refuse("added tet " + std::to_string(i) + " has a vertex out of range");
            for (int b = a + 1; b < 4; ++b)
                if (q[std::size_t(a)] == q[std::size_t(b)])
                    refuse("added tet " + std::to_string(i) + " repeats a vertex");
        }
        if (std::none_of(params_.tissues.begin(), params_.tissues.end(),
                         [&](const TissueMaterial& m) { return m.label == e.added_labels[i]; }))
            refuse("added tet " + std::to_string(i) + " has tissue label " + std::to_string(e.added_labels[i]) +
                   ", which has no material");
        const double v = core::signed_volume(rest_mm(q[0]), rest_mm(q[1]), rest_mm(q[2]), rest_mm(q[3]));
        if (!(v > 0))
            refuse("added tet " + std::to_string(i) + " is not positively oriented in the rest shape (volume " +
                   std::to_string(v) + " mm^3)");
        for (auto w : q)
            ++delta[w];
    }
    auto tets_after = [&](std::int32_t v) {
        const auto it = delta.find(v);
        return (v < n0 ? int(vertex_tets_[std::size_t(v)].size()) : 0) + (it == delta.end() ? 0 : it->second);
    };
    std::vector<std::int32_t> gone = e.removed_vertices;
    std::sort(gone.begin(), gone.end());
    for (std::size_t i = 0; i < gone.size(); ++i) {
        if (gone[i] < 0 || gone[i] >= n1)
            refuse("removed vertex " + std::to_string(gone[i]) + " out of range");
        if (i > 0 && gone[i] == gone[i - 1])
            refuse("vertex " + std::to_string(gone[i]) + " removed twice");
        if (tets_after(gone[i]) != 0)
            refuse("removed vertex " + std::to_string(gone[i]) + " is still in a tet");
    }
    for (std::int32_t v = n0; v < n1; ++v)
        if (tets_after(v) == 0 && !std::binary_search(gone.begin(), gone.end(), v))
            refuse("new vertex " + std::to_string(v - n0) + " is in no tet");
    for (const auto& [v, d] : delta)
        if (v < n0 && tets_after(v) == 0 && !std::binary_search(gone.begin(), gone.end(), v))
            refuse("vertex " + std::to_string(v) + " would be left in no tet");

    // ---- new vertices ------------------------------------------------------------------------
    EditResult result;
    result.first_new_vertex = n0;
    std::vector<std::int32_t> nodes;     // whose mass changes
    std::vector<std::uint64_t> edges;    // whose tets change
    std::vector<std::uint64_t> faces;    // whose tets change
    for (std::int32_t i = 0; i < nn; ++i) {
        const auto& nv = e.new_vertices[std::size_t(i)];
        mesh_.vertices.push_back(new_rest[std::size_t(i)]);
        for (int c = 0; c < 3; ++c) {
            rest_.push_back(new_rest[std::size_t(i)][c] * kMmToM);
            st.x.push_back(st.x[3 * std::size_t(nv.a) + std::size_t(c)] * (1 - nv.t) + st.x[3 * std::size_t(nv.b) + std::size_t(c)] * nv.t);
            st.v.push_back(st.v[3 * std::size_t(nv.a) + std::size_t(c)] * (1 - nv.t) + st.v[3 * std::size_t(nv.b) + std::size_t(c)] * nv.t);
        }
        mass_.push_back(0);
        inv_mass_.push_back(0);
        fixed_.push_back(fixed_[std::size_t(nv.a)] && fixed_[std::size_t(nv.b)] ? 1 : 0);
        vertex_tets_.emplace_back();
    }

    auto touch = [&](const std::array<std::int32_t, 4>& q) {
        for (auto v : q)
            nodes.push_back(v);
        for (const auto& d : kTetEdges)
            edges.push_back(edge_key(q[std::size_t(d[0])], q[std::size_t(d[1])]));
        for (const auto& f : kTetFaces)
            faces.push_back(face_key(q[std::size_t(f[0])], q[std::size_t(f[1])], q[std::size_t(f[2])]));
    };

    // ---- removed tets: the last tet moves into each hole (largest index first, so that the
    // tet that moves is never one still to be removed) ---------------------------------------
    for (auto r = removed.rbegin(); r != removed.rend(); ++r) {
        const auto t = *r;
        const auto q = mesh_.tets[std::size_t(t)];
        touch(q);
        for (auto v : q) {
            auto& list = vertex_tets_[std::size_t(v)];
            list.erase(std::find(list.begin(), list.end(), t));
        }
        const auto last = std::int32_t(mesh_.tets.size()) - 1;
        if (t != last) {
            const auto moved = mesh_.tets[std::size_t(last)];
            mesh_.tets[std::size_t(t)] = moved;
            mesh_.tet_labels[std::size_t(t)] = mesh_.tet_labels[std::size_t(last)];
            tet_e_[std::size_t(t)] = tet_e_[std::size_t(last)];
            tet_v0_[std::size_t(t)] = tet_v0_[std::size_t(last)];
            tet_kv_[std::size_t(t)] = tet_kv_[std::size_t(last)];
            tet_density_[std::size_t(t)] = tet_density_[std::size_t(last)];
            if (!tet_dm_inv_.empty())
                std::copy_n(tet_dm_inv_.begin() + 9 * std::ptrdiff_t(last), 9, tet_dm_inv_.begin() + 9 * std::ptrdiff_t(t));
            for (auto v : moved)
                std::replace(vertex_tets_[std::size_t(v)].begin(), vertex_tets_[std::size_t(v)].end(), last, t);
            for (const auto& f : kTetFaces) {
                const auto it = face_slot_.find(face_key(moved[std::size_t(f[0])], moved[std::size_t(f[1])], moved[std::size_t(f[2])]));
                if (it != face_slot_.end() && surface_face_tets_[std::size_t(it->second)] == last)
                    surface_face_tets_[std::size_t(it->second)] = t;
            }
            result.moved_tets.emplace_back(last, t);
        }
        mesh_.tets.pop_back();
        mesh_.tet_labels.pop_back();
        tet_e_.pop_back();
        tet_v0_.pop_back();
        tet_kv_.pop_back();
        tet_density_.pop_back();
        if (!tet_dm_inv_.empty())
            tet_dm_inv_.resize(tet_dm_inv_.size() - 9);
    }

    // ---- added tets --------------------------------------------------------------------------
    result.first_new_tet = std::int32_t(mesh_.tets.size());
    for (std::size_t i = 0; i < e.added_tets.size(); ++i) {
        const auto t = mesh_.tets.size();
        mesh_.tets.push_back(e.added_tets[i]);
        mesh_.tet_labels.push_back(e.added_labels[i]);
        tet_e_.push_back(0);
        tet_v0_.push_back(0);
        tet_kv_.push_back(0);
        tet_density_.push_back(0);
        if (params_.formulation != Formulation::MassSpring)
            tet_dm_inv_.resize(tet_dm_inv_.size() + 9);
        set_tet(t);
        for (auto v : e.added_tets[i])
            vertex_tets_[std::size_t(v)].push_back(std::int32_t(t));
        touch(e.added_tets[i]);
    }

    // ---- masses of the touched nodes, from the tets now around them (exact: no drift) -----
    unique_sorted(nodes);
    for (auto v : nodes) {
        double m = 0;
        for (auto t : vertex_tets_[std::size_t(v)])
            m += tet_density_[std::size_t(t)] * tet_v0_[std::size_t(t)] / 4;
        mass_[std::size_t(v)] = m;
        inv_mass_[std::size_t(v)] = fixed_[std::size_t(v)] || m == 0 ? 0 : 1 / m;
    }

    // ---- springs of the touched edges: sums over the tets around each edge ----------------
    unique_sorted(edges);
    for (auto key : edges) {
        const auto a = edge_first(key), b = edge_second(key);
        double sum_e = 0, sum_ev = 0;
        int count = 0;
        for (auto t : vertex_tets_[std::size_t(a)])
            if (contains(mesh_.tets[std::size_t(t)], b)) {
                sum_e += tet_e_[std::size_t(t)];
                sum_ev += tet_e_[std::size_t(t)] * tet_v0_[std::size_t(t)];
                ++count;
            }
        const auto it = edge_slot_.find(key);
        if (count == 0) {
            if (it != edge_slot_.end())
                remove_spring(std::size_t(it->second));
            continue;
        }
        std::size_t k = 0;
        if (it != edge_slot_.end()) {
            k = std::size_t(it->second);
        } else {
            k = springs_.size();
            double l2 = 0;
            for (std::size_t c = 0; c < 3; ++c) {
                const double d = rest_[3 * std::size_t(b) + c] - rest_[3 * std::size_t(a) + c];
                l2 += d * d;
            }
            springs_.a.push_back(a);
            springs_.b.push_back(b);
            springs_.rest_length.push_back(std::sqrt(l2));
            springs_.stiffness.push_back(0);
            springs_.damping.push_back(0);
            spring_sum_e_.push_back(0);
            spring_sum_ev_.push_back(0);
            spring_count_.push_back(0);
            if (params_.formulation != Formulation::MassSpring)
                fem_k_.push_back(0);
            edge_slot_.emplace(key, std::int32_t(k));
        }
        spring_sum_e_[k] = sum_e;
        spring_sum_ev_[k] = sum_ev;
        spring_count_[k] = count;
    }
    // Stiffness and damping of every spring at a touched node (damping follows the masses).
    std::unordered_set<std::int32_t> redo;
    for (auto v : nodes)
        for (auto t : vertex_tets_[std::size_t(v)])
            for (auto w : mesh_.tets[std::size_t(t)])
                if (w != v)
                    redo.insert(edge_slot_.at(edge_key(v, w)));
    // Paloc's bound (min m/k over the springs) and the shortest edge follow the changed
    // springs alone, so an edit costs what it touches, not the mesh.
    double ratio = std::numeric_limits<double>::infinity(), shortest = ratio;
    for (auto k : redo) {
        set_spring(std::size_t(k));
        const auto a = std::size_t(springs_.a[std::size_t(k)]), b = std::size_t(springs_.b[std::size_t(k)]);
        ratio = std::min(ratio, std::min(mass_[a], mass_[b]) / springs_.stiffness[std::size_t(k)]);
        shortest = std::min(shortest, springs_.rest_length[std::size_t(k)]);
    }

    // ---- boundary faces ----------------------------------------------------------------------
    unique_sorted(faces);
    for (auto key : faces)
        refresh_face(key);

    // ---- removed vertices: the last vertex moves into each hole -----------------------------
    for (auto r = gone.rbegin(); r != gone.rend(); ++r) {
        const auto v = *r;
        const auto last = std::int32_t(mass_.size()) - 1;
        if (v != last) {
            // Everything that names `last` is found from the tets around it.
            for (auto t : vertex_tets_[std::size_t(last)]) {
                auto& q = mesh_.tets[std::size_t(t)];
                for (auto w : q) {
                    if (w == last)
                        continue;
                    const auto it = edge_slot_.find(edge_key(last, w));
                    if (it == edge_slot_.end())
                        continue; // renamed through an earlier tet
                    const auto k = std::size_t(it->second);
                    edge_slot_.erase(it);
                    springs_.a[k] = std::min(v, w);
                    springs_.b[k] = std::max(v, w);
                    edge_slot_.emplace(edge_key(v, w), std::int32_t(k));
                }
                for (const auto& f : kTetFaces) {
                    std::array<std::int32_t, 3> g{q[std::size_t(f[0])], q[std::size_t(f[1])], q[std::size_t(f[2])]};
                    if (g[0] != last && g[1] != last && g[2] != last)
                        continue;
                    const auto it = face_slot_.find(face_key(g[0], g[1], g[2]));
                    if (it == face_slot_.end())
                        continue;
                    const auto slot = it->second;
                    face_slot_.erase(it);
                    for (auto& x : surface_faces_[std::size_t(slot)])
                        if (x == last)
                            x = v;
                    const auto& h = surface_faces_[std::size_t(slot)];
                    face_slot_.emplace(face_key(h[0], h[1], h[2]), slot);
                }
                replace(q, last, v);
            }
            mesh_.vertices[std::size_t(v)] = mesh_.vertices[std::size_t(last)];
            for (std::size_t c = 0; c < 3; ++c) {
                rest_[3 * std::size_t(v) + c] = rest_[3 * std::size_t(last) + c];
                st.x[3 * std::size_t(v) + c] = st.x[3 * std::size_t(last) + c];
                st.v[3 * std::size_t(v) + c] = st.v[3 * std::size_t(last) + c];
            }
            mass_[std::size_t(v)] = mass_[std::size_t(last)];
            inv_mass_[std::size_t(v)] = inv_mass_[std::size_t(last)];
            fixed_[std::size_t(v)] = fixed_[std::size_t(last)];
            vertex_tets_[std::size_t(v)] = std::move(vertex_tets_[std::size_t(last)]);
            result.moved_vertices.emplace_back(last, v);
        }
        mesh_.vertices.pop_back();
        rest_.resize(rest_.size() - 3);
        st.x.resize(st.x.size() - 3);
        st.v.resize(st.v.size() - 3);
        mass_.pop_back();
        inv_mass_.pop_back();
        fixed_.pop_back();
        vertex_tets_.pop_back();
    }

    surface_nodes_stale_ = true;
    gershgorin_stale_ = true; // only reported: recomputed in full when asked
    // The springs an edit removes can only raise the true minimum, so the running minimum errs
    // on the safe side (a step no longer than the exact bound); an edit that removes vertices
    // (coarsening) makes elements larger again and recomputes the bounds over the whole mesh.
    if (!gone.empty())
        bounds_stale_ = true;
    else if (!bounds_stale_) {
        dt_critical_ = std::min(dt_critical_, kPi * std::sqrt(ratio));
        min_edge_ = std::min(min_edge_, shortest);
    }
    return result;
}

core::Vec3 Model::boundary_normal(std::int32_t v, const State& s) const
{
    core::Vec3 n{0, 0, 0};
    for (auto t : vertex_tets_[std::size_t(v)]) {
        const auto& q = mesh_.tets[std::size_t(t)];
        for (const auto& f : kTetFaces) {
            const std::array<std::int32_t, 3> g{q[std::size_t(f[0])], q[std::size_t(f[1])], q[std::size_t(f[2])]};
            if (g[0] != v && g[1] != v && g[2] != v)
                continue;
            const auto it = face_slot_.find(face_key(g[0], g[1], g[2]));
            if (it == face_slot_.end() || surface_face_tets_[std::size_t(it->second)] != t)
                continue;
            const core::Vec3 p0 = s.position_mm(std::size_t(g[0])), p1 = s.position_mm(std::size_t(g[1])),
                             p2 = s.position_mm(std::size_t(g[2]));
            n += cross(p1 - p0, p2 - p0); // twice the area, outward (kTetFaces orientation)
        }
    }
    const double l = norm(n);
    return l > 0 ? n / l : core::Vec3{0, 0, 0};
}

} // namespace lobe::mss
