#include "common/classification/object_description.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>
#include <opencv2/imgproc.hpp>

#include "common/image/image.h"
#include "common/organization/filter_bank.h"

namespace placerec {
namespace {

constexpr double kHalfPi = 1.57079632679489661923;

std::string SizeText(const cv::Size& size) {
  return std::to_string(size.width) + "x" + std::to_string(size.height);
}

// A mask of `expected` size (any size when empty), CV_8UC1, with at least one object pixel.
Status CheckMask(const cv::Mat& mask, const cv::Size& expected) {
  if (mask.empty()) return Status::InvalidArgument("object mask is empty (no pixels)");
  if (mask.type() != CV_8UC1) {
    return Status::InvalidArgument("object mask must be CV_8UC1 (8-bit, one channel), got type " +
                                   std::to_string(mask.type()) + " with " +
                                   std::to_string(mask.channels()) + " channel(s)");
  }
  if (!expected.empty() && mask.size() != expected) {
    return Status::InvalidArgument("object mask is " + SizeText(mask.size()) +
                                   " pixels but the image is " + SizeText(expected));
  }
  if (cv::countNonZero(mask) == 0) {
    return Status::InvalidArgument("object mask has no object pixels (all zero)");
  }
  return Status::Ok();
}

Status CheckOptions(const ObjectDescriptionOptions& options) {
  std::string error;
  if (!options.Check(&error)) return Status::InvalidArgument(error);
  return Status::Ok();
}

// A texton map the size of `mask`, CV_16UC1, with ids below k on every mask pixel.
Status CheckTextonIds(const cv::Mat& texton_ids, const cv::Mat& mask, int k) {
  if (k < 1)
    return Status::InvalidArgument("texton count must be at least 1, got " + std::to_string(k));
  if (texton_ids.type() != CV_16UC1) {
    return Status::InvalidArgument("texton map must be CV_16UC1, got type " +
                                   std::to_string(texton_ids.type()));
  }
  if (Status status = CheckMask(mask, texton_ids.size()); !status.ok()) return status;
  for (int y = 0; y < mask.rows; ++y) {
    const uint8_t* m = mask.ptr<uint8_t>(y);
    const uint16_t* ids = texton_ids.ptr<uint16_t>(y);
    for (int x = 0; x < mask.cols; ++x) {
      if (m[x] != 0 && ids[x] >= k) {
        return Status::InvalidArgument("texton id " + std::to_string(ids[x]) + " at (" +
                                       std::to_string(x) + ", " + std::to_string(y) +
                                       ") is not below the texton count " + std::to_string(k));
      }
    }
  }
  return Status::Ok();
}

// Scales `counts` to sum to one (left all zero when empty).
void Normalise(float* counts, int k) {
  double total = 0;
  for (int t = 0; t < k; ++t) total += counts[t];
  if (total <= 0) return;
  const float inv = static_cast<float>(1.0 / total);
  for (int t = 0; t < k; ++t) counts[t] *= inv;
}

// U with 0 outside the image (the Dirichlet value).
double At(const cv::Mat& u, int x, int y) {
  if (x < 0 || y < 0 || x >= u.cols || y >= u.rows) return 0.0;
  return u.at<double>(y, x);
}

// The mask's bounding box, scaled so that its longer side is at most `max_side` (0/255 CV_8U).
cv::Mat WorkingMask(const cv::Mat& mask, int max_side) {
  const cv::Rect box = cv::boundingRect(mask);
  cv::Mat crop = mask(box) != 0;  // 0 / 255
  const int longer = std::max(box.width, box.height);
  if (longer <= max_side) return crop;
  const double scale = static_cast<double>(max_side) / longer;
  const cv::Size size(std::max(1, static_cast<int>(std::lround(box.width * scale))),
                      std::max(1, static_cast<int>(std::lround(box.height * scale))));
  cv::Mat area;
  cv::resize(crop, area, size, 0, 0, cv::INTER_AREA);
  cv::Mat working = area >= 128;
  // A thin object can vanish at half coverage; then every pixel it touches is kept.
  if (cv::countNonZero(working) == 0) working = area > 0;
  return working;
}

}  // namespace

bool ObjectDescriptionOptions::Check(std::string* error) const {
  if (shape_max_side < 8 || shape_max_side > 2048) {
    *error = "object description shape_max_side must be in [8, 2048], got " +
             std::to_string(shape_max_side);
    return false;
  }
  if (!(orientation_gamma > 0) || !std::isfinite(orientation_gamma)) {
    *error = "object description orientation_gamma must be positive and finite";
    return false;
  }
  if (!(concavity_delta > 0) || !std::isfinite(concavity_delta)) {
    *error = "object description concavity_delta must be positive and finite";
    return false;
  }
  return true;
}

std::vector<float> ObjectDescription::Concatenated() const {
  std::vector<float> all;
  all.reserve(appearance.size() + parts_layout.size() + shape.size());
  all.insert(all.end(), appearance.begin(), appearance.end());
  all.insert(all.end(), parts_layout.begin(), parts_layout.end());
  all.insert(all.end(), shape.begin(), shape.end());
  return all;
}

StatusOr<std::vector<float>> AppearanceFeatures(const cv::Mat& texton_ids, const cv::Mat& mask,
                                                int k) {
  if (Status status = CheckTextonIds(texton_ids, mask, k); !status.ok()) return status;
  std::vector<float> out(static_cast<size_t>(AppearanceSize(k)), 0.0f);
  int64_t row_sum = 0;
  int64_t area = 0;
  for (int y = 0; y < mask.rows; ++y) {
    const uint8_t* m = mask.ptr<uint8_t>(y);
    const uint16_t* ids = texton_ids.ptr<uint16_t>(y);
    for (int x = 0; x < mask.cols; ++x) {
      if (m[x] == 0) continue;
      ++out[ids[x]];
      row_sum += y;
      ++area;
    }
  }
  Normalise(out.data(), k);
  out[k] = static_cast<float>((static_cast<double>(row_sum) / area + 0.5) / mask.rows);
  return out;
}

StatusOr<std::vector<float>> PartsLayoutFeatures(const cv::Mat& texton_ids, const cv::Mat& mask,
                                                 int k) {
  if (Status status = CheckTextonIds(texton_ids, mask, k); !status.ok()) return status;
  const cv::Rect box = cv::boundingRect(mask);
  // Centroid in continuous coordinates (pixel x covers [x, x + 1)).
  double sum_x = 0;
  double sum_y = 0;
  int64_t area = 0;
  for (int y = box.y; y < box.y + box.height; ++y) {
    const uint8_t* m = mask.ptr<uint8_t>(y);
    for (int x = box.x; x < box.x + box.width; ++x) {
      if (m[x] == 0) continue;
      sum_x += x + 0.5;
      sum_y += y + 0.5;
      ++area;
    }
  }
  const double cx = sum_x / area;
  const double cy = sum_y / area;
  // Lines of the fine grid: half-way between the centroid and the box's sides.
  const double left = 0.5 * (box.x + cx);
  const double right = 0.5 * (cx + box.x + box.width);
  const double top = 0.5 * (box.y + cy);
  const double bottom = 0.5 * (cy + box.y + box.height);

  std::vector<float> out(static_cast<size_t>(PartsLayoutSize(k)), 0.0f);
  for (int y = box.y; y < box.y + box.height; ++y) {
    const uint8_t* m = mask.ptr<uint8_t>(y);
    const uint16_t* ids = texton_ids.ptr<uint16_t>(y);
    const double py = y + 0.5;
    const int coarse_row = py < cy ? 0 : 1;
    const int fine_row = coarse_row == 0 ? (py < top ? 0 : 1) : (py < bottom ? 2 : 3);
    for (int x = box.x; x < box.x + box.width; ++x) {
      if (m[x] == 0) continue;
      const double px = x + 0.5;
      const int coarse_col = px < cx ? 0 : 1;
      const int fine_col = coarse_col == 0 ? (px < left ? 0 : 1) : (px < right ? 2 : 3);
      const int coarse_block = 2 * coarse_row + coarse_col;
      const int fine_block = 4 + 4 * fine_row + fine_col;
      ++out[static_cast<size_t>(coarse_block) * k + ids[x]];
      ++out[static_cast<size_t>(fine_block) * k + ids[x]];
    }
  }
  for (int block = 0; block < kPartsLayoutBlocks; ++block) {
    Normalise(out.data() + static_cast<size_t>(block) * k, k);
  }
  return out;
}

StatusOr<cv::Mat> SolvePoisson(const cv::Mat& mask) {
  if (Status status = CheckMask(mask, cv::Size()); !status.ok()) return status;
  // Unknowns: the mask's pixels in row-major order.
  cv::Mat index(mask.size(), CV_32S, cv::Scalar(-1));
  int n = 0;
  for (int y = 0; y < mask.rows; ++y) {
    const uint8_t* m = mask.ptr<uint8_t>(y);
    int* idx = index.ptr<int>(y);
    for (int x = 0; x < mask.cols; ++x) {
      if (m[x] != 0) idx[x] = n++;
    }
  }
  // -Delta U = 1 with the 5-point Laplacian (h = 1); neighbours outside the mask are the
  // boundary, U = 0, and drop out of the system. The matrix is symmetric positive definite.
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(static_cast<size_t>(n) * 5);
  const int dx[4] = {1, -1, 0, 0};
  const int dy[4] = {0, 0, 1, -1};
  for (int y = 0; y < mask.rows; ++y) {
    const int* idx = index.ptr<int>(y);
    for (int x = 0; x < mask.cols; ++x) {
      const int i = idx[x];
      if (i < 0) continue;
      triplets.emplace_back(i, i, 4.0);
      for (int d = 0; d < 4; ++d) {
        const int nx = x + dx[d];
        const int ny = y + dy[d];
        if (nx < 0 || ny < 0 || nx >= mask.cols || ny >= mask.rows) continue;
        const int j = index.at<int>(ny, nx);
        if (j >= 0) triplets.emplace_back(i, j, -1.0);
      }
    }
  }
  Eigen::SparseMatrix<double> a(n, n);
  a.setFromTriplets(triplets.begin(), triplets.end());
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(a);
  if (solver.info() != Eigen::Success) {
    return Status::Internal("Poisson system of " + std::to_string(n) +
                            " pixels could not be factorised");
  }
  const Eigen::VectorXd u = solver.solve(Eigen::VectorXd::Ones(n));
  if (solver.info() != Eigen::Success) {
    return Status::Internal("Poisson system of " + std::to_string(n) +
                            " pixels could not be solved");
  }
  cv::Mat out = cv::Mat::zeros(mask.size(), CV_64F);
  for (int y = 0; y < mask.rows; ++y) {
    const int* idx = index.ptr<int>(y);
    double* row = out.ptr<double>(y);
    for (int x = 0; x < mask.cols; ++x) {
      if (idx[x] >= 0) row[x] = u[idx[x]];
    }
  }
  return out;
}

StatusOr<ShapeMaps> ComputeShapeMaps(const cv::Mat& mask, const ObjectDescriptionOptions& options) {
  if (Status status = CheckOptions(options); !status.ok()) return status;
  StatusOr<cv::Mat> solved = SolvePoisson(mask);
  if (!solved.ok()) return solved.status();
  ShapeMaps maps;
  maps.u = std::move(*solved);
  const cv::Mat& u = maps.u;
  maps.phi = cv::Mat::zeros(mask.size(), CV_64F);
  maps.angle = cv::Mat::zeros(mask.size(), CV_64F);
  maps.w_vertical = cv::Mat::zeros(mask.size(), CV_64F);
  maps.w_horizontal = cv::Mat::zeros(mask.size(), CV_64F);
  maps.w_concave = cv::Mat::zeros(mask.size(), CV_64F);
  const double gamma = options.orientation_gamma;
  double max_abs_phi = 0;
  for (int y = 0; y < mask.rows; ++y) {
    const uint8_t* m = mask.ptr<uint8_t>(y);
    for (int x = 0; x < mask.cols; ++x) {
      if (m[x] == 0) continue;
      const double c = At(u, x, y);
      const double e = At(u, x + 1, y);
      const double w = At(u, x - 1, y);
      const double s = At(u, x, y + 1);
      const double nn = At(u, x, y - 1);
      // Eq. 4.5: Phi = U + |grad U|^2, central differences.
      const double ux = 0.5 * (e - w);
      const double uy = 0.5 * (s - nn);
      const double phi = c + ux * ux + uy * uy;
      maps.phi.at<double>(y, x) = phi;
      max_abs_phi = std::max(max_abs_phi, std::abs(phi));
      // Hessian [[a, b], [b, d]]. The eigenvector of the larger eigenvalue, m + r, is at angle
      // theta = atan2(2 b, a - d) / 2 to the x axis; that of m - r is perpendicular to it. The
      // leading one is that of the eigenvalue largest in absolute value.
      const double a = e - 2 * c + w;
      const double d = s - 2 * c + nn;
      const double b = 0.25 * (At(u, x + 1, y + 1) - At(u, x + 1, y - 1) - At(u, x - 1, y + 1) +
                               At(u, x - 1, y - 1));
      // Where both eigenvalues are equal (r = 0, e.g. a symmetric disc's centre) there is no
      // leading eigenvector; alpha = pi/4 there, as vertical as horizontal.
      const double r = std::hypot(0.5 * (a - d), b);
      double alpha = 0.5 * kHalfPi;
      if (r > 1e-9 * (std::abs(0.5 * (a + d)) + r)) {
        double theta = 0.5 * std::atan2(2 * b, a - d);
        if (a + d < 0) theta += kHalfPi;  // m - r is the larger in absolute value
        // |alpha| of the line through the eigenvector, folded into [0, pi/2].
        alpha = std::atan2(std::abs(std::sin(theta)), std::abs(std::cos(theta)));
      }
      maps.angle.at<double>(y, x) = alpha;
      maps.w_vertical.at<double>(y, x) = std::exp(-gamma * alpha);                        // eq. 4.3
      maps.w_horizontal.at<double>(y, x) = std::exp(-gamma * std::abs(kHalfPi - alpha));  // 4.4
    }
  }
  // Eq. 4.6 with Phi normalised to a largest absolute value of 1 (U > 0 inside, so max > 0).
  CHECK_GT(max_abs_phi, 0.0);
  for (int y = 0; y < mask.rows; ++y) {
    const uint8_t* m = mask.ptr<uint8_t>(y);
    for (int x = 0; x < mask.cols; ++x) {
      if (m[x] == 0) continue;
      const double phi_n = maps.phi.at<double>(y, x) / max_abs_phi;
      maps.w_concave.at<double>(y, x) = 1.0 / (1.0 + std::exp(-options.concavity_delta * phi_n));
    }
  }
  return maps;
}

StatusOr<std::vector<float>> ShapeFeatures(const cv::Mat& mask,
                                           const ObjectDescriptionOptions& options) {
  if (Status status = CheckMask(mask, cv::Size()); !status.ok()) return status;
  if (Status status = CheckOptions(options); !status.ok()) return status;
  const cv::Mat working = WorkingMask(mask, options.shape_max_side);
  StatusOr<ShapeMaps> maps = ComputeShapeMaps(working, options);
  if (!maps.ok()) return maps.status();

  // Coordinates relative to the centroid, in units of sqrt(area).
  double sum_x = 0;
  double sum_y = 0;
  int64_t area = 0;
  for (int y = 0; y < working.rows; ++y) {
    const uint8_t* m = working.ptr<uint8_t>(y);
    for (int x = 0; x < working.cols; ++x) {
      if (m[x] == 0) continue;
      sum_x += x;
      sum_y += y;
      ++area;
    }
  }
  const double cx = sum_x / area;
  const double cy = sum_y / area;
  const double inv_scale = 1.0 / std::sqrt(static_cast<double>(area));

  // (p, q) of eq. 4.7 in output order.
  constexpr int kOrders[kShapeMomentsPerMeasure][2] = {{0, 0}, {1, 0}, {0, 1}, {2, 0}, {1, 1},
                                                       {0, 2}, {3, 0}, {2, 1}, {1, 2}, {0, 3}};
  const cv::Mat* measures[3] = {&maps->w_vertical, &maps->w_horizontal, &maps->w_concave};
  std::vector<float> out(kShapeFeatureSize, 0.0f);
  for (int k = 0; k < 3; ++k) {
    double sums[kShapeMomentsPerMeasure] = {};
    for (int y = 0; y < working.rows; ++y) {
      const uint8_t* m = working.ptr<uint8_t>(y);
      const double* w = measures[k]->ptr<double>(y);
      const double yy = (y - cy) * inv_scale;
      for (int x = 0; x < working.cols; ++x) {
        if (m[x] == 0) continue;
        const double xx = (x - cx) * inv_scale;
        const double px[4] = {1.0, xx, xx * xx, xx * xx * xx};
        const double py[4] = {1.0, yy, yy * yy, yy * yy * yy};
        for (int i = 0; i < kShapeMomentsPerMeasure; ++i) {
          sums[i] += w[x] * px[kOrders[i][0]] * py[kOrders[i][1]];
        }
      }
    }
    // Every weight is positive (W_0, W_pi/2 >= exp(-gamma pi/2), W_c >= 1 / (1 + e^delta)).
    CHECK_GT(sums[0], 0.0);
    float* moments = out.data() + static_cast<size_t>(k) * kShapeMomentsPerMeasure;
    moments[0] = static_cast<float>(sums[0] / area);
    for (int i = 1; i < kShapeMomentsPerMeasure; ++i) {
      moments[i] = static_cast<float>(sums[i] / sums[0]);
    }
  }
  return out;
}

StatusOr<ObjectDescription> DescribeObjectInFeatures(const cv::Mat& features, const cv::Mat& mask,
                                                     const TextonAssigner& textons,
                                                     const ObjectDescriptionOptions& options) {
  if (features.empty()) return Status::InvalidArgument("filter-bank image is empty");
  if (features.type() != CV_MAKETYPE(CV_32F, kTextonFeatureSize)) {
    return Status::InvalidArgument("filter-bank image must be CV_32FC(" +
                                   std::to_string(kTextonFeatureSize) + "), got type " +
                                   std::to_string(features.type()));
  }
  if (Status status = CheckMask(mask, features.size()); !status.ok()) return status;
  if (Status status = CheckOptions(options); !status.ok()) return status;
  const int k = textons.size();
  // Textons of the object's pixels only.
  cv::Mat ids = cv::Mat::zeros(mask.size(), CV_16U);
  const cv::Rect box = cv::boundingRect(mask);
  for (int y = box.y; y < box.y + box.height; ++y) {
    const uint8_t* m = mask.ptr<uint8_t>(y);
    const float* f = features.ptr<float>(y);
    uint16_t* out = ids.ptr<uint16_t>(y);
    for (int x = box.x; x < box.x + box.width; ++x) {
      if (m[x] != 0) {
        out[x] =
            static_cast<uint16_t>(textons.Assign(f + static_cast<size_t>(x) * kTextonFeatureSize));
      }
    }
  }
  ObjectDescription description;
  StatusOr<std::vector<float>> appearance = AppearanceFeatures(ids, mask, k);
  if (!appearance.ok()) return appearance.status();
  description.appearance = std::move(*appearance);
  StatusOr<std::vector<float>> parts = PartsLayoutFeatures(ids, mask, k);
  if (!parts.ok()) return parts.status();
  description.parts_layout = std::move(*parts);
  StatusOr<std::vector<float>> shape = ShapeFeatures(mask, options);
  if (!shape.ok()) return shape.status();
  description.shape = std::move(*shape);
  return description;
}

StatusOr<ObjectDescription> DescribeObject(const cv::Mat& bgr, const cv::Mat& mask,
                                           const TextonAssigner& textons,
                                           const ObjectDescriptionOptions& options) {
  if (bgr.empty()) return Status::InvalidArgument("image is empty");
  if (bgr.type() != CV_8UC3) {
    return Status::InvalidArgument("image must be CV_8UC3 (8-bit BGR), got type " +
                                   std::to_string(bgr.type()));
  }
  // Checked before the filter bank so that bad input costs nothing.
  if (Status status = CheckMask(mask, bgr.size()); !status.ok()) return status;
  if (Status status = CheckOptions(options); !status.ok()) return status;
  return DescribeObjectInFeatures(ComputeFilterBank(ToLab(bgr)), mask, textons, options);
}

}  // namespace placerec
