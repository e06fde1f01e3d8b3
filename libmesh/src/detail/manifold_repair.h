#pragma once
// Private to libmesh: makes every label's region of a labelled tetrahedralisation a manifold
// solid by relabelling a few cells. Why and how: docs/algorithms/meshing.md, "Manifold repair".

#include "lobe/core/types.h"

#include <array>
#include <cstdint>
#include <vector>

namespace lobe::mesh::detail {

//! A tetrahedralisation of a convex region (all finite cells of a Delaunay triangulation),
//! labelled: 0 is outside the domain, > 0 a tissue.
struct LabelledCells {
    std::vector<core::Vec3> vertices;
    std::vector<std::array<std::int32_t, 4>> cells;
    //! neighbours[c][i]: the cell across the face opposite cells[c][i], -1 outside the hull
    std::vector<std::array<std::int32_t, 4>> neighbours;
    std::vector<int> labels;
    //! cells whose label must not change (the cells outside the domain: turning one into tissue
    //! would add an element the mesher never refined)
    std::vector<char> fixed;
};

struct ManifoldRepairStats {
    std::int64_t bad_vertices_before = 0; //!< vertices where some label's region is not a disc
    std::int64_t bad_vertices_after = 0;  //!< the same once repaired (0 unless a fix was blocked)
    std::int64_t relabelled = 0;          //!< cells whose label changed
    std::int64_t removed = 0;             //!< of which became outside (label 0)
    double volume = 0;                    //!< their total volume [mm^3]
};

//! Number of vertices at which some label's cells (label 0 and the outside of the hull
//! included) do not form one disc in the vertex's link, i.e. where a tissue surface or the
//! outer surface is non-manifold (an edge or a vertex where a region touches itself).
std::int64_t count_non_manifold_vertices(const LabelledCells& m);

//! Relabels cells until every label's region is manifold at every vertex: at a bad vertex, the
//! cheapest (by volume) of dropping a stray piece of a label into its neighbour, filling a
//! pocket, or opening a bridge of cells between two pieces. Fixed cells never change and
//! every other cell changes at most four times, so the repair terminates; a vertex whose fixes
//! are all blocked stays bad and is counted in bad_vertices_after.
ManifoldRepairStats repair_manifold(LabelledCells& m);

struct PeelStats {
    std::int64_t tets = 0;
    double volume = 0; //!< [mm^3]
};

//! Sets to 0 (outside) and fixes every tissue cell whose smallest dihedral angle is below
//! `min_angle_deg`, that has a face on the outside (label 0) and whose four vertices all lie on
//! faces between different labels: a flat cap on the outer boundary.
PeelStats peel_boundary_slivers(LabelledCells& m, double min_angle_deg);

} // namespace lobe::mesh::detail
