#include "common/change/masked_correlation.h"

#include <opencv2/imgproc.hpp>

namespace placerec {

void MaskedCorrelation(const cv::Mat& image, const cv::Mat& templ, const cv::Mat& mask,
                       cv::Mat* scores) {
  const cv::Size result(image.cols - templ.cols + 1, image.rows - templ.rows + 1);
  if (result == cv::Size(1, 4)) {
    cv::Mat transposed;
    cv::matchTemplate(image.t(), templ.t(), transposed, cv::TM_CCOEFF_NORMED, mask.t());
    *scores = transposed.t();
    return;
  }
  cv::matchTemplate(image, templ, *scores, cv::TM_CCOEFF_NORMED, mask);
}

}  // namespace placerec
