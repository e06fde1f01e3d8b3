// Multi-tissue meshing with CGAL Mesh_3 on a labelled-image domain. Why it is done this way:
// docs/algorithms/meshing.md.
#include "lobe/mesh/tetrahedralize.h"

#include "lobe/core/errors.h"
#include "lobe/mesh/quality.h"
#include "detail/manifold_repair.h"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Image_3.h>
#include <CGAL/Labeled_mesh_domain_3.h>
#include <CGAL/Mesh_complex_3_in_triangulation_3.h>
#include <CGAL/Mesh_criteria_3.h>
#include <CGAL/Mesh_triangulation_3.h>
#include <CGAL/Random.h>
#include <CGAL/Spatial_sort_traits_adapter_3.h>
#include <CGAL/hilbert_sort.h>
#include <CGAL/make_mesh_3.h>
#include <CGAL/refine_mesh_3.h>
// after Mesh_3's own headers: they declare the worksharing structures the optimisers use
#include <CGAL/exude_mesh_3.h>
#include <CGAL/perturb_mesh_3.h>

#ifdef CGAL_LINKED_WITH_TBB
#include <tbb/global_control.h>
#include <tbb/info.h>
#endif

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <map>
#include <memory>
#include <queue>
#include <set>
#include <unordered_map>

namespace lobe::mesh {

namespace {

using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using Domain = CGAL::Labeled_mesh_domain_3<K>;
using Point = K::Point_3;

using core::Vec3;

constexpr int kMaxTissueLabel = 9;
const double kPi = std::acos(-1.0);

// The label volume after tissue selection, speck removal and padding, in CGAL's frame:
// point = (index - pad) * spacing, i.e. the original image's index space scaled to mm.
struct Prepared {
    core::LabelImage3D labels;          // padded, only selected tissues, specks removed
    int pad = 0;
    std::vector<int> component;         // per voxel of `labels`: component id or -1
    std::vector<ComponentReport> comps; // by id
    std::vector<std::array<int, 3>> seed_voxel; // a voxel of each component (padded indices)
};

double voxel_volume(const core::ImageGeometry& g) { return g.spacing[0] * g.spacing[1] * g.spacing[2]; }

std::vector<int> selected_tissues(const core::LabelImage3D& labels, const MeshParams& p)
{
    std::array<bool, 256> present{};
    for (auto v : labels.data)
        present[v] = true;
    std::vector<int> out;
    if (p.tissues.empty()) {
        for (int l = 1; l <= kMaxTissueLabel; ++l)
            if (present[static_cast<std::size_t>(l)])
                out.push_back(l);
    } else {
        for (int l : p.tissues) {
            if (l < 1 || l > 255)
                throw core::InvalidInputError("mesh_labels: tissue label " + std::to_string(l) +
                                              " is outside 1..255");
            if (present[static_cast<std::size_t>(l)])
                out.push_back(l);
        }
        std::sort(out.begin(), out.end());
        out.erase(std::unique(out.begin(), out.end()), out.end());
    }
    return out;
}

// 6-connected components of every non-zero label; returns the component id image.
int label_components(const core::LabelImage3D& img, std::vector<int>& comp, std::vector<std::int64_t>& sizes,
                     std::vector<int>& comp_label, std::vector<std::array<int, 3>>& first)
{
    const int nx = img.size[0], ny = img.size[1], nz = img.size[2];
    comp.assign(img.data.size(), -1);
    int n = 0;
    std::vector<std::size_t> stack;
    for (int k = 0; k < nz; ++k)
        for (int j = 0; j < ny; ++j)
            for (int i = 0; i < nx; ++i) {
                const std::size_t s = img.index(i, j, k);
                if (img.data[s] == 0 || comp[s] >= 0)
                    continue;
                const auto lab = img.data[s];
                comp[s] = n;
                stack.assign(1, s);
                std::int64_t count = 0;
                while (!stack.empty()) {
                    const std::size_t v = stack.back();
                    stack.pop_back();
                    ++count;
                    const int vi = static_cast<int>(v % static_cast<std::size_t>(nx));
                    const int vj = static_cast<int>((v / static_cast<std::size_t>(nx)) % static_cast<std::size_t>(ny));
                    const int vk = static_cast<int>(v / (static_cast<std::size_t>(nx) * static_cast<std::size_t>(ny)));
                    const int nb[6][3] = {{vi - 1, vj, vk}, {vi + 1, vj, vk}, {vi, vj - 1, vk},
                                          {vi, vj + 1, vk}, {vi, vj, vk - 1}, {vi, vj, vk + 1}};
                    for (const auto& q : nb) {
                        if (!img.contains(q[0], q[1], q[2]))
                            continue;
                        const std::size_t w = img.index(q[0], q[1], q[2]);
                        if (img.data[w] == lab && comp[w] < 0) {
                            comp[w] = n;
                            stack.push_back(w);
                        }
                    }
                }
                sizes.push_back(count);
                comp_label.push_back(lab);
                first.push_back({i, j, k});
                ++n;
            }
    return n;
}

Prepared prepare(const core::LabelImage3D& in, const MeshParams& p, MeshResult& result)
{
    const auto tissues = selected_tissues(in, p);
    if (tissues.empty())
        throw core::InvalidInputError("mesh_labels: the label volume has no voxel of the tissues to mesh" +
                                      std::string(p.tissues.empty() ? " (labels 1-9)" : ""));
    std::array<bool, 256> keep{};
    for (int l : tissues)
        keep[static_cast<std::size_t>(l)] = true;
    // Padding: a tissue touching the border would be cut open by the image's bounding box, so
    // pad by one background voxel when any selected voxel lies on the border.
    bool touches = false;
    const int nx = in.size[0], ny = in.size[1], nz = in.size[2];
    for (int k = 0; k < nz && !touches; ++k)
        for (int j = 0; j < ny && !touches; ++j)
            for (int i = 0; i < nx; ++i)
                if ((i == 0 || j == 0 || k == 0 || i == nx - 1 || j == ny - 1 || k == nz - 1) && keep[in.at(i, j, k)]) {
                    touches = true;
                    break;
                }
    Prepared pr;
    pr.pad = touches ? 1 : 0;
    result.padded = touches;
    core::ImageGeometry g = in.geometry();
    for (int a = 0; a < 3; ++a)
        g.size[a] += 2 * pr.pad;
    pr.labels = core::LabelImage3D(g, 0);
    for (int k = 0; k < nz; ++k)
        for (int j = 0; j < ny; ++j)
            for (int i = 0; i < nx; ++i) {
                const auto v = in.at(i, j, k);
                pr.labels.at(i + pr.pad, j + pr.pad, k + pr.pad) = keep[v] ? v : 0;
            }
    // Specks: components below the threshold take their neighbours' majority label.
    std::vector<std::int64_t> sizes;
    std::vector<int> comp_label;
    std::vector<std::array<int, 3>> first;
    label_components(pr.labels, pr.component, sizes, comp_label, first);
    std::map<int, int> specks;
    bool changed = false;
    std::map<int, std::vector<std::size_t>> small; // voxels of each speck, one pass
    for (std::size_t s = 0; s < pr.component.size(); ++s) {
        const int c = pr.component[s];
        if (c >= 0 && sizes[static_cast<std::size_t>(c)] < p.min_component_voxels)
            small[c].push_back(s);
    }
    for (const auto& [c, voxels] : small) {
        std::map<int, int> votes;
        for (auto s : voxels) {
            const int vi = static_cast<int>(s % static_cast<std::size_t>(g.size[0]));
            const int vj = static_cast<int>((s / static_cast<std::size_t>(g.size[0])) % static_cast<std::size_t>(g.size[1]));
            const int vk = static_cast<int>(s / (static_cast<std::size_t>(g.size[0]) * static_cast<std::size_t>(g.size[1])));
            const int nb[6][3] = {{vi - 1, vj, vk}, {vi + 1, vj, vk}, {vi, vj - 1, vk},
                                  {vi, vj + 1, vk}, {vi, vj, vk - 1}, {vi, vj, vk + 1}};
            for (const auto& q : nb)
                if (pr.labels.contains(q[0], q[1], q[2])) {
                    const std::size_t w = pr.labels.index(q[0], q[1], q[2]);
                    if (pr.component[w] != c)
                        ++votes[pr.labels.data[w]];
                }
        }
        int best = 0, best_votes = -1;
        for (auto [lab, n] : votes)
            if (n > best_votes)
                best = lab, best_votes = n;
        for (auto s : voxels)
            pr.labels.data[s] = static_cast<std::uint8_t>(best);
        const auto cu = static_cast<std::size_t>(c);
        ++specks[comp_label[cu]];
        changed = true;
        result.warnings.push_back("dropped a speck of label " + std::to_string(comp_label[cu]) + " (" +
                                  std::to_string(sizes[cu]) + " voxels at index " + std::to_string(first[cu][0] - pr.pad) +
                                  "," + std::to_string(first[cu][1] - pr.pad) + "," +
                                  std::to_string(first[cu][2] - pr.pad) + "), relabelled " + std::to_string(best));
    }
    if (changed) {
        sizes.clear();
        comp_label.clear();
        first.clear();
        label_components(pr.labels, pr.component, sizes, comp_label, first);
    }
    const double vv = voxel_volume(g);
    for (std::size_t c = 0; c < sizes.size(); ++c) {
        ComponentReport r;
        r.label = comp_label[c];
        r.voxels = sizes[c];
        r.label_volume = static_cast<double>(sizes[c]) * vv;
        pr.comps.push_back(r);
        pr.seed_voxel.push_back(first[c]);
    }
    bool any = false;
    for (auto v : pr.labels.data)
        any = any || v != 0;
    if (!any)
        throw core::InvalidInputError("mesh_labels: nothing left to mesh once specks below " +
                                      std::to_string(p.min_component_voxels) + " voxels were dropped");
    for (int l : tissues) {
        TissueReport t;
        t.label = l;
        t.specks_dropped = specks.count(l) ? specks[l] : 0;
        result.tissues.push_back(t);
    }
    return pr;
}

double default_size(const core::ImageGeometry& g)
{
    return 3 * std::max({g.spacing[0], g.spacing[1], g.spacing[2]});
}

double tissue_size(const MeshParams& p, int label, double size)
{
    for (const auto& t : p.tissue_sizes)
        if (t.label == label && t.size > 0)
            return t.size;
    return size;
}

// Distance [mm] from a point to the region of interest (0 inside), in CGAL's frame.
struct RoiFrame {
    RegionOfInterest::Kind kind = RegionOfInterest::Kind::None;
    Vec3 lo, hi;
    std::vector<Vec3> centres;
    double radius = 0;
    double size = 0;
    double slope = 0.5;

    double distance(const Vec3& q) const
    {
        if (kind == RegionOfInterest::Kind::Box) {
            double d2 = 0;
            for (int a = 0; a < 3; ++a) {
                const double e = std::max({lo[a] - q[a], 0.0, q[a] - hi[a]});
                d2 += e * e;
            }
            return std::sqrt(d2);
        }
        double d = std::numeric_limits<double>::infinity();
        for (const auto& c : centres)
            d = std::min(d, core::distance(q, c) - radius);
        return std::max(d, 0.0);
    }
};

// CGAL's sizing field: per-tissue size, refined towards the ROI.
struct SizingField {
    using FT = K::FT;
    using Index = Domain::Index;
    std::array<double, 256> by_label{};
    double fallback = 1;
    std::shared_ptr<const RoiFrame> roi;

    double label_size(int l) const
    {
        const double s = (l >= 0 && l < 256) ? by_label[static_cast<std::size_t>(l)] : 0;
        return s > 0 ? s : fallback;
    }

    FT operator()(const Point& p, const int dim, const Index& index) const
    {
        double s = fallback;
        if (dim == 3) {
            if (const int* sub = boost::get<int>(&index))
                s = label_size(*sub);
        } else if (dim == 2) {
            if (const auto* patch = boost::get<std::pair<int, int>>(&index))
                s = std::min(label_size(patch->first), label_size(patch->second));
        }
        if (roi && roi->kind != RegionOfInterest::Kind::None)
            s = std::min(s, roi->size + roi->slope * roi->distance({p.x(), p.y(), p.z()}));
        return s;
    }
};

// Position-only fields of the surface facets (why position only: run_mesh_3). A boundary point
// lies between voxel centres of different labels, so the eight voxels around it hold the
// tissues it separates; the facet size and the distance bound are the smallest of theirs.
struct BoundaryMaps {
    const core::LabelImage3D* labels = nullptr; // padded (Prepared outlives the meshing)
    int pad = 0;
    std::array<double, 3> spacing{};
    std::array<double, 256> size{}, distance{}; // per label [mm]

    template <class F>
    void around(const Point& p, F&& f) const
    {
        const double u[3] = {p.x() / spacing[0] + pad, p.y() / spacing[1] + pad, p.z() / spacing[2] + pad};
        const int i0 = static_cast<int>(std::floor(u[0])), j0 = static_cast<int>(std::floor(u[1])),
                  k0 = static_cast<int>(std::floor(u[2]));
        for (int dk = 0; dk <= 1; ++dk)
            for (int dj = 0; dj <= 1; ++dj)
                for (int di = 0; di <= 1; ++di)
                    if (labels->contains(i0 + di, j0 + dj, k0 + dk))
                        if (const auto l = labels->at(i0 + di, j0 + dj, k0 + dk); l != 0)
                            f(static_cast<std::size_t>(l));
    }
};

struct FacetSizeField {
    using FT = K::FT;
    std::shared_ptr<const BoundaryMaps> maps;
    std::shared_ptr<const RoiFrame> roi;
    double fallback = 1; // the smallest tissue size, should no tissue voxel lie around

    FT operator()(const Point& p, const int, const Domain::Index&) const
    {
        double s = std::numeric_limits<double>::infinity();
        maps->around(p, [&](std::size_t l) { s = std::min(s, maps->size[l]); });
        if (!std::isfinite(s))
            s = fallback;
        if (roi && roi->kind != RegionOfInterest::Kind::None)
            s = std::min(s, roi->size + roi->slope * roi->distance({p.x(), p.y(), p.z()}));
        return s;
    }
};

struct FacetDistanceField {
    using FT = K::FT;
    std::shared_ptr<const BoundaryMaps> maps;
    double fallback = 1; // the smallest tissue tolerance, should no tissue voxel lie around

    FT operator()(const Point& p, const int, const Domain::Index&) const
    {
        double d = std::numeric_limits<double>::infinity();
        maps->around(p, [&](std::size_t l) { d = std::min(d, maps->distance[l]); });
        return std::isfinite(d) ? d : fallback;
    }
};

// Map between physical space and CGAL's frame x = D^T (p - origin) (index * spacing).
Vec3 to_frame(const core::ImageGeometry& g, const Vec3& p)
{
    const Vec3 d = p - Vec3{g.origin[0], g.origin[1], g.origin[2]};
    return {dot(g.axis(0), d), dot(g.axis(1), d), dot(g.axis(2), d)};
}

Vec3 to_physical(const core::ImageGeometry& g, const Vec3& x)
{
    Vec3 p{g.origin[0], g.origin[1], g.origin[2]};
    for (int a = 0; a < 3; ++a)
        p += g.axis(a) * x[a];
    return p;
}

double det3(const core::ImageGeometry& g)
{
    return dot(g.axis(0), cross(g.axis(1), g.axis(2)));
}

// Initial points: for every component, boundary points found by intersecting the domain along
// segments from some of its voxels to a neighbour of another label (always a boundary crossing),
// spread over the component. This is what makes CGAL mesh every piece.
template <class C3t3>
void insert_initial_points(C3t3& c3t3, const Domain& domain, const Prepared& pr, const core::ImageGeometry& g,
                           int per_component)
{
    const auto& img = pr.labels;
    const int nx = img.size[0], ny = img.size[1];
    auto frame = [&](int i, int j, int k) {
        return Point((i - pr.pad) * g.spacing[0], (j - pr.pad) * g.spacing[1], (k - pr.pad) * g.spacing[2]);
    };
    // Boundary voxels per component, and each component's centroid; then every n-th boundary
    // voxel so that the points spread over the whole component.
    auto boundary_face = [&](std::size_t s, int i, int j, int k) {
        const int nb[6][3] = {{i - 1, j, k}, {i + 1, j, k}, {i, j - 1, k}, {i, j + 1, k}, {i, j, k - 1}, {i, j, k + 1}};
        for (int d = 0; d < 6; ++d) {
            const auto& q = nb[d];
            if (!img.contains(q[0], q[1], q[2]) || img.at(q[0], q[1], q[2]) != img.data[s])
                return d;
        }
        return -1;
    };
    std::vector<std::int64_t> count(pr.comps.size(), 0);
    std::vector<Vec3> centroid(pr.comps.size());
    for (int k = 0; k < img.size[2]; ++k)
        for (int j = 0; j < ny; ++j)
            for (int i = 0; i < nx; ++i) {
                const std::size_t s = img.index(i, j, k);
                const int c = pr.component[s];
                if (c < 0)
                    continue;
                const auto cu = static_cast<std::size_t>(c);
                centroid[cu] += Vec3{double(i), double(j), double(k)};
                if (boundary_face(s, i, j, k) >= 0)
                    ++count[cu];
            }
    std::vector<std::vector<std::pair<std::size_t, int>>> boundary(pr.comps.size());
    std::vector<std::int64_t> seen(pr.comps.size(), 0);
    for (int k = 0; k < img.size[2]; ++k)
        for (int j = 0; j < ny; ++j)
            for (int i = 0; i < nx; ++i) {
                const std::size_t s = img.index(i, j, k);
                const int c = pr.component[s];
                if (c < 0)
                    continue;
                const int d = boundary_face(s, i, j, k);
                if (d < 0)
                    continue;
                const auto cu = static_cast<std::size_t>(c);
                const auto stride = std::max<std::int64_t>(1, count[cu] / per_component);
                auto& b = boundary[cu];
                if (static_cast<int>(b.size()) < per_component && seen[cu]++ % stride == 0)
                    b.emplace_back(s, d);
            }
    auto cwp = c3t3.triangulation().geom_traits().construct_weighted_point_3_object();
    auto intersect = domain.construct_intersection_object();
    for (std::size_t c = 0; c < boundary.size(); ++c)
        for (auto [s, d] : boundary[c]) {
            const int i = static_cast<int>(s % static_cast<std::size_t>(nx));
            const int j = static_cast<int>((s / static_cast<std::size_t>(nx)) % static_cast<std::size_t>(ny));
            const int k = static_cast<int>(s / (static_cast<std::size_t>(nx) * static_cast<std::size_t>(ny)));
            const int di[6][3] = {{-1, 0, 0}, {1, 0, 0}, {0, -1, 0}, {0, 1, 0}, {0, 0, -1}, {0, 0, 1}};
            const Point a = frame(i, j, k);
            const Point b = frame(i + di[d][0], j + di[d][1], k + di[d][2]);
            const auto x = intersect(K::Segment_3(a, b));
            if (std::get<2>(x) == 0)
                continue;
            auto v = c3t3.triangulation().insert(cwp(std::get<0>(x)));
            if (v != typename C3t3::Triangulation::Vertex_handle()) {
                c3t3.set_dimension(v, 2);
                c3t3.set_index(v, std::get<1>(x));
            }
        }
    // One interior point per component, at its centroid's voxel when that voxel lies inside
    // the component with all its face neighbours. Points on a sphere alone are cospherical:
    // their Delaunay cells all share one circumcentre, and when it lies outside the tissue (the
    // 4/5 sphere's centre is on its cut) no dual edge crosses the boundary, CGAL finds no
    // facet to start from and meshes nothing. That happened to the 4/5 sphere test when the
    // boundary points were the first few of the scan; the even spread above fixed it, and the
    // interior point keeps it from depending on where the spread falls.
    for (std::size_t c = 0; c < pr.comps.size(); ++c) {
        const Vec3 m = centroid[c] / static_cast<double>(pr.comps[c].voxels);
        const int i = static_cast<int>(std::lround(m.x)), j = static_cast<int>(std::lround(m.y)),
                  k = static_cast<int>(std::lround(m.z));
        if (!img.contains(i, j, k) || pr.component[img.index(i, j, k)] != static_cast<int>(c) ||
            boundary_face(img.index(i, j, k), i, j, k) >= 0)
            continue;
        auto v = c3t3.triangulation().insert(cwp(frame(i, j, k)));
        if (v != typename C3t3::Triangulation::Vertex_handle()) {
            c3t3.set_dimension(v, 3);
            c3t3.set_index(v, typename Domain::Index(static_cast<int>(pr.comps[c].label)));
        }
    }
}

// CGAL numbers the vertices in its triangulation's order, which scatters neighbours through
// memory: a mass-spring step gathers each spring's second node, and once the node arrays outgrow
// L2 those gathers miss (docs/benchmarks.md, "Liver meshes"). Renumber the vertices along a
// Hilbert curve and sort the tets by their smallest vertex, which keeps the mesh unchanged.
void spatial_order(core::TetMesh& m)
{
    using Map = CGAL::Pointer_property_map<K::Point_3>::type;
    std::vector<K::Point_3> points;
    points.reserve(m.vertices.size());
    for (const auto& v : m.vertices)
        points.emplace_back(v.x, v.y, v.z);
    std::vector<std::size_t> order(points.size());
    for (std::size_t i = 0; i < order.size(); ++i)
        order[i] = i;
    CGAL::hilbert_sort(order.begin(), order.end(),
                       CGAL::Spatial_sort_traits_adapter_3<K, Map>(CGAL::make_property_map(points)));
    std::vector<std::int32_t> rank(order.size());
    std::vector<core::Vec3> vertices(order.size());
    for (std::size_t i = 0; i < order.size(); ++i) {
        rank[order[i]] = static_cast<std::int32_t>(i);
        vertices[i] = m.vertices[order[i]];
    }
    m.vertices = std::move(vertices);
    std::vector<std::size_t> tets(m.tets.size());
    std::vector<std::int32_t> first(m.tets.size());
    for (std::size_t t = 0; t < m.tets.size(); ++t) {
        for (auto& v : m.tets[t])
            v = rank[static_cast<std::size_t>(v)];
        first[t] = *std::min_element(m.tets[t].begin(), m.tets[t].end());
        tets[t] = t;
    }
    std::stable_sort(tets.begin(), tets.end(), [&](std::size_t a, std::size_t b) { return first[a] < first[b]; });
    auto tets_sorted = m.tets;
    auto labels_sorted = m.tet_labels;
    for (std::size_t i = 0; i < tets.size(); ++i) {
        tets_sorted[i] = m.tets[tets[i]];
        labels_sorted[i] = m.tet_labels[tets[i]];
    }
    m.tets = std::move(tets_sorted);
    m.tet_labels = std::move(labels_sorted);
}

// CGAL's refinement and optimisation, then the complex's cells as a TetMesh in physical space.
// Serial (Sequential_tag) runs repeat exactly; Parallel_tag runs use TBB and vary run to run.
template <class Tag>
void run_mesh_3(const Domain& domain, const SizingField& field, const FacetSizeField& facet_size,
                const FacetDistanceField& facet_distance, const Prepared& pr,
                const core::ImageGeometry& g, const MeshParams& p, const std::function<void(const std::string&)>& say,
                core::TetMesh& out, MeshResult::ManifoldRepair& repair, MeshResult::Peeled& peeled,
                std::string& optimisation)
{
    using Tr = typename CGAL::Mesh_triangulation_3<Domain, CGAL::Default, Tag>::type;
    using C3t3 = CGAL::Mesh_complex_3_in_triangulation_3<Tr>;
    using Criteria = CGAL::Mesh_criteria_3<Tr>;
    namespace cp = CGAL::parameters;
    // Surface facets get fields of the position only: a facet size looked up per surface patch
    // index (the smaller of the two tissues' sizes) made CGAL 5.5's facet refinement run without
    // end on the phantom (docs/algorithms/meshing.md), while the same sizes found from the
    // voxels around the point finish; tets get per-tissue sizes by subdomain.
    Criteria criteria(cp::facet_angle = p.facet_angle, cp::facet_size = facet_size, cp::facet_distance = facet_distance,
                      cp::cell_radius_edge_ratio = p.radius_edge_ratio, cp::cell_size = field);

    C3t3 c3t3;
    insert_initial_points(c3t3, domain, pr, g, 12);
    if (c3t3.triangulation().dimension() != 3)
        CGAL::Mesh_3::internal::init_c3t3(c3t3, domain, criteria, 20);

    say("refining");
    const double tl = p.optimisation_time_limit;
    try {
        CGAL::refine_mesh_3(c3t3, domain, criteria,
                            p.lloyd ? CGAL::parameters::lloyd(cp::time_limit = tl) : CGAL::parameters::no_lloyd(),
                            p.odt ? CGAL::parameters::odt(cp::time_limit = tl) : CGAL::parameters::no_odt(),
                            CGAL::parameters::no_perturb(), CGAL::parameters::no_exude());
        // The optimisers run here rather than inside refine_mesh_3 so that their outcome can be
        // reported, and repeated: the perturber often stops early ("cannot improve") with
        // slivers left that a second pass removes (CGAL's liver: 351 tets below 10 degrees after
        // one pass, 2 after two), so passes repeat while they raise the smallest angle, three
        // at most.
        auto code_name = [](CGAL::Mesh_optimization_return_code c) {
            switch (c) {
            case CGAL::BOUND_REACHED: return "bound reached";
            case CGAL::TIME_LIMIT_REACHED: return "time limit reached";
            case CGAL::CANT_IMPROVE_ANYMORE: return "cannot improve";
            default: return "stopped";
            }
        };
        auto smallest_angle = [&] {
            double worst = 180;
            const auto& tr = c3t3.triangulation();
            for (auto c = c3t3.cells_in_complex_begin(); c != c3t3.cells_in_complex_end(); ++c) {
                std::array<Vec3, 4> q;
                for (int i = 0; i < 4; ++i) {
                    const auto& pt = tr.point(c, i).point();
                    q[static_cast<std::size_t>(i)] = {pt.x(), pt.y(), pt.z()};
                }
                const auto a = dihedral_angles(q[0], q[1], q[2], q[3]);
                worst = std::min(worst, *std::min_element(a.begin(), a.end()) * 180 / kPi);
            }
            return worst;
        };
        double before = -1;
        for (int pass = 0; pass < 3 && (p.perturb || p.exude); ++pass) {
            if (p.perturb) {
                say("perturbing slivers");
                const auto c = CGAL::perturb_mesh_3(c3t3, domain, cp::time_limit = tl, cp::sliver_bound = p.sliver_bound);
                optimisation += std::string(optimisation.empty() ? "" : ", ") + "perturb: " + code_name(c);
            }
            if (p.exude) {
                say("exuding slivers");
                const auto c = CGAL::exude_mesh_3(c3t3, cp::time_limit = tl, cp::sliver_bound = p.sliver_bound);
                optimisation += std::string(optimisation.empty() ? "" : ", ") + "exude: " + code_name(c);
            }
            const double after = smallest_angle();
            char buf[64];
            std::snprintf(buf, sizeof buf, " (smallest angle %.2f deg)", after);
            optimisation += buf;
            if (after >= p.sliver_bound || after <= before)
                break;
            before = after;
        }
    } catch (const std::exception& e) {
        throw core::SolverError(std::string("mesh_labels: CGAL Mesh_3 failed: ") + e.what());
    }

    say("extracting the mesh");
    // Every finite cell of the triangulation, labelled (0 outside the domain), with its
    // neighbours: the manifold repair needs the cells outside the domain too, to tell whether
    // two outside regions around a vertex are one.
    const auto& tr = c3t3.triangulation();
    detail::LabelledCells cells;
    std::unordered_map<typename Tr::Vertex_handle, std::int32_t> vindex;
    std::unordered_map<typename Tr::Cell_handle, std::int32_t> cindex;
    for (auto c : tr.finite_cell_handles())
        cindex.emplace(c, static_cast<std::int32_t>(cindex.size()));
    cells.cells.resize(cindex.size());
    cells.neighbours.resize(cindex.size());
    cells.labels.resize(cindex.size());
    cells.fixed.resize(cindex.size());
    std::size_t cu = 0;
    for (auto c : tr.finite_cell_handles()) { // the same order as cindex: runs repeat exactly
        for (int i = 0; i < 4; ++i) {
            const auto v = c->vertex(i);
            auto it = vindex.find(v);
            if (it == vindex.end()) {
                const auto& q = tr.point(v).point();
                it = vindex.emplace(v, static_cast<std::int32_t>(cells.vertices.size())).first;
                cells.vertices.push_back(Vec3{q.x(), q.y(), q.z()});
            }
            cells.cells[cu][static_cast<std::size_t>(i)] = it->second;
            const auto n = c->neighbor(i);
            const auto nt = cindex.find(n);
            cells.neighbours[cu][static_cast<std::size_t>(i)] = nt == cindex.end() ? -1 : nt->second;
        }
        const bool in = c3t3.is_in_complex(c);
        cells.labels[cu] = in ? static_cast<int>(c3t3.subdomain_index(c)) : 0;
        cells.fixed[cu] = in ? 0 : 1;
        ++cu;
    }
    auto repair_once = [&] {
        const auto s = detail::repair_manifold(cells);
        if (repair.tets_relabelled == 0 && repair.bad_vertices_before == 0)
            repair.bad_vertices_before = s.bad_vertices_before;
        repair.bad_vertices_after = s.bad_vertices_after;
        repair.tets_relabelled += s.relabelled;
        repair.tets_removed += s.removed;
        repair.volume += s.volume;
    };
    if (p.repair_manifold) {
        say("repairing non-manifold tissue boundaries");
        repair_once();
    }
    if (p.peel_slivers) {
        // Flat tets on the outer boundary, which the exuder cannot remove (their vertices stay
        // on the surface); removing one can make a vertex non-manifold, so repair after each
        // round (the peeled tets stay outside).
        say("peeling boundary slivers");
        for (int round = 0; round < 4; ++round) {
            const auto s = detail::peel_boundary_slivers(cells, p.sliver_bound);
            peeled.tets += s.tets;
            peeled.volume += s.volume;
            if (s.tets == 0)
                break;
            if (p.repair_manifold)
                repair_once();
        }
    }
    const bool flip = det3(g) < 0;
    std::vector<std::int32_t> index(cells.vertices.size(), -1);
    for (std::size_t c = 0; c < cells.cells.size(); ++c) {
        if (cells.labels[c] == 0)
            continue;
        std::array<std::int32_t, 4> t{};
        for (std::size_t i = 0; i < 4; ++i) {
            const auto v = static_cast<std::size_t>(cells.cells[c][i]);
            if (index[v] < 0) {
                index[v] = static_cast<std::int32_t>(out.vertices.size());
                out.vertices.push_back(to_physical(g, cells.vertices[v]));
            }
            t[i] = index[v];
        }
        if (flip)
            std::swap(t[0], t[1]);
        out.tets.push_back(t);
        out.tet_labels.push_back(cells.labels[c]);
    }
}

} // namespace

std::int64_t estimate_tet_count(const core::LabelImage3D& labels, const MeshParams& p)
{
    const double size = p.size > 0 ? p.size : default_size(labels);
    std::array<std::int64_t, 256> count{};
    for (auto v : labels.data)
        ++count[v];
    const auto tissues = selected_tissues(labels, p);
    double tets = 0;
    // A regular tet of circumradius r has volume 0.513 r^3; Delaunay refinement meshes come out
    // at about half that on average (measured, docs/algorithms/meshing.md), hence 0.25 r^3.
    for (int l : tissues) {
        double s = tissue_size(p, l, size);
        if (p.roi.kind != RegionOfInterest::Kind::None)
            s = std::min(s, p.roi.size > 0 ? p.roi.size : size / 3);
        tets += static_cast<double>(count[static_cast<std::size_t>(l)]) * voxel_volume(labels) / (0.25 * s * s * s);
    }
    return static_cast<std::int64_t>(tets);
}

MeshResult mesh_labels(const core::LabelImage3D& labels, const MeshParams& p)
{
    core::validate_geometry(labels, "mesh_labels: the label volume");
    if (labels.data.size() != labels.voxel_count() || labels.data.empty())
        throw core::InvalidInputError("mesh_labels: the label volume is empty or its data does not match its size");
    if (p.size < 0 || !std::isfinite(p.size))
        throw core::InvalidInputError("mesh_labels: size must be >= 0 mm, got " + std::to_string(p.size));
    if (!(p.radius_edge_ratio >= 1.0))
        throw core::InvalidInputError("mesh_labels: radius_edge_ratio must be >= 1, got " +
                                      std::to_string(p.radius_edge_ratio));
    if (!(p.facet_angle > 0 && p.facet_angle <= 30))
        throw core::InvalidInputError("mesh_labels: facet_angle must be in (0, 30] degrees, got " +
                                      std::to_string(p.facet_angle));
    if (!(p.curvature_factor > 0) || !(p.grading > 1) || !(p.distance_per_size > 0))
        throw core::InvalidInputError("mesh_labels: curvature_factor and distance_per_size must be > 0 and grading > 1");
    for (const auto& t : p.tissue_sizes)
        if (!(t.size >= 0) || !(t.facet_distance >= 0) || !std::isfinite(t.size) || !std::isfinite(t.facet_distance) ||
            (t.size == 0 && t.facet_distance == 0))
            throw core::InvalidInputError("mesh_labels: the size and boundary tolerance of tissue " +
                                          std::to_string(t.label) + " must be >= 0 mm, one of them > 0");
    if (p.roi.kind == RegionOfInterest::Kind::Spheres && (p.roi.centres.empty() || !(p.roi.radius >= 0)))
        throw core::InvalidInputError("mesh_labels: a spherical region of interest needs centres and a radius >= 0");
    if (p.roi.kind == RegionOfInterest::Kind::Box)
        for (int a = 0; a < 3; ++a)
            if (!(p.roi.box_lo[a] <= p.roi.box_hi[a]))
                throw core::InvalidInputError("mesh_labels: the region-of-interest box has lo > hi");
    const auto estimate = estimate_tet_count(labels, p);
    if (estimate > p.max_tets)
        throw core::InvalidInputError("mesh_labels: the requested mesh would have about " + std::to_string(estimate) +
                                      " tets, above the limit of " + std::to_string(p.max_tets) +
                                      "; use a larger element size");
    auto say = [&](const std::string& s) {
        if (p.progress)
            p.progress(s);
    };

    MeshResult result;
    const double size = p.size > 0 ? p.size : default_size(labels);
    result.size = size;
    say("preparing labels");
    Prepared pr = prepare(labels, p, result);
    const core::ImageGeometry& g = labels.geometry();

    // CGAL image: the padded labels, voxel size = spacing, translated so that original index i
    // sits at i * spacing.
    const auto& img = pr.labels;
    _image* im = _createImage(static_cast<std::size_t>(img.size[0]), static_cast<std::size_t>(img.size[1]),
                              static_cast<std::size_t>(img.size[2]), 1, g.spacing[0], g.spacing[1], g.spacing[2], 1,
                              WK_FIXED, SGN_UNSIGNED);
    if (im == nullptr)
        throw core::SolverError("mesh_labels: CGAL could not allocate the image");
    std::memcpy(im->data, img.data.data(), img.data.size());
    im->tx = static_cast<float>(-pr.pad * g.spacing[0]);
    im->ty = static_cast<float>(-pr.pad * g.spacing[1]);
    im->tz = static_cast<float>(-pr.pad * g.spacing[2]);
    CGAL::Image_3 image(im);

    CGAL::Random rng(p.seed);
    namespace cp = CGAL::parameters;
    const double min_spacing = std::min({g.spacing[0], g.spacing[1], g.spacing[2]});
    Domain domain = Domain::create_labeled_image_mesh_domain(image, cp::relative_error_bound = 1e-6,
                                                             cp::p_rng = &rng);

    // Sizing.
    SizingField field;
    field.fallback = size;
    for (int l = 1; l < 256; ++l)
        field.by_label[static_cast<std::size_t>(l)] = tissue_size(p, l, size);
    if (p.roi.kind != RegionOfInterest::Kind::None) {
        auto roi = std::make_shared<RoiFrame>();
        roi->kind = p.roi.kind;
        roi->size = p.roi.size > 0 ? p.roi.size : size / 3;
        roi->slope = p.grading - 1;
        roi->radius = p.roi.radius;
        if (p.roi.kind == RegionOfInterest::Kind::Box) {
            // The box's corners in the frame; a rotated box becomes its bounding box there.
            Vec3 lo{1e300, 1e300, 1e300}, hi{-1e300, -1e300, -1e300};
            for (int c = 0; c < 8; ++c) {
                const Vec3 q{(c & 1) ? p.roi.box_hi.x : p.roi.box_lo.x, (c & 2) ? p.roi.box_hi.y : p.roi.box_lo.y,
                             (c & 4) ? p.roi.box_hi.z : p.roi.box_lo.z};
                const Vec3 f = to_frame(g, q);
                for (int a = 0; a < 3; ++a) {
                    lo[a] = std::min(lo[a], f[a]);
                    hi[a] = std::max(hi[a], f[a]);
                }
            }
            roi->lo = lo;
            roi->hi = hi;
        } else {
            for (const auto& c : p.roi.centres)
                roi->centres.push_back(to_frame(g, c));
        }
        field.roi = roi;
    }
    // Boundary size from the curvature factor: a chord of length s on a circle of radius R
    // deviates s^2 / (8R); bounding the deviation by cf^2 R_min / 8 keeps s <= cf R for R >= R_min.
    const double r_min = p.min_feature_radius > 0 ? p.min_feature_radius : std::max({g.spacing[0], g.spacing[1], g.spacing[2]});
    const double cf_distance = std::max(p.curvature_factor * p.curvature_factor * r_min / 8, 0.05 * min_spacing);
    // Per tissue: the facet size is its element size; the distance bound is the curvature
    // factor's, or distance_per_size x its size when smaller (a tissue meshed finer than the
    // rest is thin: a bound the size of a vessel's radius cuts a fifth of its volume), or its own.
    auto maps = std::make_shared<BoundaryMaps>();
    maps->labels = &pr.labels;
    maps->pad = pr.pad;
    maps->spacing = g.spacing;
    for (int l = 1; l < 256; ++l) {
        const auto lu = static_cast<std::size_t>(l);
        maps->size[lu] = field.label_size(l);
        maps->distance[lu] = std::min(cf_distance, p.distance_per_size * maps->size[lu]);
        for (const auto& t : p.tissue_sizes)
            if (t.label == l && t.facet_distance > 0)
                maps->distance[lu] = t.facet_distance;
    }
    FacetSizeField facet_size;
    facet_size.maps = maps;
    facet_size.roi = field.roi;
    facet_size.fallback = size;
    FacetDistanceField facet_distance;
    facet_distance.maps = maps;
    facet_distance.fallback = cf_distance;
    for (const auto& c : pr.comps) {
        facet_size.fallback = std::min(facet_size.fallback, maps->size[static_cast<std::size_t>(c.label)]);
        facet_distance.fallback = std::min(facet_distance.fallback, maps->distance[static_cast<std::size_t>(c.label)]);
    }
    for (auto& t : result.tissues) {
        t.size = maps->size[static_cast<std::size_t>(t.label)];
        t.facet_distance = maps->distance[static_cast<std::size_t>(t.label)];
    }
#ifdef CGAL_LINKED_WITH_TBB
    const int threads = p.threads > 0 ? p.threads : static_cast<int>(tbb::info::default_concurrency());
    result.threads = threads;
    say("meshing on " + std::to_string(threads) + " thread(s), " + std::to_string(pr.comps.size()) + " components");
    if (threads > 1) {
        tbb::global_control limit(tbb::global_control::max_allowed_parallelism, static_cast<std::size_t>(threads));
        run_mesh_3<CGAL::Parallel_tag>(domain, field, facet_size, facet_distance, pr, g, p, say, result.mesh,
                                          result.manifold_repair, result.peeled, result.optimisation);
    } else {
        run_mesh_3<CGAL::Sequential_tag>(domain, field, facet_size, facet_distance, pr, g, p, say, result.mesh,
                                          result.manifold_repair, result.peeled, result.optimisation);
    }
#else
    result.threads = 1;
    run_mesh_3<CGAL::Sequential_tag>(domain, field, facet_size, facet_distance, pr, g, p, say, result.mesh,
                                          result.manifold_repair, result.peeled, result.optimisation);
#endif
    if (const auto& r = result.manifold_repair; r.bad_vertices_before > 0) {
        char buf[300];
        std::snprintf(buf, sizeof buf,
                      "non-manifold tissue boundaries at %lld vertices: %lld tets relabelled (%lld of them removed), "
                      "%.1f mm^3; %lld vertices left",
                      static_cast<long long>(r.bad_vertices_before), static_cast<long long>(r.tets_relabelled),
                      static_cast<long long>(r.tets_removed), r.volume, static_cast<long long>(r.bad_vertices_after));
        result.warnings.push_back(buf);
    }
    auto& out = result.mesh;
    // CGAL cells are positively oriented; drop any tet that rounding flattened (none expected).
    {
        core::TetMesh kept;
        kept.vertices = std::move(out.vertices);
        std::size_t dropped = 0;
        for (std::size_t t = 0; t < out.tets.size(); ++t) {
            const auto& q = out.tets[t];
            if (core::signed_volume(kept.vertices[q[0]], kept.vertices[q[1]], kept.vertices[q[2]], kept.vertices[q[3]]) > 0) {
                kept.tets.push_back(q);
                kept.tet_labels.push_back(out.tet_labels[t]);
            } else {
                ++dropped;
            }
        }
        if (dropped > 0)
            result.warnings.push_back(std::to_string(dropped) + " flat tets removed");
        out = std::move(kept);
    }
    if (out.tets.empty())
        throw core::SolverError("mesh_labels: CGAL produced no tets (element size " + std::to_string(size) +
                                " mm too large for the tissues?)");
    // The slivers CGAL's perturber left (it often stops early in parallel mode): raise the
    // smallest dihedral angle where it is below the target, over the whole mesh.
    if (p.slivers.enabled) {
        say("removing slivers");
        auto sl = remove_slivers(out, p.slivers);
        out = std::move(sl.mesh);
        result.slivers = sl.stats;
        if (sl.stats.interface_flips > 0) {
            char buf[200];
            std::snprintf(buf, sizeof buf, "%lld interface flips moved %.3f mm^3 between tissues",
                          static_cast<long long>(sl.stats.interface_flips), sl.stats.interface_flip_volume);
            result.warnings.push_back(buf);
        }
    }
    // Quality on the combined measure inside the region of interest: nothing before this
    // optimises it (CGAL's optimisers target the dihedral angle). It keeps every face on a
    // surface, so the volumes counted below do not change.
    if (p.improve.enabled && p.roi.kind != RegionOfInterest::Kind::None) {
        say("improving the combined measure in the region of interest");
        auto imp = improve_quality(out, p.roi, p.improve);
        out = std::move(imp.mesh);
        result.improvement = imp.stats;
    }
    // Last, so that the vertices the passes inserted are ordered too (and the passes, which
    // visit tets in index order among equals, see the same mesh either way).
    if (p.spatial_order)
        spatial_order(out);

    // Per component: which label tets lie in it (centroid's voxel), and volumes.
    say("checking components");
    const double vv = voxel_volume(g);
    for (std::size_t t = 0; t < out.tets.size(); ++t) {
        const auto& q = out.tets[t];
        const Vec3 cen = (out.vertices[q[0]] + out.vertices[q[1]] + out.vertices[q[2]] + out.vertices[q[3]]) / 4;
        const double vol = core::signed_volume(out.vertices[q[0]], out.vertices[q[1]], out.vertices[q[2]], out.vertices[q[3]]);
        const int lab = out.tet_labels[t];
        for (auto& tr : result.tissues)
            if (tr.label == lab) {
                tr.mesh_volume += vol;
                ++tr.tets;
            }
        const Vec3 f = to_frame(g, cen);
        const int ci = static_cast<int>(std::lround(f.x / g.spacing[0])) + pr.pad;
        const int cj = static_cast<int>(std::lround(f.y / g.spacing[1])) + pr.pad;
        const int ck = static_cast<int>(std::lround(f.z / g.spacing[2])) + pr.pad;
        // The centroid's voxel, or one of its 26 neighbours, of the same label.
        int comp = -1;
        for (int r = 0; r <= 1 && comp < 0; ++r)
            for (int dk = -r; dk <= r && comp < 0; ++dk)
                for (int dj = -r; dj <= r && comp < 0; ++dj)
                    for (int di = -r; di <= r && comp < 0; ++di)
                        if (img.contains(ci + di, cj + dj, ck + dk)) {
                            const std::size_t s = img.index(ci + di, cj + dj, ck + dk);
                            if (img.data[s] == lab)
                                comp = pr.component[s];
                        }
        if (comp >= 0) {
            auto& cr = pr.comps[static_cast<std::size_t>(comp)];
            cr.mesh_volume += vol;
            ++cr.tets;
        }
    }
    for (auto& cr : pr.comps) {
        cr.meshed = cr.tets > 0;
        for (auto& tr : result.tissues)
            if (tr.label == cr.label) {
                ++tr.components;
                tr.components_meshed += cr.meshed ? 1 : 0;
                tr.voxels += cr.voxels;
            }
        if (!cr.meshed && cr.voxels >= 100)
            result.warnings.push_back("a piece of label " + std::to_string(cr.label) + " with " +
                                      std::to_string(cr.voxels) + " voxels got no tet");
    }
    for (auto& tr : result.tissues)
        tr.label_volume = static_cast<double>(tr.voxels) * vv;
    result.components = std::move(pr.comps);
    return result;
}

} // namespace lobe::mesh
