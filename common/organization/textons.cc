#include "common/organization/textons.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <string>

#include <glog/logging.h>
#include <opencv2/core/persistence.hpp>

#include "common/organization/filter_bank.h"
#include "common/util/cpu.h"

namespace placerec {

bool TextonTrainingOptions::Check(std::string* error) const {
  if (k < 2 || k > 65535) {
    *error = "texton k must be in [2, 65535], got " + std::to_string(k);
    return false;
  }
  if (max_iterations < 1) {
    *error = "texton max_iterations must be at least 1, got " + std::to_string(max_iterations);
    return false;
  }
  if (!(epsilon >= 0.0) || !std::isfinite(epsilon)) {
    *error = "texton epsilon must be a finite value >= 0";
    return false;
  }
  if (attempts < 1) {
    *error = "texton attempts must be at least 1, got " + std::to_string(attempts);
    return false;
  }
  return true;
}

TextonModel TrainTextons(const cv::Mat& samples, const TextonTrainingOptions& options) {
  std::string error;
  CHECK(options.Check(&error)) << error;
  CHECK_EQ(samples.type(), CV_32F);
  CHECK_EQ(samples.cols, kTextonFeatureSize);
  CHECK_GE(samples.rows, options.k) << "fewer samples than textons";
  TextonModel model;
  cv::Mat mean;
  cv::Mat stddev;
  model.mean.create(1, kTextonFeatureSize, CV_32F);
  model.inv_std.create(1, kTextonFeatureSize, CV_32F);
  for (int d = 0; d < kTextonFeatureSize; ++d) {
    cv::Scalar m;
    cv::Scalar s;
    cv::meanStdDev(samples.col(d), m, s);
    model.mean.at<float>(d) = options.standardise ? static_cast<float>(m[0]) : 0.0f;
    model.inv_std.at<float>(d) =
        options.standardise && s[0] > 1e-6 ? static_cast<float>(1.0 / s[0]) : 1.0f;
  }
  cv::Mat standardised(samples.size(), CV_32F);
  for (int r = 0; r < samples.rows; ++r) {
    const float* in = samples.ptr<float>(r);
    float* out = standardised.ptr<float>(r);
    for (int d = 0; d < kTextonFeatureSize; ++d) {
      out[d] = (in[d] - model.mean.at<float>(d)) * model.inv_std.at<float>(d);
    }
  }
  cv::setRNGSeed(static_cast<int>(options.seed & 0x7fffffff));
  cv::Mat assignment;
  cv::kmeans(standardised, options.k, assignment,
             cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS,
                              options.max_iterations, options.epsilon),
             options.attempts, cv::KMEANS_PP_CENTERS, model.centres);
  model.centres.convertTo(model.centres, CV_32F);
  return model;
}

int NearestTexton(const TextonModel& model, const float* feature) {
  CHECK(!model.empty());
  double z[kTextonFeatureSize];
  for (int d = 0; d < kTextonFeatureSize; ++d) {
    z[d] = (static_cast<double>(feature[d]) - model.mean.at<float>(d)) * model.inv_std.at<float>(d);
  }
  int best = 0;
  double best_distance = std::numeric_limits<double>::infinity();
  for (int c = 0; c < model.size(); ++c) {
    const float* centre = model.centres.ptr<float>(c);
    double distance = 0;
    for (int d = 0; d < kTextonFeatureSize; ++d) {
      const double diff = z[d] - centre[d];
      distance += diff * diff;
    }
    if (distance < best_distance) {
      best_distance = distance;
      best = c;
    }
  }
  return best;
}

TextonAssigner::TextonAssigner(const TextonModel& model) {
  CHECK(!model.empty()) << "TextonAssigner needs a trained model";
  CHECK_EQ(model.centres.cols, kTextonFeatureSize);
  k_ = model.size();
  padded_ = (k_ + 7) / 8 * 8;
  mean_.assign(model.mean.ptr<float>(), model.mean.ptr<float>() + kTextonFeatureSize);
  inv_std_.assign(model.inv_std.ptr<float>(), model.inv_std.ptr<float>() + kTextonFeatureSize);
  transposed_.assign(static_cast<size_t>(kTextonFeatureSize) * padded_, 0.0f);
  half_norms_.assign(static_cast<size_t>(padded_), std::numeric_limits<float>::infinity());
  for (int c = 0; c < k_; ++c) {
    const float* centre = model.centres.ptr<float>(c);
    double norm = 0;
    for (int d = 0; d < kTextonFeatureSize; ++d) {
      transposed_[static_cast<size_t>(d) * padded_ + c] = centre[d];
      norm += static_cast<double>(centre[d]) * centre[d];
    }
    half_norms_[c] = static_cast<float>(0.5 * norm);
  }
  std::string values;
  auto append = [&values](const void* data, size_t bytes) {
    values.append(static_cast<const char*>(data), bytes);
  };
  append(&k_, sizeof(k_));
  append(mean_.data(), mean_.size() * sizeof(float));
  append(inv_std_.data(), inv_std_.size() * sizeof(float));
  append(transposed_.data(), transposed_.size() * sizeof(float));
  digest_ = std::hash<std::string>()(values);
}

namespace {

// scores[c] = half_norms[c] - z.c for the `padded` centres, z the standardised feature. The loops
// are inlined into two functions, one compiled for the baseline and one for AVX2, and the
// processor chooses once (a plain check rather than an ifunc, which would run before sanitizers
// start): the same additions and multiplications in the same order (no fused multiply-add), so
// the same scores either way.
inline __attribute__((always_inline)) void TextonScoresLoops(
    const float* feature, const float* mean, const float* inv_std, const float* transposed,
    const float* half_norms, int padded, float* scores) {
  for (int c = 0; c < padded; ++c) scores[c] = half_norms[c];
  for (int d = 0; d < kTextonFeatureSize; ++d) {
    const float z = (feature[d] - mean[d]) * inv_std[d];
    const float* column = transposed + static_cast<size_t>(d) * padded;
    for (int c = 0; c < padded; ++c) scores[c] -= z * column[c];
  }
}

void TextonScoresBaseline(const float* feature, const float* mean, const float* inv_std,
                          const float* transposed, const float* half_norms, int padded,
                          float* scores) {
  TextonScoresLoops(feature, mean, inv_std, transposed, half_norms, padded, scores);
}

#if defined(__x86_64__)
__attribute__((target("avx2"))) void TextonScoresAvx2(const float* feature, const float* mean,
                                                      const float* inv_std, const float* transposed,
                                                      const float* half_norms, int padded,
                                                      float* scores) {
  TextonScoresLoops(feature, mean, inv_std, transposed, half_norms, padded, scores);
}
#endif

void TextonScores(const float* feature, const float* mean, const float* inv_std,
                  const float* transposed, const float* half_norms, int padded, float* scores) {
#if defined(__x86_64__)
  if (CpuHasAvx2()) {
    TextonScoresAvx2(feature, mean, inv_std, transposed, half_norms, padded, scores);
    return;
  }
#endif
  TextonScoresBaseline(feature, mean, inv_std, transposed, half_norms, padded, scores);
}

}  // namespace

int TextonAssigner::Assign(const float* feature) const {
  // distance^2 / 2 - ||z||^2 / 2 = ||c||^2 / 2 - z.c, minimised over c.
  alignas(32) float score[1024];
  float* scores = padded_ <= 1024 ? score : nullptr;
  std::vector<float> heap_scores;
  if (scores == nullptr) {
    heap_scores.resize(static_cast<size_t>(padded_));
    scores = heap_scores.data();
  }
  TextonScores(feature, mean_.data(), inv_std_.data(), transposed_.data(), half_norms_.data(),
               padded_, scores);
  int best = 0;
  float best_score = scores[0];
  for (int c = 1; c < k_; ++c) {
    if (scores[c] < best_score) {
      best_score = scores[c];
      best = c;
    }
  }
  return best;
}

TextonMap ComputeTextonMap(const cv::Mat& features, const TextonAssigner& assigner, int stride) {
  CHECK_EQ(features.type(), CV_MAKETYPE(CV_32F, kTextonFeatureSize));
  CHECK_GE(stride, 1);
  TextonMap map;
  map.stride = stride;
  map.model = assigner.digest();
  const int rows = (features.rows + stride - 1) / stride;
  const int cols = (features.cols + stride - 1) / stride;
  map.ids.create(rows, cols, CV_16U);
  for (int r = 0; r < rows; ++r) {
    const float* row = features.ptr<float>(r * stride);
    uint16_t* out = map.ids.ptr<uint16_t>(r);
    for (int c = 0; c < cols; ++c) {
      out[c] = static_cast<uint16_t>(
          assigner.Assign(row + static_cast<size_t>(c) * stride * kTextonFeatureSize));
    }
  }
  return map;
}

cv::Mat RegionAppearance(const cv::Mat& labels, int num_regions, const TextonMap& map,
                         const cv::Mat& features, const TextonAssigner& assigner) {
  CHECK_EQ(labels.type(), CV_32S);
  CHECK(labels.size() == features.size()) << "labels and features differ in size";
  CHECK_EQ(features.type(), CV_MAKETYPE(CV_32F, kTextonFeatureSize));
  CHECK_GE(num_regions, 0);
  const int k = assigner.size();
  const int stride = map.stride;
  CHECK_EQ(map.ids.rows, (labels.rows + stride - 1) / stride);
  CHECK_EQ(map.ids.cols, (labels.cols + stride - 1) / stride);
  constexpr int kF = kTextonFeatureSize;
  cv::Mat out = cv::Mat::zeros(num_regions, k + 1 + kAppearanceExtras, CV_32F);
  // Per region: sums of the features and of their squares over the samples.
  std::vector<double> sums(static_cast<size_t>(num_regions) * 2 * kF, 0.0);
  auto accumulate = [&sums](int l, const float* f) {
    double* s = &sums[static_cast<size_t>(l) * 2 * kF];
    for (int i = 0; i < kF; ++i) {
      s[i] += f[i];
      s[kF + i] += static_cast<double>(f[i]) * f[i];
    }
  };
  std::vector<int64_t> row_sum(static_cast<size_t>(num_regions), 0);
  std::vector<int> area(static_cast<size_t>(num_regions), 0);
  std::vector<int> samples(static_cast<size_t>(num_regions), 0);
  for (int y = 0; y < labels.rows; ++y) {
    const int* row = labels.ptr<int>(y);
    for (int x = 0; x < labels.cols; ++x) {
      const int l = row[x];
      if (l < 0 || l >= num_regions) continue;
      ++area[l];
      row_sum[l] += y;
    }
  }
  for (int r = 0; r < map.ids.rows; ++r) {
    const int* row = labels.ptr<int>(r * stride);
    const uint16_t* ids = map.ids.ptr<uint16_t>(r);
    for (int c = 0; c < map.ids.cols; ++c) {
      const int l = row[c * stride];
      if (l < 0 || l >= num_regions) continue;
      ++out.at<float>(l, ids[c]);
      ++samples[l];
      accumulate(l, features.ptr<float>(r * stride) + static_cast<size_t>(c * stride) * kF);
    }
  }
  // Regions the grid misses: textons of all their pixels.
  std::vector<char> missed(static_cast<size_t>(num_regions), 0);
  bool any_missed = false;
  for (int l = 0; l < num_regions; ++l) {
    if (area[l] > 0 && samples[l] == 0) {
      missed[l] = 1;
      any_missed = true;
    }
  }
  if (any_missed) {
    for (int y = 0; y < labels.rows; ++y) {
      const int* row = labels.ptr<int>(y);
      const float* feature_row = features.ptr<float>(y);
      for (int x = 0; x < labels.cols; ++x) {
        const int l = row[x];
        if (l < 0 || l >= num_regions || !missed[l]) continue;
        ++out.at<float>(l,
                        assigner.Assign(feature_row + static_cast<size_t>(x) * kTextonFeatureSize));
        ++samples[l];
        accumulate(l, feature_row + static_cast<size_t>(x) * kF);
      }
    }
  }
  for (int l = 0; l < num_regions; ++l) {
    if (area[l] == 0) continue;
    float* row = out.ptr<float>(l);
    const float inv = 1.0f / static_cast<float>(samples[l]);
    for (int t = 0; t < k; ++t) row[t] *= inv;
    row[k] = static_cast<float>((static_cast<double>(row_sum[l]) / area[l] + 0.5) / labels.rows);
    const double* s = &sums[static_cast<size_t>(l) * 2 * kF];
    for (int i = 0; i < kF; ++i) {
      const double mean = s[i] / samples[l];
      const double variance = std::max(0.0, s[kF + i] / samples[l] - mean * mean);
      row[k + 1 + i] = static_cast<float>(mean);
      row[k + 1 + kF + i] = static_cast<float>(std::sqrt(variance));
    }
  }
  return out;
}

Status SaveTextons(const TextonModel& model, const std::string& path) {
  if (model.empty()) return Status::InvalidArgument("no textons to save");
  try {
    cv::FileStorage fs(path, cv::FileStorage::WRITE);
    if (!fs.isOpened()) return Status::IoError("cannot write " + path);
    fs << "format_version" << TextonModel::kFormatVersion;
    fs << "k" << model.size();
    fs << "features" << kTextonFeatureSize;
    fs << "mean" << model.mean;
    fs << "inv_std" << model.inv_std;
    fs << "centres" << model.centres;
  } catch (const cv::Exception& e) {
    return Status::IoError("cannot write " + path + ": " + e.what());
  }
  return Status::Ok();
}

StatusOr<TextonModel> LoadTextons(const std::string& path) {
  TextonModel model;
  try {
    cv::FileStorage fs(path, cv::FileStorage::READ);
    if (!fs.isOpened()) return Status::NotFound("cannot read textons " + path);
    int version = 0;
    int k = 0;
    int features = 0;
    fs["format_version"] >> version;
    fs["k"] >> k;
    fs["features"] >> features;
    if (version != TextonModel::kFormatVersion) {
      return Status::InvalidArgument(path + ": texton format version " + std::to_string(version) +
                                     ", expected " + std::to_string(TextonModel::kFormatVersion));
    }
    fs["mean"] >> model.mean;
    fs["inv_std"] >> model.inv_std;
    fs["centres"] >> model.centres;
    if (features != kTextonFeatureSize || k < 2 || model.centres.rows != k ||
        model.centres.cols != kTextonFeatureSize || model.centres.type() != CV_32F ||
        model.mean.total() != kTextonFeatureSize || model.mean.type() != CV_32F ||
        model.inv_std.total() != kTextonFeatureSize || model.inv_std.type() != CV_32F) {
      return Status::InvalidArgument(path + ": malformed texton model");
    }
    model.mean = model.mean.reshape(1, 1);
    model.inv_std = model.inv_std.reshape(1, 1);
  } catch (const cv::Exception& e) {
    return Status::InvalidArgument("cannot parse " + path + ": " + e.what());
  }
  return model;
}

}  // namespace placerec
