#include "lobe/mesh/surface.h"

#include "lobe/core/errors.h"
#include "lobe/mesh/quality.h"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/polygon_soup_to_polygon_mesh.h>
#include <CGAL/Polygon_mesh_processing/remesh.h>
#include <CGAL/Polygon_mesh_processing/self_intersections.h>
#include <CGAL/Surface_mesh.h>

#include <algorithm>
#include <array>
#include <map>
#include <numeric>
#include <set>
#include <unordered_map>
#include <utility>

namespace lobe::mesh {

namespace {

using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using SurfaceMesh = CGAL::Surface_mesh<K::Point_3>;
namespace pmp = CGAL::Polygon_mesh_processing;
using core::Vec3;

using Face = std::array<std::int32_t, 3>;

// Outward faces of a positively oriented tet (a, b, c, d), face i opposite vertex i.
constexpr int kTetFace[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};

Face key(const Face& f)
{
    Face k = f;
    std::sort(k.begin(), k.end());
    return k;
}

core::TriMesh compact(const std::vector<Vec3>& vertices, const std::vector<Face>& faces)
{
    core::TriMesh out;
    std::unordered_map<std::int32_t, std::int32_t> index;
    for (const auto& f : faces) {
        std::array<std::int32_t, 3> t{};
        for (int i = 0; i < 3; ++i) {
            auto it = index.find(f[static_cast<std::size_t>(i)]);
            if (it == index.end()) {
                it = index.emplace(f[static_cast<std::size_t>(i)], static_cast<std::int32_t>(out.vertices.size())).first;
                out.vertices.push_back(vertices[static_cast<std::size_t>(f[static_cast<std::size_t>(i)])]);
            }
            t[static_cast<std::size_t>(i)] = it->second;
        }
        out.triangles.push_back(t);
    }
    return out;
}

void check_wellformed(const core::TriMesh& s, const char* what)
{
    if (const auto problem = core::mesh_problem(s); !problem.empty())
        throw core::InvalidInputError(std::string(what) + ": the surface " + problem);
}

bool to_surface_mesh(const core::TriMesh& s, SurfaceMesh& sm)
{
    std::vector<K::Point_3> points;
    points.reserve(s.vertices.size());
    for (const auto& v : s.vertices)
        points.emplace_back(v.x, v.y, v.z);
    std::vector<std::vector<std::size_t>> polygons;
    polygons.reserve(s.triangles.size());
    for (const auto& t : s.triangles)
        polygons.push_back({static_cast<std::size_t>(t[0]), static_cast<std::size_t>(t[1]), static_cast<std::size_t>(t[2])});
    if (!pmp::is_polygon_soup_a_polygon_mesh(polygons))
        return false;
    pmp::polygon_soup_to_polygon_mesh(points, polygons, sm);
    return true;
}

} // namespace

std::vector<TissueSurface> tissue_surfaces(const core::TetMesh& mesh)
{
    if (const auto problem = core::mesh_problem(mesh); !problem.empty())
        throw core::InvalidInputError("tissue_surfaces: the mesh " + problem);
    // Each face with the (tet, oriented face) on each side.
    std::map<Face, std::vector<std::pair<std::size_t, Face>>> sides;
    for (std::size_t t = 0; t < mesh.tets.size(); ++t) {
        const auto& q = mesh.tets[t];
        for (const auto& f : kTetFace) {
            const Face o{q[static_cast<std::size_t>(f[0])], q[static_cast<std::size_t>(f[1])], q[static_cast<std::size_t>(f[2])]};
            sides[key(o)].emplace_back(t, o);
        }
    }
    std::set<int> labels(mesh.tet_labels.begin(), mesh.tet_labels.end());
    std::map<int, std::vector<Face>> faces;
    faces[0];
    for (const auto& [k, s] : sides) {
        if (s.size() == 1) {
            faces[0].push_back(s[0].second);
            faces[mesh.tet_labels[s[0].first]].push_back(s[0].second);
        } else {
            for (std::size_t i = 0; i < s.size(); ++i) {
                const int li = mesh.tet_labels[s[i].first];
                bool alone = true;
                for (std::size_t j = 0; j < s.size(); ++j)
                    alone = alone && (j == i || mesh.tet_labels[s[j].first] != li);
                if (alone)
                    faces[li].push_back(s[i].second);
            }
        }
    }
    std::vector<TissueSurface> out;
    for (const auto& [label, f] : faces)
        out.push_back({label, compact(mesh.vertices, f)});
    return out;
}

core::TriMesh taubin_smooth(const core::TriMesh& surface, const TaubinParams& params)
{
    check_wellformed(surface, "taubin_smooth");
    if (!(params.lambda > 0 && params.lambda < 1) || !(params.mu < -params.lambda) || params.iterations < 0)
        throw core::InvalidInputError("taubin_smooth: need 0 < lambda < 1, mu < -lambda and iterations >= 0");
    const std::size_t n = surface.vertices.size();
    std::vector<std::vector<std::int32_t>> nb(n);
    for (const auto& t : surface.triangles)
        for (int i = 0; i < 3; ++i) {
            const auto a = t[static_cast<std::size_t>(i)], b = t[static_cast<std::size_t>((i + 1) % 3)];
            nb[static_cast<std::size_t>(a)].push_back(b);
            nb[static_cast<std::size_t>(b)].push_back(a);
        }
    for (auto& v : nb) {
        std::sort(v.begin(), v.end());
        v.erase(std::unique(v.begin(), v.end()), v.end());
    }
    core::TriMesh out = surface;
    std::vector<Vec3> next(n);
    auto step = [&](double f) {
        for (std::size_t i = 0; i < n; ++i) {
            if (nb[i].empty()) {
                next[i] = out.vertices[i];
                continue;
            }
            Vec3 avg;
            for (auto j : nb[i])
                avg += out.vertices[static_cast<std::size_t>(j)];
            avg /= static_cast<double>(nb[i].size());
            next[i] = out.vertices[i] + f * (avg - out.vertices[i]);
        }
        out.vertices.swap(next);
    };
    for (int it = 0; it < params.iterations; ++it) {
        step(params.lambda);
        step(params.mu);
    }
    return out;
}

core::TriMesh remesh_surface(const core::TriMesh& surface, double target_edge, int iterations)
{
    check_wellformed(surface, "remesh_surface");
    if (!(target_edge > 0) || iterations < 1)
        throw core::InvalidInputError("remesh_surface: target_edge must be > 0 mm and iterations >= 1");
    SurfaceMesh sm;
    if (!to_surface_mesh(surface, sm))
        throw core::InvalidInputError("remesh_surface: the surface is not a manifold polygon mesh");
    pmp::isotropic_remeshing(faces(sm), target_edge, sm, CGAL::parameters::number_of_iterations(iterations));
    sm.collect_garbage();
    core::TriMesh out;
    for (auto v : sm.vertices()) {
        const auto& p = sm.point(v);
        out.vertices.push_back({p.x(), p.y(), p.z()});
    }
    for (auto f : sm.faces()) {
        std::array<std::int32_t, 3> t{};
        int i = 0;
        for (auto v : CGAL::vertices_around_face(sm.halfedge(f), sm))
            t[static_cast<std::size_t>(i++)] = static_cast<std::int32_t>(v.idx());
        out.triangles.push_back(t);
    }
    return out;
}

SurfaceCheck check_surface(const core::TriMesh& s)
{
    check_wellformed(s, "check_surface");
    SurfaceCheck c;
    c.vertices = static_cast<std::int64_t>(s.vertices.size());
    c.triangles = static_cast<std::int64_t>(s.triangles.size());
    // Edges: undirected count and directed count.
    std::map<std::pair<std::int32_t, std::int32_t>, int> undirected, directed;
    std::map<std::pair<std::int32_t, std::int32_t>, std::vector<std::size_t>> edge_faces;
    for (std::size_t t = 0; t < s.triangles.size(); ++t) {
        const auto& f = s.triangles[t];
        for (int i = 0; i < 3; ++i) {
            const auto a = f[static_cast<std::size_t>(i)], b = f[static_cast<std::size_t>((i + 1) % 3)];
            ++directed[{a, b}];
            edge_faces[{std::min(a, b), std::max(a, b)}].push_back(t);
        }
        const Vec3 &p = s.vertices[static_cast<std::size_t>(f[0])], &q = s.vertices[static_cast<std::size_t>(f[1])],
                   &r = s.vertices[static_cast<std::size_t>(f[2])];
        c.area += core::norm(core::cross(q - p, r - p)) / 2;
        c.volume += core::dot(p, core::cross(q, r)) / 6;
        const double tq = triangle_quality(p, q, r);
        c.min_triangle_quality = t == 0 ? tq : std::min(c.min_triangle_quality, tq);
        c.mean_triangle_quality += tq;
    }
    if (!s.triangles.empty())
        c.mean_triangle_quality /= static_cast<double>(s.triangles.size());
    for (const auto& [e, n] : directed)
        if (n > 1)
            c.inconsistent_edges += 1;
    // Triangle components (union-find over shared edges).
    std::vector<std::size_t> parent(s.triangles.size());
    std::iota(parent.begin(), parent.end(), std::size_t{0});
    auto find = [&](std::size_t x) {
        while (parent[x] != x)
            x = parent[x] = parent[parent[x]];
        return x;
    };
    for (const auto& [e, fs] : edge_faces) {
        if (fs.size() == 1)
            ++c.boundary_edges;
        if (fs.size() > 2)
            ++c.non_manifold_edges;
        for (std::size_t i = 1; i < fs.size(); ++i)
            parent[find(fs[i])] = find(fs[0]);
    }
    for (std::size_t t = 0; t < parent.size(); ++t)
        c.components += find(t) == t;
    // Non-manifold vertices: the triangles around a vertex must form one fan (connected
    // through edges that contain the vertex).
    std::vector<std::vector<std::size_t>> around(s.vertices.size());
    for (std::size_t t = 0; t < s.triangles.size(); ++t)
        for (auto v : s.triangles[t])
            around[static_cast<std::size_t>(v)].push_back(t);
    for (std::size_t v = 0; v < around.size(); ++v) {
        const auto& fs = around[v];
        if (fs.size() < 2)
            continue;
        std::map<std::size_t, std::size_t> local;
        for (std::size_t i = 0; i < fs.size(); ++i)
            local[fs[i]] = i;
        std::vector<std::size_t> lp(fs.size());
        std::iota(lp.begin(), lp.end(), std::size_t{0});
        auto lfind = [&](std::size_t x) {
            while (lp[x] != x)
                x = lp[x] = lp[lp[x]];
            return x;
        };
        for (auto t : fs)
            for (auto w : s.triangles[t]) {
                if (static_cast<std::size_t>(w) == v)
                    continue;
                const auto key = std::make_pair(std::min<std::int32_t>(static_cast<std::int32_t>(v), w),
                                                std::max<std::int32_t>(static_cast<std::int32_t>(v), w));
                for (auto u : edge_faces[key])
                    lp[lfind(local[u])] = lfind(local[t]);
            }
        int fans = 0;
        for (std::size_t i = 0; i < lp.size(); ++i)
            fans += lfind(i) == i;
        if (fans > 1)
            ++c.non_manifold_vertices;
    }
    // Self-intersections with CGAL, when the surface is a polygon mesh (otherwise it has
    // already failed the manifold check).
    SurfaceMesh sm;
    if (c.non_manifold_edges == 0 && c.non_manifold_vertices == 0 && to_surface_mesh(s, sm)) {
        std::vector<std::pair<SurfaceMesh::Face_index, SurfaceMesh::Face_index>> pairs;
        pmp::self_intersections(faces(sm), sm, std::back_inserter(pairs));
        c.self_intersections = static_cast<std::int64_t>(pairs.size());
    }
    return c;
}

std::string describe(const SurfaceCheck& c)
{
    std::string s;
    if (c.ok()) {
        s = "closed, manifold, oriented, no self-intersections";
    } else {
        std::vector<std::string> bad;
        if (!c.closed())
            bad.push_back(std::to_string(c.boundary_edges) + " boundary edges");
        if (c.non_manifold_edges > 0)
            bad.push_back(std::to_string(c.non_manifold_edges) + " non-manifold edges");
        if (c.non_manifold_vertices > 0)
            bad.push_back(std::to_string(c.non_manifold_vertices) + " non-manifold vertices");
        if (c.inconsistent_edges > 0)
            bad.push_back(std::to_string(c.inconsistent_edges) + " inconsistently oriented edges");
        if (c.inconsistent_edges == 0 && c.volume <= 0)
            bad.push_back("oriented inward");
        if (c.self_intersections > 0)
            bad.push_back(std::to_string(c.self_intersections) + " self-intersecting triangle pairs");
        for (std::size_t i = 0; i < bad.size(); ++i)
            s += (i ? ", " : "") + bad[i];
    }
    char buf[200];
    std::snprintf(buf, sizeof buf, ": %lld vertices, %lld triangles, %d components, area %.1f mm^2, volume %.1f mm^3",
                  static_cast<long long>(c.vertices), static_cast<long long>(c.triangles), c.components, c.area, c.volume);
    return s + buf;
}

} // namespace lobe::mesh
