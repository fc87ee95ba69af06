#include "common/organization/filter_bank.h"

#include <cmath>
#include <vector>

#include <glog/logging.h>
#include <opencv2/imgproc.hpp>

namespace placerec {

namespace {

// Gaussian smoothing truncated at 3 sigma (kernel 2 * ceil(3 sigma) + 1 taps).
cv::Mat Smooth(const cv::Mat& image, double sigma) {
  const int radius = static_cast<int>(std::ceil(3.0 * sigma));
  cv::Mat out;
  cv::GaussianBlur(image, out, cv::Size(2 * radius + 1, 2 * radius + 1), sigma, sigma,
                   cv::BORDER_REFLECT_101);
  return out;
}

}  // namespace

const char* TextonFeatureName(int index) {
  static const char* const kNames[kTextonFeatureSize] = {
      "G1.L", "G1.a", "G1.b", "G2.L", "G2.a", "G2.b", "G4.L", "G4.a", "G4.b", "LoG1",
      "LoG2", "LoG4", "LoG8", "Dx2",  "Dy2",  "Dx4",  "Dy4",  "L",    "a",    "b"};
  CHECK(index >= 0 && index < kTextonFeatureSize) << "feature index " << index;
  return kNames[index];
}

cv::Mat ComputeFilterBank(const cv::Mat& lab) {
  CHECK(!lab.empty()) << "ComputeFilterBank needs an image";
  CHECK_EQ(lab.type(), CV_32FC3) << "ComputeFilterBank needs CV_32FC3 Lab";
  std::vector<cv::Mat> planes;
  planes.reserve(kTextonFeatureSize);
  std::vector<cv::Mat> smoothed_l;  // G1, G2, G4, G8 of L
  for (const double sigma : {1.0, 2.0, 4.0}) {
    std::vector<cv::Mat> channels;
    cv::split(Smooth(lab, sigma), channels);
    smoothed_l.push_back(channels[0]);
    for (const cv::Mat& c : channels) planes.push_back(c);
  }
  std::vector<cv::Mat> lab_channels;
  cv::split(lab, lab_channels);
  smoothed_l.push_back(Smooth(lab_channels[0], 8.0));

  // Laplacians of Gaussian: the 4-neighbour discrete Laplacian of the smoothed L, times sigma^2.
  const double sigmas[4] = {1.0, 2.0, 4.0, 8.0};
  for (int i = 0; i < 4; ++i) {
    cv::Mat log;
    cv::Laplacian(smoothed_l[i], log, CV_32F, 1, sigmas[i] * sigmas[i], 0.0,
                  cv::BORDER_REFLECT_101);
    planes.push_back(log);
  }
  // Derivatives of Gaussian: central differences of the smoothed L, times sigma.
  for (int i = 1; i <= 2; ++i) {
    cv::Mat dx;
    cv::Mat dy;
    cv::Sobel(smoothed_l[i], dx, CV_32F, 1, 0, 1, 0.5 * sigmas[i], 0.0, cv::BORDER_REFLECT_101);
    cv::Sobel(smoothed_l[i], dy, CV_32F, 0, 1, 1, 0.5 * sigmas[i], 0.0, cv::BORDER_REFLECT_101);
    planes.push_back(dx);
    planes.push_back(dy);
  }
  for (const cv::Mat& c : lab_channels) planes.push_back(c);
  CHECK_EQ(static_cast<int>(planes.size()), kTextonFeatureSize);
  cv::Mat out;
  cv::merge(planes, out);
  return out;
}

}  // namespace placerec
