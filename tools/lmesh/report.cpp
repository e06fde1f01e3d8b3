#include "lmesh/report.h"

#include <cstdio>
#include <sstream>

namespace lobe::lmesh {

namespace {

std::string name_of(const Report& r, int label)
{
    for (const auto& [l, n] : r.names)
        if (l == label)
            return n;
    return label == 0 ? "outer" : "tissue_" + std::to_string(label);
}

nlohmann::json summary_json(const mesh::MeasureSummary& s)
{
    return {{"min", s.min}, {"mean", s.mean}, {"max", s.max}, {"count", s.count},
            {"bands", {{"below_0.3", s.bands[0]}, {"0.3_0.5", s.bands[1]}, {"0.5_0.7", s.bands[2]}, {"above_0.7", s.bands[3]}}},
            {"histogram", s.histogram}};
}

nlohmann::json tissue_quality_json(const mesh::TissueQuality& t)
{
    nlohmann::json j{{"tets", t.tets},
                     {"volume_mm3", t.volume},
                     {"min_dihedral_deg", t.min_dihedral_deg},
                     {"max_dihedral_deg", t.max_dihedral_deg},
                     {"max_radius_edge_ratio", t.max_radius_edge_ratio}};
    for (int i = 0; i < mesh::kMeasureCount; ++i)
        j["measures"][mesh::measure_name(static_cast<mesh::Measure>(i))] = summary_json(t.measures[static_cast<std::size_t>(i)]);
    return j;
}

} // namespace

nlohmann::json report_json(const Report& r)
{
    const auto& res = *r.result;
    const auto& q = *r.quality;
    nlohmann::json j;
    j["input"] = r.input;
    j["seconds"] = r.seconds;
    j["mesh"] = {{"vertices", res.mesh.vertices.size()}, {"tets", res.mesh.tets.size()}, {"element_size_mm", res.size},
                 {"threads", res.threads}, {"padded", res.padded}, {"reference_edge_mm", q.reference_edge}};
    j["warnings"] = res.warnings;
    const auto& mr = res.manifold_repair;
    j["manifold_repair"] = {{"bad_vertices_before", mr.bad_vertices_before}, {"bad_vertices_after", mr.bad_vertices_after},
                            {"tets_relabelled", mr.tets_relabelled}, {"tets_removed", mr.tets_removed},
                            {"volume_mm3", mr.volume}};
    j["slivers_peeled"] = {{"tets", res.peeled.tets}, {"volume_mm3", res.peeled.volume}};
    j["optimisation"] = res.optimisation;
    if (const auto& sl = res.slivers; sl.ran)
        j["slivers"] = {{"seconds", sl.seconds},
                        {"rounds", sl.rounds},
                        {"flips23", sl.flips23},
                        {"edge_removals", sl.edge_removals},
                        {"vertex_moves", sl.vertex_moves},
                        {"vertices_inserted", sl.vertices_inserted},
                        {"interface_flips", sl.interface_flips},
                        {"interface_flip_volume_mm3", sl.interface_flip_volume},
                        {"surface_moves", sl.surface_moves},
                        {"surface_move_volume_mm3", sl.surface_move_volume},
                        {"below_goal_before", sl.below_before},
                        {"below_goal_after", sl.below_after},
                        {"below_goal_after_on_surfaces", sl.below_after_pinned},
                        {"below_goal_after_with_surface_face", sl.below_after_surface_face},
                        {"min_dihedral_before_deg", sl.worst_before},
                        {"min_dihedral_after_deg", sl.worst_after}};
    if (const auto& im = res.improvement; im.ran)
        j["roi_improvement"] = {{"seconds", im.seconds},
                                {"rounds", im.rounds},
                                {"flips23", im.flips23},
                                {"edge_removals", im.edge_removals},
                                {"vertex_moves", im.vertex_moves},
                                {"vertices_inserted", im.vertices_inserted},
                                {"interface_flips", im.interface_flips},
                                {"surface_moves", im.surface_moves},
                                {"roi_tets_before", im.tets_in_region_before},
                                {"roi_tets_after", im.tets_in_region_after},
                                {"roi_below_0.3_before", im.below_before},
                                {"roi_below_0.3_after", im.below_after},
                                {"roi_below_0.3_after_on_surfaces", im.below_after_pinned},
                                {"roi_below_0.3_after_with_surface_face", im.below_after_surface_face},
                                {"roi_min_combined_before", im.worst_before},
                                {"roi_min_combined_after", im.worst_after}};
    for (const auto& t : res.tissues) {
        nlohmann::json tj{{"label", t.label},
                          {"name", name_of(r, t.label)},
                          {"voxels", t.voxels},
                          {"label_volume_mm3", t.label_volume},
                          {"mesh_volume_mm3", t.mesh_volume},
                          {"volume_ratio", t.label_volume > 0 ? t.mesh_volume / t.label_volume : 0.0},
                          {"tets", t.tets},
                          {"element_size_mm", t.size},
                          {"facet_distance_mm", t.facet_distance},
                          {"components", t.components},
                          {"components_meshed", t.components_meshed},
                          {"specks_dropped", t.specks_dropped}};
        for (const auto& tq : q.tissues)
            if (tq.label == t.label)
                tj["quality"] = tissue_quality_json(tq);
        j["tissues"].push_back(tj);
    }
    j["quality"] = tissue_quality_json(q.all);
    for (const auto& c : res.components)
        j["components"].push_back({{"label", c.label}, {"voxels", c.voxels}, {"label_volume_mm3", c.label_volume},
                                   {"mesh_volume_mm3", c.mesh_volume}, {"tets", c.tets}, {"meshed", c.meshed}});
    for (const auto& w : q.worst)
        j["worst"].push_back({{"tet", w.tet}, {"label", w.label}, {"combined", w.combined},
                              {"min_dihedral_deg", w.min_dihedral_deg}, {"max_dihedral_deg", w.max_dihedral_deg},
                              {"centroid_mm", {w.centroid.x, w.centroid.y, w.centroid.z}}});
    for (const auto& s : r.surfaces)
        j["surfaces"].push_back({{"label", s.label},
                                 {"name", s.name},
                                 {"ok", s.check.ok()},
                                 {"closed", s.check.closed()},
                                 {"manifold", s.check.manifold()},
                                 {"oriented", s.check.oriented()},
                                 {"self_intersections", s.check.self_intersections},
                                 {"vertices", s.check.vertices},
                                 {"triangles", s.check.triangles},
                                 {"components", s.check.components},
                                 {"area_mm2", s.check.area},
                                 {"volume_mm3", s.check.volume},
                                 {"min_triangle_quality", s.check.min_triangle_quality},
                                 {"mean_triangle_quality", s.check.mean_triangle_quality}});
    return j;
}

std::string report_text(const Report& r)
{
    const auto& res = *r.result;
    std::ostringstream os;
    char buf[400];
    std::snprintf(buf, sizeof buf, "lmesh %s: %zu tets, %zu vertices, element size %.2f mm, %d thread(s), %.2f s\n",
                  r.input.c_str(), res.mesh.tets.size(), res.mesh.vertices.size(), res.size, res.threads, r.seconds);
    os << buf;
    os << "tissue            voxels   label mm^3    mesh mm^3   ratio     tets  pieces meshed/all\n";
    for (const auto& t : res.tissues) {
        std::snprintf(buf, sizeof buf, "%-14s %9lld %12.1f %12.1f %7.3f %8lld  %d/%d%s\n", name_of(r, t.label).c_str(),
                      static_cast<long long>(t.voxels), t.label_volume, t.mesh_volume,
                      t.label_volume > 0 ? t.mesh_volume / t.label_volume : 0.0, static_cast<long long>(t.tets),
                      t.components_meshed, t.components,
                      t.specks_dropped ? (" (" + std::to_string(t.specks_dropped) + " specks dropped)").c_str() : "");
        os << buf;
    }
    for (const auto& s : r.surfaces)
        os << "surface " << s.name << ": " << mesh::describe(s.check) << "\n";
    if (!res.optimisation.empty() || res.peeled.tets > 0) {
        std::snprintf(buf, sizeof buf, "optimisation: %s; %lld boundary slivers peeled (%.1f mm^3)\n",
                      res.optimisation.empty() ? "none" : res.optimisation.c_str(), static_cast<long long>(res.peeled.tets),
                      res.peeled.volume);
        os << buf;
    }
    if (const auto& sl = res.slivers; sl.ran) {
        std::snprintf(buf, sizeof buf,
                      "sliver pass: %lld tets below %.0f deg (smallest dihedral) before, %lld after (%lld with four "
                      "vertices on surfaces); worst %.2f -> %.2f deg; %lld 2-3 flips, %lld edge removals, %lld "
                      "interface flips (%.3f mm^3), %lld vertex moves, %lld surface moves (%.3f mm^3), %lld vertices "
                      "inserted, %.2f s\n",
                      static_cast<long long>(sl.below_before), sl.goal, static_cast<long long>(sl.below_after),
                      static_cast<long long>(sl.below_after_pinned), sl.worst_before, sl.worst_after,
                      static_cast<long long>(sl.flips23), static_cast<long long>(sl.edge_removals),
                      static_cast<long long>(sl.interface_flips), sl.interface_flip_volume,
                      static_cast<long long>(sl.vertex_moves), static_cast<long long>(sl.surface_moves),
                      sl.surface_move_volume, static_cast<long long>(sl.vertices_inserted), sl.seconds);
        os << buf;
    }
    if (const auto& im = res.improvement; im.ran) {
        std::snprintf(buf, sizeof buf,
                      "ROI quality pass: %lld of %lld tets below 0.3 (combined) before, %lld of %lld after (%lld with "
                      "four vertices on surfaces); worst %.3f -> %.3f; %lld 2-3 flips, %lld edge removals, %lld vertex "
                      "moves, %lld surface moves, %lld interface flips, %lld vertices inserted in %d rounds, %.2f s\n",
                      static_cast<long long>(im.below_before), static_cast<long long>(im.tets_in_region_before),
                      static_cast<long long>(im.below_after), static_cast<long long>(im.tets_in_region_after),
                      static_cast<long long>(im.below_after_pinned), im.worst_before, im.worst_after,
                      static_cast<long long>(im.flips23), static_cast<long long>(im.edge_removals),
                      static_cast<long long>(im.vertex_moves), static_cast<long long>(im.surface_moves),
                      static_cast<long long>(im.interface_flips), static_cast<long long>(im.vertices_inserted), im.rounds,
                      im.seconds);
        os << buf;
    }
    for (const auto& w : res.warnings)
        os << "warning: " << w << "\n";
    os << mesh::format_quality_report(*r.quality);
    return os.str();
}

} // namespace lobe::lmesh
