#pragma once
//! \file
//! \brief CentrelineGraph: the centre lines of a vessel tree as a graph of nodes (end points and
//! branch points) joined by edges (vessel segments), each edge with its polyline and radius.

#include "lobe/core/types.h"

#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

namespace lobe::core {

//! A node: an end point or a branch point of the centre lines.
struct CentrelineNode {
    Vec3 position;           //!< [mm, LPS]
    double radius_mm = 0;    //!< vessel radius there [mm]
};

//! An edge: the vessel segment between two nodes.
struct CentrelineEdge {
    std::int32_t from = 0;   //!< node index, the end nearer the tree's root
    std::int32_t to = 0;     //!< node index
    std::int32_t level = 0;  //!< branch level: 1 = trunk, 2 = its branches, ...; 0 = unknown
    std::int32_t label = 0;  //!< tissue label of the tree (2 portal vein, 3 hepatic veins; 0 = unknown)
    double radius_mm = 0;    //!< representative radius (the median along the edge) [mm]
    double length_mm = 0;    //!< length of the polyline [mm]
    std::string name;        //!< anatomical name where known ("RHV", "LPV", ...), else empty
    std::vector<Vec3> points;        //!< polyline from `from` to `to` inclusive [mm]; at least 2
    std::vector<double> point_radius; //!< radius at each point [mm]; same size as `points`
};

//! A centre-line graph (a forest: one tree per connected vessel system).
struct CentrelineGraph {
    std::vector<CentrelineNode> nodes;
    std::vector<CentrelineEdge> edges;
};

//! Why a graph is malformed, or an empty string: node indices in range, from != to, polylines
//! with at least two points and one radius per point, finite coordinates and radii >= 0.
inline std::string graph_problem(const CentrelineGraph& g)
{
    const auto n = static_cast<std::int64_t>(g.nodes.size());
    auto finite = [](const Vec3& p) { return std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z); };
    for (std::size_t i = 0; i < g.nodes.size(); ++i)
        if (!finite(g.nodes[i].position) || !(g.nodes[i].radius_mm >= 0) || !std::isfinite(g.nodes[i].radius_mm))
            return "node " + std::to_string(i) + " has a non-finite position or an invalid radius";
    for (std::size_t e = 0; e < g.edges.size(); ++e) {
        const auto& ed = g.edges[e];
        if (ed.from < 0 || ed.from >= n || ed.to < 0 || ed.to >= n)
            return "edge " + std::to_string(e) + " has a node index outside [0, " + std::to_string(n) + ")";
        if (ed.from == ed.to)
            return "edge " + std::to_string(e) + " joins node " + std::to_string(ed.from) + " to itself";
        if (ed.points.size() < 2)
            return "edge " + std::to_string(e) + " has fewer than two polyline points";
        if (ed.point_radius.size() != ed.points.size())
            return "edge " + std::to_string(e) + " has " + std::to_string(ed.point_radius.size()) + " radii for " +
                   std::to_string(ed.points.size()) + " points";
        for (std::size_t p = 0; p < ed.points.size(); ++p)
            if (!finite(ed.points[p]) || !(ed.point_radius[p] >= 0) || !std::isfinite(ed.point_radius[p]))
                return "edge " + std::to_string(e) + " has a non-finite point or an invalid radius";
        if (!(ed.radius_mm >= 0) || !std::isfinite(ed.radius_mm) || !(ed.length_mm >= 0) || !std::isfinite(ed.length_mm))
            return "edge " + std::to_string(e) + " has an invalid radius or length";
    }
    return {};
}

} // namespace lobe::core
