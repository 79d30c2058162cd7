// Texturing a triangle mesh from calibrated photos (issue 11, "Texture"): one photo per face,
// charts packed into atlas pages, baked from the original photos, seams levelled.
//
// The method follows Waechter, Moehrle and Goesele, "Let there be color! Large-scale
// texturing of 3D reconstructions" (ECCV 2014), the algorithm of mvs-texturing and OpenMVS, in
// a simpler form whose choices are argued where they are made:
//  1. Visibility (face_labeling.h): each view renders a z-buffer of the mesh at a reduced
//     resolution; a face is a candidate for a view when it is in front of the camera, inside the
//     photo, facing it at less than max_view_angle_deg, and not occluded at four points.
//  2. Labelling (face_labeling.h): data term from the projected area and the viewing angle,
//     Potts smoothness between faces sharing an edge, greedy start then iterated conditional
//     modes and whole-chart moves.
//  3. Charts: connected faces with the same view. A chart's texture coordinates are its corners
//     projected into its photo through the camera's distortion model, so the photo is used as
//     it was taken (no undistortion, no resampling); the chart's bounding rectangle in the photo,
//     plus `padding` pixels for bilinear and mip-map filtering, is copied into an atlas page
//     (atlas_packing.h), shrunk only to fit a page or max_megatexels. The rectangle's pixels
//     outside the chart's faces are the photo's own (the surface around the chart), so texture
//     filtering across a chart's border reads plausible colours and no dilation is needed; the
//     price is that an irregular chart carries the unused photo pixels of its bounding box.
//  4. Seam levelling: one additive colour offset per chart and channel, by robust (Huber) least
//     squares over colour samples on both sides of the chart borders (LevelSeams in
//     texture_mesh.cc), then blending along the borders (seam_blending.h).
//  5. Faces no view sees point at a small block of `unseen_color` and are counted.
//
// Memory: visibility needs only the cameras and a float z-buffer of at most
// visibility_max_side² pixels per thread; photos are loaded one per thread during the single
// baking pass (TextureView::load is called exactly once per view that owns a chart) and
// released before the next, so with num_threads = 2 at most two decoded photos are alive beside
// the atlas pages (fountain-P11: 2 x 19 MB photos, pages of at most 48 MB each), and per
// thread the view's vertex projections (~60 bytes a vertex). texture_benchmark: 500 k faces,
// 11 views of 3072 x 2048, 4.5 s in all on 2 threads, peak 217 MB.
#ifndef RECONDUIT_CORE_TEXTURE_TEXTURE_MESH_H_
#define RECONDUIT_CORE_TEXTURE_TEXTURE_MESH_H_

#include "core/geometry/camera.h"
#include "core/geometry/rigid3.h"
#include "core/scene/triangle_mesh.h"
#include "core/util/cancel.h"
#include "core/util/progress.h"

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include <functional>
#include <string>
#include <vector>

namespace reconduit {

struct TextureView {
  // For log lines only (e.g. the photo's name).
  std::string name;
  // The camera of the photo at its ORIGINAL resolution, with its distortion: texture
  // coordinates are projections through this model into the photo as loaded.
  Camera camera;
  Rigid3d cam_from_world;
  // Returns the photo: CV_8UC3 BGR (or CV_8UC1, converted), camera.width x camera.height.
  // Called at most once per TextureMesh call, possibly from a worker thread (make it
  // thread-safe), only for views that own at least one chart. Throwing propagates.
  std::function<cv::Mat()> load;
};

struct TextureOptions {
  // Largest side of an atlas page, pixels, >= 64. 4096 is what phone browsers still display.
  int page_size = 4096;
  // Largest total area of the charts' photo rectangles, in millions of texels, > 0: above it
  // every chart is shrunk by one factor. The atlas costs 3 bytes a texel in memory (and the
  // pages' JPEGs in model.glb ~0.3-1 byte); 64 holds fountain-P11's eleven 6.3 MP photos at
  // nearly full resolution in four 4096² pages' worth.
  double max_megatexels = 64.0;
  // Pixels of photo kept around each chart's bounding rectangle, [0, 16], so that bilinear
  // filtering and the first mip levels read photo pixels rather than a neighbour chart.
  int padding = 2;
  // Largest side of the visibility z-buffer, pixels, >= 64: ~4x smaller than a 12 MP photo is
  // enough to find occluders (visibility is tested at face level) and 16x cheaper.
  int visibility_max_side = 1024;
  // A face point is occluded when it lies farther than (1 + depth_tolerance) times the
  // z-buffer's depth at its pixel, (0, 1).
  double depth_tolerance = 0.02;
  // Views that see a face at a larger angle from its normal are not candidates, (0, 90).
  double max_view_angle_deg = 80.0;
  // Potts weight per pair of adjacent faces with different views, >= 0, against data costs in
  // [0, 1] (0 for a face's best view; see face_labeling.h). 0 keeps the greedy labelling.
  double smoothness_weight = 0.5;
  // Smoothing sweeps at most (face and chart moves, face_labeling.h), >= 0; it stops earlier
  // when no label changes (36 sweeps on a fragmented 3600-face test wall).
  int max_smoothing_sweeps = 100;
  // Levels colours across chart borders (one additive offset per chart and channel).
  bool level_seams = true;
  // Seam samples whose colours differ by more than this (grey levels, any channel) are left
  // out of the levelling: misregistered or occluded borders, not exposure differences.
  double seam_outlier_threshold = 60.0;
  // Blends colours along chart borders after the levelling: both sides pulled to a common
  // colour at the border vertices, the pull fading over seam_blend_rings rings of vertices into
  // each chart (seam_blending.h).
  bool blend_seams = true;
  // [0, 16]; 0 blends within the faces that touch a border only.
  int seam_blend_rings = 2;
  // BGR colour of faces no view sees.
  Eigen::Vector3d unseen_color = Eigen::Vector3d(128.0, 128.0, 128.0);
  // Threads over views (see EffectiveNumThreads).
  int num_threads = 2;

  // False, with a message naming the field, when an option is out of range.
  bool Check(std::string* error) const;
};

struct TextureSummary {
  int num_faces = 0;
  int num_textured_faces = 0;
  int num_unseen_faces = 0;   // Faces no view sees: unseen_color.
  int num_charts_greedy = 0;  // Charts of the greedy labelling, before smoothing.
  int num_charts = 0;         // Charts of the final labelling.
  int smoothing_sweeps = 0;
  int num_pages = 0;
  int num_seam_samples = 0;  // Colour pairs the levelling used.
  // Mean absolute colour difference across chart borders (mean over samples and channels),
  // before and after levelling.
  double seam_difference_before = 0.0;
  double seam_difference_after = 0.0;
  // Blending: vertices where charts meet, their mean absolute difference from the mean of their
  // charts' colours before blending (after levelling), and the faces whose texels changed.
  int seam_border_vertices = 0;
  double seam_vertex_difference = 0.0;
  int seam_blended_faces = 0;
  double visibility_seconds = 0.0;
  double labelling_seconds = 0.0;
  double atlas_seconds = 0.0;  // Charts, texture coordinates and packing.
  double bake_seconds = 0.0;   // Loading photos and copying their rectangles.
  double levelling_seconds = 0.0;
  double blending_seconds = 0.0;
  double total_seconds = 0.0;
};

struct TextureResult {
  // The input mesh with texcoords, face_pages and texture_pages filled.
  TriangleMesh mesh;
  // Per face, the index of the view it was textured from, or -1 (unseen).
  std::vector<int> face_views;
  TextureSummary summary;
};

// Textures `mesh` from `views`. Throws CheckError for invalid options, cameras or a mesh with
// out-of-range indices, and CanceledError when `cancel` fires (checked per view and between
// steps). `progress` may be null. Deterministic: the result does not depend on num_threads.
TextureResult TextureMesh(const TriangleMesh& mesh,
                          const std::vector<TextureView>& views,
                          const TextureOptions& options,
                          Progress* progress,
                          const CancelToken& cancel);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_TEXTURE_TEXTURE_MESH_H_
