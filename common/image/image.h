// Pipeline step 1 (DESIGN.md): decode a frame and compute the colour spaces later stages need:
// CIE Lab (textons, region colours, seed §3.4) and the Gaussian colour model with its colour
// invariant H = D_lambda / D_lambdalambda (seed eq. 5.6 and 5.13).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "common/util/status.h"

namespace placerec {

enum class ImageEncoding {
  kJpeg,
  kPng,
  kRawBgr8,   // width * height * 3 bytes, rows top to bottom, B G R per pixel
  kRawGray8,  // width * height bytes
};

const char* ImageEncodingName(ImageEncoding encoding);

struct DecodeOptions {
  // Frames larger than this in either dimension are rejected (pixels); protects the server
  // from absurd sizes before any allocation.
  int max_dimension = 8192;
  // Frames smaller than this in either dimension are rejected (pixels).
  int min_dimension = 16;
  // Frames of more pixels than this are rejected (width x height; 16 megapixels holds a phone
  // photo of 4608x3456). JPEG and PNG sizes are read from the header before decoding, so a
  // small file declaring a huge image costs nothing.
  int64_t max_pixels = int64_t{1} << 24;

  bool Check(std::string* error) const;
};

// Decodes `size` bytes into an 8-bit BGR image. For JPEG and PNG, `width` and `height` may be 0
// (unknown); when given they must match the decoded image. For raw encodings they are required
// and `size` must equal width * height * channels. Every failure is a kBadImage status whose
// message says what was wrong. JPEG and PNG sizes are checked from the header before any
// decoding, and bytes that end before the image does (no JPEG end-of-image marker, no PNG IEND
// chunk) are refused instead of decoded in part.
StatusOr<cv::Mat> DecodeImage(const uint8_t* data, size_t size, ImageEncoding encoding, int width,
                              int height, const DecodeOptions& options);

// The width and height a JPEG (its first frame header) or PNG (IHDR) declares, without decoding.
// kBadImage when the header is missing or malformed.
Status ReadHeaderSize(const uint8_t* data, size_t size, ImageEncoding encoding, int* width,
                      int* height);

// Reads an image file (JPEG, PNG, ...) into 8-bit BGR.
StatusOr<cv::Mat> ReadImageFile(const std::string& path);

// Scales `bgr` down (INTER_AREA) so that its width is at most `max_width`; 0 keeps it. Returns
// the factor new/old through `scale` (1 when unchanged).
cv::Mat LimitWidth(const cv::Mat& bgr, int max_width, double* scale);

// Scales `bgr` so that its width lies in [min_width, max_width]: down with INTER_AREA, up with
// INTER_CUBIC; a bound of 0 is no bound, and max_width wins where the two disagree. Scaling up
// stops at 2 x min_width^2 pixels (a 1:2 portrait frame reaches min_width), so that a tall, narrow
// frame (16 x 8192 px) does not become hundreds of megapixels. Returns the factor new/old
// through `scale`.
cv::Mat FitWidth(const cv::Mat& bgr, int min_width, int max_width, double* scale);

// Scales `bgr` to exactly `width` pixels wide (aspect kept; down INTER_AREA, up INTER_CUBIC).
cv::Mat ResizeToWidth(const cv::Mat& bgr, int width);

// The dilation of a mask that is zero but at `points` by `kernel` (CV_8U, odd size, anchored at
// its centre): the same mask as setting those pixels to 255 and calling cv::dilate, at a cost in
// proportion to the points times the kernel instead of the image times the kernel (a few hundred
// points under a kernel as wide as a third of the image). Points outside `size` are skipped.
cv::Mat DilatePoints(const std::vector<cv::Point>& points, const cv::Size& size,
                     const cv::Mat& kernel);

// CIE Lab with L in [0, 100] and a, b roughly in [-127, 127] (CV_32FC3).
cv::Mat ToLab(const cv::Mat& bgr);

// Gaussian colour model (seed eq. 5.6): channels D, D_lambda, D_lambdalambda (CV_32FC3) from
// RGB scaled to [0, 1].
cv::Mat GaussianColourModel(const cv::Mat& bgr);

struct ColourInvariantOptions {
  // Pixels darker than this (D of eq. 5.6, RGB in [0, 1]) carry no reliable colour.
  double min_intensity = 0.04;
  // Pixels with |D_lambdalambda| < min_denominator * D are near the pole of the ratio.
  double min_denominator = 0.02;
  // H is clamped to [-max_abs_h, max_abs_h]; beyond that the ratio is noise.
  double max_abs_h = 4.0;

  bool Check(std::string* error) const;
};

// Colour invariant H = D_lambda / D_lambdalambda per pixel (seed eq. 5.13), CV_32F, clamped.
// `valid` (CV_8U, 255 = usable) marks pixels that pass the intensity and pole tests.
cv::Mat ColourInvariantH(const cv::Mat& bgr, const ColourInvariantOptions& options, cv::Mat* valid);

}  // namespace placerec
