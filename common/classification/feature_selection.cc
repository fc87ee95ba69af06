#include "common/classification/feature_selection.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>
#include <set>

#include <glog/logging.h>

#include "common/classification/object_description.h"
#include "common/organization/background.h"

namespace placerec {

namespace {

constexpr int kMaxBins = 16;

// The columns `columns` of `samples`' rows `rows` as a new matrix.
cv::Mat Gather(const cv::Mat& samples, const std::vector<int>& rows,
               const std::vector<int>& columns) {
  cv::Mat out(static_cast<int>(rows.size()), static_cast<int>(columns.size()), CV_32F);
  for (size_t i = 0; i < rows.size(); ++i) {
    const float* in = samples.ptr<float>(rows[i]);
    float* o = out.ptr<float>(static_cast<int>(i));
    for (size_t j = 0; j < columns.size(); ++j) o[j] = in[columns[j]];
  }
  return out;
}

// Initial boosting weights of `rows` under which both labels weigh alike in total.
cv::Mat BalancedWeights(const std::vector<int>& labels, const std::vector<int>& rows) {
  int positives = 0;
  for (const int r : rows) positives += labels[r] == 1;
  const int negatives = static_cast<int>(rows.size()) - positives;
  cv::Mat weights(static_cast<int>(rows.size()), 1, CV_32F);
  for (size_t i = 0; i < rows.size(); ++i) {
    weights.at<float>(static_cast<int>(i)) =
        labels[rows[i]] == 1 ? 0.5f / std::max(positives, 1) : 0.5f / std::max(negatives, 1);
  }
  return weights;
}

cv::Mat Responses(const std::vector<int>& labels, const std::vector<int>& rows) {
  cv::Mat responses(static_cast<int>(rows.size()), 1, CV_32S);
  for (size_t i = 0; i < rows.size(); ++i) responses.at<int>(static_cast<int>(i)) = labels[rows[i]];
  return responses;
}

// A cross-validated error with the folds fixed once for a class (so that two feature subsets
// are compared on the same splits) and a count of the fits.
class Wrapper {
 public:
  Wrapper(const cv::Mat& samples, const std::vector<int>& labels,
          const FeatureSelectionOptions& options)
      : samples_(samples), labels_(labels), options_(options) {
    std::vector<int> positives;
    std::vector<int> negatives;
    for (int i = 0; i < static_cast<int>(labels.size()); ++i) {
      (labels[i] == 1 ? positives : negatives).push_back(i);
    }
    std::mt19937_64 random(options.seed);
    std::shuffle(positives.begin(), positives.end(), random);
    std::shuffle(negatives.begin(), negatives.end(), random);
    fold_.assign(labels.size(), 0);
    for (size_t i = 0; i < positives.size(); ++i)
      fold_[positives[i]] = static_cast<int>(i) % options.folds;
    for (size_t i = 0; i < negatives.size(); ++i)
      fold_[negatives[i]] = static_cast<int>(i) % options.folds;
  }

  double Error(const std::vector<int>& columns) {
    int wrong_positive = 0;
    int wrong_negative = 0;
    int positives = 0;
    int negatives = 0;
    for (int f = 0; f < options_.folds; ++f) {
      std::vector<int> train;
      std::vector<int> test;
      for (int i = 0; i < static_cast<int>(labels_.size()); ++i) {
        (fold_[i] == f ? test : train).push_back(i);
      }
      const cv::Ptr<cv::ml::Boost> boost =
          TrainGentleBoost(Gather(samples_, train, columns), Responses(labels_, train),
                           BalancedWeights(labels_, train), options_.wrapper_weak_count,
                           options_.wrapper_max_depth, 0.95);
      ++fits_;
      const cv::Mat sums = BoostedSums(*boost, Gather(samples_, test, columns));
      for (size_t i = 0; i < test.size(); ++i) {
        const bool positive = labels_[test[i]] == 1;
        const bool said = sums.at<float>(static_cast<int>(i)) > 0.0f;
        if (positive) {
          ++positives;
          wrong_positive += !said;
        } else {
          ++negatives;
          wrong_negative += said;
        }
      }
    }
    return 0.5 * (static_cast<double>(wrong_positive) / std::max(positives, 1) +
                  static_cast<double>(wrong_negative) / std::max(negatives, 1));
  }

  int fits() const { return fits_; }

 private:
  const cv::Mat& samples_;
  const std::vector<int>& labels_;
  const FeatureSelectionOptions& options_;
  std::vector<int> fold_;
  int fits_ = 0;
};

}  // namespace

std::vector<FeatureGroup> DescriptionGroups(int k, int parts_layout_candidates) {
  const int a = AppearanceSize(k);
  const int p = PartsLayoutSize(k);
  return {{"appearance", 0, a, 0},
          {"parts_layout", a, a + p, parts_layout_candidates},
          {"shape", a + p, a + p + kShapeFeatureSize, 0}};
}

std::vector<uint8_t> DiscretiseFeature(const cv::Mat& column, int bins) {
  CHECK(bins >= 1 && bins <= 256) << "bins " << bins;
  const int n = static_cast<int>(column.total());
  if (n == 0) return {};
  std::vector<float> values(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) values[i] = column.at<float>(i);
  std::vector<float> sorted = values;
  std::sort(sorted.begin(), sorted.end());
  // Bin b ends at the value of rank b n / bins; a value's code is the number of bin ends
  // strictly below it, so equal values share a code and the smallest value always has code 0.
  std::vector<float> cuts;
  for (int b = 1; b < bins; ++b) {
    const int64_t rank = std::max<int64_t>(0, static_cast<int64_t>(b) * n / bins - 1);
    const float cut = sorted[static_cast<size_t>(rank)];
    if (cuts.empty() || cut > cuts.back()) cuts.push_back(cut);
  }
  std::vector<uint8_t> codes(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) {
    codes[i] =
        static_cast<uint8_t>(std::lower_bound(cuts.begin(), cuts.end(), values[i]) - cuts.begin());
  }
  return codes;
}

double Entropy(const std::vector<uint8_t>& codes) {
  if (codes.empty()) return 0.0;
  std::vector<int> counts(256, 0);
  for (const uint8_t c : codes) ++counts[c];
  double h = 0.0;
  const double n = static_cast<double>(codes.size());
  for (const int count : counts) {
    if (count > 0) h -= count / n * std::log2(count / n);
  }
  return h;
}

double MutualInformation(const std::vector<uint8_t>& x, const std::vector<uint8_t>& y) {
  CHECK_EQ(x.size(), y.size());
  if (x.empty()) return 0.0;
  const int nx = *std::max_element(x.begin(), x.end()) + 1;
  const int ny = *std::max_element(y.begin(), y.end()) + 1;
  std::vector<int> joint(static_cast<size_t>(nx * ny), 0);
  std::vector<int> px(static_cast<size_t>(nx), 0);
  std::vector<int> py(static_cast<size_t>(ny), 0);
  for (size_t i = 0; i < x.size(); ++i) {
    ++joint[x[i] * ny + y[i]];
    ++px[x[i]];
    ++py[y[i]];
  }
  const double n = static_cast<double>(x.size());
  double mi = 0.0;
  for (int a = 0; a < nx; ++a) {
    for (int b = 0; b < ny; ++b) {
      const int c = joint[a * ny + b];
      if (c > 0) mi += c / n * std::log2(c * n / (static_cast<double>(px[a]) * py[b]));
    }
  }
  return std::max(mi, 0.0);
}

double InformationGain(const std::vector<uint8_t>& x, const std::vector<uint8_t>& t) {
  const double h = Entropy(x);
  if (h <= 1e-12) return 0.0;
  return MutualInformation(x, t) / h;
}

bool FeatureSelectionOptions::Check(std::string* error) const {
  if (bins < 2 || bins > kMaxBins) {
    *error = "feature selection bins must be in [2, " + std::to_string(kMaxBins) + "], got " +
             std::to_string(bins);
    return false;
  }
  if (parts_layout_candidates < 1) {
    *error = "parts_layout_candidates must be at least 1";
    return false;
  }
  if (wrapper_weak_count < 1 || wrapper_max_depth < 1 || wrapper_max_depth > 10) {
    *error = "wrapper_weak_count must be >= 1 and wrapper_max_depth in [1, 10]";
    return false;
  }
  if (folds < 2) {
    *error = "feature selection folds must be at least 2, got " + std::to_string(folds);
    return false;
  }
  if (!(redundancy >= 0.0 && redundancy <= 1.0)) {
    *error = "feature selection redundancy must be in [0, 1]";
    return false;
  }
  if (!(max_negatives_per_positive >= 0.0) || !std::isfinite(max_negatives_per_positive)) {
    *error = "max_negatives_per_positive must be a finite value >= 0";
    return false;
  }
  return true;
}

double CrossValidatedError(const cv::Mat& samples, const std::vector<int>& labels,
                           const std::vector<int>& columns,
                           const FeatureSelectionOptions& options) {
  Wrapper wrapper(samples, labels, options);
  return wrapper.Error(columns);
}

StatusOr<std::vector<int>> SelectFeatures(const cv::Mat& all_samples,
                                          const std::vector<int>& all_labels,
                                          const std::vector<FeatureGroup>& groups,
                                          const FeatureSelectionOptions& options,
                                          FeatureSelectionSummary* summary) {
  std::string error;
  if (!options.Check(&error)) return Status::InvalidArgument(error);
  if (all_samples.type() != CV_32F || all_samples.rows != static_cast<int>(all_labels.size())) {
    return Status::InvalidArgument("feature selection needs CV_32F samples, one label per row");
  }
  std::vector<bool> in_group(static_cast<size_t>(all_samples.cols), false);
  for (const FeatureGroup& group : groups) {
    if (group.begin < 0 || group.end > all_samples.cols || group.begin >= group.end) {
      return Status::InvalidArgument("feature group " + group.name + " is outside the " +
                                     std::to_string(all_samples.cols) + " columns");
    }
    for (int c = group.begin; c < group.end; ++c) {
      if (in_group[c]) return Status::InvalidArgument("feature groups overlap at " + group.name);
      in_group[c] = true;
    }
  }
  if (groups.empty()) return Status::InvalidArgument("no feature groups to select from");
  std::vector<int> positives;
  std::vector<int> negatives;
  for (int i = 0; i < static_cast<int>(all_labels.size()); ++i) {
    if (all_labels[i] != 0 && all_labels[i] != 1) {
      return Status::InvalidArgument("feature selection labels must be 0 or 1");
    }
    (all_labels[i] == 1 ? positives : negatives).push_back(i);
  }
  if (static_cast<int>(positives.size()) < options.folds ||
      static_cast<int>(negatives.size()) < options.folds) {
    return Status::InvalidArgument(
        "feature selection needs at least " + std::to_string(options.folds) +
        " positives and negatives, got " + std::to_string(positives.size()) + " and " +
        std::to_string(negatives.size()));
  }
  // The wrapper's rows: every positive, at most max_negatives_per_positive negatives each.
  std::mt19937_64 random(options.seed);
  if (options.max_negatives_per_positive > 0.0) {
    const size_t keep = std::max<size_t>(
        static_cast<size_t>(options.folds),
        static_cast<size_t>(std::ceil(options.max_negatives_per_positive * positives.size())));
    if (negatives.size() > keep) {
      std::shuffle(negatives.begin(), negatives.end(), random);
      negatives.resize(keep);
    }
  }
  std::vector<int> rows = positives;
  rows.insert(rows.end(), negatives.begin(), negatives.end());
  std::sort(rows.begin(), rows.end());
  std::vector<int> every_column(static_cast<size_t>(all_samples.cols));
  std::iota(every_column.begin(), every_column.end(), 0);
  const cv::Mat samples = Gather(all_samples, rows, every_column);
  std::vector<int> labels(rows.size());
  std::vector<uint8_t> target(rows.size());
  for (size_t i = 0; i < rows.size(); ++i) {
    labels[i] = all_labels[rows[i]];
    target[i] = static_cast<uint8_t>(labels[i]);
  }

  // Codes and gains of every grouped column.
  std::vector<std::vector<uint8_t>> codes(static_cast<size_t>(samples.cols));
  std::vector<double> gain(static_cast<size_t>(samples.cols), 0.0);
  for (int c = 0; c < samples.cols; ++c) {
    if (!in_group[c]) continue;
    codes[c] = DiscretiseFeature(samples.col(c).clone(), options.bins);
    gain[c] = InformationGain(codes[c], target);
  }

  // Stage 1: PC_1.
  FeatureSelectionSummary stats;
  std::vector<int> candidates;
  for (const FeatureGroup& group : groups) {
    std::vector<int> members(static_cast<size_t>(group.size()));
    std::iota(members.begin(), members.end(), group.begin);
    std::stable_sort(members.begin(), members.end(),
                     [&](int a, int b) { return gain[a] > gain[b]; });
    if (group.top > 0) {
      members.resize(std::min<size_t>(members.size(), static_cast<size_t>(group.top)));
    } else {
      double mean = 0.0;
      for (int c = group.begin; c < group.end; ++c) mean += gain[c];
      mean /= group.size();
      members.erase(
          std::remove_if(members.begin(), members.end(), [&](int c) { return !(gain[c] > mean); }),
          members.end());
    }
    // A group whose gains are all equal (e.g. all zero) still offers its best feature.
    if (members.empty()) members.push_back(group.begin);
    candidates.insert(candidates.end(), members.begin(), members.end());
  }
  std::stable_sort(candidates.begin(), candidates.end(),
                   [&](int a, int b) { return gain[a] > gain[b]; });
  stats.candidates = candidates;

  // Stage 2: the wrapper. Redundant candidates first (largest I(X, Z) / H(X) with another
  // candidate at least options.redundancy), each part by increasing gain.
  std::vector<double> redundancy(static_cast<size_t>(samples.cols), 0.0);
  for (const int x : candidates) {
    const double hx = Entropy(codes[x]);
    if (hx <= 1e-12) {
      redundancy[x] = 1.0;  // a constant candidate carries nothing: try it first
      continue;
    }
    for (const int z : candidates) {
      if (z != x)
        redundancy[x] = std::max(redundancy[x], MutualInformation(codes[x], codes[z]) / hx);
    }
  }
  std::vector<int> order = candidates;
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) {
    const bool ra = redundancy[a] >= options.redundancy;
    const bool rb = redundancy[b] >= options.redundancy;
    if (ra != rb) return ra;
    return gain[a] < gain[b];
  });
  Wrapper wrapper(samples, labels, options);
  std::set<int> current(candidates.begin(), candidates.end());
  double best = wrapper.Error(std::vector<int>(current.begin(), current.end()));
  stats.candidates_error = best;
  for (const int feature : order) {
    if (current.size() <= 1) break;
    current.erase(feature);
    const double trial = wrapper.Error(std::vector<int>(current.begin(), current.end()));
    if (trial <= best + 1e-12) {
      best = trial;
    } else {
      current.insert(feature);
    }
  }
  stats.after_wrapper.assign(current.begin(), current.end());

  // Stage 3: children's parents.
  if (options.add_spouses) {
    const std::set<int> pc1(candidates.begin(), candidates.end());
    for (const int x : stats.after_wrapper) {
      int spouse = -1;
      double spouse_gain = 0.0;
      for (int y = 0; y < samples.cols; ++y) {
        if (!in_group[y] || pc1.count(y) || current.count(y)) continue;
        const double g = InformationGain(codes[y], codes[x]);
        if (g > spouse_gain) {
          spouse_gain = g;
          spouse = y;
        }
      }
      if (spouse < 0) continue;
      current.insert(spouse);
      const double trial = wrapper.Error(std::vector<int>(current.begin(), current.end()));
      if (trial < best - 1e-12) {
        best = trial;
      } else {
        current.erase(spouse);
      }
    }
  }
  stats.selected.assign(current.begin(), current.end());
  stats.selected_error = best;
  stats.fits = wrapper.fits();
  for (const FeatureGroup& group : groups) {
    stats.per_group.push_back(
        static_cast<int>(std::count_if(stats.selected.begin(), stats.selected.end(),
                                       [&](int c) { return c >= group.begin && c < group.end; })));
  }
  if (summary != nullptr) *summary = stats;
  return stats.selected;
}

}  // namespace placerec
