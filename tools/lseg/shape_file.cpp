// Reading and writing the shape memory file of lseg train.
#include "lseg/shape_file.h"

#include "lobe/io/hdf5.h"

#include <cmath>
#include <limits>
#include <string>
#include <vector>

namespace lobe::lseg {
namespace fs = std::filesystem;

namespace {

constexpr int kColumns = 11; // per step, see the docs
constexpr int kSummary = 22;

core::Image3D<double> table(int nx, int ny)
{
    core::ImageGeometry g;
    g.size = {nx, ny, 1};
    return core::Image3D<double>(g, 0.0);
}

} // namespace

void write_shape_memory(const fs::path& path, const seg::ShapeMemory& m, const io::Provenance& provenance)
{
    int radius_bins = 0;
    while (radius_bins < static_cast<int>(m.steps.size()) &&
           m.steps[static_cast<std::size_t>(radius_bins)].rho_min == m.steps[0].rho_min)
        ++radius_bins;
    auto s = table(kSummary, 1);
    const double v[kSummary] = {double(kShapeFileVersion), double(m.volumes), double(m.slices), double(m.transitions),
                                m.margin, m.allowance_px, m.volume_ml_min, m.volume_ml_max, m.extent_mm_min,
                                m.extent_mm_max, m.max_area_mm2_min, m.max_area_mm2_max, double(m.intensity.voxels),
                                m.intensity.mean, m.intensity.sd, m.intensity.quantiles[0], m.intensity.quantiles[1],
                                m.intensity.quantiles[2], m.intensity.quantiles[3], m.intensity.quantiles[4],
                                double(radius_bins), double(m.steps.size())};
    std::copy(v, v + kSummary, s.data.begin());
    auto t = table(kColumns, static_cast<int>(m.steps.size()));
    for (std::size_t r = 0; r < m.steps.size(); ++r) {
        const auto& st = m.steps[r];
        const double row[kColumns] = {st.radius_min_mm,  st.rho_min,         double(st.transitions), st.outward_per_mm,
                                      st.envelope_per_mm, st.inward_per_mm, st.growth_per_mm,       st.shrink_per_mm,
                                      st.centroid_per_mm, st.dice_min,      0.0};
        std::copy(row, row + kColumns, t.data.begin() + static_cast<std::ptrdiff_t>(r * kColumns));
    }
    io::Provenance p = provenance;
    p.parameters.emplace_back("shape.modality", m.intensity.modality);
    io::Hdf5WriteParams wp;
    wp.write_xdmf = false; // tables, not images to view
    io::Hdf5Writer h5(path, wp);
    h5.write_image("shape_summary", s);
    h5.write_image("shape_steps", t);
    h5.write_provenance(p);
    h5.commit();
}

seg::ShapeMemory read_shape_memory(const fs::path& path)
{
    const io::Hdf5Reader h5(path);
    const std::string what = path.string();
    const auto names = h5.images();
    auto has = [&](const std::string& n) { return std::find(names.begin(), names.end(), n) != names.end(); };
    if (!has("shape_summary") || !has("shape_steps"))
        throw core::InvalidInputError(what + ": not a shape memory (no /images/shape_summary and /images/shape_steps;"
                                             " write one with lseg train)");
    const auto s = core::convert_image<double>(h5.read_image("shape_summary"));
    const auto t = core::convert_image<double>(h5.read_image("shape_steps"));
    if (s.data.size() != kSummary || s.size[0] != kSummary)
        throw core::InvalidInputError(what + ": /images/shape_summary holds " + std::to_string(s.data.size()) +
                                      " values, expected " + std::to_string(kSummary));
    for (double x : s.data)
        if (!std::isfinite(x))
            throw core::InvalidInputError(what + ": /images/shape_summary holds a non-finite value");
    if (static_cast<int>(s.data[0]) > kShapeFileVersion || s.data[0] < 1)
        throw core::InvalidInputError(what + ": shape memory layout " + std::to_string(s.data[0]) +
                                      " is not supported (this lseg reads up to " +
                                      std::to_string(kShapeFileVersion) + ")");
    const auto radius_bins = static_cast<std::size_t>(s.data[20]);
    const auto steps = static_cast<std::size_t>(s.data[21]);
    if (t.size[0] != kColumns || static_cast<std::size_t>(t.size[1]) != steps || t.size[2] != 1 || steps == 0 ||
        radius_bins == 0 || steps % radius_bins != 0)
        throw core::InvalidInputError(what + ": /images/shape_steps is " + std::to_string(t.size[0]) + " x " +
                                      std::to_string(t.size[1]) + ", expected " + std::to_string(kColumns) + " x " +
                                      std::to_string(steps) + " (" + std::to_string(radius_bins) + " radius bins)");
    seg::ShapeMemory m;
    m.volumes = static_cast<int>(s.data[1]);
    m.slices = static_cast<std::size_t>(s.data[2]);
    m.transitions = static_cast<std::size_t>(s.data[3]);
    m.margin = s.data[4];
    m.allowance_px = s.data[5];
    m.volume_ml_min = s.data[6];
    m.volume_ml_max = s.data[7];
    m.extent_mm_min = s.data[8];
    m.extent_mm_max = s.data[9];
    m.max_area_mm2_min = s.data[10];
    m.max_area_mm2_max = s.data[11];
    m.intensity.voxels = static_cast<std::size_t>(s.data[12]);
    m.intensity.mean = s.data[13];
    m.intensity.sd = s.data[14];
    for (std::size_t q = 0; q < 5; ++q)
        m.intensity.quantiles[q] = s.data[15 + q];
    if (m.volumes < 1 || !(m.margin > 0) || !(m.allowance_px >= 0))
        throw core::InvalidInputError(what + ": /images/shape_summary: invalid volumes, margin or allowance");
    constexpr double inf = std::numeric_limits<double>::infinity();
    m.steps.resize(steps);
    for (std::size_t r = 0; r < steps; ++r) {
        const double* row = t.data.data() + r * kColumns;
        for (int c = 0; c < kColumns; ++c)
            if (!std::isfinite(row[c]) || row[c] < 0)
                throw core::InvalidInputError(what + ": /images/shape_steps row " + std::to_string(r) +
                                              " holds a negative or non-finite value");
        auto& st = m.steps[r];
        st.radius_min_mm = row[0];
        st.rho_min = row[1];
        st.transitions = static_cast<std::size_t>(row[2]);
        st.outward_per_mm = row[3];
        st.envelope_per_mm = row[4];
        st.inward_per_mm = row[5];
        st.growth_per_mm = row[6];
        st.shrink_per_mm = row[7];
        st.centroid_per_mm = row[8];
        st.dice_min = row[9];
    }
    for (std::size_t r = 0; r < steps; ++r) {
        const std::size_t br = r % radius_bins, bp = r / radius_bins;
        m.steps[r].radius_max_mm = br + 1 < radius_bins ? m.steps[r + 1].radius_min_mm : inf;
        m.steps[r].rho_max = (bp + 1) * radius_bins < steps ? m.steps[r + radius_bins].rho_min : inf;
    }
    for (const auto& p : h5.provenance())
        for (const auto& [k, v] : p.parameters)
            if (k == "shape.modality")
                m.intensity.modality = v;
    return m;
}

} // namespace lobe::lseg
