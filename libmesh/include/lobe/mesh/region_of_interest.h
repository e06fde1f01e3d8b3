#pragma once
//! \file
//! \brief The region of interest of a mesh: where mesh_labels refines (tetrahedralize.h) and
//! where improve_quality works (improve.h).

#include "lobe/core/types.h"

#include <vector>

namespace lobe::mesh {

//! Region of interest: the mesh is fine (roi.size) inside and coarsens outside it with the
//! distance d to the region as size(d) = roi.size + (grading - 1) d, capped by the tissue size,
//! so that neighbouring elements differ by at most the grading factor.
struct RegionOfInterest {
    enum class Kind { None, Box, Spheres };
    Kind kind = Kind::None;
    core::Vec3 box_lo, box_hi;       //!< Box: corners [mm, physical space]
    std::vector<core::Vec3> centres; //!< Spheres: centres [mm, physical space]
    double radius = 0;               //!< Spheres: radius [mm]
    double size = 0;                 //!< element size inside [mm]; 0 = MeshParams::size / 3
};

//! Distance [mm] from physical point `p` to the region (0 inside; 0 everywhere for Kind::None,
//! which stands for the whole space).
double distance_to_region(const RegionOfInterest& roi, const core::Vec3& p);

} // namespace lobe::mesh
