// Surface export and import through assimp (formats and precision: lobe/io/surface.h).

#include "lobe/io/surface.h"

#include "lobe/io/limits.h"

#include "lobe/core/errors.h"

#include <assimp/Exporter.hpp>
#include <assimp/Importer.hpp>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cctype>
#include <cmath>
#include <cstring>
#include <memory>
#include <string>
#include <system_error>
#include <unordered_map>
#include <unistd.h>
#include <vector>

namespace lobe::io {
namespace {

using core::InvalidInputError;
using core::IoError;

struct Format {
    const char* extension;
    const char* assimp_id; // Assimp::Exporter format id
};
constexpr std::array<Format, 5> kFormats{{
    {".stl", "stlb"},     // binary: a third of ASCII's size, and exact float32
    {".obj", "objnomtl"}, // no .mtl: a surface has no material worth a second file
    {".ply", "plyb"},
    {".gltf", "gltf2"},
    {".glb", "glb2"},
}};

std::string lower(std::string s)
{
    std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    return s;
}

const Format& format_of(const std::filesystem::path& path)
{
    const std::string ext = lower(path.extension().string());
    for (const auto& f : kFormats)
        if (ext == f.extension)
            return f;
    throw InvalidInputError(path.string() + ": unknown surface format '" + path.extension().string() +
                            "' (use .stl, .obj, .ply, .gltf or .glb)");
}

// A hidden folder beside the target: assimp writes there under the final file name (so that a
// .gltf names its buffer "mesh.bin", not a temporary), and the folder goes away whatever happens.
class TempDir {
public:
    explicit TempDir(const std::filesystem::path& target)
    {
        static std::atomic<unsigned> counter{0};
        const auto parent = target.has_parent_path() ? target.parent_path() : std::filesystem::path(".");
        std::error_code ec;
        if (!std::filesystem::is_directory(parent, ec))
            throw IoError(target.string() + ": cannot write: directory '" + parent.string() + "' does not exist");
        dir_ = parent / (".tmp-" + std::to_string(::getpid()) + "-" + std::to_string(counter++) + "-" +
                         target.filename().string() + ".d");
        if (!std::filesystem::create_directory(dir_, ec) || ec)
            throw IoError(target.string() + ": cannot create temporary folder '" + dir_.string() + "': " + ec.message());
    }
    TempDir(const TempDir&) = delete;
    TempDir& operator=(const TempDir&) = delete;
    ~TempDir()
    {
        std::error_code ec;
        std::filesystem::remove_all(dir_, ec);
    }
    const std::filesystem::path& path() const { return dir_; }

private:
    std::filesystem::path dir_;
};

// The scene owns everything it points to (aiScene's destructor frees meshes, materials, nodes).
std::unique_ptr<aiScene> make_scene(const core::TriMesh& mesh)
{
    auto scene = std::make_unique<aiScene>();
    scene->mRootNode = new aiNode("surface");
    scene->mRootNode->mNumMeshes = 1;
    scene->mRootNode->mMeshes = new unsigned int[1]{0};
    // glTF and OBJ exporters expect a material; a default one is neutral grey in every viewer.
    scene->mNumMaterials = 1;
    scene->mMaterials = new aiMaterial*[1]{new aiMaterial()};
    scene->mNumMeshes = 1;
    scene->mMeshes = new aiMesh*[1]{new aiMesh()};
    aiMesh& m = *scene->mMeshes[0];
    m.mName = aiString("surface");
    m.mMaterialIndex = 0;
    m.mPrimitiveTypes = aiPrimitiveType_TRIANGLE;
    m.mNumVertices = static_cast<unsigned>(mesh.vertices.size());
    m.mVertices = new aiVector3D[mesh.vertices.size()];
    for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
        const auto& v = mesh.vertices[i];
        m.mVertices[i] = aiVector3D(static_cast<ai_real>(v.x), static_cast<ai_real>(v.y), static_cast<ai_real>(v.z));
    }
    m.mNumFaces = static_cast<unsigned>(mesh.triangles.size());
    m.mFaces = new aiFace[mesh.triangles.size()];
    for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
        aiFace& f = m.mFaces[t];
        f.mNumIndices = 3;
        f.mIndices = new unsigned int[3];
        for (int k = 0; k < 3; ++k)
            f.mIndices[k] = static_cast<unsigned>(mesh.triangles[t][static_cast<std::size_t>(k)]);
    }
    return scene;
}

void check_writable(const std::filesystem::path& path, const core::TriMesh& mesh)
{
    const std::string file = path.string();
    if (mesh.triangles.empty())
        throw InvalidInputError(file + ": the surface has no triangles");
    if (mesh.vertices.size() > kMaxMeshElements || mesh.triangles.size() > kMaxMeshElements)
        throw InvalidInputError(file + ": the surface exceeds the limit of " + std::to_string(kMaxMeshElements) +
                                " vertices or triangles");
    if (const std::string problem = core::mesh_problem(mesh); !problem.empty())
        throw InvalidInputError(file + ": cannot write the surface: " + problem);
    for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
        const auto& v = mesh.vertices[i];
        if (!std::isfinite(v.x) || !std::isfinite(v.y) || !std::isfinite(v.z))
            throw InvalidInputError(file + ": cannot write the surface: vertex " + std::to_string(i) +
                                    " has a non-finite coordinate");
    }
}

// A position as assimp holds it, and a hash of its exact bytes, for joining vertices that are
// the same point.
using PositionKey = std::array<ai_real, 3>;
struct PositionHash {
    std::size_t operator()(const PositionKey& p) const
    {
        unsigned char bytes[sizeof(PositionKey)];
        std::memcpy(bytes, p.data(), sizeof bytes);
        std::size_t h = 1469598103934665603ull; // FNV-1a
        for (const unsigned char b : bytes)
            h = (h ^ b) * 1099511628211ull;
        return h;
    }
};

} // namespace

void write_surface(const std::filesystem::path& path, const core::TriMesh& mesh)
{
    const Format& format = format_of(path);
    check_writable(path, mesh);
    const std::unique_ptr<aiScene> scene = make_scene(mesh);

    TempDir temp(path);
    const std::filesystem::path staged = temp.path() / path.filename();
    Assimp::Exporter exporter;
    if (exporter.Export(scene.get(), format.assimp_id, staged.string(), 0u) != aiReturn_SUCCESS)
        throw IoError(path.string() + ": assimp cannot write it: " + exporter.GetErrorString());

    // Sidecars (the .gltf's .bin) first, the file itself last: whoever sees the new file sees
    // everything it refers to.
    std::vector<std::filesystem::path> files;
    std::error_code ec;
    for (const auto& entry : std::filesystem::directory_iterator(temp.path(), ec))
        if (entry.path().filename() != path.filename())
            files.push_back(entry.path());
    if (ec)
        throw IoError(path.string() + ": cannot list the temporary folder: " + ec.message());
    if (!std::filesystem::exists(staged, ec))
        throw IoError(path.string() + ": assimp reported success but wrote no file");
    files.push_back(staged);
    const auto parent = path.has_parent_path() ? path.parent_path() : std::filesystem::path(".");
    for (const auto& f : files) {
        std::filesystem::rename(f, parent / f.filename(), ec);
        if (ec)
            throw IoError((parent / f.filename()).string() + ": cannot move the finished file into place: " + ec.message());
    }
}

core::TriMesh read_surface(const std::filesystem::path& path)
{
    const std::string file = path.string();
    std::error_code ec;
    if (!std::filesystem::exists(path, ec))
        throw IoError(file + ": no such file");
    if (std::filesystem::is_directory(path, ec))
        throw IoError(file + ": is a directory, not a surface file");

    Assimp::Importer importer;
    // Points and lines are not part of a surface; SortByPType separates them and this drops them.
    importer.SetPropertyInteger(AI_CONFIG_PP_SBP_REMOVE, aiPrimitiveType_POINT | aiPrimitiveType_LINE);
    const aiScene* scene = importer.ReadFile(file, aiProcess_Triangulate | aiProcess_SortByPType |
                                                       aiProcess_PreTransformVertices | aiProcess_ValidateDataStructure);
    if (!scene)
        throw IoError(file + ": assimp cannot read it as a surface: " + importer.GetErrorString());

    core::TriMesh out;
    std::unordered_map<PositionKey, std::int32_t, PositionHash> index_of;
    std::size_t total_faces = 0;
    for (unsigned mi = 0; mi < scene->mNumMeshes; ++mi) {
        const aiMesh* m = scene->mMeshes[mi];
        if (!m || !(m->mPrimitiveTypes & aiPrimitiveType_TRIANGLE))
            continue;
        total_faces += m->mNumFaces;
        if (total_faces > kMaxMeshElements || m->mNumVertices > kMaxMeshElements)
            throw InvalidInputError(file + ": more than " + std::to_string(kMaxMeshElements) + " triangles or vertices");
        // Join vertices by exact position, not by assimp's JoinIdenticalVertices, which also
        // compares normals and so keeps STL's per-face copies apart.
        std::vector<std::int32_t> remap(m->mNumVertices);
        for (unsigned v = 0; v < m->mNumVertices; ++v) {
            const aiVector3D& p = m->mVertices[v];
            // "+ 0" turns -0 into +0: the same point, whose bits must hash alike.
            const PositionKey key{p.x + ai_real(0), p.y + ai_real(0), p.z + ai_real(0)};
            const auto [it, inserted] = index_of.emplace(key, static_cast<std::int32_t>(out.vertices.size()));
            if (inserted) {
                if (!std::isfinite(key[0]) || !std::isfinite(key[1]) || !std::isfinite(key[2]))
                    throw InvalidInputError(file + ": vertex " + std::to_string(v) + " has a non-finite coordinate");
                out.vertices.push_back({double(key[0]), double(key[1]), double(key[2])});
            }
            remap[v] = it->second;
        }
        for (unsigned f = 0; f < m->mNumFaces; ++f) {
            const aiFace& face = m->mFaces[f];
            if (face.mNumIndices != 3)
                continue;
            std::array<std::int32_t, 3> tri{};
            for (int k = 0; k < 3; ++k) {
                const unsigned idx = face.mIndices[k];
                if (idx >= m->mNumVertices) // ValidateDataStructure checks this too; cheap to be sure
                    throw InvalidInputError(file + ": triangle " + std::to_string(f) + " has vertex index " +
                                            std::to_string(idx) + " outside [0, " + std::to_string(m->mNumVertices) + ")");
                tri[static_cast<std::size_t>(k)] = remap[idx];
            }
            if (tri[0] == tri[1] || tri[1] == tri[2] || tri[0] == tri[2])
                continue; // degenerate: two corners at the same point
            out.triangles.push_back(tri);
        }
    }
    if (out.triangles.empty())
        throw InvalidInputError(file + ": contains no triangles");
    return out;
}

} // namespace lobe::io
