#pragma once
//! \file
//! \brief Quality improvement of a multi-tissue tet mesh on the thesis's combined measure,
//! restricted to a region of interest: topological flips (2-3, and edge removal, which includes
//! 3-2 and 4-4) and smoothing of the vertices inside one tissue, each accepted only when the
//! worst combined measure of the tets it touches rises. Every tissue interface and the outer
//! boundary are kept face for face, so the tissues' sub-domains (and volumes) do not change.
//! See docs/algorithms/meshing.md ("Quality improvement in the region of interest").
//! References: J. R. Shewchuk, "Two discrete optimization algorithms for the topological
//! improvement of tetrahedral meshes" (2002); B. M. Klingner, J. R. Shewchuk, "Aggressive
//! tetrahedral mesh improvement" (IMR 2007); L. Freitag, M. Jones, P. Plassmann, "An efficient
//! parallel algorithm for mesh smoothing" (IMR 1995).

#include "lobe/core/tet_mesh.h"
#include "lobe/mesh/region_of_interest.h"

#include <cstdint>

namespace lobe::mesh {

//! Options of improve_quality (and of the pass mesh_labels runs when it is given a region of
//! interest, MeshParams::improve).
struct ImproveParams {
    bool enabled = true;          //!< mesh_labels: run the pass when a region of interest is given
                                  //!< (never without one); improve_quality ignores it
    double target = 0.4;          //!< combined measure below which a tet is worked on; above the
                                  //!< issue's 0.3 so that the operations keep some margin
    double margin = 0;            //!< [mm] work on the tets whose centroid lies within this distance
                                  //!< of the region of interest
    int max_rounds = 8;           //!< rounds of (flips, smoothing, insertion) per stage; a stage
                                  //!< ends earlier when a round changes nothing
    bool raise_worst_last = true; //!< the first stage's changes must raise the worst tet they
                                  //!< replace without adding tets below 0.3; then a second stage
                                  //!< whose changes need only raise the worst (it may add a few
                                  //!< below 0.3: docs/algorithms/meshing.md)
    int smoothing_steps = 6;      //!< line-search steps per vertex and round
    double weight = 0.6;          //!< w of the combined measure (QualityParams::weight, thesis: 0.6)
    double min_dihedral = 10;     //!< [deg] a change may not leave a tet with a smallest dihedral
                                  //!< angle below this unless a tet it replaces was already lower
                                  //!< (so that the pass keeps what remove_slivers achieved); 0 = off
    bool interface_flips = true;  //!< also flip the interface across a bad tet with two faces on it
                                  //!< (see remove_slivers); moves the interface by a sliver's
                                  //!< thickness, so the tissue volumes change by its volume
    bool surface_moves = true;    //!< let a vertex inside one surface patch (outer boundary or one
                                  //!< interface, not a curve where they meet) slide along its
                                  //!< surface triangles, once per pass; the tissue volumes change
                                  //!< by the chords' sliver (ImproveStats::surface_move_volume)
};

//! Options of remove_slivers (and of the pass mesh_labels runs after CGAL's optimisers,
//! MeshParams::slivers).
struct SliverParams {
    bool enabled = true;         //!< mesh_labels: run the pass; remove_slivers ignores it
    double goal = 10;            //!< [deg] the smallest dihedral angle aimed for (the issue's bound);
                                 //!< a change may not add tets below it
    double target = 12;          //!< [deg] tets below this are worked on (CGAL's sliver bound)
    int max_rounds = 8;          //!< as ImproveParams::max_rounds
    int smoothing_steps = 6;     //!< as ImproveParams::smoothing_steps
    bool interface_flips = true; //!< a sliver with two faces on one interface (between its tissue
                                 //!< and one other) is given to the other tissue and the edge
                                 //!< between those faces removed: a 2-2 flip of the interface
                                 //!< surface, which moves it by at most the sliver's thickness
                                 //!< (held below 0.3 of its mean edge) and changes the two
                                 //!< tissues' volumes by the sliver's volume
    bool surface_moves = true;   //!< as ImproveParams::surface_moves
};

//! What improve_quality did. "In the region" counts the tets whose centroid lies in the region
//! of interest (distance 0, not the margin), as the benchmark does.
//! For remove_slivers the measure is the smallest dihedral angle [deg] and the goal params.goal.
struct ImproveStats {
    bool ran = false; //!< mesh_labels: whether the pass ran
    double goal = 0;  //!< what "below" counts under: 0.3 (combined), or SliverParams::goal [deg]
    std::int64_t tets_in_region_before = 0, tets_in_region_after = 0;
    std::int64_t below_before = 0, below_after = 0; //!< tets in the region below the goal (combined < 0.3)
    double worst_before = 0, worst_after = 0;       //!< smallest measure in the region
    std::int64_t below_after_pinned = 0;            //!< of below_after, tets whose four vertices all
                                                    //!< lie on surfaces (outer boundary, interfaces):
                                                    //!< smoothing cannot move them
    std::int64_t below_after_surface_face = 0;      //!< of below_after, tets with a face on a surface
    std::int64_t flips23 = 0;                       //!< 2-3 flips done
    std::int64_t edge_removals = 0;                 //!< edge removals done (3-2, 4-4, 5-6, ...)
    std::int64_t vertex_moves = 0;                  //!< smoothing moves accepted
    std::int64_t vertices_inserted = 0;             //!< vertices inserted inside a tissue
    std::int64_t interface_flips = 0;               //!< 2-2 flips of an interface (see SliverParams)
    double interface_flip_volume = 0;               //!< [mm^3] volume those flips moved between tissues
    std::int64_t surface_moves = 0;                 //!< surface vertices slid along their surface
    double surface_move_volume = 0;                 //!< [mm^3] volume those moves moved between tissues
                                                    //!< (or out of the mesh, on the outer boundary)
    int rounds = 0;                                 //!< rounds run
    double seconds = 0;                             //!< wall clock
};

struct ImproveResult {
    core::TetMesh mesh; //!< the improved mesh: the input's vertices (those on surfaces moved only
                        //!< along their surface), then the inserted ones; positively oriented
    ImproveStats stats;
};

//! Raises the worst combined measure (QualityParams' eq 6.16) of the tets of `mesh` inside
//! `roi` (Kind::None = the whole mesh). A face between two tets of one tissue may be flipped
//! (2-3), an edge all of whose tets belong to one tissue removed (n tets -> 2n-4), a vertex all
//! of whose tets belong to one tissue and which is not on the outer boundary moved, a vertex
//! inserted in a cavity of one tissue's tets; faces on the outer boundary or between two
//! tissues, and the vertices on them, never change. Every change is accepted only if the
//! smallest combined measure of the tets it replaces rises, so every tet stays positively
//! oriented and the worst tet the pass touches never gets worse (the region's worst could only
//! drop at its border, where a change started inside may replace a worse tet lying outside).
//! \pre core::mesh_problem(mesh) is empty. \throw core::InvalidInputError otherwise or for bad params.
ImproveResult improve_quality(const core::TetMesh& mesh, const RegionOfInterest& roi, const ImproveParams& params = {});

//! Raises the smallest dihedral angle of the tets of `mesh` below params.target degrees, over the
//! whole mesh, with the same operations as improve_quality on that objective (an inverted tet
//! counts below any angle), plus the interface flip of SliverParams::interface_flips. It is what
//! lets mesh_labels keep the worst dihedral above 10 degrees where CGAL's perturber stops early
//! (its parallel mode). The stats' "below" count the tets under params.goal and "worst" is in
//! degrees; the region is the whole mesh.
//! \pre core::mesh_problem(mesh) is empty. 	hrow core::InvalidInputError otherwise or for bad params.
ImproveResult remove_slivers(const core::TetMesh& mesh, const SliverParams& params = {});

} // namespace lobe::mesh
