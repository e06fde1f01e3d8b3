#pragma once
//! \file
//! \brief Tissue boundary surfaces of a labelled tet mesh, Taubin smoothing, surface
//! remeshing and the checks a surface must pass (closed, manifold, consistently and outward
//! oriented, free of self-intersections). See docs/algorithms/meshing.md.

#include "lobe/core/tet_mesh.h"
#include "lobe/core/tri_mesh.h"

#include <cstdint>
#include <string>
#include <vector>

namespace lobe::mesh {

//! The boundary of one tissue: every tet face with a tet of the tissue on one side only,
//! oriented outward from the tissue. Interfaces between two tissues appear in both surfaces
//! (with opposite orientations) and share their vertices' positions exactly.
struct TissueSurface {
    int label = 0;        //!< 0 = the outer boundary of the whole mesh
    core::TriMesh surface;
};

//! Surfaces of every label present (ascending) and, first, the outer boundary (label 0).
//! \throw core::InvalidInputError if the mesh is malformed (core::mesh_problem).
std::vector<TissueSurface> tissue_surfaces(const core::TetMesh& mesh);

//! Options of Taubin's lambda|mu smoothing (G. Taubin, "A signal processing approach to fair
//! surface design", SIGGRAPH 1995): a shrinking step lambda then an inflating step mu < -lambda,
//! with the uniform (umbrella) Laplacian, so that the surface is smoothed without shrinking.
struct TaubinParams {
    int iterations = 10;  //!< lambda|mu pairs
    double lambda = 0.5;  //!< 0 < lambda < 1
    double mu = -0.53;    //!< mu < -lambda (pass band k_PB = 1/lambda + 1/mu = 0.113)
};

//! Smoothed copy of `surface` (same connectivity). \throw core::InvalidInputError on bad
//! parameters or a malformed surface.
core::TriMesh taubin_smooth(const core::TriMesh& surface, const TaubinParams& params = {});

//! CGAL's isotropic remeshing (Polygon_mesh_processing) to `target_edge` mm, keeping the
//! border. \throw core::InvalidInputError if the surface is not a polygon mesh or target_edge
//! is not positive.
core::TriMesh remesh_surface(const core::TriMesh& surface, double target_edge, int iterations = 3);

//! What check_surface found.
struct SurfaceCheck {
    std::int64_t vertices = 0, triangles = 0;
    std::int64_t boundary_edges = 0;        //!< edges with one triangle (0 = closed)
    std::int64_t non_manifold_edges = 0;    //!< edges with more than two triangles
    std::int64_t non_manifold_vertices = 0; //!< vertices whose link is not one disc/fan
    std::int64_t inconsistent_edges = 0;    //!< edges traversed in the same direction twice
    std::int64_t self_intersections = 0;    //!< pairs of intersecting non-adjacent triangles
    int components = 0;                     //!< connected components (by shared edges)
    double area = 0;                        //!< [mm^2]
    double volume = 0;                      //!< enclosed signed volume [mm^3] (> 0 = outward)
    double min_triangle_quality = 0;        //!< the thesis's normalised A^4/(sum l^2)^4
    double mean_triangle_quality = 0;

    bool closed() const { return boundary_edges == 0; }
    bool manifold() const { return non_manifold_edges == 0 && non_manifold_vertices == 0; }
    bool oriented() const { return inconsistent_edges == 0 && volume > 0; }
    bool ok() const { return closed() && manifold() && oriented() && self_intersections == 0; }
};

//! Checks a surface. Self-intersections are found with CGAL's box intersection
//! (Polygon_mesh_processing::self_intersections) when the surface is a polygon mesh.
//! \throw core::InvalidInputError if the surface is malformed (core::mesh_problem).
SurfaceCheck check_surface(const core::TriMesh& surface);

//! One line: "closed, manifold, oriented, no self-intersections: V vertices, T triangles, ..."
//! or what is wrong.
std::string describe(const SurfaceCheck& check);

} // namespace lobe::mesh
