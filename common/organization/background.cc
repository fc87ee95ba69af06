#include "common/organization/background.h"

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cmath>
#include <numeric>
#include <random>
#include <thread>

#include <glog/logging.h>
#include <opencv2/core/persistence.hpp>

#include "common/util/paths.h"
#include "common/util/timer.h"

namespace placerec {

namespace {

// ml::Boost returns the sum of the weak responses only with PREDICT_SUM as well as RAW_OUTPUT;
// RAW_OUTPUT alone gives the 0/1 vote (OpenCV's DTreesImplForBoost::predictTrees), and the
// five-way argmax then broke every tie toward the first class (sky).
constexpr int kSumFlags = cv::ml::StatModel::RAW_OUTPUT | cv::ml::DTrees::PREDICT_SUM;

std::string ClassifierFile(const std::string& directory, const std::string& name) {
  return directory + "/background_" + name + ".yml.gz";
}

std::string ClassifierFile(const std::string& directory, int c) {
  return ClassifierFile(directory, SegmentClassName(BackgroundClassOf(c)));
}

// One trained classifier file that reads `features` columns.
StatusOr<cv::Ptr<cv::ml::Boost>> LoadBoost(const std::string& file, int features) {
  if (!PathExists(file)) return Status::NotFound("cannot read " + file);
  cv::Ptr<cv::ml::Boost> boost = cv::Algorithm::load<cv::ml::Boost>(file);
  if (!boost || !boost->isTrained()) return Status::NotFound("cannot read " + file);
  if (boost->getVarCount() != features) {
    return Status::InvalidArgument(file + ": " + std::to_string(boost->getVarCount()) +
                                   " features, expected " + std::to_string(features));
  }
  if (BoostedForest::Depth(*boost) > BoostedForest::kMaxDepth) {
    return Status::InvalidArgument(file + ": trees deeper than " +
                                   std::to_string(BoostedForest::kMaxDepth));
  }
  if (!BoostedForest::Intact(*boost)) {
    return Status::InvalidArgument(
        file + ": values that are not finite numbers or splits on variables it does not have (a " +
        "damaged model); restore models/ or retrain");
  }
  return boost;
}

// Structured class names become file names: letters, digits, '_' and '-' only.
bool SafeName(const std::string& name) {
  if (name.empty()) return false;
  for (const char ch : name) {
    if (!std::isalnum(static_cast<unsigned char>(ch)) && ch != '_' && ch != '-') return false;
  }
  return true;
}

}  // namespace

cv::Ptr<cv::ml::Boost> TrainGentleBoost(const cv::Mat& samples, const cv::Mat& responses,
                                        const cv::Mat& weights, int weak_count, int max_depth,
                                        double weight_trim_rate) {
  cv::Ptr<cv::ml::Boost> boost = cv::ml::Boost::create();
  boost->setBoostType(cv::ml::Boost::GENTLE);
  boost->setWeakCount(weak_count);
  boost->setMaxDepth(max_depth);
  boost->setWeightTrimRate(weight_trim_rate);
  boost->setUseSurrogates(false);
  boost->setCVFolds(0);
  boost->train(cv::ml::TrainData::create(samples, cv::ml::ROW_SAMPLE, responses, cv::noArray(),
                                         cv::noArray(), weights));
  return boost;
}

cv::Mat BoostedSums(const cv::ml::Boost& boost, const cv::Mat& samples) {
  cv::Mat sums(samples.rows, 1, CV_32F);
  if (samples.rows == 0) return sums;
  cv::Mat raw;
  boost.predict(samples, raw, kSumFlags);
  raw.reshape(1, samples.rows).copyTo(sums);
  return sums;
}

SegmentClass BackgroundClassOf(int index) {
  CHECK(index >= 0 && index < kBackgroundClasses) << "background class index " << index;
  return static_cast<SegmentClass>(index);
}

bool CheckGentleBoostOptions(const std::string& what, int weak_count, int max_depth,
                             double weight_trim_rate, std::string* error) {
  if (weak_count < 1) {
    *error = what + " weak_count must be at least 1, got " + std::to_string(weak_count);
    return false;
  }
  if (max_depth < 1 || max_depth > BoostedForest::kMaxTrainingDepth) {
    *error = what + " max_depth must be in [1, " +
             std::to_string(BoostedForest::kMaxTrainingDepth) + "], got " +
             std::to_string(max_depth);
    return false;
  }
  if (!(weight_trim_rate >= 0.0 && weight_trim_rate <= 1.0)) {
    *error = what + " weight_trim_rate must be in [0, 1]";
    return false;
  }
  return true;
}

bool BackgroundTrainingOptions::Check(std::string* error) const {
  if (!CheckGentleBoostOptions("background", weak_count, max_depth, weight_trim_rate, error)) {
    return false;
  }
  if (!(max_negatives_per_positive >= 0.0) || !std::isfinite(max_negatives_per_positive)) {
    *error = "background max_negatives_per_positive must be a finite value >= 0";
    return false;
  }
  return true;
}

StatusOr<BackgroundClassifier> BackgroundClassifier::Train(
    const cv::Mat& features, const std::vector<int>& labels, const std::vector<float>& weights,
    const BackgroundTrainingOptions& options, BackgroundTrainingSummary* summary,
    const std::vector<std::string>& structured_names, const std::vector<int>& structured_labels) {
  std::string error;
  CHECK(options.Check(&error)) << error;
  CHECK_EQ(features.type(), CV_32F);
  CHECK_EQ(features.rows, static_cast<int>(labels.size()));
  CHECK(weights.empty() || weights.size() == labels.size());
  CHECK(structured_names.empty() || structured_labels.size() == labels.size());
  Timer timer;
  const int classes = kBackgroundClasses + static_cast<int>(structured_names.size());
  BackgroundTrainingSummary stats;
  stats.positives.assign(classes, 0);
  stats.negatives.assign(classes, 0);
  stats.training_accuracy.assign(classes, 0.0);
  std::vector<cv::Ptr<cv::ml::Boost>> boosts(static_cast<size_t>(classes));

  // Classifier c: background class c, or structured class c - kBackgroundClasses. Its rows
  // split into positives and negatives before any training, so that a class that cannot be
  // learned is an error before any time is spent on the others.
  std::vector<std::vector<int>> positives_of(static_cast<size_t>(classes));
  std::vector<std::vector<int>> negatives_of(static_cast<size_t>(classes));
  for (int c = 0; c < classes; ++c) {
    for (int i = 0; i < features.rows; ++i) {
      if (labels[i] < 0) continue;
      const bool positive =
          c < kBackgroundClasses ? labels[i] == c : structured_labels[i] == c - kBackgroundClasses;
      (positive ? positives_of[c] : negatives_of[c]).push_back(i);
    }
    const std::string name = c < kBackgroundClasses ? SegmentClassName(BackgroundClassOf(c))
                                                    : structured_names[c - kBackgroundClasses];
    if (positives_of[c].empty() || negatives_of[c].empty()) {
      const std::string what = positives_of[c].empty() ? "no" : "only";
      return Status::InvalidArgument(what + " training regions of class " + name +
                                     ": its classifier needs regions of the class and of others");
    }
  }
  auto train_one = [&](int c) {
    const std::vector<int>& positives = positives_of[c];
    std::vector<int>& negatives = negatives_of[c];
    if (options.max_negatives_per_positive > 0) {
      const size_t keep = static_cast<size_t>(
          std::ceil(options.max_negatives_per_positive * static_cast<double>(positives.size())));
      if (negatives.size() > keep) {
        std::mt19937_64 rng(options.seed + static_cast<uint64_t>(c));
        std::shuffle(negatives.begin(), negatives.end(), rng);
        negatives.resize(keep);
        std::sort(negatives.begin(), negatives.end());
      }
    }
    cv::Mat samples(static_cast<int>(positives.size() + negatives.size()), features.cols, CV_32F);
    cv::Mat responses(samples.rows, 1, CV_32S);
    cv::Mat sample_weights(samples.rows, 1, CV_32F, cv::Scalar(1.0f));
    int row = 0;
    for (const std::vector<int>* rows : {&positives_of[c], &negatives_of[c]}) {
      for (const int i : *rows) {
        features.row(i).copyTo(samples.row(row));
        responses.at<int>(row) = rows == &positives ? 1 : 0;
        if (!weights.empty()) sample_weights.at<float>(row) = weights[i];
        ++row;
      }
    }
    boosts[c] = TrainGentleBoost(samples, responses, sample_weights, options.weak_count,
                                 options.max_depth, options.weight_trim_rate);
    const cv::Mat raw = BoostedSums(*boosts[c], samples);
    int correct = 0;
    for (int r = 0; r < samples.rows; ++r) {
      correct += (raw.at<float>(r) > 0) == (responses.at<int>(r) == 1);
    }
    stats.positives[c] = static_cast<int>(positives.size());
    stats.negatives[c] = static_cast<int>(negatives.size());
    stats.training_accuracy[c] = static_cast<double>(correct) / samples.rows;
  };
  // Two workers (the machines this runs on have two cores); each classifier is independent.
  std::atomic<int> next{0};
  auto worker = [&] {
    for (int c = next++; c < classes; c = next++) train_one(c);
  };
  std::thread helper(worker);
  worker();
  helper.join();

  BackgroundClassifier classifier;
  for (int c = 0; c < kBackgroundClasses; ++c) classifier.boosts_[c] = boosts[c];
  classifier.structured_names_ = structured_names;
  classifier.structured_.assign(boosts.begin() + kBackgroundClasses, boosts.end());
  classifier.Flatten();
  stats.seconds = timer.ElapsedMs() / 1000.0;
  if (summary != nullptr) *summary = stats;
  return classifier;
}

int BackgroundClassifier::feature_size() const { return empty() ? 0 : boosts_[0]->getVarCount(); }

void BackgroundClassifier::Flatten() {
  forests_.clear();
  for (const auto& boost : boosts_) forests_.emplace_back(*boost);
  for (const auto& boost : structured_) forests_.emplace_back(*boost);
}

cv::Mat BackgroundClassifier::ForestScores(const cv::Mat& features, int first, int count) const {
  CHECK(!empty()) << "background classifiers not loaded";
  CHECK_EQ(features.type(), CV_32F);
  CHECK_GE(features.cols, feature_size());
  cv::Mat scores(features.rows, count, CV_32F);
  if (features.rows == 0) return scores;
  std::vector<double> sums(static_cast<size_t>(features.rows));
  for (int c = 0; c < count; ++c) {
    forests_[static_cast<size_t>(first + c)].Sums(features.ptr<float>(0), features.step1(),
                                                  features.rows, sums.data());
    for (int r = 0; r < features.rows; ++r) scores.at<float>(r, c) = static_cast<float>(sums[r]);
  }
  return scores;
}

void BackgroundClassifier::ForestSums(const float* row, int first, int count, float* out) const {
  for (int c = 0; c < count; ++c) {
    out[c] = static_cast<float>(forests_[static_cast<size_t>(first + c)].Sum(row));
  }
}

void BackgroundClassifier::RowScores(const float* features, float* background,
                                     float* structured) const {
  CHECK(!empty()) << "background classifiers not loaded";
  ForestSums(features, 0, kBackgroundClasses, background);
  ForestSums(features, kBackgroundClasses, structured_classes(), structured);
}

cv::Mat BackgroundClassifier::Scores(const cv::Mat& features) const {
  return ForestScores(features, 0, kBackgroundClasses);
}

cv::Mat BackgroundClassifier::StructuredScores(const cv::Mat& features) const {
  if (structured_.empty()) return cv::Mat(features.rows, 0, CV_32F);
  return ForestScores(features, kBackgroundClasses, structured_classes());
}

std::vector<float> BackgroundClassifier::Rivals(const cv::Mat& features, bool one_per_class) const {
  std::vector<float> rivals(static_cast<size_t>(features.rows),
                            -std::numeric_limits<float>::infinity());
  if (!one_per_class || structured_.empty()) return rivals;
  const cv::Mat structured = StructuredScores(features);
  for (int r = 0; r < structured.rows; ++r) {
    const float* s = structured.ptr<float>(r);
    rivals[r] = *std::max_element(s, s + structured.cols);
  }
  return rivals;
}

SegmentClass BackgroundClassifier::Decide(const float* scores, double threshold, float rival) {
  int best = 0;
  for (int c = 1; c < kBackgroundClasses; ++c) {
    if (scores[c] > scores[best]) best = c;
  }
  return scores[best] > threshold && scores[best] > rival ? BackgroundClassOf(best)
                                                          : SegmentClass::kStructured;
}

std::vector<SegmentClass> BackgroundClassifier::Classify(const cv::Mat& features, double threshold,
                                                         bool one_per_class) const {
  const cv::Mat scores = Scores(features);
  const std::vector<float> rivals = Rivals(features, one_per_class);
  std::vector<SegmentClass> classes(static_cast<size_t>(features.rows));
  for (int r = 0; r < features.rows; ++r) {
    classes[r] = Decide(scores.ptr<float>(r), threshold, rivals[r]);
  }
  return classes;
}

Status BackgroundClassifier::Save(const std::string& directory) const {
  if (empty()) return Status::InvalidArgument("no background classifiers to save");
  try {
    cv::FileStorage fs(directory + "/background.yml", cv::FileStorage::WRITE);
    if (!fs.isOpened()) return Status::IoError("cannot write " + directory + "/background.yml");
    fs << "format_version" << kFormatVersion;
    fs << "features" << feature_size();
    fs << "classes"
       << "[";
    for (int c = 0; c < kBackgroundClasses; ++c) fs << SegmentClassName(BackgroundClassOf(c));
    fs << "]";
    fs << "structured_classes"
       << "[";
    for (const std::string& name : structured_names_) fs << name;
    fs << "]";
    fs.release();
    for (int c = 0; c < kBackgroundClasses; ++c) boosts_[c]->save(ClassifierFile(directory, c));
    for (int j = 0; j < structured_classes(); ++j) {
      if (!SafeName(structured_names_[j])) {
        return Status::InvalidArgument("structured class name '" + structured_names_[j] +
                                       "' is not usable as a file name");
      }
      structured_[j]->save(ClassifierFile(directory, structured_names_[j]));
    }
  } catch (const cv::Exception& e) {
    return Status::IoError("cannot write background classifiers to " + directory + ": " + e.what());
  }
  return Status::Ok();
}

StatusOr<BackgroundClassifier> BackgroundClassifier::Load(const std::string& directory) {
  BackgroundClassifier classifier;
  const std::string index = directory + "/background.yml";
  try {
    cv::FileStorage fs(index, cv::FileStorage::READ);
    if (!fs.isOpened()) return Status::NotFound("cannot read " + index);
    int version = 0;
    int features = 0;
    fs["format_version"] >> version;
    fs["features"] >> features;
    if (version != 1 && version != kFormatVersion) {
      return Status::InvalidArgument(index + ": format version " + std::to_string(version) +
                                     ", this build reads 1 and " + std::to_string(kFormatVersion));
    }
    std::vector<std::string> names;
    fs["classes"] >> names;
    if (static_cast<int>(names.size()) != kBackgroundClasses) {
      return Status::InvalidArgument(index + ": expected five classes");
    }
    for (int c = 0; c < kBackgroundClasses; ++c) {
      if (names[c] != SegmentClassName(BackgroundClassOf(c))) {
        return Status::InvalidArgument(index + ": class " + std::to_string(c) + " is " + names[c]);
      }
      StatusOr<cv::Ptr<cv::ml::Boost>> boost = LoadBoost(ClassifierFile(directory, c), features);
      if (!boost.ok()) return boost.status();
      classifier.boosts_[c] = *boost;
    }
    std::vector<std::string> structured;
    if (version >= 2 && !fs["structured_classes"].empty()) fs["structured_classes"] >> structured;
    for (const std::string& name : structured) {
      if (!SafeName(name)) {
        return Status::InvalidArgument(index + ": bad structured class name '" + name + "'");
      }
      StatusOr<cv::Ptr<cv::ml::Boost>> boost = LoadBoost(ClassifierFile(directory, name), features);
      if (!boost.ok()) return boost.status();
      classifier.structured_names_.push_back(name);
      classifier.structured_.push_back(*boost);
    }
    classifier.Flatten();
  } catch (const cv::Exception& e) {
    return Status::InvalidArgument("cannot load background classifiers from " + directory + ": " +
                                   e.what());
  }
  return classifier;
}

}  // namespace placerec
