#include "core/io/mesh_ply.h"

#include "core/io/file_util.h"

#include <bit>
#include <cstdlib>
#include <cstring>
#include <string>

namespace reconduit {
namespace {

static_assert(std::endian::native == std::endian::little,
              "mesh_ply copies floats and ints as they are in memory");

constexpr const char* kNormalProperties =
    "property float nx\nproperty float ny\nproperty float nz\n";
constexpr const char* kColorProperties =
    "property uchar red\nproperty uchar green\nproperty uchar blue\n";

std::string Header(const TriangleMesh& mesh) {
  std::string h = "ply\nformat binary_little_endian 1.0\ncomment Reconduit mesh\nelement vertex " +
                  std::to_string(mesh.NumVertices()) +
                  "\nproperty float x\nproperty float y\nproperty float z\n";
  if (!mesh.normals.empty()) h += kNormalProperties;
  if (!mesh.colors.empty()) h += kColorProperties;
  h += "element face " + std::to_string(mesh.NumFaces()) +
       "\nproperty list uchar int vertex_indices\nend_header\n";
  return h;
}

template <typename T>
void Append(const T& value, std::string* out) {
  const char* bytes = reinterpret_cast<const char*>(&value);
  out->append(bytes, sizeof(T));
}

template <typename T>
bool Take(const std::string& in, std::size_t* pos, T* value) {
  if (in.size() - *pos < sizeof(T)) return false;
  std::memcpy(value, in.data() + *pos, sizeof(T));
  *pos += sizeof(T);
  return true;
}

Status CheckMesh(const TriangleMesh& mesh) {
  const std::size_t n = mesh.NumVertices();
  if ((!mesh.normals.empty() && mesh.normals.size() != n) ||
      (!mesh.colors.empty() && mesh.colors.size() != n)) {
    return Status::InvalidArgument("mesh with " + std::to_string(n) + " vertices, " +
                                   std::to_string(mesh.normals.size()) + " normals and " +
                                   std::to_string(mesh.colors.size()) + " colours");
  }
  for (const Eigen::Vector3i& t : mesh.faces) {
    if (t.minCoeff() < 0 || t.maxCoeff() >= static_cast<int>(n))
      return Status::InvalidArgument("face index out of range in a mesh of " + std::to_string(n) +
                                     " vertices");
  }
  return Status::Ok();
}

}  // namespace

Status WriteMeshPly(const std::filesystem::path& path, const TriangleMesh& mesh) {
  if (Status s = CheckMesh(mesh); !s.ok()) return s;
  std::string out = Header(mesh);
  out.reserve(out.size() + mesh.NumVertices() * 27 + mesh.NumFaces() * 13);
  for (std::size_t v = 0; v < mesh.NumVertices(); ++v) {
    for (int k = 0; k < 3; ++k) Append(mesh.positions[v][k], &out);
    if (!mesh.normals.empty()) {
      for (int k = 0; k < 3; ++k) Append(mesh.normals[v][k], &out);
    }
    if (!mesh.colors.empty()) {
      for (int k = 0; k < 3; ++k) Append(mesh.colors[v][k], &out);
    }
  }
  for (const Eigen::Vector3i& t : mesh.faces) {
    Append(std::uint8_t{3}, &out);
    for (int k = 0; k < 3; ++k) Append(static_cast<std::int32_t>(t[k]), &out);
  }
  return WriteFileAtomically(path, out);
}

Result<TriangleMesh> ReadMeshPly(const std::filesystem::path& path) {
  auto bytes = ReadFile(path);
  if (!bytes.ok()) return bytes.status();
  const std::string& in = *bytes;
  const std::size_t end = in.find("end_header\n");
  if (end == std::string::npos) return Status::InvalidArgument(path.string() + ": no PLY header");
  const std::string header = in.substr(0, end + std::string("end_header\n").size());
  auto count = [&](const std::string& element) -> std::size_t {
    const std::size_t at = header.find("element " + element + " ");
    return at == std::string::npos
               ? 0
               : std::strtoull(header.c_str() + at + 9 + element.size(), nullptr, 10);
  };
  const std::size_t vertices = count("vertex"), faces = count("face");
  const bool normals = header.find(kNormalProperties) != std::string::npos;
  const bool colors = header.find(kColorProperties) != std::string::npos;
  // Sizes checked against the file before anything is allocated for them.
  const std::size_t vertex_bytes = 12 + (normals ? 12 : 0) + (colors ? 3 : 0);
  if (vertices > in.size() / vertex_bytes || faces > in.size() / 13 ||
      vertices * vertex_bytes + faces * 13 != in.size() - header.size()) {
    return Status::InvalidArgument(path.string() + ": truncated, or not a Reconduit mesh PLY");
  }
  TriangleMesh mesh;
  mesh.positions.resize(vertices);
  if (normals) mesh.normals.resize(vertices);
  if (colors) mesh.colors.resize(vertices);
  mesh.faces.resize(faces);
  if (header != Header(mesh))
    return Status::InvalidArgument(path.string() + ": not a Reconduit mesh PLY (header differs)");
  std::size_t pos = end + std::string("end_header\n").size();
  bool ok = true;
  for (std::size_t v = 0; v < vertices && ok; ++v) {
    for (int k = 0; k < 3; ++k) ok = ok && Take(in, &pos, &mesh.positions[v][k]);
    for (int k = 0; k < 3 && normals; ++k) ok = ok && Take(in, &pos, &mesh.normals[v][k]);
    for (int k = 0; k < 3 && colors; ++k) ok = ok && Take(in, &pos, &mesh.colors[v][k]);
  }
  for (std::size_t f = 0; f < faces && ok; ++f) {
    std::uint8_t corners = 0;
    ok = Take(in, &pos, &corners) && corners == 3;
    for (int k = 0; k < 3 && ok; ++k) {
      std::int32_t index = 0;
      ok = Take(in, &pos, &index);
      mesh.faces[f][k] = index;
    }
  }
  if (!ok) return Status::InvalidArgument(path.string() + ": truncated or not triangles");
  if (Status s = CheckMesh(mesh); !s.ok())
    return Status::InvalidArgument(path.string() + ": " + s.message());
  return mesh;
}

}  // namespace reconduit
