#pragma once
//! \file
//! \brief Multi-tissue tetrahedral meshing of a label volume (CGAL Mesh_3 on a labelled-image
//! domain): one conforming mesh whose tets carry the tissue label, tissues sharing their
//! interface vertices. See docs/algorithms/meshing.md.

#include "lobe/core/image3d.h"
#include "lobe/core/tet_mesh.h"
#include "lobe/core/types.h"
#include "lobe/mesh/improve.h"
#include "lobe/mesh/region_of_interest.h"

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace lobe::mesh {

//! A per-tissue element size and boundary tolerance.
struct TissueSize {
    int label = 0;
    double size = 0;           //!< [mm], as MeshParams::size; 0 = MeshParams::size
    double facet_distance = 0; //!< how far the tissue's boundary facets may lie from its label
                               //!< surface [mm]; 0 = the default (MeshParams::distance_per_size)
};

//! Options of mesh_labels. Sizes are CGAL's: a bound on the circumradius of the tets and on the
//! radius of the surface Delaunay balls of the boundary facets (a regular tet of circumradius r
//! has edges of 1.63 r).
struct MeshParams {
    std::vector<int> tissues;             //!< labels to mesh; empty = every label 1..9 present.
                                          //!< Other labels count as background.
    double size = 0;                      //!< element size [mm]; 0 = 3 x the largest voxel spacing
    std::vector<TissueSize> tissue_sizes; //!< overrides of `size` per label
    double curvature_factor = 1.0;        //!< thesis: boundary element size <= factor x radius of
                                          //!< curvature, for radii >= min_feature_radius
    double min_feature_radius = 0;        //!< [mm] smallest curvature radius resolved; 0 = 1 voxel
    double distance_per_size = 0.2;       //!< a tissue's boundary tolerance is at most this x its
                                          //!< element size (and at most the curvature factor's),
                                          //!< so that tissues meshed finer (vessels) keep their
                                          //!< volume; TissueSize::facet_distance overrides it
    double facet_angle = 25;              //!< lower bound on surface facet angles [deg] (CGAL: <= 30)
    double radius_edge_ratio = 1.9;       //!< bound B on circumradius / shortest edge (< 2, thesis)
    double grading = 1.5;                 //!< max size ratio between neighbours for the ROI sizing
    RegionOfInterest roi;
    bool perturb = false;                 //!< CGAL's sliver perturbation: off, because the sliver
                                          //!< pass (slivers) reaches the same angles in a tenth of
                                          //!< its time (docs/benchmarks.md, meshing)
    bool exude = true;                    //!< CGAL sliver exudation
    bool lloyd = false;                   //!< Lloyd smoothing before perturb/exude (slow)
    bool odt = false;                     //!< ODT smoothing before perturb/exude (slow)
    double optimisation_time_limit = 30;  //!< per optimisation pass [s]; 0 = none
    double sliver_bound = 12;             //!< perturb/exude target: min dihedral angle [deg]
    bool peel_slivers = true;             //!< remove the tets flatter than sliver_bound that lie
                                          //!< on the outer boundary with all four vertices on
                                          //!< tissue surfaces (the exuder cannot remove them)
    bool repair_manifold = true;          //!< relabel the few tets where a tissue (or the whole
                                          //!< mesh) touches itself along an edge or at a vertex,
                                          //!< so that every tissue surface is a manifold
    SliverParams slivers;                 //!< after CGAL's optimisers and the peeling: flips,
                                          //!< smoothing and insertion on the tets whose smallest
                                          //!< dihedral angle is below slivers.target (improve.h)
    ImproveParams improve;                //!< quality improvement on the combined measure inside
                                          //!< the region of interest (improve.h): on by default,
                                          //!< runs only when a region of interest is given
    bool spatial_order = true;            //!< number the vertices along a Hilbert curve (CGAL's
                                          //!< hilbert_sort) and the tets by their vertices, so
                                          //!< that neighbours sit close in memory: a mass-spring
                                          //!< step of a 100 k-node mesh runs ~1.3x faster
    int min_component_voxels = 8;         //!< smaller connected components (6-connected) are
                                          //!< specks: relabelled to their neighbours' majority
    std::int64_t max_tets = 5'000'000;    //!< refuse requests estimated above this
    int threads = 0;                      //!< 0 = all cores (CGAL parallel mode, TBB; runs vary);
                                          //!< 1 = serial (runs repeat exactly)
    std::uint32_t seed = 0;               //!< seed of CGAL's random generator
    std::function<void(const std::string&)> progress; //!< optional stage messages
};

//! One 6-connected piece of one label.
struct ComponentReport {
    int label = 0;
    std::int64_t voxels = 0;
    double label_volume = 0;  //!< voxels x voxel volume [mm^3]
    double mesh_volume = 0;   //!< volume of this label's tets whose centroid lies in the piece's
                              //!< voxels or is nearest to them [mm^3]
    std::int64_t tets = 0;
    bool meshed = false;      //!< at least one tet of the label inside the piece
};

//! Per tissue: label volume against mesh volume.
struct TissueReport {
    int label = 0;
    std::int64_t voxels = 0;
    double label_volume = 0;  //!< [mm^3]
    double mesh_volume = 0;   //!< [mm^3]
    std::int64_t tets = 0;
    double size = 0;           //!< element size used [mm]
    double facet_distance = 0; //!< boundary tolerance used [mm]
    int components = 0;
    int components_meshed = 0;
    int specks_dropped = 0;   //!< components below min_component_voxels
};

struct MeshResult {
    core::TetMesh mesh;                     //!< physical space [mm], positively oriented, labelled
    std::vector<TissueReport> tissues;      //!< ascending label
    std::vector<ComponentReport> components;
    bool padded = false;                    //!< a tissue touched the volume border: padded by one
                                            //!< voxel of background so that it is closed there
    double size = 0;                        //!< the element size used [mm]
    //! Manifold repair (MeshParams::repair_manifold): vertices where a tissue's region or the
    //! whole mesh touched itself, before and after; the tets relabelled (to another tissue, or
    //! removed) and their volume. The tissue volumes above are those after the repair.
    struct ManifoldRepair {
        std::int64_t bad_vertices_before = 0, bad_vertices_after = 0;
        std::int64_t tets_relabelled = 0, tets_removed = 0;
        double volume = 0; //!< [mm^3]
    } manifold_repair;
    //! Boundary slivers removed (MeshParams::peel_slivers).
    struct Peeled {
        std::int64_t tets = 0;
        double volume = 0; //!< [mm^3]
    } peeled;
    ImproveStats slivers;                   //!< MeshParams::slivers (angles in degrees)
    ImproveStats improvement;               //!< MeshParams::improve (ran = false without a ROI)
    std::string optimisation;               //!< CGAL's perturber and exuder outcomes
    int threads = 1;                        //!< threads used
    std::vector<std::string> warnings;      //!< specks dropped, pieces not meshed, ...
};

//! Meshes the tissues of `labels`. The vertices are in the image's physical space (origin,
//! spacing, direction). Every 6-connected piece of min_component_voxels voxels or more gets
//! initial points on its boundary so that CGAL meshes it (result.components says which were).
//! \throw core::InvalidInputError if the volume has no voxel of the selected tissues, bad
//! parameters, or an estimated mesh above max_tets. \throw core::SolverError if CGAL fails.
MeshResult mesh_labels(const core::LabelImage3D& labels, const MeshParams& params = {});

//! Estimated tet count for `labels` with `params` (what max_tets is checked against).
std::int64_t estimate_tet_count(const core::LabelImage3D& labels, const MeshParams& params);

} // namespace lobe::mesh
