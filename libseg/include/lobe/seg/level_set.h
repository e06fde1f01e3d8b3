#pragma once
//! \file
//! \brief Narrow-band level-set evolution shared by every snake (thesis §4.11-4.12, eq. 4.29):
//!
//!     φ_t = ε g κ |∇φ|  -  P |∇φ|  -  V · ∇φ
//!
//! with φ a signed distance in mm, negative inside. The curvature term (central differences,
//! weighted by the stopping function g) smooths and shrinks convex bumps; the pressure P > 0
//! expands the contour (Osher-Sethian / Godunov entropy-satisfying upwind |∇φ|); the advection
//! field V moves the front along V (first-order upwind, eq. 4.32). Only voxels within the
//! narrow band δ2 are updated; φ is re-initialised to a signed distance when the front nears the
//! band's edge. One implementation serves 2-D (size[2] == 1) and 3-D grids; multiple contours,
//! splitting and merging come for free.

#include "lobe/core/image3d.h"
#include "lobe/seg/vector_field.h"

#include <cstdint>
#include <vector>

namespace lobe::seg {

//! The static speed terms (computed once from the image; thesis L3774). Pointers may be null:
//! a null term is absent. Non-null images must share φ's grid.
struct SpeedTerms {
    double curvature_weight = 0.0;          //!< ε [mm^2 per unit time]
    const core::ImageF* stopping = nullptr; //!< g multiplying the curvature term (null = 1)
    const core::ImageF* pressure = nullptr; //!< P [mm per unit time], > 0 expands
    const VectorField* advection = nullptr; //!< V along the index axes [mm per unit time]
};

//! Inputs of `evolve_level_set`.
struct LevelSetParams {
    int band_voxels = 4;            //!< δ2 half-width in voxels (of the largest spacing of the axes
                                    //!< longer than one voxel); at least 2
    double cfl = 0.7;               //!< Δt = cfl × the explicit stability bound of the terms present
    int max_iterations = 2000;      //!< hard bound: a run that reaches it returns converged = false
    int check_interval = 20;        //!< iterations between convergence checks
    double convergence_tolerance = 5e-3; //!< converged when the voxels whose inside/outside status
                                    //!< differs from the previous check, divided by the contour's
                                    //!< boundary voxels, stay below this for `convergence_checks`
                                    //!< checks in a row (a translating shape never converges)
    int convergence_checks = 2;
    //! Leak stop (0 = off). The measure is the net growth per check: voxels that became inside
    //! minus those that became outside, per boundary voxel. Once its lowest value is below
    //! `leak_slowdown` times its largest (the front has slowed at the edges), a growth that rises
    //! at this many checks in a row, ends above convergence_tolerance, and has risen from the
    //! lowest by more than the smaller of (`leak_rise` - 1) x the lowest and convergence_tolerance
    //! (the flicker level; a slow steady leak never rises 1.5x) is a part of the front that broke
    //! through a gap and spreads,
    //! growing its own front: the run ends and returns φ as it was at the lowest growth.
    int leak_checks = 0;
    double leak_slowdown = 0.25;
    double leak_rise = 1.5;
    //! The band's row runs are updated by a vectorised loop; false updates every voxel with the
    //! scalar code instead (the same arithmetic, hence the same bits: a check and a comparison).
    bool vectorise = true;
};

//! What `evolve_level_set` returns.
struct LevelSetResult {
    core::ImageF phi;          //!< final level set (signed distance in mm near the front, clamped far away)
    core::LabelImage3D mask;   //!< 1 where φ < 0
    int iterations = 0;
    bool converged = false;    //!< false: hit max_iterations, the front vanished, or the input was unusable
    int reinitialisations = 0;
    double time_step = 0.0;    //!< Δt used
    double last_change = 0.0;  //!< the last convergence measure (see convergence_tolerance)
    bool leak_stopped = false; //!< the leak stop ended the run (converged is false)
    int leak_iteration = 0;    //!< ... and φ is the one of this iteration
};

//! Evolves φ0 under `terms`. Non-finite values in φ0 or in a term are rejected up front.
//! \throw InvalidInputError on a grid mismatch, an empty grid, or non-finite input.
LevelSetResult evolve_level_set(const core::ImageF& phi0, const SpeedTerms& terms, const LevelSetParams& params = {});

//! Signed distance initialisation of a mask (thesis L3752-3756): negative inside, mm.
//! \throw InvalidInputError if the mask is empty or fills the whole grid.
core::ImageF initial_level_set(const core::LabelImage3D& mask);

//! Initial level set of balls of radius `radius_mm` around `seeds` (continuous voxel indices):
//! multiple seeds give multiple contours. \throw InvalidInputError if a seed lies outside the grid.
core::ImageF level_set_from_seeds(const core::ImageGeometry& grid, const std::vector<core::Vec3>& seeds, double radius_mm);

} // namespace lobe::seg
