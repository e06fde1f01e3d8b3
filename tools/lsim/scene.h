#pragma once
// The lsim scene file: a human-written description of one simulation run (docs/algorithms/
// mass_spring.md, "Scene files"). `key = value` lines in [sections]; '#' starts a comment; every
// error names the file and line.

#include "lobe/mss/instrument.h"
#include "lobe/mss/model.h"
#include "lobe/mss/simulator.h"

#include <filesystem>
#include <string>
#include <vector>

namespace lobe::lsim {

struct FixedBox {
    core::Vec3 lo, hi; // [mm]
};

struct Scene {
    mss::ModelParams model;
    mss::SimulatorParams simulator;
    std::vector<FixedBox> fixed;
    std::vector<mss::ProbeParams> probes;
    std::vector<mss::GraspParams> grasps;
    std::vector<mss::BladeParams> blades;
    double duration = 1.0;        // [s]
    double frame_interval = 0.02; // [s] between output frames
    std::vector<double> png_times; // frames to draw with --png [s]; empty = first, middle, last
    std::string text;             // the file as read, for the provenance
};

// Frames of output after the first: duration / frame_interval rounded up (at most 100 000 in a
// parsed scene).
double frame_count(const Scene& s);

// Parses scene text; `file` names it in messages. \throw core::InvalidInputError "file:line: ..."
Scene parse_scene(const std::string& text, const std::string& file);

// Reads and parses a scene file. \throw core::IoError if unreadable
Scene read_scene(const std::filesystem::path& path);

} // namespace lobe::lsim
