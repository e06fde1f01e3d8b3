#pragma once
//! \file
//! \brief 3-D skeletonisation of tubular masks into a centre-line graph: topology-preserving
//! curve thinning (directional sub-iterations deleting simple, non-end border voxels, after Lee,
//! Kashyap & Chu, CVGIP 56(6) 1994, with Bertrand & Malandain's topological numbers as the
//! simple-point test), then a graph of end and branch points with the polyline and radius (from
//! the Euclidean distance map) of every segment, spur pruning, and branch levels from a root.
//! See docs/algorithms/vessels.md.

#include "lobe/core/centreline_graph.h"
#include "lobe/core/image3d.h"

#include <cstddef>
#include <vector>

namespace lobe::seg {

//! Curve thinning of the non-zero voxels of `mask` (26-connected object, 6-connected
//! background): a one-voxel-wide skeleton (1) with the same number of components, cavities and
//! tunnels as the mask, whose curve ends stay where the object's extremities were. Works on
//! anisotropic grids (the peeling is symmetric in voxels, so centred in each axis).
//! \throw InvalidInputError on an invalid grid or a data size that does not match it.
core::LabelImage3D thin(const core::LabelImage3D& mask);

//! True if voxel (i, j, k) of `mask` (non-zero = object) is simple for (26, 6) connectivity:
//! removing it changes no topology (one 26-component of object neighbours, one 6-component of
//! background 18-neighbours touching it). Voxels outside the grid count as background.
bool is_simple_point(const core::LabelImage3D& mask, int i, int j, int k);

//! Inputs of `centreline_graph`.
struct CentrelineParams {
    //! A terminal segment (an end point to a branch point) is a spur and is pruned if it is
    //! shorter than max(min_spur_mm, spur_radius_factor × the radius at its branch point): the
    //! bumps of a noisy surface make short side curves that end inside the vessel's own radius.
    double min_spur_mm = 3.0;
    double spur_radius_factor = 1.5;
    //! Branch points joined by a segment shorter than junction_merge_factor × the larger of their
    //! radii are one branch point (thinning splits a thick bifurcation into two close ones).
    double junction_merge_factor = 1.0;
    //! Connected parts of the graph with less centre line than this in all are dropped (noise).
    double min_component_length_mm = 10.0;
    int max_prune_passes = 5;     //!< spur pruning repeats until nothing changes, at most this often
};

//! Counts of what `centreline_graph` removed.
struct CentrelineStats {
    std::size_t skeleton_voxels = 0;
    std::size_t spurs_pruned = 0;
    std::size_t junctions_merged = 0;
    std::size_t components_dropped = 0;
    std::size_t cycles_broken = 0;  //!< edges left out because they closed a loop
};

//! The graph of a skeleton (from `thin`). `distance_mm` is the Euclidean distance map of the
//! background (seg::euclidean_distance of the complement of the mask), from which each point's
//! radius is estimated as distance - half the finest spacing (the distance runs between voxel
//! centres; the wall lies half a voxel beyond the last object voxel). Levels and labels are left
//! 0; edges run from the end with the larger radius. \throw InvalidInputError on grid mismatches.
core::CentrelineGraph centreline_graph(const core::LabelImage3D& skeleton, const core::ImageF& distance_mm,
                                       const CentrelineParams& params = {}, CentrelineStats* stats = nullptr);

//! Orients the edges of the tree containing node `root` away from it and sets their branch level
//! and `label`. The edges leaving the root are level 1; at a branch point the children are one
//! level deeper, except that a branch point with exactly one child whose subtree holds at least
//! `min_branch_mm` of centre line (the others being shorter: side spurs, noise) is not counted,
//! and that child continues its parent's level. Edges of other trees are untouched.
//! \throw InvalidInputError if `root` is not a node of `graph`.
void assign_branch_levels(core::CentrelineGraph& graph, int root, int label, double min_branch_mm = 0.0);

//! Nodes per connected part of the graph (each part listed once, nodes ascending).
std::vector<std::vector<int>> graph_components(const core::CentrelineGraph& graph);

} // namespace lobe::seg
