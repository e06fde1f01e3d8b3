#pragma once
//! \file
//! \brief Topology changes built from Model::apply: edge splits (the primitive of cutting and
//! refinement), the undo of a split (coarsening) and vertex duplication along cut faces
//! (docs/algorithms/instruments.md).

#include "lobe/mss/model.h"

#include <cstdint>
#include <vector>

namespace lobe::mss {

//! Edge (a, b) split at t in (0, 1): a new vertex on the edge (rest shape, position and velocity
//! interpolated), every tet around the edge replaced by its two halves (volumes t V and
//! (1 - t) V, so masses, volumes and momentum are conserved). Returns the new vertex.
//! \pre model.editing_enabled() or not (it is enabled)
//! \throw core::InvalidInputError if (a, b) is not an edge or t is not inside (0, 1)
std::int32_t split_edge(Model& model, State& state, std::int32_t a, std::int32_t b, double t);

//! Undoes split_edge: removes vertex m if its tets pair up as the halves of tets around an edge
//! (a, b) (same other two vertices and label), merging each pair back, provided the merged tets
//! are positively oriented in the current state. Returns false (and changes nothing) otherwise.
//! `moved` receives the renumbering of the edit (the last vertex takes m's index).
bool merge_split(Model& model, State& state, std::int32_t m, std::int32_t a, std::int32_t b,
                 std::vector<std::pair<std::int32_t, std::int32_t>>* moved = nullptr);

//! Splits vertex v into one copy per group of its tets that are connected through faces not in
//! `cut_faces` (packed keys of faces that are cut, see face_id()); the first group keeps v.
//! Returns the copies, one per further group (empty when the tets around v stay connected).
std::vector<std::int32_t> separate_vertex(Model& model, State& state, std::int32_t v,
                                          const std::vector<std::uint64_t>& cut_faces);

//! The packed key of face (a, b, c), independent of the vertex order.
std::uint64_t face_id(std::int32_t a, std::int32_t b, std::int32_t c);

//! Tets containing both a and b (needs editing enabled).
std::vector<std::int32_t> tets_around_edge(const Model& model, std::int32_t a, std::int32_t b);

} // namespace lobe::mss
