// Torr's Geometric Robust Information Criterion (GRIC) for two-view model selection.
//
// P. H. S. Torr, "Geometric Motion Segmentation and Model Selection", Phil. Trans. R. Soc.
// Lond. A 356 (1998), and "Bayesian Model Estimation and Selection for Epipolar Geometry and
// Generic Manifold Fitting", IJCV 50(1) (2002):
//
//   GRIC = sum_i rho(e_i² / sigma²) + lambda1 * d * n + lambda2 * k,
//   rho(x) = min(x, lambda3 * (r - d)),
//   lambda1 = log(r), lambda2 = log(r * n), lambda3 = 2,
//
// where n is the number of correspondences, r the dimension of the data (4 for two image
// points), d the dimension of the model manifold (3 for F, 2 for H), k the number of model
// parameters (7 for F, 8 for H), e_i the distance of correspondence i to the model manifold
// in R^4 (we use the Sampson approximation) and sigma the standard deviation of the image
// noise. The model with the LOWER score is preferred. The d*n term charges F for the extra
// dimension it gives every point, so H wins when it explains the data about as well as F:
// planar scenes and pure rotations.
#ifndef RECONDUIT_CORE_ESTIMATORS_GRIC_H_
#define RECONDUIT_CORE_ESTIMATORS_GRIC_H_

#include <vector>

namespace reconduit {

// Dimensions and parameter counts of the two-view models (Torr 1998, table 1).
inline constexpr int kGricDataDim = 4;
inline constexpr int kGricFundamentalDim = 3;
inline constexpr int kGricFundamentalParams = 7;
inline constexpr int kGricHomographyDim = 2;
inline constexpr int kGricHomographyParams = 8;

// GRIC of a model.
//
// @param squared_residuals  e_i², squared distances to the model manifold (same units as
//                           sigma squared, e.g. pixels²); n = size(). Non-finite values are
//                           charged the cap, like outliers.
// @param sigma              Noise standard deviation (> 0, else CheckError).
// @param data_dim           r (> model_dim, else CheckError).
// @param model_dim          d.
// @param num_params         k.
// @return The score; lower is better.
double ComputeGRIC(const std::vector<double>& squared_residuals,
                   double sigma,
                   int data_dim,
                   int model_dim,
                   int num_params);

}  // namespace reconduit

#endif  // RECONDUIT_CORE_ESTIMATORS_GRIC_H_
