#pragma once
//! \file
//! \brief Element quality: the tetrahedron and triangle measures the thesis compares
//! (docs/algorithms/mesh_quality.md, ../shared/spec/seed-deformable.md section 5).
//!
//! Every measure is normalised so that the regular tetrahedron (equilateral triangle) scores
//! exactly 1, higher is better, a degenerate element scores 0 (or the measure's known limit,
//! e.g. the radius-edge measure of a cocircular sliver) and, for the signed measures, an
//! inverted tet scores below 0. References: J. R. Shewchuk, "What is a good linear element?"
//! (2002); the thesis's eq 6.14-6.17 and the 0.3/0.5/0.7 bands of its figures.

#include "lobe/core/tet_mesh.h"
#include "lobe/core/tri_mesh.h"
#include "lobe/core/types.h"

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace lobe::mesh {

//! The tetrahedron measures, in the order of TetMeasures::values.
enum class Measure : int {
    InterpolationSizeShape = 0, //!< Shewchuk ||f-g||inf, size-and-shape: (r_mc(regular of edge h) / r_mc)^2
    Interpolation,              //!< Shewchuk ||f-g||inf, scale-invariant: V / r_mc^3
    GradientSizeShape,          //!< Shewchuk ||grad f - grad g||inf, size-and-shape, c_t = 1/h (eq 6.15 term)
    Gradient,                   //!< same bound with c_t = V^(-1/3) (the thesis's plots): scale-invariant
    Conditioning,               //!< Shewchuk, non-smooth: V^(1/3) / lambda_max of the P1 stiffness matrix
    ConditioningSmooth,         //!< Shewchuk, smooth: V / (sum A_i^2)^(3/4)
    RadiusEdgeInverse,          //!< Paloc's 1/B = l_min / R_circ
    MinDihedral,                //!< smallest dihedral angle / 70.53 deg
    MaxDihedral,                //!< (180 - largest dihedral angle) / (180 - 70.53) deg
    Combined,                   //!< the thesis's eq 6.16, each term divided by its regular value
    Fast,                       //!< the thesis's eq 6.17: (72 sqrt3 V / (sum l^2)^(3/2))^3
};
inline constexpr int kMeasureCount = 11;

//! Short snake_case name of a measure, used for the HDF5 datasets and the reports
//! ("interpolation_size_shape", ..., "combined", "fast").
const char* measure_name(Measure m);

//! Options of the quality evaluation.
struct QualityParams {
    double weight = 0.6;          //!< w of eq 6.14: share of the conditioning term (thesis: 0.6)
    double reference_edge = 0.0;  //!< h [mm] of the size-and-shape measures (a regular tet of edge h
                                  //!< scores 1); 0 = the mesh's mean edge length
    bool exact_lambda = false;    //!< combined measure: exact lambda_max instead of sum A^2/(18V)
    int histogram_bins = 20;      //!< bins over [0, 1] of each histogram
    int worst_count = 10;         //!< how many worst elements (by the combined measure) to list
};

//! Every measure of one tetrahedron, plus the raw geometric figures behind them.
struct TetMeasures {
    std::array<double, kMeasureCount> values{}; //!< indexed by Measure, normalised (regular = 1)
    double volume = 0;              //!< signed volume [mm^3]
    double radius_edge_ratio = 0;   //!< B = R_circ / l_min (regular: sqrt(6)/4 = 0.612; skinny if >= 2)
    double min_dihedral_deg = 0;    //!< smallest interior dihedral angle [degrees]
    double max_dihedral_deg = 0;    //!< largest interior dihedral angle [degrees]
    double lambda_max = 0;          //!< largest eigenvalue of the P1 stiffness matrix V grad(l) grad(l)^T [mm]

    double operator[](Measure m) const { return values[static_cast<int>(m)]; }
};

//! All measures of tet (a, b, c, d). `reference_edge` [mm] is h of the size-and-shape measures
//! (> 0). A degenerate tet (zero volume) gets 0 for the volume-based measures; an inverted one
//! negative values for the signed ones (interpolation, gradient, conditioning, combined, fast).
TetMeasures tet_measures(const core::Vec3& a, const core::Vec3& b, const core::Vec3& c, const core::Vec3& d,
                         double reference_edge, const QualityParams& params = {});

//! The thesis's fast measure alone (eq 6.17, normalised: 1 for the regular tet, negative for an
//! inverted one), equal to tet_measures(...)[Measure::Fast] at a fraction of the cost: what
//! on-the-fly refinement checks every new element with.
double fast_measure(const core::Vec3& a, const core::Vec3& b, const core::Vec3& c, const core::Vec3& d);

//! The thesis's combined measure alone (eq 6.16, normalised: 1 for the regular tet, negative for
//! an inverted one, 0 for a flat one), equal to tet_measures(...)[Measure::Combined] with the
//! same params (only weight and exact_lambda matter) without the other measures' work: what the
//! quality improvement pass (improve.h) evaluates for every candidate.
double combined_measure(const core::Vec3& a, const core::Vec3& b, const core::Vec3& c, const core::Vec3& d,
                        const QualityParams& params = {});

//! The six interior dihedral angles [radians] of tet (a, b, c, d), at edges ab, ac, ad, bc, bd, cd.
std::array<double, 6> dihedral_angles(const core::Vec3& a, const core::Vec3& b, const core::Vec3& c,
                                      const core::Vec3& d);

//! Largest eigenvalue [mm] of the tet's P1 (Laplacian) element stiffness matrix, exact.
double stiffness_lambda_max(const core::Vec3& a, const core::Vec3& b, const core::Vec3& c, const core::Vec3& d);

//! The thesis's estimate sum A_i^2 / (18 |V|) of the same (eq 6.13), infinite for a flat tet.
double stiffness_lambda_max_estimate(const core::Vec3& a, const core::Vec3& b, const core::Vec3& c,
                                     const core::Vec3& d);

//! The thesis's surface measure A^4 / (sum l^2)^4 normalised: (4 sqrt3 A / sum l^2)^4 in [0, 1],
//! 1 for the equilateral triangle, 0 for a degenerate one.
double triangle_quality(const core::Vec3& a, const core::Vec3& b, const core::Vec3& c);

//! Distribution of one measure over a set of elements.
struct MeasureSummary {
    std::int64_t count = 0;
    double min = 0, mean = 0, max = 0;
    std::vector<std::int64_t> histogram;   //!< QualityParams::histogram_bins bins over [0, 1]; values
                                           //!< below 0 fall in the first, above 1 in the last
    std::array<std::int64_t, 4> bands{};   //!< the thesis's bands: < 0.3, [0.3, 0.5), [0.5, 0.7), >= 0.7
};

//! Summaries of every measure over the tets of one tissue label (or all, label = 0).
struct TissueQuality {
    int label = 0;                                     //!< 0 = the whole mesh
    std::int64_t tets = 0;
    double volume = 0;                                 //!< [mm^3]
    double min_dihedral_deg = 0, max_dihedral_deg = 0; //!< extremes over the tissue [degrees]
    double max_radius_edge_ratio = 0;
    std::array<MeasureSummary, kMeasureCount> measures;
};

//! One element flagged as among the worst.
struct WorstElement {
    std::int64_t tet = 0;
    int label = 0;
    double combined = 0;
    double min_dihedral_deg = 0, max_dihedral_deg = 0;
    core::Vec3 centroid;
};

//! Quality of a whole tet mesh.
struct MeshQuality {
    double reference_edge = 0;                               //!< h used [mm]
    std::array<std::vector<double>, kMeasureCount> per_tet;  //!< each measure, one value per tet
    std::vector<double> min_dihedral_deg;                    //!< per tet [degrees]
    std::vector<double> max_dihedral_deg;                    //!< per tet [degrees]
    std::vector<double> radius_edge_ratio;                   //!< per tet, B
    TissueQuality all;                                       //!< label 0
    std::vector<TissueQuality> tissues;                      //!< one per tet label present, ascending
    std::vector<WorstElement> worst;                         //!< worst first
};

//! Evaluates every tet of `mesh`. \throw core::InvalidInputError if the mesh is malformed
//! (core::mesh_problem), empty or params are out of range.
MeshQuality evaluate_quality(const core::TetMesh& mesh, const QualityParams& params = {});

//! A plain-text report: per tissue, count, volume, extreme angles, and for every measure
//! min/mean/max and the band counts; then the worst elements.
std::string format_quality_report(const MeshQuality& quality);

} // namespace lobe::mesh
