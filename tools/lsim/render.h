#pragma once
// Pictures of a simulation: the deformed mesh's surface (flat-shaded, coloured by tissue, with
// the probes) and the instrument force over time. OpenCV draws; it stays out of this header.

#include "common/picture.h"
#include "lobe/io/hdf5.h"
#include "lobe/mss/model.h"

#include <string>
#include <vector>

namespace lobe::lsim {

struct Sphere {
    core::Vec3 centre_mm;
    double radius_mm = 0;
};

// The surface of `model` at `positions_mm`, seen obliquely from the front (LPS: anterior, above
// and to the patient's right), framed on the rest mesh so that frames of a run line up.
tools::RgbImage render_mesh(const mss::Model& model, const std::vector<core::Vec3>& positions_mm,
                            const std::vector<Sphere>& probes, const std::string& caption);

// |F| and its components against time [N, s].
tools::RgbImage plot_force(const std::vector<io::SimulationStep>& steps, const std::string& caption);

} // namespace lobe::lsim
