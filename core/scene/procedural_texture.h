// Procedural surface textures for rendered synthetic scenes.
//
// A texture is a pure function of a seed and the surface coordinates (u, v) in metres: there
// is no stored image, so it never aliases through resampling and any point can be evaluated
// exactly (tests compare rendered pixels with it). It is built to give feature detectors
// (SIFT) many distinctive corners and blobs at several scales:
// - a background of multi-octave value noise (smooth, C1) around a base colour;
// - `num_layers` layers of random discs and rotated rectangles in random colours, the first
//   layer on a grid of `cell_size` metres and each next layer on a grid half as fine, each
//   cell holding at most one shape (with probability shape_probability) of radius 0.15-0.5
//   cells, centred within a quarter cell of the cell's middle. Shapes have a soft edge 8 % of
//   the cell wide; finer layers are painted on top.
//
// Thread-safe: evaluation has no state.
#ifndef RECONDUIT_CORE_SCENE_PROCEDURAL_TEXTURE_H_
#define RECONDUIT_CORE_SCENE_PROCEDURAL_TEXTURE_H_

#include <Eigen/Core>

#include <cstdint>
#include <string>

namespace reconduit {

struct ProceduralTexture {
  // Seed of the pattern: different seeds give unrelated patterns.
  std::uint64_t seed = 0;
  // Grid size of the coarsest shape layer, metres, > 0. The default suits views from 2-10 m
  // at ~500 px focal: shapes from ~1 px to ~40 px across.
  double cell_size = 0.4;
  // Number of shape layers, [0, 8]; layer i has cells of cell_size / 2^i.
  int num_layers = 4;
  // Probability that a cell holds a shape, [0, 1].
  double shape_probability = 0.7;
  // Mean colour of the noise background, BGR, [0, 255] per channel.
  Eigen::Vector3d base_color = Eigen::Vector3d(128.0, 128.0, 128.0);
  // The background varies by up to +-noise_amplitude around base_color (clamped to
  // [0, 255]), >= 0.
  double noise_amplitude = 60.0;

  // False, with a message naming the field, when an option is out of range.
  bool Check(std::string* error) const;
};

// Colour at surface coordinates (u, v) in metres: BGR, each channel in [0, 255].
Eigen::Vector3d EvaluateTexture(const ProceduralTexture& texture, double u, double v);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_SCENE_PROCEDURAL_TEXTURE_H_
