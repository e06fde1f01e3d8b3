#pragma once
// Pictures of a simulation: the deformed mesh's surface (flat-shaded, coloured by tissue, with
// the probes) and the instrument force over time. OpenCV draws; it stays out of this header.

#include "common/picture.h"
#include "lobe/io/hdf5.h"
#include "lobe/mss/model.h"

#include <array>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace lobe::lsim {

struct Sphere {
    core::Vec3 centre_mm;
    double radius_mm = 0;
    bool forceps = false; // drawn as jaws (open: an outline; closed: filled)
    bool closed = false;
};

// The boundary and the instruments at one frame (the mesh changes when it is cut or refined).
struct Snapshot {
    double time = 0;
    std::vector<std::array<std::int32_t, 3>> faces; // outward
    std::vector<std::int32_t> labels;               // tissue of each face
    std::vector<core::Vec3> positions;              // [mm]
    std::vector<std::array<std::int32_t, 3>> cut_faces; // the faces cuts made, outlined in red
    std::vector<Sphere> spheres;
    std::vector<std::pair<core::Vec3, core::Vec3>> blades; // cutting edges
};

// The surface at a frame, seen obliquely from the front (LPS: anterior, above and to the
// patient's right), framed on `framing` (the rest mesh) so that the frames of a run line up.
tools::RgbImage render_mesh(const Snapshot& shot, const std::vector<core::Vec3>& framing, const std::string& caption);

// |F| and its components against time [N, s].
tools::RgbImage plot_force(const std::vector<io::SimulationStep>& steps, const std::string& caption);

} // namespace lobe::lsim
