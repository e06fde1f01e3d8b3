// The scene file parser.
#include "lsim/scene.h"

#include "lobe/core/errors.h"

#include <cmath>
#include <fstream>
#include <functional>
#include <map>
#include <sstream>

namespace lobe::lsim {
namespace {

std::string trim(const std::string& s)
{
    const auto b = s.find_first_not_of(" \t\r");
    if (b == std::string::npos)
        return {};
    const auto e = s.find_last_not_of(" \t\r");
    return s.substr(b, e - b + 1);
}

// Tissue names of the tet labels (docs/file-format.md).
const std::map<std::string, std::int32_t> kTissues = {{"liver", 1}, {"portal_vein", 2}, {"hepatic_veins", 3}, {"tumour", 4}};

// Frames an lsim run may write (100 000 frames of a 10 000-node mesh are 24 GB of positions).
constexpr int kMaxFrames = 100000;

std::string number_text(double v)
{
    std::ostringstream o;
    o << v;
    return o.str();
}

class Parser {
public:
    explicit Parser(std::string file) : file_(std::move(file)) {}

    [[noreturn]] void fail(const std::string& what) const
    {
        throw core::InvalidInputError(file_ + ":" + std::to_string(line_) + ": " + what);
    }

    std::vector<double> numbers(const std::string& value, std::size_t want, const std::string& key) const
    {
        std::istringstream in(value);
        std::vector<double> out;
        std::string word;
        while (in >> word) {
            char* end = nullptr;
            const double v = std::strtod(word.c_str(), &end);
            if (end == word.c_str() || *end != '\0' || !std::isfinite(v))
                fail("'" + key + "': '" + word + "' is not a finite number");
            out.push_back(v);
        }
        if (want > 0 && out.size() != want)
            fail("'" + key + "' needs " + std::to_string(want) + " number" + (want > 1 ? "s" : "") + ", got " +
                 std::to_string(out.size()));
        return out;
    }
    double number(const std::string& value, const std::string& key) const { return numbers(value, 1, key)[0]; }
    double positive(const std::string& value, const std::string& key) const
    {
        const double v = number(value, key);
        if (!(v > 0))
            fail("'" + key + "' must be positive");
        return v;
    }
    double non_negative(const std::string& value, const std::string& key) const
    {
        const double v = number(value, key);
        if (!(v >= 0))
            fail("'" + key + "' must not be negative");
        return v;
    }
    template <class F>
    auto named(F&& parse, const std::string& value) const
    {
        try {
            return parse(value);
        } catch (const core::InvalidInputError& e) {
            fail(e.what());
        }
    }

    Scene parse(const std::string& text)
    {
        Scene s;
        s.text = text;
        std::istringstream in(text);
        std::string raw, section;
        std::map<std::int32_t, double> modulus;
        double density = 0;
        while (std::getline(in, raw)) {
            ++line_;
            const std::string l = trim(raw.substr(0, raw.find('#')));
            if (l.empty())
                continue;
            if (l.front() == '[') {
                if (l.back() != ']')
                    fail("a section header must end with ']'");
                section = trim(l.substr(1, l.size() - 2));
                if (section == "probe")
                    s.probes.emplace_back().name = "probe" + std::to_string(s.probes.size());
                else if (section == "grasp")
                    s.grasps.emplace_back().name = "forceps" + std::to_string(s.grasps.size());
                else if (section == "blade")
                    s.blades.emplace_back().name = "scalpel" + std::to_string(s.blades.size());
                else if (section != "model" && section != "tissues" && section != "fixed" && section != "integrator" &&
                         section != "time" && section != "output" && section != "refine")
                    fail("unknown section [" + section + "] (model, tissues, fixed, integrator, time, probe, grasp, blade, "
                         "refine, output)");
                continue;
            }
            const auto eq = l.find('=');
            if (eq == std::string::npos)
                fail("expected 'key = value'");
            const std::string key = trim(l.substr(0, eq)), value = trim(l.substr(eq + 1));
            if (section.empty())
                fail("'" + key + "' before any [section]");
            if (value.empty())
                fail("'" + key + "' has no value");
            auto& m = s.model;
            auto& ts = s.simulator.time_step;
            if (section == "model") {
                if (key == "formulation")
                    m.formulation = named(mss::parse_formulation, value);
                else if (key == "poisson_ratio")
                    m.poisson_ratio = number(value, key);
                else if (key == "stiffness")
                    m.stiffness = named(mss::parse_stiffness, value);
                else if (key == "havp_c")
                    m.havp_c = positive(value, key);
                else if (key == "volume_coefficient")
                    m.volume_coefficient = non_negative(value, key);
                else if (key == "reference_length")
                    m.reference_length_mm = positive(value, key);
                else if (key == "damping_ratio")
                    m.damping_ratio = non_negative(value, key);
                else if (key == "mass_damping")
                    m.mass_damping = non_negative(value, key);
                else if (key == "gravity") {
                    const auto g = numbers(value, 3, key);
                    m.gravity = {g[0], g[1], g[2]};
                } else if (key == "threads") {
                    const double t = positive(value, key);
                    if (t != std::floor(t) || t > 64)
                        fail("threads must be a whole number from 1 to 64, got '" + value + "'");
                    m.threads = static_cast<int>(t);
                } else if (key == "simd") {
                    if (value != "true" && value != "false")
                        fail("'simd' is true or false, got '" + value + "'");
                    m.simd = value == "true";
                } else
                    fail("unknown key '" + key + "' in [model] (formulation, poisson_ratio, stiffness, havp_c, volume_coefficient, reference_length, "
                         "damping_ratio, mass_damping, gravity, threads, simd)");
            } else if (section == "tissues") {
                if (key == "density")
                    density = positive(value, key);
                else if (kTissues.count(key))
                    modulus[kTissues.at(key)] = positive(value, key);
                else {
                    char* end = nullptr;
                    const long label = std::strtol(key.c_str(), &end, 10);
                    if (end == key.c_str() || *end != '\0' || label < 1 || label > 255)
                        fail("unknown tissue '" + key + "' (liver, portal_vein, hepatic_veins, tumour, a label 1..255, "
                             "or density)");
                    modulus[std::int32_t(label)] = positive(value, key);
                }
            } else if (section == "fixed") {
                if (key != "box")
                    fail("unknown key '" + key + "' in [fixed] (box = x0 y0 z0 x1 y1 z1, mm)");
                const auto b = numbers(value, 6, key);
                if (b[0] > b[3] || b[1] > b[4] || b[2] > b[5])
                    fail("'box' needs its lower corner first");
                s.fixed.push_back({{b[0], b[1], b[2]}, {b[3], b[4], b[5]}});
            } else if (section == "integrator") {
                if (key == "method")
                    s.simulator.integrator = named(mss::parse_integrator, value);
                else if (key == "solver")
                    s.simulator.solver = named(mss::parse_linear_solver, value);
                else if (key == "max_speed")
                    s.simulator.max_speed = positive(value, key);
                else
                    fail("unknown key '" + key + "' in [integrator] (method, solver, max_speed)");
            } else if (section == "time") {
                if (key == "policy")
                    ts.policy = named(mss::parse_step_policy, value);
                else if (key == "dt")
                    ts.dt = positive(value, key);
                else if (key == "safety")
                    ts.safety = positive(value, key);
                else if (key == "max_factor")
                    ts.max_factor = positive(value, key);
                else if (key == "floor_factor")
                    ts.floor_factor = positive(value, key);
                else if (key == "tolerance")
                    ts.tolerance = positive(value, key);
                else if (key == "duration")
                    s.duration = positive(value, key);
                else if (key == "frame_interval")
                    s.frame_interval = positive(value, key);
                else if (key == "topology_interval")
                    s.simulator.topology_interval = positive(value, key);
                else
                    fail("unknown key '" + key + "' in [time] (policy, dt, safety, max_factor, floor_factor, tolerance, "
                         "duration, frame_interval, topology_interval)");
            } else if (section == "probe") {
                auto& p = s.probes.back();
                if (key == "name")
                    p.name = value;
                else if (key == "radius")
                    p.radius_mm = positive(value, key);
                else if (key == "point") {
                    const auto q = numbers(value, 4, key);
                    if (!p.path.empty() && !(q[0] > p.path.back().time))
                        fail("path times must increase");
                    p.path.push_back({q[0], {q[1], q[2], q[3]}});
                } else
                    fail("unknown key '" + key + "' in [probe] (name, radius, point = t x y z)");
            } else if (section == "grasp") {
                auto& g = s.grasps.back();
                if (key == "name")
                    g.name = value;
                else if (key == "radius")
                    g.jaw_radius_mm = positive(value, key);
                else if (key == "close")
                    g.close_time = non_negative(value, key);
                else if (key == "open")
                    g.open_time = positive(value, key);
                else if (key == "max_force")
                    g.max_force_n = positive(value, key);
                else if (key == "point") {
                    const auto q = numbers(value, 4, key);
                    if (!g.path.empty() && !(q[0] > g.path.back().time))
                        fail("path times must increase");
                    g.path.push_back({q[0], {q[1], q[2], q[3]}});
                } else
                    fail("unknown key '" + key + "' in [grasp] (name, radius, close, open, max_force, point = t x y z)");
                if (key == "open" && !(g.open_time > g.close_time))
                    fail("'open' must come after 'close'");
            } else if (section == "blade") {
                auto& b = s.blades.back();
                if (key == "name")
                    b.name = value;
                else if (key == "snap") {
                    b.snap = positive(value, key);
                    if (!(b.snap < 0.5))
                        fail("'snap' must be below 0.5");
                } else if (key == "min_edge")
                    b.min_edge_mm = non_negative(value, key);
                else if (key == "pose") {
                    const auto q = numbers(value, 7, key);
                    if (!b.path.empty() && !(q[0] > b.path.back().time))
                        fail("pose times must increase");
                    if (q[1] == q[4] && q[2] == q[5] && q[3] == q[6])
                        fail("the blade's two ends coincide");
                    b.path.push_back({q[0], {q[1], q[2], q[3]}, {q[4], q[5], q[6]}});
                } else
                    fail("unknown key '" + key + "' in [blade] (name, snap, min_edge, pose = t ax ay az bx by bz)");
            } else if (section == "refine") {
                auto& r = s.simulator.refine;
                r.enabled = true;
                if (key == "enabled") {
                    if (value != "true" && value != "false")
                        fail("'enabled' is true or false");
                    r.enabled = value == "true";
                } else if (key == "margin")
                    r.margin_mm = non_negative(value, key);
                else if (key == "edge")
                    r.edge_mm = non_negative(value, key);
                else if (key == "min_edge")
                    r.min_edge_mm = non_negative(value, key);
                else if (key == "min_quality")
                    r.min_quality = non_negative(value, key);
                else if (key == "coarsen_factor") {
                    r.coarsen_factor = positive(value, key);
                    if (!(r.coarsen_factor >= 1))
                        fail("'coarsen_factor' must be at least 1");
                } else if (key == "max_splits")
                    r.max_splits = int(positive(value, key));
                else
                    fail("unknown key '" + key + "' in [refine] (enabled, margin, edge, min_edge, min_quality, "
                         "coarsen_factor, max_splits)");
            } else if (section == "output") {
                if (key == "png_times")
                    s.png_times = numbers(value, 0, key);
                else
                    fail("unknown key '" + key + "' in [output] (png_times)");
            }
        }
        for (std::size_t i = 0; i < s.probes.size(); ++i)
            if (s.probes[i].path.empty())
                throw core::InvalidInputError(file_ + ": probe '" + s.probes[i].name + "' has no 'point'");
        for (const auto& g : s.grasps)
            if (g.path.empty())
                throw core::InvalidInputError(file_ + ": forceps '" + g.name + "' have no 'point'");
        for (const auto& b : s.blades)
            if (b.path.empty())
                throw core::InvalidInputError(file_ + ": blade '" + b.name + "' has no 'pose'");
        if (!modulus.empty() || density > 0)
            for (auto& t : s.model.tissues) {
                if (modulus.count(t.label))
                    t.youngs_modulus = modulus[t.label];
                if (density > 0)
                    t.density = density;
            }
        for (const auto& [label, e] : modulus) {
            bool known = false;
            for (const auto& t : s.model.tissues)
                known = known || t.label == label;
            if (!known)
                s.model.tissues.push_back({label, e, density > 0 ? density : 1060});
        }
        if (s.simulator.time_step.policy == mss::StepPolicy::Fixed && !(s.simulator.time_step.dt > 0))
            throw core::InvalidInputError(file_ + ": [time] policy = fixed needs dt");
        // Every frame is a copy of the nodes in the output file, and lsim counts frames in an int.
        const double frames = frame_count(s);
        if (!(frames <= kMaxFrames))
            throw core::InvalidInputError(file_ + ": [time] duration / frame_interval asks for " + number_text(frames) +
                                          " frames, more than " + std::to_string(kMaxFrames) +
                                          " (lengthen frame_interval)");
        return s;
    }

private:
    std::string file_;
    int line_ = 0;
};

} // namespace

double frame_count(const Scene& s)
{
    return std::ceil(s.duration / s.frame_interval - 1e-9);
}

Scene parse_scene(const std::string& text, const std::string& file) { return Parser(file).parse(text); }

Scene read_scene(const std::filesystem::path& path)
{
    std::ifstream f(path, std::ios::binary);
    if (!f)
        throw core::IoError(path.string() + ": cannot read the scene file");
    std::ostringstream text;
    text << f.rdbuf();
    return parse_scene(text.str(), path.string());
}

} // namespace lobe::lsim
