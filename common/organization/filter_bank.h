// Pipeline step 4, first half (DESIGN.md; seed §3.4, §4.1.1): the 17-filter bank of [Winn05]
// on CIE Lab plus the three Lab values, 20 numbers per pixel. Textons (textons.h) are clusters
// of these vectors.
//
// The bank, on a Lab image with L in [0, 100]:
//   0-8    Gaussians sigma 1, 2, 4 on L, a and b (G1.L G1.a G1.b G2.L ... G4.b)
//   9-12   Laplacians of Gaussian sigma 1, 2, 4, 8 on L, scale-normalised (times sigma^2)
//   13-16  x and y derivatives of Gaussian sigma 2 and 4 on L, scale-normalised (times sigma):
//          Dx2 Dy2 Dx4 Dy4
//   17-19  L, a, b
// Gaussians are separable, truncated at 3 sigma and sum to one; the Laplacian and derivative
// responses are the discrete Laplacian (4-neighbour) and central differences of the Gaussian-
// smoothed L, so the whole bank costs four Gaussian smoothings. Borders are mirrored
// (BORDER_REFLECT_101), so a constant image gives its own value in 0-8 and 17-19 and zero in
// 9-16.
#pragma once

#include <opencv2/core.hpp>

namespace placerec {

constexpr int kFilterBankSize = 17;
// Filter responses plus L, a, b (seed §4.1.1: "a 20 dimensional feature vector").
constexpr int kTextonFeatureSize = 20;

// Short name of feature dimension `index` (0..19), e.g. "G2.a", "LoG8", "Dy4", "L".
const char* TextonFeatureName(int index);

// The 20 features of every pixel of `lab` (CV_32FC3, L in [0, 100]): a CV_32FC(20) image of
// the same size, channels in the order above.
cv::Mat ComputeFilterBank(const cv::Mat& lab);

}  // namespace placerec
