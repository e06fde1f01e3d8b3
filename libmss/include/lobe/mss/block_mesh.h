#pragma once
//! \file
//! \brief Tetrahedral meshes of a box, for tests, benchmarks and demonstrations until meshes come
//! from lmesh: a grid of cubes (or cuboids), each split into 5 or 6 tets, conforming across cubes.

#include "lobe/core/tet_mesh.h"
#include "lobe/core/types.h"

#include <array>
#include <cstdint>

namespace lobe::mss {

//! The box and how it is cut.
struct BlockMeshParams {
    std::array<int, 3> cells{4, 4, 4}; //!< cuboids along x, y, z (each >= 1)
    core::Vec3 size{40, 40, 40};       //!< [mm]
    core::Vec3 origin{0, 0, 0};        //!< corner with the smallest coordinates [mm]
    int tets_per_cell = 6;             //!< 6 (Kuhn split along the main diagonal) or 5 (alternating)
    std::int32_t label = 1;            //!< tissue label of every tet
};

//! Vertex (i, j, k) of the grid has index i + (nx+1)*(j + (ny+1)*k).
//! \throw core::InvalidInputError for a bad cell count, size or split
core::TetMesh make_block_mesh(const BlockMeshParams& params = {});

//! Relabels every tet whose centroid lies within `radius_mm` of `centre_mm`; returns how many.
std::size_t label_sphere(core::TetMesh& mesh, const core::Vec3& centre_mm, double radius_mm, std::int32_t label);

} // namespace lobe::mss
