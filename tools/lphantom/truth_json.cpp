#include "lphantom/truth_json.h"

namespace lobe::phantom {

namespace {

nlohmann::ordered_json vec(const core::Vec3& v) { return {v.x, v.y, v.z}; }

} // namespace

nlohmann::ordered_json truth_json(const phantom::PhantomParams& p, const phantom::PhantomResult& r,
                                  const std::string& command, const tools::Timings& timings)
{
    using nlohmann::ordered_json;
    ordered_json j;
    j["generator"] = "lphantom";
    j["lobe_version"] = LOBE_VERSION_STRING;
    j["command"] = command;
    ordered_json& par = j["parameters"];
    par["size"] = p.size;
    par["spacing_mm"] = p.spacing;
    par["center_mm"] = p.center;
    par["seed"] = p.seed;
    par["noise_sigma_hu"] = p.noise_sigma_hu;
    par["blur_sigma_mm"] = p.blur_sigma_mm;
    par["supersample_mm"] = p.supersample_mm;
    par["tumours"] = p.tumours;
    par["vessels"] = p.vessels;
    par["fissure_width_voxels"] = p.fissure_width_voxels;
    par["odd_fissure_width_voxels"] = p.odd_fissure_width_voxels;
    par["vessel_radius_mm"] = p.vessel_radius_mm;
    par["contact_line_mm"] = p.contact_line_mm;
    par["tumour_contrast_hu"] = p.tumour_contrast_hu;
    const phantom::PhantomHu& h = p.hu;
    par["hu"] = {{"air", h.air}, {"lung", h.lung}, {"fat", h.fat}, {"skin", h.skin}, {"muscle", h.muscle},
                 {"subcostal", h.subcostal}, {"bone_cortex", h.bone_cortex}, {"bone_marrow", h.bone_marrow},
                 {"cartilage", h.cartilage}, {"disc", h.disc}, {"csf", h.csf}, {"liver", h.liver},
                 {"portal_vein", h.portal_vein}, {"hepatic_vein", h.hepatic_vein}, {"ivc", h.ivc},
                 {"aorta", h.aorta}, {"heart_wall", h.heart_wall}, {"heart_blood", h.heart_blood},
                 {"kidney", h.kidney}, {"contact_line", h.contact_line}, {"spleen", h.spleen},
                 {"bowel", h.bowel}, {"pancreas", h.pancreas}, {"stomach_wall", h.stomach_wall},
                 {"stomach_fluid", h.stomach_fluid}, {"gas", h.gas}, {"bile", h.bile},
                 {"mediastinal_fat", h.mediastinal_fat}};
    j["geometry"] = {{"size", r.ct.size}, {"spacing_mm", r.ct.spacing}, {"origin_mm", r.ct.origin},
                     {"direction", r.ct.direction}, {"frame", "LPS"}};
    for (const auto& l : phantom::label_table())
        j["labels"].push_back({{"value", l.label}, {"name", l.name}, {"description", l.description}});
    j["liver"] = {{"mask_labels", {1, 2, 3, 4}}, {"volume_ml", r.truth.liver_volume_ml}};
    j["tumours"] = ordered_json::array();
    for (const auto& t : r.truth.tumours)
        j["tumours"].push_back({{"name", t.name}, {"centroid_mm", vec(t.centroid)}, {"volume_ml", t.volume_ml},
                                {"equivalent_radius_mm", t.equivalent_radius_mm}, {"contrast_hu", t.contrast_hu},
                                {"touches_boundary", t.touches_boundary}});
    ordered_json& v = j["vessels"];
    v["nodes"] = ordered_json::array();
    v["edges"] = ordered_json::array();
    for (const auto& n : r.truth.vessel_nodes)
        v["nodes"].push_back({{"position_mm", vec(n.position)}, {"radius_mm", n.radius_mm}});
    for (const auto& e : r.truth.vessel_edges)
        v["edges"].push_back({{"from", e.from}, {"to", e.to}, {"level", e.level},
                              {"tree", e.tree == phantom::VesselTree::Portal ? "portal" : "hepatic"},
                              {"radius_mm", e.radius_mm}, {"length_mm", e.length_mm},
                              {"inside_liver", e.inside_liver}});
    j["features"] = {{"ivc_neck_width_mm", r.truth.ivc_neck_width_mm},
                     {"ivc_body_width_mm", r.truth.ivc_body_width_mm},
                     {"fissure_width_mm", r.truth.fissure_width_mm},
                     {"odd_fissure_width_mm", r.truth.odd_fissure_width_mm}};
    j["landmarks"] = ordered_json::array();
    for (const auto& l : r.truth.landmarks)
        j["landmarks"].push_back({{"name", l.name}, {"description", l.description},
                                  {"position_mm", vec(l.position)}, {"index", l.index}});
    ordered_json& t = j["timings_s"];
    for (const auto& [name, s] : r.timings)
        t["generate: " + name] = s;
    for (const auto& [name, s] : timings.entries())
        t[name] = s;
    return j;
}

} // namespace lobe::phantom
