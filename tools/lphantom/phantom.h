#pragma once
//! \file
//! \brief The synthetic patient: a deterministic contrast-enhanced (portal-venous phase)
//! abdominal CT with known ground truth, the project's built-in default input.
//!
//! The anatomy is defined analytically in physical millimetres (LPS: +x = patient left,
//! +y = posterior, +z = superior), so any size or spacing rasterises the same patient. The one
//! exception is on purpose: the two thin fissures are snapped to the voxel grid so that their
//! width is an exact number of voxels (the even/odd GVF parity case). It contains what makes
//! liver segmentation hard (docs/phantom.md; thesis failure cases in
//! ../shared/spec/seed-segmentation.md sections 4.5-4.9, 5.1-5.3, 8):
//!  - heart and right kidney touching the liver at near-equal HU (weak contacting boundaries);
//!  - the inferior vena cava deeply indenting the liver behind a narrow neck (Omega concavity);
//!  - an even-width (and an odd-width) thin fissure;
//!  - ribs with subcostal tissue of liver-like grey level between them and the liver;
//!  - portal and hepatic venous trees with >= 4 branch levels of decreasing radius;
//!  - a lobular tumour, a small satellite and a tumour touching the liver boundary, all of low
//!    contrast; partial-volume blur and Gaussian noise.
//!
//! Labels: 0 outside the body, 1 liver parenchyma, 2 portal vein, 3 hepatic veins, 4 tumour
//! (the project-wide tissue labels; the liver mask is {1,2,3,4}, the SLIVER07 convention), and
//! neighbours from 10 up (see Label).

#include "lobe/core/centreline_graph.h"
#include "lobe/core/image3d.h"
#include "lobe/core/types.h"

#include <array>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace lobe::phantom {

//! Label values of the phantom's label volume. 0-4 are the project-wide tissue labels that the
//! segmentation tools output; 10 and up are the neighbours, documented in docs/phantom.md.
enum Label : std::uint8_t {
    kBackground = 0,      //!< outside the body (air)
    kLiver = 1,           //!< liver parenchyma
    kPortalVein = 2,      //!< portal vein inside the liver
    kHepaticVein = 3,     //!< hepatic veins
    kTumour = 4,          //!< liver tumours
    kSoftTissue = 10,     //!< skin, abdominal/back muscles, diaphragm, bowel, pancreas
    kFat = 11,            //!< subcutaneous and intra-abdominal fat, fissure and renal sinus fat
    kBone = 12,           //!< ribs and costal cartilage
    kHeart = 13,          //!< heart wall (myocardium and pericardium)
    kRightKidney = 14,    //!< right kidney with its capsule
    kIvc = 15,            //!< inferior vena cava
    kLungs = 16,          //!< lungs
    kSpleen = 17,         //!< spleen
    kAorta = 18,          //!< aorta
    kSpine = 19,          //!< vertebrae, discs and spinal canal
    kSubcostal = 20,      //!< subcostal tissue: the inner wall layer between the ribs and the organs
    kLeftKidney = 21,     //!< left kidney with its capsule
    kStomach = 22,        //!< stomach (wall, fluid and gas)
    kGallbladder = 23,    //!< gallbladder
    kPortalVeinExtra = 24,//!< extrahepatic portal vein (trunk below the hilum)
    kHeartBlood = 25,     //!< heart chambers (blood pool)
    kMediastinum = 26,    //!< mediastinal fat between the lungs
};

//! One row of the label table: value, short name and the HU the phantom gives it.
struct LabelInfo {
    int label = 0;
    std::string name;
    std::string description;
};

//! Every label the phantom writes, in increasing order.
const std::vector<LabelInfo>& label_table();

//! CT numbers of each tissue in Hounsfield units, portal-venous phase. Defaults are typical
//! values (docs/phantom.md cites the ranges); heart wall and kidney are deliberately a few HU
//! from liver so that only a thin line separates them.
struct PhantomHu {
    double air = -1000;
    double lung = -850;
    double fat = -100;            //!< subcutaneous and intra-abdominal fat
    double skin = 30;
    double muscle = 50;           //!< abdominal wall, back muscles, diaphragm, psoas
    double subcostal = 65;        //!< subcostal tissue: liver-like grey level (the leak path)
    double bone_cortex = 900;     //!< rib and vertebral cortex
    double bone_marrow = 230;     //!< cancellous bone
    double cartilage = 120;       //!< costal cartilage
    double disc = 80;             //!< intervertebral disc
    double csf = 10;              //!< spinal canal
    double liver = 105;
    double portal_vein = 175;
    double hepatic_vein = 160;
    double ivc = 145;
    double aorta = 165;
    double heart_wall = 100;      //!< myocardium: 5 HU below liver
    double heart_blood = 150;     //!< blood pool
    double kidney = 112;          //!< renal parenchyma: 7 HU above liver
    double contact_line = 45;     //!< pericardium/diaphragm and renal capsule: the thin line
    double spleen = 115;
    double bowel = 40;            //!< bowel wall and small bowel loops
    double pancreas = 95;
    double stomach_wall = 60;
    double stomach_fluid = 15;    //!< stomach and colon content
    double gas = -950;            //!< stomach and colon gas
    double bile = 10;             //!< gallbladder
    double mediastinal_fat = -90;
};

//! Parameters of the phantom. `{}` gives the documented default: 512 x 512 x 80 voxels of
//! 0.7 x 0.7 x 2.5 mm (358.4 x 358.4 x 200 mm), centred on the anatomy.
struct PhantomParams {
    std::array<int, 3> size{512, 512, 80};            //!< voxels along x, y, z
    std::array<double, 3> spacing{0.7, 0.7, 2.5};     //!< voxel size [mm]
    std::array<double, 3> center{0.0, 0.0, 0.0};      //!< physical position of the grid centre [mm]
    std::uint64_t seed = 1;                           //!< noise seed (the anatomy never depends on it)
    double noise_sigma_hu = 12.0;                     //!< Gaussian noise standard deviation [HU], >= 0
    double blur_sigma_mm = 0.6;                       //!< Gaussian PSF standard deviation [mm], >= 0
    double supersample_mm = 1.0;                      //!< partial volume: voxels at a boundary
                                                      //!< average sub-samples about this far apart
                                                      //!< [mm] (at most 27 per voxel); at the
                                                      //!< default 3 along z: the slice profile
    bool tumours = true;                              //!< include the three tumours
    bool vessels = true;                              //!< include the portal and hepatic trees
    int fissure_width_voxels = 2;                     //!< the even thin indentation [voxels along x], >= 1
    int odd_fissure_width_voxels = 3;                 //!< a second one for contrast; 0 = none
    std::vector<double> vessel_radius_mm{6.0, 4.0, 2.5, 1.5}; //!< radius per branch level 1, 2, ...
                                                      //!< (decreasing; its size is the number of levels)
    double contact_line_mm = 1.0;                     //!< thickness of the line between liver and
                                                      //!< heart / kidney [mm]
    std::array<double, 3> tumour_contrast_hu{-20.0, -25.0, -30.0}; //!< lobular, satellite, boundary
                                                      //!< tumour HU minus liver HU
    PhantomHu hu;                                     //!< tissue CT numbers
};

//! Which venous tree a centreline edge belongs to.
enum class VesselTree { Portal, Hepatic };

//! A centreline node: position [mm] and the vessel radius there [mm].
struct VesselNode {
    core::Vec3 position;
    double radius_mm = 0;
};

//! A centreline edge: a straight tube of constant radius between two nodes.
struct VesselEdge {
    int from = 0;                  //!< node index (the end nearer the root)
    int to = 0;                    //!< node index
    int level = 1;                 //!< branch level: 1 = trunk, 2 = its branches, ...
    VesselTree tree = VesselTree::Portal;
    double radius_mm = 0;
    double length_mm = 0;
    double inside_liver = 1.0;     //!< fraction of the centreline inside the liver envelope
};

//! Ground truth of one tumour.
struct TumourTruth {
    std::string name;              //!< "lobular", "satellite", "boundary"
    core::Vec3 centroid;           //!< [mm]
    double volume_ml = 0;
    double equivalent_radius_mm = 0; //!< radius of the sphere of the same volume
    double contrast_hu = 0;        //!< tumour HU minus liver HU
    bool touches_boundary = false;   //!< reaches the liver surface
};

//! A named place where a feature can be seen; `index` is its voxel index on the generated grid
//! (rounded, possibly outside the grid for a small field of view).
struct Landmark {
    std::string name;
    std::string description;
    core::Vec3 position;           //!< [mm]
    std::array<int, 3> index{0, 0, 0};
};

//! Everything known about the phantom.
struct PhantomTruth {
    double liver_volume_ml = 0;    //!< volume of the liver mask {1,2,3,4} from the analytic shape
    std::vector<TumourTruth> tumours;
    std::vector<VesselNode> vessel_nodes;
    std::vector<VesselEdge> vessel_edges;
    std::vector<Landmark> landmarks;
    double ivc_neck_width_mm = 0;  //!< width of the Omega concavity's neck
    double ivc_body_width_mm = 0;  //!< width of the IVC inside it (left-right)
    double fissure_width_mm = 0;   //!< even fissure width = fissure_width_voxels * spacing[0]
    double odd_fissure_width_mm = 0;

    //! The landmark called `name`. \throw core::InvalidInputError if there is none.
    const Landmark& landmark(const std::string& name) const;
};

//! The generated phantom.
struct PhantomResult {
    core::Image3D<std::int16_t> ct;    //!< HU
    core::LabelImage3D labels;         //!< analytic labels at the voxel centres
    PhantomTruth truth;
    std::vector<std::pair<std::string, double>> timings; //!< seconds per generation stage
};

//! The grid a phantom with these parameters is generated on (size, spacing, origin such that
//! the grid centre is at params.center, identity direction).
core::ImageGeometry phantom_geometry(const PhantomParams& params);

//! The size that covers the default field of view (358.4 x 358.4 x 200 mm) at `spacing`.
std::array<int, 3> size_for_spacing(const std::array<double, 3>& spacing);

//! Why the parameters are invalid, or an empty string if they are valid.
std::string params_problem(const PhantomParams& params);

//! The truth's vessel trees as a centre-line graph (label 2 portal, 3 hepatic; straight
//! two-point polylines with the edge radius), the form lobe's vessel segmentation is compared in.
core::CentrelineGraph truth_graph(const PhantomTruth& truth);

//! A failure case for vessel segmentation: a gap in contrast along vessel edge `edge` of the
//! truth (a stenosis or poorly filled stretch). Over `length_mm` of its centre line starting
//! `start_mm` from its `from` node, the vessel's contrast above the liver is scaled by
//! `contrast_fraction` (0 = invisible) in the CT; the noise and the labels stay (the vessel is
//! there, it is just not seen). Returns the number of voxels changed.
//! \throw core::InvalidInputError for an edge out of range or a fraction outside [0, 1].
std::size_t add_vessel_gap(PhantomResult& phantom, const PhantomParams& params, int edge, double start_mm,
                           double length_mm, double contrast_fraction);

//! A T1-weighted look of a CT phantom, for the MR paths: HU mapped piecewise linearly to grey
//! levels in a T1 image's order (fat brightest, the liver the brightest soft tissue; muscle,
//! fluid, blood and bone darker; air and lung black; relative levels as in mr-small: liver 97,
//! wall muscle 20-60, fat 200-550). No shading: a caller multiplies in its own field.
core::ImageF t1_weighted(const core::ImageF& hu);

//! Generates the phantom. Deterministic: the same parameters give the same bytes; the seed
//! changes only the noise. Single-threaded; about 3 s for the default grid on one core.
//! \throw core::InvalidInputError if params_problem(params) is not empty.
PhantomResult generate_phantom(const PhantomParams& params = {});

} // namespace lobe::phantom
