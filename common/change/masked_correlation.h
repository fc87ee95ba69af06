// Masked normalised correlation (cv::matchTemplate, TM_CCOEFF_NORMED with a mask) on windows of
// every size: the scene-change detector's "seen elsewhere" test (seed §7.2.4) looks for a region's
// pixels in the stored view with it.
#pragma once

#include <opencv2/core.hpp>

namespace placerec {

// cv::matchTemplate(image, templ, scores, cv::TM_CCOEFF_NORMED, mask): `image` and `templ` CV_8U
// with one channel, `mask` CV_8U of templ's size (non-zero: the template's pixels that count),
// `image` at least as large as `templ`; `scores` CV_32F of (image - templ + 1) columns and rows.
//
// OpenCV 4.6 throws from arithm_op ("When the input arrays in add/subtract/multiply/divide
// functions have different types, the output array type must be explicitly specified") when the
// scores are one column by four rows: an intermediate of that shape is taken for a scalar
// (opencv/opencv#26389, also on 4.8.1). The correlation of the transposed arrays is the same
// (to float rounding) and has one row by four columns, so this shape is computed that way. The
// same throw for a template of one column by four rows, or of four columns by one row with such
// scores, is not worked around: such templates are not allowed (the detector's are at least
// 4 x 4 pixels).
void MaskedCorrelation(const cv::Mat& image, const cv::Mat& templ, const cv::Mat& mask,
                       cv::Mat* scores);

}  // namespace placerec
