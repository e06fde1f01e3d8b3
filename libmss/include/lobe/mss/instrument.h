#pragma once
//! \file
//! \brief Rigid instruments that touch the tissue. This issue has the probe: a sphere tip moving
//! along a scripted path; contact projects the surface nodes that enter the sphere back onto its
//! surface (no penetration of nodes) and the reaction force is the momentum that took
//! (docs/algorithms/mass_spring.md, "Probe").

#include "lobe/core/types.h"

#include <string>
#include <vector>

namespace lobe::mss {

//! One waypoint of a scripted path.
struct PathPoint {
    double time = 0;          //!< [s]
    core::Vec3 position_mm{}; //!< [mm]
};

//! A rigid sphere tip. Between waypoints it moves linearly; before the first it waits at the
//! first, after the last at the last.
struct ProbeParams {
    std::string name = "probe";
    double radius_mm = 5;        //!< tip radius [mm]; should exceed the surface edge length, since
                                 //!< only nodes are kept out (a smaller sphere slips between them)
    std::vector<PathPoint> path; //!< waypoints with strictly increasing times; at least one
};

//! Position of the probe's centre at time t [mm]. \pre params.path is not empty
core::Vec3 probe_position(const ProbeParams& params, double time);

//! \throw core::InvalidInputError if the path is empty, times do not increase, or a value is
//!        not finite or the radius not positive
void validate_probe(const ProbeParams& params);

} // namespace lobe::mss
