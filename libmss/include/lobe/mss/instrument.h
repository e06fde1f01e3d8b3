#pragma once
//! \file
//! \brief Rigid instruments on scripted paths: a probe (a sphere tip whose contact projects the
//! surface nodes that enter it back onto its surface; docs/algorithms/mass_spring.md, "Probe"),
//! forceps that grasp, pull and release, and a scalpel blade that cuts progressively; and the
//! on-the-fly refinement around them (docs/algorithms/instruments.md).

#include "lobe/core/types.h"

#include <functional>
#include <limits>
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

//! Laparoscopic forceps: the jaw centre follows a scripted path; when the jaws close, every free
//! surface node within jaw_radius_mm of the centre is held at its offset from the centre (a
//! position constraint, stable at any step) until the jaws open. The grasp force is the force of
//! the held tissue on the jaws; above max_force_n the tissue slips out, the most loaded node
//! first.
struct GraspParams {
    std::string name = "forceps";
    double jaw_radius_mm = 5;  //!< reach of the closed jaws [mm]; should exceed the surface edge length
    double close_time = 0;     //!< the jaws close at this time [s]
    double open_time = std::numeric_limits<double>::infinity(); //!< and open (release) at this one [s]
    double max_force_n = 5;    //!< the most the jaws hold [N] (a firm laparoscopic grasp holds a few N)
    std::vector<PathPoint> path; //!< the jaw centre; strictly increasing times, at least one point
};
//! \throw core::InvalidInputError for an empty path, times that do not increase, a value that is
//!        not finite, a radius or force that is not positive, or open_time before close_time
void validate_grasp(const GraspParams& params);

//! One pose of a scalpel's cutting edge, a segment from a_mm to b_mm.
struct BladePose {
    double time = 0;    //!< [s]
    core::Vec3 a_mm{};  //!< one end of the edge [mm]
    core::Vec3 b_mm{};  //!< the other end [mm]
};

//! A scalpel: an infinitely sharp segment on a scripted path of poses (linear in between). Each
//! topology update cuts the tissue along the surface the edge swept since the last one: it splits
//! the edges that surface crosses, then separates the tissue along the crossed faces
//! (docs/algorithms/instruments.md, "Cutting"). The blade exerts no force of its own.
struct BladeParams {
    std::string name = "scalpel";
    std::vector<BladePose> path; //!< strictly increasing times, at least one pose
    //! A crossing nearer than snap x the edge length to an end of the edge moves onto that end
    //! instead of splitting the edge: no part of a split is thinner than snap of its tet.
    double snap = 0.2;
    //! d_min [mm]: a crossing whose split would make an edge shorter than this snaps instead
    //! (0 = snap x the model's shortest edge at the start), so the time step stays bounded.
    double min_edge_mm = 0;
};
//! \throw core::InvalidInputError for an empty path, times that do not increase, a value that is
//!        not finite, a zero-length edge, or snap outside (0, 0.5)
void validate_blade(const BladeParams& params);

//! Position of the blade's edge at time t (a, b) [mm]. \pre params.path is not empty
std::pair<core::Vec3, core::Vec3> blade_position(const BladeParams& params, double time);
//! Position of the jaw centre at time t [mm]. \pre params.path is not empty
core::Vec3 grasp_position(const GraspParams& params, double time);

//! Quality of a tetrahedron (a, b, c, d) [mm], 1 for the regular one, <= 0 for a degenerate or
//! inverted one. lsim passes libmesh's implementation of the thesis's fast measure (eq 6.17); a
//! library that cannot depend on libmesh takes it as a function.
using TetQuality = std::function<double(const core::Vec3&, const core::Vec3&, const core::Vec3&, const core::Vec3&)>;

//! On-the-fly local refinement (model no more than a scene needs): around each instrument the
//! mesh is refined by edge bisection, with the halves' quality checked and no edge shorter than
//! d_min, and coarsened back (the bisections undone, newest first) once every instrument has left
//! (docs/algorithms/instruments.md, "Refinement").
struct RefineParams {
    bool enabled = false;
    //! Reach of the region around each instrument, beyond its own radius (a probe's or the jaws')
    //! or its edge (a blade) [mm]; 0 = twice the mean rest edge length.
    double margin_mm = 0;
    double edge_mm = 0;     //!< split rest edges longer than this in the region [mm] (0 = half the mean edge)
    double min_edge_mm = 0; //!< d_min [mm]: no split makes a shorter edge (0 = half the shortest edge at the start)
    double min_quality = 0.1; //!< every half must score at least this (rest and current shape) by `quality`
    TetQuality quality;       //!< empty: the halves' quality is not checked
    double coarsen_factor = 2; //!< undo a split once no instrument is within this x the region's reach (hysteresis)
    int max_splits = 500;     //!< per topology update, longest edges first
};

} // namespace lobe::mss
