#include "core/io/gltf.h"

#include "core/io/gltf_test_util.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <tiny_gltf.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

namespace reconduit {
namespace {

namespace fs = std::filesystem;
using testing_util::MakeCube;
using testing_util::MakeRing;

class GltfTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("gltf_test_" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  tinygltf::Model Load(const fs::path& path) {
    tinygltf::TinyGLTF loader;
    tinygltf::Model model;
    std::string err, warn;
    EXPECT_TRUE(loader.LoadBinaryFromFile(&model, &err, &warn, path.string())) << err;
    EXPECT_EQ(err, "");
    return model;
  }

  fs::path dir_;
};

// Element i of an accessor as T (tightly packed or strided).
template <typename T>
T Element(const tinygltf::Model& model, int accessor_index, std::size_t i) {
  const tinygltf::Accessor& accessor = model.accessors[static_cast<std::size_t>(accessor_index)];
  const tinygltf::BufferView& view =
      model.bufferViews[static_cast<std::size_t>(accessor.bufferView)];
  const std::size_t stride = view.byteStride ? view.byteStride : sizeof(T);
  T value;
  std::memcpy(
      static_cast<void*>(&value),
      model.buffers[view.buffer].data.data() + view.byteOffset + accessor.byteOffset + i * stride,
      sizeof(T));
  return value;
}

std::uint32_t Index(const tinygltf::Model& model, int accessor_index, std::size_t i) {
  const int type = model.accessors[static_cast<std::size_t>(accessor_index)].componentType;
  if (type == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT) {
    return Element<std::uint16_t>(model, accessor_index, i);
  }
  EXPECT_EQ(type, TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT);
  return Element<std::uint32_t>(model, accessor_index, i);
}

const tinygltf::Node* FindNode(const tinygltf::Model& model, const std::string& name) {
  for (const tinygltf::Node& node : model.nodes) {
    if (node.name == name) return &node;
  }
  return nullptr;
}

// The scene extras' gltf_from_world.
Rigid3d FrameFromExtras(const tinygltf::Model& model) {
  const tinygltf::Value& g = model.scenes.at(0).extras.Get("gltf_from_world");
  Eigen::Matrix3d r;
  for (int i = 0; i < 9; ++i) {
    r(i / 3, i % 3) = g.Get("rotation").Get(i).GetNumberAsDouble();
  }
  Eigen::Vector3d t;
  for (int i = 0; i < 3; ++i) t[i] = g.Get("translation").Get(i).GetNumberAsDouble();
  return Rigid3d(r, t);
}

// A camera node's gltf_from_node (rotation and translation).
Rigid3d NodeTransform(const tinygltf::Node& node) {
  EXPECT_EQ(node.rotation.size(), 4u);
  EXPECT_EQ(node.translation.size(), 3u);
  const Eigen::Quaterniond q(node.rotation[3], node.rotation[0], node.rotation[1],
                             node.rotation[2]);
  return Rigid3d(q, Eigen::Vector3d(node.translation[0], node.translation[1], node.translation[2]));
}

Camera TestCamera() { return Camera::FromFocal(640, 480, 500.0); }

TEST_F(GltfTest, TexturedCubeReadsBackWithItsTrianglesTexcoordsAndPages) {
  const TriangleMesh mesh = MakeCube({1, 2, 3}, 0.5f, 2);
  const std::vector<GltfCameraView> cameras =
      MakeRing({1, 2, 3}, Eigen::Vector3d::UnitZ(), 4.0, 4, TestCamera());
  GltfSummary summary;
  ASSERT_TRUE(WriteModelGlb(dir_ / "model.glb", mesh, cameras, GltfOptions(), &summary).ok());
  EXPECT_EQ(summary.num_primitives, 2u);
  EXPECT_EQ(summary.num_images, 2u);
  EXPECT_EQ(summary.num_cameras, 4u);
  EXPECT_EQ(summary.num_faces, 12u);
  EXPECT_EQ(summary.num_vertices, 24u);  // 4 corners per side: the sides share no texcoords.
  EXPECT_EQ(summary.file_bytes, fs::file_size(dir_ / "model.glb"));
  EXPECT_EQ(std::distance(fs::directory_iterator(dir_), fs::directory_iterator()), 1);

  const tinygltf::Model model = Load(dir_ / "model.glb");
  ASSERT_EQ(model.scenes.size(), 1u);
  EXPECT_EQ(model.scenes[0].nodes.size(), 5u);
  ASSERT_EQ(model.nodes.size(), 5u);
  EXPECT_EQ(model.nodes[0].name, "mesh");
  for (int i = 0; i < 4; ++i) {
    EXPECT_EQ(model.nodes[static_cast<std::size_t>(i + 1)].name,
              cameras[static_cast<std::size_t>(i)].name);
  }
  EXPECT_THAT(model.extensionsUsed, ::testing::Contains("KHR_materials_unlit"));

  const Rigid3d gltf_from_world = FrameFromExtras(model);
  const Rigid3d world_from_gltf = gltf_from_world.Inverse();
  ASSERT_EQ(model.meshes.size(), 1u);
  const auto& primitives = model.meshes[0].primitives;
  ASSERT_EQ(primitives.size(), 2u);
  for (std::size_t p = 0; p < 2; ++p) {
    const tinygltf::Primitive& prim = primitives[p];
    const int pos = prim.attributes.at("POSITION");
    const int tex = prim.attributes.at("TEXCOORD_0");
    EXPECT_EQ(prim.attributes.count("COLOR_0"), 0u);
    EXPECT_EQ(model.accessors[static_cast<std::size_t>(pos)].count, 12u);
    EXPECT_EQ(model.accessors[static_cast<std::size_t>(pos)].minValues.size(), 3u);
    EXPECT_EQ(model.accessors[static_cast<std::size_t>(pos)].maxValues.size(), 3u);
    const tinygltf::Accessor& idx = model.accessors[static_cast<std::size_t>(prim.indices)];
    EXPECT_EQ(idx.componentType, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT);
    ASSERT_EQ(idx.count, 18u);  // 3 sides, 6 triangles.
    // Triangle t of page p is face 6p + t of the mesh: same corners (back in the world frame)
    // and same texcoords, in the same order (so the same winding).
    for (std::size_t c = 0; c < 18; ++c) {
      const std::uint32_t i = Index(model, prim.indices, c);
      ASSERT_LT(i, 12u);
      const std::size_t face = 6 * p + c / 3;
      const Eigen::Vector3d world =
          world_from_gltf * Element<Eigen::Vector3f>(model, pos, i).cast<double>();
      EXPECT_LT((world - mesh.positions[mesh.faces[face][c % 3]].cast<double>()).norm(), 1e-5);
      EXPECT_EQ(Element<Eigen::Vector2f>(model, tex, i), mesh.texcoords[3 * face + c % 3]);
    }
    // Its material: the page, unlit, with the metallic-0 rough fallback, clamped.
    const tinygltf::Material& material = model.materials[static_cast<std::size_t>(prim.material)];
    EXPECT_EQ(material.extensions.count("KHR_materials_unlit"), 1u);
    EXPECT_EQ(material.pbrMetallicRoughness.metallicFactor, 0.0);
    EXPECT_EQ(material.pbrMetallicRoughness.roughnessFactor, 1.0);
    const int texture = material.pbrMetallicRoughness.baseColorTexture.index;
    ASSERT_GE(texture, 0);
    const tinygltf::Texture& t = model.textures[static_cast<std::size_t>(texture)];
    const tinygltf::Sampler& sampler = model.samplers[static_cast<std::size_t>(t.sampler)];
    EXPECT_EQ(sampler.wrapS, TINYGLTF_TEXTURE_WRAP_CLAMP_TO_EDGE);
    EXPECT_EQ(sampler.wrapT, TINYGLTF_TEXTURE_WRAP_CLAMP_TO_EDGE);
    const tinygltf::Image& image = model.images[static_cast<std::size_t>(t.source)];
    EXPECT_EQ(image.mimeType, "image/jpeg");
    ASSERT_GE(image.bufferView, 0);
    // The JPEG is the page: the centre of side 3p's cell has its colour.
    const tinygltf::BufferView& view =
        model.bufferViews[static_cast<std::size_t>(image.bufferView)];
    const std::vector<std::uint8_t> jpeg(
        model.buffers[0].data.begin() + static_cast<std::ptrdiff_t>(view.byteOffset),
        model.buffers[0].data.begin() +
            static_cast<std::ptrdiff_t>(view.byteOffset + view.byteLength));
    const cv::Mat decoded = cv::imdecode(jpeg, cv::IMREAD_COLOR);
    ASSERT_EQ(decoded.cols, 96);
    ASSERT_EQ(decoded.rows, 64);
    const cv::Vec3b bgr = decoded.at<cv::Vec3b>(16, 16);
    const auto rgb = testing_util::SideColor(static_cast<int>(3 * p));
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(bgr[2 - k], rgb[k], 6) << "page " << p;
  }
}

// The camera node reproduces the camera's centre, viewing direction and image up in the glTF
// frame, and the glTF projection (yfov, aspect ratio) puts a 3-D point on our pixel.
// check_projection: the cameras have no distortion and a centred principal point (what glTF can
// express).
void ExpectCameraNodesMatch(const tinygltf::Model& model,
                            const std::vector<GltfCameraView>& cameras,
                            bool check_projection = true) {
  const Rigid3d gltf_from_world = FrameFromExtras(model);
  for (const GltfCameraView& view : cameras) {
    const tinygltf::Node* node = FindNode(model, view.name);
    ASSERT_NE(node, nullptr) << view.name;
    ASSERT_GE(node->camera, 0);
    const tinygltf::Camera& cam = model.cameras[static_cast<std::size_t>(node->camera)];
    EXPECT_EQ(cam.type, "perspective");
    EXPECT_NEAR(cam.perspective.yfov, 2 * std::atan(0.5 * view.camera.height / view.camera.focal),
                1e-12);
    EXPECT_NEAR(cam.perspective.aspectRatio, double(view.camera.width) / view.camera.height, 1e-12);
    EXPECT_GT(cam.perspective.znear, 0);
    EXPECT_GT(cam.perspective.zfar, cam.perspective.znear);
    EXPECT_EQ(cam.extras.Get("focal").GetNumberAsDouble(), view.camera.focal);
    EXPECT_EQ(cam.extras.Get("cx").GetNumberAsDouble(), view.camera.cx);
    EXPECT_EQ(cam.extras.Get("cy").GetNumberAsDouble(), view.camera.cy);
    EXPECT_EQ(cam.extras.Get("width").GetNumberAsInt(), view.camera.width);
    EXPECT_EQ(cam.extras.Get("height").GetNumberAsInt(), view.camera.height);
    EXPECT_EQ(cam.extras.Get("k1").GetNumberAsDouble(), view.camera.k1);
    EXPECT_EQ(cam.extras.Get("k2").GetNumberAsDouble(), view.camera.k2);

    const Rigid3d gltf_from_node = NodeTransform(*node);
    const Eigen::Matrix3d world_from_cam =
        view.cam_from_world.rotation.toRotationMatrix().transpose();
    const Eigen::Matrix3d g = gltf_from_world.rotation.toRotationMatrix();
    EXPECT_LT(
        (gltf_from_node.translation - gltf_from_world * view.cam_from_world.CenterInWorld()).norm(),
        1e-9);
    const Eigen::Matrix3d n = gltf_from_node.rotation.toRotationMatrix();
    EXPECT_LT((n * -Eigen::Vector3d::UnitZ() - g * world_from_cam.col(2)).norm(), 1e-9);
    EXPECT_LT((n * Eigen::Vector3d::UnitY() - g * -world_from_cam.col(1)).norm(), 1e-9);

    if (!check_projection) continue;
    // A point in front of the camera, off the axis: glTF's projection and ours agree.
    const Eigen::Vector3d point_in_cam(0.7, -0.4, 3.0);
    const Eigen::Vector3d world = view.cam_from_world.Inverse() * point_in_cam;
    const Eigen::Vector3d in_node = gltf_from_node.Inverse() * (gltf_from_world * world);
    const double t = std::tan(0.5 * cam.perspective.yfov);
    const double x_ndc = in_node.x() / -in_node.z() / (t * cam.perspective.aspectRatio);
    const double y_ndc = in_node.y() / -in_node.z() / t;
    const Eigen::Vector2d pixel((x_ndc + 1) / 2 * view.camera.width - 0.5,
                                (1 - y_ndc) / 2 * view.camera.height - 0.5);
    const Eigen::Vector2d ours = *view.camera.ImgFromCam(point_in_cam);
    EXPECT_LT((pixel - ours).norm(), 1e-6) << view.name;
  }
}

TEST_F(GltfTest, WorldUpAlongZBecomesGltfYAndCameraNodesMatch) {
  const TriangleMesh mesh = MakeCube({0, 0, 0}, 1.0f, 1);
  const std::vector<GltfCameraView> cameras =
      MakeRing({0, 0, 0}, Eigen::Vector3d::UnitZ(), 5.0, 6, TestCamera());
  GltfSummary summary;
  ASSERT_TRUE(WriteModelGlb(dir_ / "model.glb", mesh, cameras, GltfOptions(), &summary).ok());
  EXPECT_LT((summary.frame.up_in_world - Eigen::Vector3d::UnitZ()).norm(), 1e-9);
  const tinygltf::Model model = Load(dir_ / "model.glb");
  const Rigid3d g = FrameFromExtras(model);
  EXPECT_LT((g.rotation * Eigen::Vector3d::UnitZ() - Eigen::Vector3d::UnitY()).norm(), 1e-9);
  EXPECT_NEAR(g.rotation.toRotationMatrix().determinant(), 1.0, 1e-12);  // Right-handed.
  ExpectCameraNodesMatch(model, cameras);
}

TEST_F(GltfTest, TiltedUpAndOffCentreCamerasMatch) {
  const Eigen::Vector3d up = Eigen::Vector3d(0.3, -0.8, 0.5).normalized();
  const TriangleMesh mesh = MakeCube({2, -1, 4}, 0.3f, 1);
  Camera camera = TestCamera();
  camera.cx = 300.0;
  camera.cy = 250.0;
  camera.k1 = -0.05;
  camera.k2 = 0.01;
  // Only three of a ring of 8 (on one side): the mean viewing direction is not degenerate.
  std::vector<GltfCameraView> cameras = MakeRing({2, -1, 4}, up, 3.0, 8, camera);
  cameras.resize(3);
  GltfSummary summary;
  ASSERT_TRUE(WriteModelGlb(dir_ / "m.glb", mesh, cameras, GltfOptions(), &summary).ok());
  EXPECT_LT((summary.frame.up_in_world - up).norm(), 1e-9);
  const tinygltf::Model model = Load(dir_ / "m.glb");
  const Rigid3d g = FrameFromExtras(model);
  EXPECT_LT((g.rotation * up - Eigen::Vector3d::UnitY()).norm(), 1e-9);
  // The mean viewing direction (the middle camera's, by symmetry) looks down glTF -Z.
  const Eigen::Vector3d middle =
      cameras[1].cam_from_world.rotation.inverse() * Eigen::Vector3d::UnitZ();
  EXPECT_LT((g.rotation * middle - -Eigen::Vector3d::UnitZ()).norm(), 1e-9);
  // Centred: the cube's centre is the origin.
  EXPECT_LT((g * Eigen::Vector3d(2, -1, 4)).norm(), 1e-6);
  ExpectCameraNodesMatch(model, cameras, /*check_projection=*/false);  // Extras, pose, yfov.
  // glTF's projection has no distortion and a centred principal point: compare it with ours
  // for such cameras.
  for (GltfCameraView& view : cameras) view.camera = TestCamera();
  ASSERT_TRUE(WriteModelGlb(dir_ / "m.glb", mesh, cameras, GltfOptions(), nullptr).ok());
  ExpectCameraNodesMatch(Load(dir_ / "m.glb"), cameras);
}

TEST_F(GltfTest, UpIsTheMeanOfTheCamerasUps) {
  const TriangleMesh mesh = MakeCube({0, 0, 0}, 1.0f, 0);
  const Camera camera = TestCamera();
  // Two cameras at the same place, rolled by +10 and -10 degrees about their axis.
  const Rigid3d base = Rigid3d::LookAt({0, 0, -5}, {0, 0, 0}, Eigen::Vector3d::UnitY());
  std::vector<GltfCameraView> cameras;
  for (double roll : {10.0, -10.0}) {
    const Eigen::Matrix3d r(Eigen::AngleAxisd(roll * M_PI / 180, Eigen::Vector3d::UnitZ()));
    cameras.push_back({"r" + std::to_string(int(roll)) + ".png", camera,
                       Rigid3d(r, Eigen::Vector3d::Zero()) * base});
  }
  const GltfFrame frame = ComputeGltfFrame(mesh, cameras);
  EXPECT_LT((frame.up_in_world - Eigen::Vector3d::UnitY()).norm(), 1e-9);
  // Without cameras: world -y.
  EXPECT_LT((ComputeGltfFrame(mesh, {}).up_in_world - Eigen::Vector3d(0, -1, 0)).norm(), 1e-12);
  GltfOptions options;
  options.center = false;
  EXPECT_EQ(ComputeGltfFrame(mesh, cameras, options).gltf_from_world.translation,
            Eigen::Vector3d::Zero());
}

TEST_F(GltfTest, UntexturedMeshHasColoursAndNormals) {
  const TriangleMesh mesh = MakeCube({0, 0, 0}, 1.0f, 0);
  GltfSummary summary;
  ASSERT_TRUE(WriteModelGlb(dir_ / "model.glb", mesh, {}, GltfOptions(), &summary).ok());
  EXPECT_EQ(summary.num_vertices, 8u);
  EXPECT_EQ(summary.num_images, 0u);
  const tinygltf::Model model = Load(dir_ / "model.glb");
  EXPECT_TRUE(model.images.empty());
  EXPECT_TRUE(model.cameras.empty());
  ASSERT_EQ(model.meshes.at(0).primitives.size(), 1u);
  const tinygltf::Primitive& prim = model.meshes[0].primitives[0];
  const tinygltf::Accessor& color =
      model.accessors[static_cast<std::size_t>(prim.attributes.at("COLOR_0"))];
  EXPECT_EQ(color.componentType, TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE);
  EXPECT_TRUE(color.normalized);
  EXPECT_EQ(color.type, TINYGLTF_TYPE_VEC4);
  for (std::size_t i = 0; i < 8; ++i) {
    const auto rgba = Element<std::array<std::uint8_t, 4>>(model, prim.attributes.at("COLOR_0"), i);
    for (int k = 0; k < 3; ++k) EXPECT_EQ(rgba[static_cast<std::size_t>(k)], mesh.colors[i][k]);
    EXPECT_EQ(rgba[3], 255);
    const Eigen::Vector3f n = Element<Eigen::Vector3f>(model, prim.attributes.at("NORMAL"), i);
    EXPECT_NEAR(n.norm(), 1.0f, 1e-6f);
  }
  EXPECT_EQ(model.accessors[static_cast<std::size_t>(prim.indices)].count, 36u);
  EXPECT_EQ(model.materials.at(0).extensions.count("KHR_materials_unlit"), 1u);
}

TEST_F(GltfTest, LargeMeshUsesUnsignedIntIndices) {
  TriangleMesh mesh;
  for (int i = 0; i < 70000; ++i) mesh.positions.emplace_back(float(i % 300), float(i / 300), 0.0f);
  for (int i = 0; i + 2 < 70000; i += 3) mesh.faces.emplace_back(i, i + 1, i + 2);
  ASSERT_TRUE(WriteModelGlb(dir_ / "big.glb", mesh, {}, GltfOptions(), nullptr).ok());
  const tinygltf::Model model = Load(dir_ / "big.glb");
  const tinygltf::Primitive& prim = model.meshes.at(0).primitives.at(0);
  EXPECT_EQ(model.accessors[static_cast<std::size_t>(prim.indices)].componentType,
            TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT);
  EXPECT_EQ(Index(model, prim.indices, 3 * 23332 + 2), 69998u);
  EXPECT_EQ(model.materials.at(0).extensions.count("KHR_materials_unlit"), 0u);  // Lit grey.
}

TEST_F(GltfTest, BadInputsAreInvalidArguments) {
  const fs::path path = dir_ / "model.glb";
  auto expect_invalid = [&](const TriangleMesh& mesh, const std::vector<GltfCameraView>& cameras,
                            const std::string& says) {
    const Status status = WriteModelGlb(path, mesh, cameras, GltfOptions(), nullptr);
    EXPECT_EQ(status.code(), StatusCode::kInvalidArgument) << status;
    EXPECT_THAT(status.message(), ::testing::HasSubstr(says));
    EXPECT_FALSE(fs::exists(path));
  };
  expect_invalid(TriangleMesh(), {}, "empty");
  const TriangleMesh cube = MakeCube({0, 0, 0}, 1.0f, 1);
  TriangleMesh bad = cube;
  bad.faces[5][1] = 8;
  expect_invalid(bad, {}, "face 5 refers to vertex 8");
  bad = cube;
  bad.faces[0][0] = -1;
  expect_invalid(bad, {}, "face 0");
  bad = cube;
  bad.texcoords.pop_back();
  expect_invalid(bad, {}, "texture coordinates");
  bad = cube;
  bad.face_pages[3] = 1;
  expect_invalid(bad, {}, "page 1 of 1");
  bad = cube;
  bad.texture_pages[0] = cv::Mat(4, 4, CV_8UC1);
  expect_invalid(bad, {}, "CV_8UC3");
  bad = MakeCube({0, 0, 0}, 1.0f, 0);
  bad.colors.pop_back();
  expect_invalid(bad, {}, "colours");
  bad = cube;
  bad.positions[2].x() = std::nanf("");
  expect_invalid(bad, {}, "not finite");
  std::vector<GltfCameraView> cameras =
      MakeRing({0, 0, 0}, Eigen::Vector3d::UnitY(), 4, 2, TestCamera());
  cameras[1].name = cameras[0].name;
  expect_invalid(cube, cameras, "two cameras named '0000.jpg'");
  cameras[1].name = "";
  expect_invalid(cube, cameras, "without a name");
  cameras[1].name = "b.jpg";
  cameras[1].camera.focal = 0;
  expect_invalid(cube, cameras, "camera 'b.jpg'");
  GltfOptions options;
  options.jpeg_quality = 0;
  EXPECT_EQ(WriteModelGlb(path, cube, {}, options, nullptr).code(), StatusCode::kInvalidArgument);
  EXPECT_TRUE(fs::is_empty(dir_));
}

}  // namespace
}  // namespace reconduit
