#include "common/classification/object_classifier.h"

#include <algorithm>
#include <atomic>
#include <mutex>
#include <numeric>
#include <thread>

#include <glog/logging.h>
#include <opencv2/core/persistence.hpp>

#include "common/organization/background.h"
#include "common/organization/boosted_forest.h"
#include "common/util/paths.h"
#include "common/util/timer.h"

namespace placerec {

namespace {

std::string IndexFile(const std::string& directory) { return directory + "/objects.yml"; }

std::string BoostFile(const std::string& directory, int c) {
  return directory + "/objects_" + std::to_string(c) + ".yml.gz";
}

}  // namespace

bool ObjectClassifierOptions::Check(std::string* error) const {
  if (!CheckGentleBoostOptions("object classifier", weak_count, max_depth, weight_trim_rate,
                               error)) {
    return false;
  }
  if (threads < 1) {
    *error = "object classifier threads must be at least 1";
    return false;
  }
  return selection.Check(error);
}

StatusOr<ObjectClassifier> ObjectClassifier::Train(
    const cv::Mat& samples, const std::vector<int>& labels, const std::vector<std::string>& names,
    const std::vector<FeatureGroup>& groups, const ObjectClassifierOptions& options,
    std::vector<ObjectClassSummary>* summary,
    const std::function<void(int done, const ObjectClassSummary&)>& progress) {
  std::string error;
  if (!options.Check(&error)) return Status::InvalidArgument(error);
  if (samples.type() != CV_32F || samples.rows != static_cast<int>(labels.size())) {
    return Status::InvalidArgument("object classifier needs CV_32F samples, one label per row");
  }
  if (names.empty()) return Status::InvalidArgument("no object classes to train");
  if (groups.empty()) return Status::InvalidArgument("no feature groups");
  const int classes = static_cast<int>(names.size());
  std::vector<int> rows;
  std::vector<int> counts(static_cast<size_t>(classes), 0);
  for (int i = 0; i < samples.rows; ++i) {
    if (labels[i] < -1 || labels[i] >= classes) {
      return Status::InvalidArgument("object label " + std::to_string(labels[i]) + " outside the " +
                                     std::to_string(classes) + " classes");
    }
    if (labels[i] >= 0) {
      rows.push_back(i);
      ++counts[labels[i]];
    }
  }
  for (int c = 0; c < classes; ++c) {
    if (counts[c] < options.selection.folds ||
        static_cast<int>(rows.size()) - counts[c] < options.selection.folds) {
      return Status::InvalidArgument(
          "class " + names[c] + " has " + std::to_string(counts[c]) + " training objects of " +
          std::to_string(rows.size()) + "; its classifier needs at least " +
          std::to_string(options.selection.folds) + " of it and of the others");
    }
  }
  std::vector<int> group_columns;
  for (const FeatureGroup& group : groups) {
    if (group.begin < 0 || group.end > samples.cols || group.begin >= group.end) {
      return Status::InvalidArgument("feature group " + group.name + " outside the columns");
    }
    for (int c = group.begin; c < group.end; ++c) group_columns.push_back(c);
  }
  std::sort(group_columns.begin(), group_columns.end());
  if (std::adjacent_find(group_columns.begin(), group_columns.end()) != group_columns.end()) {
    return Status::InvalidArgument("feature groups overlap");
  }
  // The labelled rows only, once.
  cv::Mat data(static_cast<int>(rows.size()), samples.cols, CV_32F);
  for (size_t i = 0; i < rows.size(); ++i)
    samples.row(rows[i]).copyTo(data.row(static_cast<int>(i)));

  ObjectClassifier classifier;
  classifier.feature_size_ = samples.cols;
  classifier.names_ = names;
  classifier.columns_.assign(static_cast<size_t>(classes), {});
  classifier.boosts_.assign(static_cast<size_t>(classes), nullptr);
  std::vector<ObjectClassSummary> stats(static_cast<size_t>(classes));
  std::vector<Status> failures(static_cast<size_t>(classes), Status::Ok());

  auto train_one = [&](int c) {
    Timer timer;
    ObjectClassSummary& s = stats[c];
    s.name = names[c];
    std::vector<int> binary(rows.size());
    for (size_t i = 0; i < rows.size(); ++i) binary[i] = labels[rows[i]] == c ? 1 : 0;
    s.positives = counts[c];
    s.negatives = static_cast<int>(rows.size()) - counts[c];
    std::vector<int> columns = group_columns;
    if (options.select_features) {
      FeatureSelectionOptions selection = options.selection;
      selection.seed += static_cast<uint64_t>(c);
      StatusOr<std::vector<int>> selected =
          SelectFeatures(data, binary, groups, selection, &s.selection);
      if (!selected.ok()) {
        failures[c] =
            Status::InvalidArgument("class " + names[c] + ": " + selected.status().message());
        return;
      }
      columns = *selected;
    }
    cv::Mat x(data.rows, static_cast<int>(columns.size()), CV_32F);
    for (int r = 0; r < data.rows; ++r) {
      const float* in = data.ptr<float>(r);
      float* out = x.ptr<float>(r);
      for (size_t j = 0; j < columns.size(); ++j) out[j] = in[columns[j]];
    }
    cv::Mat responses(data.rows, 1, CV_32S);
    cv::Mat weights(data.rows, 1, CV_32F);
    for (int r = 0; r < data.rows; ++r) {
      responses.at<int>(r) = binary[r];
      weights.at<float>(r) = binary[r] ? 0.5f / s.positives : 0.5f / s.negatives;
    }
    classifier.boosts_[c] = TrainGentleBoost(x, responses, weights, options.weak_count,
                                             options.max_depth, options.weight_trim_rate);
    classifier.columns_[c] = columns;
    for (const FeatureGroup& group : groups) {
      s.per_group.push_back(
          static_cast<int>(std::count_if(columns.begin(), columns.end(), [&](int col) {
            return col >= group.begin && col < group.end;
          })));
    }
    s.seconds = timer.ElapsedMs() / 1000.0;
  };
  std::atomic<int> next{0};
  std::atomic<int> done{0};
  std::mutex report;
  auto worker = [&] {
    for (int c = next++; c < classes; c = next++) {
      train_one(c);
      std::lock_guard<std::mutex> lock(report);
      const int finished = ++done;
      if (progress) progress(finished, stats[c]);
    }
  };
  std::vector<std::thread> helpers;
  for (int t = 1; t < std::min(options.threads, classes); ++t) helpers.emplace_back(worker);
  worker();
  for (std::thread& helper : helpers) helper.join();
  for (const Status& failure : failures) {
    if (!failure.ok()) return failure;
  }
  if (summary != nullptr) *summary = stats;
  return classifier;
}

cv::Mat ObjectClassifier::Scores(const cv::Mat& samples) const {
  CHECK_EQ(samples.type(), CV_32F);
  CHECK_EQ(samples.cols, feature_size_);
  cv::Mat scores(samples.rows, classes(), CV_32F);
  for (int c = 0; c < classes(); ++c) {
    const std::vector<int>& columns = columns_[c];
    cv::Mat x(samples.rows, static_cast<int>(columns.size()), CV_32F);
    for (int r = 0; r < samples.rows; ++r) {
      const float* in = samples.ptr<float>(r);
      float* out = x.ptr<float>(r);
      for (size_t j = 0; j < columns.size(); ++j) out[j] = in[columns[j]];
    }
    BoostedSums(*boosts_[c], x).copyTo(scores.col(c));
  }
  return scores;
}

std::vector<int> ObjectClassifier::Decide(const cv::Mat& scores, const std::vector<bool>& allowed) {
  CHECK(allowed.empty() || static_cast<int>(allowed.size()) == scores.cols);
  std::vector<int> decisions(static_cast<size_t>(scores.rows), -1);
  for (int r = 0; r < scores.rows; ++r) {
    const float* row = scores.ptr<float>(r);
    for (int c = 0; c < scores.cols; ++c) {
      if (!allowed.empty() && !allowed[c]) continue;
      if (decisions[r] < 0 || row[c] > row[decisions[r]]) decisions[r] = c;
    }
  }
  return decisions;
}

Status ObjectClassifier::Save(const std::string& directory) const {
  if (boosts_.empty()) return Status::InvalidArgument("no object classifiers to save");
  if (!MakeDirectories(directory)) return Status::IoError("cannot create or write in " + directory);
  try {
    cv::FileStorage fs(IndexFile(directory), cv::FileStorage::WRITE);
    if (!fs.isOpened()) return Status::IoError("cannot write " + IndexFile(directory));
    fs << "format_version" << kFormatVersion;
    fs << "feature_size" << feature_size_;
    fs << "classes" << names_;
    fs << "columns"
       << "[";
    for (const std::vector<int>& columns : columns_) fs << columns;
    fs << "]";
    fs.release();
    for (int c = 0; c < classes(); ++c) boosts_[c]->save(BoostFile(directory, c));
  } catch (const cv::Exception& e) {
    return Status::IoError("cannot write object classifiers to " + directory + ": " + e.what());
  }
  return Status::Ok();
}

StatusOr<ObjectClassifier> ObjectClassifier::Load(const std::string& directory) {
  ObjectClassifier classifier;
  const std::string index = IndexFile(directory);
  try {
    cv::FileStorage fs(index, cv::FileStorage::READ);
    if (!fs.isOpened()) return Status::NotFound("cannot read " + index);
    int version = 0;
    fs["format_version"] >> version;
    if (version != kFormatVersion) {
      return Status::InvalidArgument(index + ": format version " + std::to_string(version) +
                                     ", this build reads " + std::to_string(kFormatVersion));
    }
    fs["feature_size"] >> classifier.feature_size_;
    fs["classes"] >> classifier.names_;
    const cv::FileNode columns = fs["columns"];
    if (classifier.names_.empty() || classifier.feature_size_ < 1 || !columns.isSeq() ||
        static_cast<int>(columns.size()) != classifier.classes()) {
      return Status::InvalidArgument(index + ": classes, feature_size or columns missing");
    }
    for (const cv::FileNode& node : columns) {
      std::vector<int> list;
      node >> list;
      for (const int col : list) {
        if (col < 0 || col >= classifier.feature_size_) {
          return Status::InvalidArgument(index + ": column " + std::to_string(col) +
                                         " outside the description");
        }
      }
      classifier.columns_.push_back(list);
    }
    for (int c = 0; c < classifier.classes(); ++c) {
      const std::string file = BoostFile(directory, c);
      if (!PathExists(file)) return Status::NotFound("cannot read " + file);
      cv::Ptr<cv::ml::Boost> boost = cv::Algorithm::load<cv::ml::Boost>(file);
      if (!boost || !boost->isTrained() ||
          boost->getVarCount() != static_cast<int>(classifier.columns_[c].size())) {
        return Status::InvalidArgument(file + ": not a classifier of " +
                                       std::to_string(classifier.columns_[c].size()) + " features");
      }
      if (!BoostedForest::Intact(*boost)) {
        return Status::InvalidArgument(
            file + ": values that are not finite numbers or splits on variables it does not have " +
            "(a damaged model); restore models/ or retrain");
      }
      classifier.boosts_.push_back(boost);
    }
  } catch (const cv::Exception& e) {
    return Status::InvalidArgument("cannot load object classifiers from " + directory + ": " +
                                   e.what());
  }
  return classifier;
}

}  // namespace placerec
