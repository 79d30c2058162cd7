#include "core/io/gltf.h"

#include "core/io/file_util.h"

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <limits>
#include <random>
#include <set>
#include <unistd.h>
#include <unordered_map>
#include <utility>

namespace reconduit {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

constexpr int kArrayBuffer = 34962;
constexpr int kElementArrayBuffer = 34963;
constexpr int kUnsignedByte = 5121;
constexpr int kUnsignedShort = 5123;
constexpr int kUnsignedInt = 5125;
constexpr int kFloat = 5126;
constexpr int kLinear = 9729;
constexpr int kLinearMipmapLinear = 9987;
constexpr int kClampToEdge = 33071;
constexpr const char* kUnlit = "KHR_materials_unlit";

// The vertices and triangles of one primitive, already in the glTF frame.
struct PrimitiveData {
  std::vector<Eigen::Vector3f> positions;
  std::vector<Eigen::Vector3f> normals;             // Empty or one per position.
  std::vector<std::array<std::uint8_t, 4>> colors;  // Empty or one per position.
  std::vector<Eigen::Vector2f> texcoords;           // Empty or one per position.
  std::vector<std::uint32_t> indices;               // 3 per triangle.
};

// The binary chunk and the JSON arrays that describe it, built together.
class GlbBuilder {
 public:
  // Appends `bytes` at a 4-byte aligned offset; returns the bufferView's index. target 0: none.
  int AddBufferView(const void* data, std::size_t bytes, int target) {
    const std::size_t offset = bin_.size();
    bin_.append(static_cast<const char*>(data), bytes);
    bin_.append((4 - bin_.size() % 4) % 4, '\0');
    json view = {{"buffer", 0}, {"byteOffset", offset}, {"byteLength", bytes}};
    if (target != 0) view["target"] = target;
    buffer_views_.push_back(std::move(view));
    return static_cast<int>(buffer_views_.size()) - 1;
  }

  // An accessor over a whole, tightly packed bufferView.
  int AddAccessor(
      int view, int component_type, std::size_t count, const char* type, bool normalized = false) {
    json accessor = {
        {"bufferView", view}, {"componentType", component_type}, {"count", count}, {"type", type}};
    if (normalized) accessor["normalized"] = true;
    accessors_.push_back(std::move(accessor));
    return static_cast<int>(accessors_.size()) - 1;
  }

  json& accessor(int index) { return accessors_[static_cast<std::size_t>(index)]; }
  const std::string& bin() const { return bin_; }
  json TakeBufferViews() { return std::move(buffer_views_); }
  json TakeAccessors() { return std::move(accessors_); }

 private:
  std::string bin_;
  json buffer_views_ = json::array();
  json accessors_ = json::array();
};

template <typename T>
int AddArray(GlbBuilder* builder, const std::vector<T>& values, int target) {
  return builder->AddBufferView(values.data(), values.size() * sizeof(T), target);
}

std::string Quoted(const std::string& s) { return "'" + s + "'"; }

Status CheckMesh(const TriangleMesh& mesh) {
  const std::size_t nv = mesh.NumVertices(), nf = mesh.NumFaces();
  if (nf == 0 || nv == 0) {
    return Status::InvalidArgument("model.glb: the mesh is empty (" + std::to_string(nv) +
                                   " vertices, " + std::to_string(nf) + " faces)");
  }
  if (nv > std::numeric_limits<std::uint32_t>::max() / 2) {
    return Status::InvalidArgument("model.glb: too many vertices");
  }
  if (!mesh.normals.empty() && mesh.normals.size() != nv) {
    return Status::InvalidArgument("model.glb: " + std::to_string(mesh.normals.size()) +
                                   " normals for " + std::to_string(nv) + " vertices");
  }
  if (!mesh.colors.empty() && mesh.colors.size() != nv) {
    return Status::InvalidArgument("model.glb: " + std::to_string(mesh.colors.size()) +
                                   " colours for " + std::to_string(nv) + " vertices");
  }
  for (std::size_t i = 0; i < nv; ++i) {
    if (!mesh.positions[i].allFinite()) {
      return Status::InvalidArgument("model.glb: vertex " + std::to_string(i) + " is not finite");
    }
  }
  for (std::size_t f = 0; f < nf; ++f) {
    for (int k = 0; k < 3; ++k) {
      const int v = mesh.faces[f][k];
      if (v < 0 || static_cast<std::size_t>(v) >= nv) {
        return Status::InvalidArgument("model.glb: face " + std::to_string(f) +
                                       " refers to vertex " + std::to_string(v) + " of " +
                                       std::to_string(nv));
      }
    }
  }
  return Status::Ok();
}

Status CheckTexture(const TriangleMesh& mesh) {
  const std::size_t nf = mesh.NumFaces();
  if (!mesh.HasTexture()) {
    if (!mesh.texcoords.empty() || !mesh.face_pages.empty()) {
      return Status::InvalidArgument("model.glb: texture coordinates without texture pages");
    }
    return Status::Ok();
  }
  if (mesh.texcoords.size() != 3 * nf) {
    return Status::InvalidArgument("model.glb: " + std::to_string(mesh.texcoords.size()) +
                                   " texture coordinates for " + std::to_string(nf) +
                                   " faces (3 per face expected)");
  }
  if (mesh.face_pages.size() != nf) {
    return Status::InvalidArgument("model.glb: " + std::to_string(mesh.face_pages.size()) +
                                   " face pages for " + std::to_string(nf) + " faces");
  }
  for (std::size_t f = 0; f < nf; ++f) {
    const int page = mesh.face_pages[f];
    if (page < 0 || static_cast<std::size_t>(page) >= mesh.texture_pages.size()) {
      return Status::InvalidArgument("model.glb: face " + std::to_string(f) + " is on page " +
                                     std::to_string(page) + " of " +
                                     std::to_string(mesh.texture_pages.size()));
    }
  }
  for (std::size_t p = 0; p < mesh.texture_pages.size(); ++p) {
    const cv::Mat& page = mesh.texture_pages[p];
    if (page.empty() || page.type() != CV_8UC3) {
      return Status::InvalidArgument("model.glb: texture page " + std::to_string(p) +
                                     " is not a non-empty CV_8UC3 image");
    }
  }
  for (const Eigen::Vector2f& uv : mesh.texcoords) {
    if (!uv.allFinite()) return Status::InvalidArgument("model.glb: non-finite texcoord");
  }
  return Status::Ok();
}

Status CheckCameras(const std::vector<GltfCameraView>& cameras) {
  std::set<std::string> names;
  for (const GltfCameraView& view : cameras) {
    if (view.name.empty()) return Status::InvalidArgument("model.glb: a camera without a name");
    if (!names.insert(view.name).second) {
      return Status::InvalidArgument("model.glb: two cameras named " + Quoted(view.name));
    }
    std::string error;
    if (!view.camera.Check(&error)) {
      return Status::InvalidArgument("model.glb: camera " + Quoted(view.name) + ": " + error);
    }
    if (!view.cam_from_world.translation.allFinite() ||
        !view.cam_from_world.rotation.coeffs().allFinite()) {
      return Status::InvalidArgument("model.glb: camera " + Quoted(view.name) +
                                     " has a non-finite pose");
    }
  }
  return Status::Ok();
}

// Where a point or a direction of the world goes in the glTF frame.
struct FrameMap {
  Eigen::Matrix3f rotation;
  Eigen::Vector3f translation;
  Eigen::Vector3f Point(const Eigen::Vector3f& p) const { return rotation * p + translation; }
  // Unit normal; glTF +Y for a normal that cannot be normalised (the validator rejects
  // non-unit normals).
  Eigen::Vector3f Normal(const Eigen::Vector3f& n) const {
    const Eigen::Vector3f r = rotation * n;
    const float norm = r.norm();
    if (!(norm > 1e-12f) || !std::isfinite(norm)) return Eigen::Vector3f::UnitY();
    return r / norm;
  }
};

PrimitiveData UntexturedPrimitive(const TriangleMesh& mesh, const FrameMap& map) {
  PrimitiveData data;
  const std::size_t nv = mesh.NumVertices();
  data.positions.reserve(nv);
  for (const Eigen::Vector3f& p : mesh.positions) data.positions.push_back(map.Point(p));
  data.normals.reserve(mesh.normals.size());
  for (const Eigen::Vector3f& n : mesh.normals) data.normals.push_back(map.Normal(n));
  data.colors.reserve(mesh.colors.size());
  for (const auto& c : mesh.colors) data.colors.push_back({c[0], c[1], c[2], 255});
  data.indices.reserve(3 * mesh.NumFaces());
  for (const Eigen::Vector3i& face : mesh.faces) {
    for (int k = 0; k < 3; ++k) data.indices.push_back(static_cast<std::uint32_t>(face[k]));
  }
  return data;
}

// A mesh vertex with one texture coordinate: the unit of vertex splitting.
struct CornerKey {
  std::uint32_t vertex;
  std::uint32_t u_bits;
  std::uint32_t v_bits;
  bool operator==(const CornerKey&) const = default;
};

struct CornerKeyHash {
  std::size_t operator()(const CornerKey& key) const {
    std::uint64_t h = key.vertex;
    h = h * 0x9E3779B97F4A7C15ull ^ key.u_bits;
    h = h * 0x9E3779B97F4A7C15ull ^ key.v_bits;
    return static_cast<std::size_t>(h ^ (h >> 29));
  }
};

// The primitive of one page's faces (listed in `faces`), vertices split per texcoord.
PrimitiveData PagePrimitive(const TriangleMesh& mesh,
                            const std::vector<std::uint32_t>& faces,
                            const FrameMap& map) {
  PrimitiveData data;
  std::unordered_map<CornerKey, std::uint32_t, CornerKeyHash> index_of;
  index_of.reserve(faces.size() * 2);
  data.indices.reserve(3 * faces.size());
  for (const std::uint32_t f : faces) {
    for (int k = 0; k < 3; ++k) {
      const int v = mesh.faces[f][k];
      Eigen::Vector2f uv = mesh.texcoords[3 * static_cast<std::size_t>(f) + k];
      uv += Eigen::Vector2f::Zero();  // -0 -> +0, so that equal texcoords have equal bits.
      CornerKey key{static_cast<std::uint32_t>(v), 0, 0};
      std::memcpy(&key.u_bits, &uv.x(), 4);
      std::memcpy(&key.v_bits, &uv.y(), 4);
      const auto [it, inserted] =
          index_of.emplace(key, static_cast<std::uint32_t>(data.positions.size()));
      if (inserted) {
        data.positions.push_back(map.Point(mesh.positions[v]));
        if (!mesh.normals.empty()) data.normals.push_back(map.Normal(mesh.normals[v]));
        data.texcoords.push_back(uv);
      }
      data.indices.push_back(it->second);
    }
  }
  return data;
}

// Adds the accessors of `data` and returns its primitive object.
json AddPrimitive(GlbBuilder* builder, const PrimitiveData& data, int material) {
  json attributes;
  const std::size_t n = data.positions.size();
  Eigen::Vector3f lo = Eigen::Vector3f::Constant(std::numeric_limits<float>::max());
  Eigen::Vector3f hi = -lo;
  for (const Eigen::Vector3f& p : data.positions) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  const int position =
      builder->AddAccessor(AddArray(builder, data.positions, kArrayBuffer), kFloat, n, "VEC3");
  builder->accessor(position)["min"] = {lo.x(), lo.y(), lo.z()};
  builder->accessor(position)["max"] = {hi.x(), hi.y(), hi.z()};
  attributes["POSITION"] = position;
  if (!data.normals.empty()) {
    attributes["NORMAL"] =
        builder->AddAccessor(AddArray(builder, data.normals, kArrayBuffer), kFloat, n, "VEC3");
  }
  if (!data.colors.empty()) {
    attributes["COLOR_0"] = builder->AddAccessor(AddArray(builder, data.colors, kArrayBuffer),
                                                 kUnsignedByte, n, "VEC4", true);
  }
  if (!data.texcoords.empty()) {
    attributes["TEXCOORD_0"] =
        builder->AddAccessor(AddArray(builder, data.texcoords, kArrayBuffer), kFloat, n, "VEC2");
  }
  int indices = 0;
  if (n <= 65535) {  // 65535 itself is the primitive-restart value, which glTF forbids.
    std::vector<std::uint16_t> small(data.indices.begin(), data.indices.end());
    indices = builder->AddAccessor(AddArray(builder, small, kElementArrayBuffer), kUnsignedShort,
                                   small.size(), "SCALAR");
  } else {
    indices = builder->AddAccessor(AddArray(builder, data.indices, kElementArrayBuffer),
                                   kUnsignedInt, data.indices.size(), "SCALAR");
  }
  return {{"attributes", std::move(attributes)},
          {"indices", indices},
          {"material", material},
          {"mode", 4}};
}

json UnlitExtension() { return {{kUnlit, json::object()}}; }

// The JSON arrays of images, textures and materials.
struct Materials {
  json images = json::array();
  json textures = json::array();
  json materials = json::array();
  bool uses_unlit = false;
};

Result<int> AddPageMaterial(
    GlbBuilder* builder, const cv::Mat& page, int page_index, int quality, Materials* out) {
  std::vector<std::uint8_t> jpeg;
  try {
    if (!cv::imencode(".jpg", page, jpeg, {cv::IMWRITE_JPEG_QUALITY, quality})) {
      return Status::Internal("model.glb: JPEG encoding of page " + std::to_string(page_index) +
                              " failed");
    }
  } catch (const cv::Exception& e) {
    return Status::Internal("model.glb: JPEG encoding failed: " + std::string(e.what()));
  }
  const int view = AddArray(builder, jpeg, 0);
  const std::string name = "page" + std::to_string(page_index);
  out->images.push_back({{"bufferView", view}, {"mimeType", "image/jpeg"}, {"name", name}});
  out->textures.push_back({{"sampler", 0}, {"source", out->images.size() - 1}});
  out->materials.push_back({{"name", name},
                            {"pbrMetallicRoughness",
                             {{"baseColorTexture", {{"index", out->textures.size() - 1}}},
                              {"metallicFactor", 0.0},
                              {"roughnessFactor", 1.0}}},
                            {"extensions", UnlitExtension()}});
  out->uses_unlit = true;
  return static_cast<int>(out->materials.size()) - 1;
}

int AddVertexMaterial(bool has_colors, Materials* out) {
  json material = {
      {"name", has_colors ? "vertex_colours" : "grey"},
      {"pbrMetallicRoughness",
       {{"baseColorFactor", has_colors ? json{1.0, 1.0, 1.0, 1.0} : json{0.7, 0.7, 0.7, 1.0}},
        {"metallicFactor", 0.0},
        {"roughnessFactor", 1.0}}}};
  if (has_colors) {
    material["extensions"] = UnlitExtension();
    out->uses_unlit = true;
  }
  out->materials.push_back(std::move(material));
  return static_cast<int>(out->materials.size()) - 1;
}

// The mesh's primitives (one per page with faces, or one), with their materials.
Result<json> AddMesh(GlbBuilder* builder,
                     const TriangleMesh& mesh,
                     const FrameMap& map,
                     int quality,
                     Materials* materials,
                     GltfSummary* summary) {
  json primitives = json::array();
  if (!mesh.HasTexture()) {
    const PrimitiveData data = UntexturedPrimitive(mesh, map);
    summary->num_vertices += data.positions.size();
    primitives.push_back(
        AddPrimitive(builder, data, AddVertexMaterial(!data.colors.empty(), materials)));
    return primitives;
  }
  std::vector<std::vector<std::uint32_t>> faces_of_page(mesh.texture_pages.size());
  for (std::size_t f = 0; f < mesh.NumFaces(); ++f) {
    faces_of_page[static_cast<std::size_t>(mesh.face_pages[f])].push_back(
        static_cast<std::uint32_t>(f));
  }
  for (std::size_t p = 0; p < faces_of_page.size(); ++p) {
    if (faces_of_page[p].empty()) continue;
    Result<int> material =
        AddPageMaterial(builder, mesh.texture_pages[p], static_cast<int>(p), quality, materials);
    if (!material.ok()) return material.status();
    const PrimitiveData data = PagePrimitive(mesh, faces_of_page[p], map);
    summary->num_vertices += data.positions.size();
    primitives.push_back(AddPrimitive(builder, data, *material));
    std::vector<std::uint32_t>().swap(faces_of_page[p]);
  }
  summary->num_images = materials->images.size();
  return primitives;
}

json Vector(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }

// Diagonal of the bounding box of the mesh and the camera centres (the same in every frame).
double SceneExtent(const TriangleMesh& mesh, const std::vector<GltfCameraView>& cameras) {
  Eigen::AlignedBox3d box;
  for (const Eigen::Vector3f& p : mesh.positions) box.extend(p.cast<double>());
  for (const GltfCameraView& view : cameras) box.extend(view.cam_from_world.CenterInWorld());
  const double extent = box.isEmpty() ? 1.0 : box.diagonal().norm();
  return extent > 0 ? extent : 1.0;
}

// The cameras (objects) and their nodes.
void AddCameras(const std::vector<GltfCameraView>& cameras,
                const GltfFrame& frame,
                double extent,
                json* camera_array,
                json* nodes) {
  const Eigen::Matrix3d flip = Eigen::Vector3d(1, -1, -1).asDiagonal();
  for (const GltfCameraView& view : cameras) {
    const Camera& c = view.camera;
    const double yfov = 2.0 * std::atan(0.5 * c.height / c.focal);
    camera_array->push_back({{"name", view.name},
                             {"type", "perspective"},
                             {"perspective",
                              {{"yfov", yfov},
                               {"aspectRatio", static_cast<double>(c.width) / c.height},
                               {"znear", 1e-3 * extent},
                               {"zfar", 4.0 * extent}}},
                             {"extras",
                              {{"focal", c.focal},
                               {"cx", c.cx},
                               {"cy", c.cy},
                               {"width", c.width},
                               {"height", c.height},
                               {"k1", c.k1},
                               {"k2", c.k2}}}});
    const Rigid3d world_from_cam = view.cam_from_world.Inverse();
    const Rigid3d gltf_from_cam = frame.gltf_from_world * world_from_cam;
    const Eigen::Quaterniond q(gltf_from_cam.rotation.toRotationMatrix() * flip);
    nodes->push_back({{"name", view.name},
                      {"camera", camera_array->size() - 1},
                      {"rotation", {q.x(), q.y(), q.z(), q.w()}},
                      {"translation", Vector(gltf_from_cam.translation)}});
  }
}

json FrameExtras(const GltfFrame& frame) {
  const Eigen::Matrix3d r = frame.gltf_from_world.rotation.toRotationMatrix();
  json rotation = json::array();
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) rotation.push_back(r(i, j));
  }
  return {{"gltf_from_world",
           {{"rotation", std::move(rotation)},
            {"translation", Vector(frame.gltf_from_world.translation)}}},
          {"up_in_world", Vector(frame.up_in_world)},
          {"units", "those of cameras.json: metric up to one unknown scale"}};
}

void AppendU32(std::uint32_t value, std::string* out) {
  char bytes[4];
  for (int i = 0; i < 4; ++i) bytes[i] = static_cast<char>((value >> (8 * i)) & 0xFF);
  out->append(bytes, 4);
}

// Header, JSON chunk (space-padded) and BIN chunk, to a temporary file renamed over `path`.
Result<std::size_t> WriteGlbFile(const fs::path& path,
                                 std::string json_text,
                                 const std::string& bin) {
  json_text.append((4 - json_text.size() % 4) % 4, ' ');
  const std::uint64_t total = 12 + 8 + json_text.size() + (bin.empty() ? 0 : 8 + bin.size());
  if (total > std::numeric_limits<std::uint32_t>::max()) {
    return Status::ResourceExhausted("model.glb would exceed 4 GiB");
  }
  std::string head;
  head.append("glTF");
  AppendU32(2, &head);
  AppendU32(static_cast<std::uint32_t>(total), &head);
  AppendU32(static_cast<std::uint32_t>(json_text.size()), &head);
  AppendU32(0x4E4F534A, &head);  // "JSON"
  std::string bin_head;
  AppendU32(static_cast<std::uint32_t>(bin.size()), &bin_head);
  AppendU32(0x004E4942, &bin_head);  // "BIN\0"

  std::random_device random;
  const fs::path temp =
      path.string() + ".tmp-" + std::to_string(::getpid()) + "-" + std::to_string(random());
  std::ofstream file(temp, std::ios::binary | std::ios::trunc);
  if (!file) return Status::Internal("cannot create '" + temp.string() + "'");
  file.write(head.data(), static_cast<std::streamsize>(head.size()));
  file.write(json_text.data(), static_cast<std::streamsize>(json_text.size()));
  if (!bin.empty()) {
    file.write(bin_head.data(), static_cast<std::streamsize>(bin_head.size()));
    file.write(bin.data(), static_cast<std::streamsize>(bin.size()));
  }
  file.close();
  Status status =
      file ? CommitFile(temp, path) : Status::Internal("cannot write '" + temp.string() + "'");
  if (!status.ok()) {
    std::error_code ignored;
    fs::remove(temp, ignored);
    return status;
  }
  return static_cast<std::size_t>(total);
}

}  // namespace

GltfFrame ComputeGltfFrame(const TriangleMesh& mesh,
                           const std::vector<GltfCameraView>& cameras,
                           const GltfOptions& options) {
  GltfFrame frame;
  Eigen::Vector3d up = Eigen::Vector3d::Zero(), forward = Eigen::Vector3d::Zero();
  for (const GltfCameraView& view : cameras) {
    const Eigen::Matrix3d world_from_cam =
        view.cam_from_world.rotation.toRotationMatrix().transpose();
    up -= world_from_cam.col(1);
    forward += world_from_cam.col(2);
  }
  if (up.norm() < 1e-6 * std::max<double>(1.0, cameras.size())) up = Eigen::Vector3d(0, -1, 0);
  up.normalize();
  // glTF -Z: the mean viewing direction, perpendicular to up.
  Eigen::Vector3d minus_z = forward - forward.dot(up) * up;
  if (minus_z.norm() < 1e-6 * std::max<double>(1.0, cameras.size())) {
    minus_z = up.unitOrthogonal();
  }
  minus_z.normalize();
  const Eigen::Vector3d z = -minus_z;
  const Eigen::Vector3d x = up.cross(z);
  Eigen::Matrix3d gltf_from_world;
  gltf_from_world.row(0) = x.transpose();
  gltf_from_world.row(1) = up.transpose();
  gltf_from_world.row(2) = z.transpose();
  frame.up_in_world = up;
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();
  if (options.center) {
    Eigen::AlignedBox3d box;
    for (const Eigen::Vector3f& p : mesh.positions) box.extend(gltf_from_world * p.cast<double>());
    if (box.isEmpty()) {
      for (const GltfCameraView& view : cameras) {
        box.extend(gltf_from_world * view.cam_from_world.CenterInWorld());
      }
    }
    if (!box.isEmpty()) translation = -box.center();
  }
  frame.gltf_from_world = Rigid3d(gltf_from_world, translation);
  return frame;
}

Status WriteModelGlb(const fs::path& path,
                     const TriangleMesh& mesh,
                     const std::vector<GltfCameraView>& cameras,
                     const GltfOptions& options,
                     GltfSummary* summary) {
  if (options.jpeg_quality < 1 || options.jpeg_quality > 100) {
    return Status::InvalidArgument("model.glb: JPEG quality " +
                                   std::to_string(options.jpeg_quality) + " is not in 1-100");
  }
  for (const Status& check : {CheckMesh(mesh), CheckTexture(mesh), CheckCameras(cameras)}) {
    if (!check.ok()) return check;
  }
  GltfSummary local;
  GltfSummary& out = summary ? *summary : local;
  out = GltfSummary();
  out.frame = ComputeGltfFrame(mesh, cameras, options);
  const FrameMap map{out.frame.gltf_from_world.rotation.toRotationMatrix().cast<float>(),
                     out.frame.gltf_from_world.translation.cast<float>()};

  GlbBuilder builder;
  Materials materials;
  Result<json> primitives = AddMesh(&builder, mesh, map, options.jpeg_quality, &materials, &out);
  if (!primitives.ok()) return primitives.status();
  out.num_primitives = primitives->size();
  out.num_faces = mesh.NumFaces();
  out.num_cameras = cameras.size();

  json doc;
  doc["asset"] = {{"version", "2.0"}, {"generator", "Reconduit"}};
  json nodes = json::array({{{"name", "mesh"}, {"mesh", 0}}});
  json camera_array = json::array();
  AddCameras(cameras, out.frame, SceneExtent(mesh, cameras), &camera_array, &nodes);
  json scene_nodes = json::array();
  for (std::size_t i = 0; i < nodes.size(); ++i) scene_nodes.push_back(i);
  doc["scene"] = 0;
  doc["scenes"] = json::array(
      {{{"name", "reconstruction"}, {"nodes", scene_nodes}, {"extras", FrameExtras(out.frame)}}});
  doc["nodes"] = std::move(nodes);
  doc["meshes"] = json::array({{{"name", "mesh"}, {"primitives", std::move(primitives).value()}}});
  if (!camera_array.empty()) doc["cameras"] = std::move(camera_array);
  doc["materials"] = std::move(materials.materials);
  if (!materials.images.empty()) {
    doc["images"] = std::move(materials.images);
    doc["textures"] = std::move(materials.textures);
    doc["samplers"] = json::array({{{"magFilter", kLinear},
                                    {"minFilter", kLinearMipmapLinear},
                                    {"wrapS", kClampToEdge},
                                    {"wrapT", kClampToEdge}}});
  }
  if (materials.uses_unlit) doc["extensionsUsed"] = json::array({kUnlit});
  doc["accessors"] = builder.TakeAccessors();
  doc["bufferViews"] = builder.TakeBufferViews();
  doc["buffers"] = json::array({{{"byteLength", builder.bin().size()}}});
  Result<std::size_t> bytes = WriteGlbFile(path, doc.dump(), builder.bin());
  if (!bytes.ok()) return bytes.status();
  out.file_bytes = *bytes;
  return Status::Ok();
}

}  // namespace reconduit
