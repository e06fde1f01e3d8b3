#pragma once
// Progressive cutting by a scalpel blade (docs/algorithms/instruments.md, "Cutting"): the
// surface the blade's edge sweeps, the edge splits where it crosses the mesh, the separation of
// the tissue along the crossed faces, and the constraint that keeps the two lips of a cut from
// passing through each other.

#include "lobe/mss/instrument.h"
#include "lobe/mss/model.h"

#include <array>
#include <cstdint>
#include <utility>
#include <vector>

namespace lobe::mss::detail {

// What one blade has done so far.
struct BladeState {
    BladeParams params;
    bool started = false;
    std::pair<core::Vec3, core::Vec3> last{}; // edge at the last update [mm]
    std::vector<std::array<core::Vec3, 3>> swept; // triangles swept so far, in space [mm]
    std::vector<std::uint64_t> cut_faces;        // sorted: faces declared cut, not yet separated
    std::vector<char> on;                        // per vertex: lies on this blade's cut surface
    double d_min_mm = 0;
};

struct CutReport {
    int splits = 0;     // edges split where the swept surface crosses them
    int snapped = 0;    // crossings moved onto a vertex (snap or d_min)
    int faces = 0;      // faces newly declared cut
    int separated = 0;  // vertex copies made along cut faces
    bool changed() const { return splits > 0 || separated > 0; }
};

class Cutting {
public:
    // Cuts along the surface blade b swept since its last update, up to its pose at time t.
    CutReport cut(Model& model, State& state, BladeState& blade, double t);

    // Keeps the lips of cuts from passing through each other: a vertex of a cut face that has
    // gone behind another cut face (within half an edge, over the face) is projected back onto
    // it, the face's vertices taking their share by mass, with an inelastic velocity correction
    // (momentum is kept). Faces that touch the vertex's own neighbourhood are not obstacles.
    // Returns the corrections made; `before`, if given, receives the state as it was before the
    // first of them (left alone when there is none).
    int keep_apart(const Model& model, State& state, State* before = nullptr);

    // Rebuilds the list of cut faces (boundary faces with every vertex on a cut) after a change.
    void refresh_lips(const Model& model);
    // Finds, for each lip vertex, the lip faces it could cross before the next refresh (within
    // an edge, facing it): the per-step check then looks at these pairs only. Called after
    // refresh_lips and at every topology update (every few ms of simulated time).
    void refresh_candidates(const State& state);
    const std::vector<std::array<std::int32_t, 3>>& lips() const { return lips_; }

    // Follows a renumbering of the vertices (old, new), in order.
    void renumber(const std::vector<std::pair<std::int32_t, std::int32_t>>& moved, std::vector<BladeState>& blades);

    bool on_cut(std::int32_t v) const { return std::size_t(v) < on_cut_.size() && on_cut_[std::size_t(v)]; }

private:
    // Per lip vertex (in lip_vertices_ order), the sum of its lip faces' area vectors in `state`:
    // the direction its lip faces.
    std::vector<core::Vec3> lip_normals(const State& state) const;

    std::vector<char> on_cut_;                       // per vertex: lies on a cut surface
    std::vector<std::array<std::int32_t, 3>> lips_;  // boundary faces on cuts, outward
    std::vector<std::int32_t> lip_vertices_;  // sorted
    std::vector<std::array<std::int32_t, 3>> lip_slots_;  // each lip face's vertices in lip_vertices_
    std::vector<std::int32_t> ring_;          // per lip vertex: the vertices of its tets, sorted
    std::vector<std::size_t> ring_start_;
    std::vector<std::pair<std::int32_t, std::int32_t>> candidates_; // (lip vertex slot, lip face)
    double max_edge_mm_ = 0;
};

} // namespace lobe::mss::detail
