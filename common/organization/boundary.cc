#include "common/organization/boundary.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <vector>

#include <glog/logging.h>
#include <opencv2/core/persistence.hpp>

#include "common/organization/background.h"
#include "common/organization/filter_bank.h"

namespace placerec {
namespace {

// Bank channels whose differences across a pixel are features: G1, G2, G4 of L, a, b and the
// Laplacians of Gaussian sigma 1, 2, 4.
constexpr int kDifferenceChannels = 12;
constexpr int kDistances[3] = {1, 3, 6};
// The diagonal step for each distance, so that diagonal offsets are about as long.
constexpr int kDiagonal[3] = {1, 2, 4};
// Bank channel of L in the Gaussian of each distance's scale (G1.L, G2.L, G4.L).
constexpr int kColourAt[3] = {0, 3, 6};
constexpr int kBankDx2 = 13;
constexpr int kBankDx4 = 15;

}  // namespace

void BoundaryPixelFeatures(const cv::Mat& bank, int x, int y, float* out) {
  CHECK_EQ(bank.type(), CV_32FC(kTextonFeatureSize));
  const int w = bank.cols;
  const int h = bank.rows;
  auto at = [&](int px, int py) {
    px = std::clamp(px, 0, w - 1);
    py = std::clamp(py, 0, h - 1);
    return bank.ptr<float>(py) + static_cast<size_t>(px) * kTextonFeatureSize;
  };
  int i = 0;
  float colour[3][2];
  for (int di = 0; di < 3; ++di) {
    const int d = kDistances[di];
    const int g = kDiagonal[di];
    const int offsets[4][2] = {{d, 0}, {0, d}, {g, g}, {g, -g}};
    float largest[kDifferenceChannels];
    float smallest[kDifferenceChannels];
    std::fill(largest, largest + kDifferenceChannels, 0.0f);
    std::fill(smallest, smallest + kDifferenceChannels, std::numeric_limits<float>::max());
    float colour_max = 0.0f;
    float colour_min = std::numeric_limits<float>::max();
    for (const auto& o : offsets) {
      const float* p = at(x + o[0], y + o[1]);
      const float* q = at(x - o[0], y - o[1]);
      for (int c = 0; c < kDifferenceChannels; ++c) {
        const float diff = std::abs(p[c] - q[c]);
        largest[c] = std::max(largest[c], diff);
        smallest[c] = std::min(smallest[c], diff);
      }
      const int l = kColourAt[di];
      const float dl = p[l] - q[l];
      const float da = p[l + 1] - q[l + 1];
      const float db = p[l + 2] - q[l + 2];
      const float e = std::sqrt(dl * dl + da * da + db * db);
      colour_max = std::max(colour_max, e);
      colour_min = std::min(colour_min, e);
    }
    for (int c = 0; c < kDifferenceChannels; ++c) {
      out[i++] = largest[c];
      out[i++] = smallest[c];
    }
    colour[di][0] = colour_max;
    colour[di][1] = colour_min;
  }
  for (int di = 0; di < 3; ++di) {
    out[i++] = colour[di][0];
    out[i++] = colour[di][1];
  }
  const float* p = at(x, y);
  for (int c = 0; c < kTextonFeatureSize; ++c) out[i++] = p[c];
  out[i++] = std::hypot(p[kBankDx2], p[kBankDx2 + 1]);
  out[i++] = std::hypot(p[kBankDx4], p[kBankDx4 + 1]);
  out[i++] = h > 1 ? static_cast<float>(y) / static_cast<float>(h - 1) : 0.0f;
  CHECK_EQ(i, kBoundaryFeatures);
}

cv::Mat CrackPixels(const cv::Mat& labels, bool ignore_unlabelled) {
  CHECK_EQ(labels.type(), CV_32S);
  cv::Mat mask(labels.size(), CV_8U, cv::Scalar(0));
  auto cracks = [ignore_unlabelled](int a, int b) {
    return a != b && (!ignore_unlabelled || (a > 0 && b > 0));
  };
  for (int y = 0; y < labels.rows; ++y) {
    const int* row = labels.ptr<int>(y);
    const int* below = y + 1 < labels.rows ? labels.ptr<int>(y + 1) : nullptr;
    uint8_t* m = mask.ptr<uint8_t>(y);
    uint8_t* m_below = below != nullptr ? mask.ptr<uint8_t>(y + 1) : nullptr;
    for (int x = 0; x < labels.cols; ++x) {
      if (x + 1 < labels.cols && cracks(row[x], row[x + 1])) m[x] = m[x + 1] = 1;
      if (below != nullptr && cracks(row[x], below[x])) m[x] = m_below[x] = 1;
    }
  }
  return mask;
}

bool BoundaryModel::TrainingOptions::Check(std::string* error) const {
  if (weak_count < 1 || max_depth < 1 || max_depth > BoostedForest::kMaxTrainingDepth ||
      !(weight_trim_rate >= 0 && weight_trim_rate <= 1)) {
    *error = "boundary training: weak_count >= 1, max_depth in [1, " +
             std::to_string(BoostedForest::kMaxTrainingDepth) + "], weight_trim_rate in [0, 1]";
    return false;
  }
  return true;
}

BoundaryModel BoundaryModel::Train(const cv::Mat& features, const std::vector<int>& labels,
                                   const std::vector<float>& weights,
                                   const TrainingOptions& options) {
  CHECK_EQ(features.type(), CV_32F);
  CHECK_EQ(features.cols, kBoundaryFeatures);
  CHECK_EQ(features.rows, static_cast<int>(labels.size()));
  CHECK(weights.empty() || weights.size() == labels.size());
  std::string error;
  CHECK(options.Check(&error)) << error;
  cv::Mat responses(features.rows, 1, CV_32S);
  cv::Mat sample_weights(features.rows, 1, CV_32F, cv::Scalar(1.0f));
  for (int r = 0; r < features.rows; ++r) {
    responses.at<int>(r) = labels[r] != 0 ? 1 : 0;
    if (!weights.empty()) sample_weights.at<float>(r) = weights[r];
  }
  BoundaryModel model;
  model.boost_ = TrainGentleBoost(features, responses, sample_weights, options.weak_count,
                                  options.max_depth, options.weight_trim_rate);
  model.forest_ = BoostedForest(*model.boost_);
  return model;
}

Status BoundaryModel::Save(const std::string& directory) const {
  if (empty()) return Status::InvalidArgument("no boundary model to save");
  const std::string path = directory + "/" + kFileName;
  // The temporary name keeps the .gz ending: FileStorage compresses by the name.
  const std::string temporary = directory + "/.writing." + kFileName;
  try {
    cv::FileStorage fs(temporary, cv::FileStorage::WRITE);
    if (!fs.isOpened()) return Status::IoError("cannot write " + temporary);
    fs << "format_version" << kFormatVersion;
    fs << "features" << kBoundaryFeatures;
    fs << "boost"
       << "{";
    boost_->write(fs);
    fs << "}";
    fs.release();
  } catch (const cv::Exception& e) {
    return Status::IoError("cannot write " + temporary + ": " + e.what());
  }
  std::error_code ec;
  std::filesystem::rename(temporary, path, ec);
  if (ec) return Status::IoError("cannot move " + temporary + " to " + path + ": " + ec.message());
  return Status::Ok();
}

StatusOr<BoundaryModel> BoundaryModel::Load(const std::string& directory) {
  const std::string path = directory + "/" + kFileName;
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) return Status::NotFound("no " + path);
  BoundaryModel model;
  try {
    cv::FileStorage fs(path, cv::FileStorage::READ);
    if (!fs.isOpened()) return Status::NotFound("cannot read " + path);
    int version = 0;
    int features = 0;
    fs["format_version"] >> version;
    fs["features"] >> features;
    if (version != kFormatVersion || features != kBoundaryFeatures) {
      return Status::InvalidArgument(
          path + ": format version " + std::to_string(version) + " with " +
          std::to_string(features) + " features; this build reads version " +
          std::to_string(kFormatVersion) + " with " + std::to_string(kBoundaryFeatures) +
          " (retrain with placerec-train boundary)");
    }
    cv::Ptr<cv::ml::Boost> boost = cv::ml::Boost::create();
    boost->read(fs["boost"]);
    if (!boost->isTrained() || boost->getVarCount() != kBoundaryFeatures ||
        BoostedForest::Depth(*boost) > BoostedForest::kMaxDepth || !BoostedForest::Intact(*boost)) {
      return Status::InvalidArgument(path +
                                     " is not a trained boundary classifier (or holds values "
                                     "that are not finite numbers or splits on variables it "
                                     "does not have)");
    }
    model.boost_ = boost;
    model.forest_ = BoostedForest(*boost);
  } catch (const cv::Exception& e) {
    return Status::InvalidArgument("cannot load " + path + ": " + e.what());
  }
  return model;
}

double BoundaryModel::Score(const float* features) const {
  CHECK(!empty()) << "boundary model not loaded";
  return forest_.Sum(features);
}

cv::Mat BoundaryModel::ScoreMap(const cv::Mat& bank, const cv::Mat& mask) const {
  CHECK(!empty()) << "boundary model not loaded";
  CHECK_EQ(mask.type(), CV_8U);
  CHECK(mask.size() == bank.size());
  cv::Mat scores(bank.size(), CV_32F, cv::Scalar(0.0f));
  // Rows of features, scored in batches (BoostedForest::Sums).
  constexpr int kBatch = 256;
  std::vector<float> features(static_cast<size_t>(kBatch) * kBoundaryFeatures);
  std::vector<double> sums(kBatch);
  std::vector<float*> targets;
  targets.reserve(kBatch);
  auto flush = [&]() {
    const int n = static_cast<int>(targets.size());
    forest_.Sums(features.data(), kBoundaryFeatures, n, sums.data());
    for (int i = 0; i < n; ++i) *targets[static_cast<size_t>(i)] = static_cast<float>(sums[i]);
    targets.clear();
  };
  for (int y = 0; y < bank.rows; ++y) {
    const uint8_t* m = mask.ptr<uint8_t>(y);
    float* s = scores.ptr<float>(y);
    for (int x = 0; x < bank.cols; ++x) {
      if (m[x] == 0) continue;
      BoundaryPixelFeatures(bank, x, y, features.data() + targets.size() * kBoundaryFeatures);
      targets.push_back(s + x);
      if (static_cast<int>(targets.size()) == kBatch) flush();
    }
  }
  if (!targets.empty()) flush();
  return scores;
}

}  // namespace placerec
