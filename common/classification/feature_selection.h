// Object classification, second half (seed Ch. 4, §4.2): the feature selection that picks, for
// one object class, a compact subset of the object description (object_description.h) on which
// its binary Gentle AdaBoost classifier is trained.
//
//   1. candidates (PC_1): within each feature group the features of high information gain
//      G(X, T) = I(X, T) / H(X) with the binary class label T (eq. 4.8): in the appearance and
//      shape groups those above the group's mean gain, in the parts layout the 50 highest;
//   2. wrapper (PC_2): features are removed one at a time, the likely false positives first,
//      and a removal is kept when the cross-validated error of Gentle AdaBoost on the remaining
//      features stays the same or falls;
//   3. children's parents: for each member X of PC_2 the feature Y outside PC_1 of highest
//      G(Y, X) is tried and kept when the cross-validated error falls.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "common/util/status.h"

namespace placerec {

// A contiguous range [begin, end) of description columns that form one group of seed §4.1.
struct FeatureGroup {
  std::string name;  // "appearance", "parts_layout", "shape"
  int begin = 0;
  int end = 0;
  // How stage 1 picks the group's candidates: the `top` features of highest gain when > 0, else
  // those whose gain is above the group's mean (seed §4.2).
  int top = 0;

  int size() const { return end - begin; }
};

// The three groups of the seed's description for a dictionary of k textons (appearance k + 1,
// parts layout 20 k with top = parts_layout_candidates, shape 30), in the column order of
// ObjectDescription::Concatenated.
std::vector<FeatureGroup> DescriptionGroups(int k, int parts_layout_candidates = 50);

// Values of one feature (a column, CV_32F) cut into at most `bins` codes 0..bins-1 at its
// quantiles (equal-frequency bins, each bin (end of the previous, own end]; equal values share a
// code and the smallest value has code 0, so a feature that is mostly zero, like a texton bin,
// keeps zero apart from the rest). The seed leaves the discretisation of eq. 4.8 open.
std::vector<uint8_t> DiscretiseFeature(const cv::Mat& column, int bins);

// Entropy in bits of a code sequence (codes < 256).
double Entropy(const std::vector<uint8_t>& codes);
// Mutual information I(X, Y) in bits of two code sequences of equal length.
double MutualInformation(const std::vector<uint8_t>& x, const std::vector<uint8_t>& y);
// Seed eq. 4.8: G(X, T) = I(X, T) / H(X); 0 when H(X) = 0 (a constant feature).
double InformationGain(const std::vector<uint8_t>& x, const std::vector<uint8_t>& t);

struct FeatureSelectionOptions {
  int bins = 10;  // quantile bins of each feature for the entropies of eq. 4.8 (seed: open)
  // Parts-layout candidates of stage 1 (seed §4.2: the 50 of highest gain). Read by
  // DescriptionGroups; groups passed to SelectFeatures carry their own `top`.
  int parts_layout_candidates = 50;
  // The wrapper's classifier (seed: AdaBoost [Friedman00]): Gentle AdaBoost, this many trees of
  // this depth, judged by `folds`-fold cross-validation. Small so that the hundreds of fits per
  // class stay short; the final classifier (object_classifier.h) has its own.
  int wrapper_weak_count = 30;
  int wrapper_max_depth = 2;
  int folds = 3;
  // Stage 2 first tries the candidates whose largest normalised mutual information with another
  // candidate, I(X, Z) / H(X), is at least this ("small gain and large mutual information with
  // other members", seed §4.2), by increasing gain; then the others by increasing gain.
  double redundancy = 0.5;
  // Stage 3 (children's parents) on or off.
  bool add_spouses = true;
  // The wrapper sees every positive and at most this many negatives per positive (drawn at
  // random with `seed`); 0: all. Positives and negatives weigh alike in total either way.
  double max_negatives_per_positive = 4.0;
  uint64_t seed = 2009;

  bool Check(std::string* error) const;
};

struct FeatureSelectionSummary {
  std::vector<int> candidates;     // PC_1, columns by decreasing gain
  std::vector<int> after_wrapper;  // PC_2, increasing column order
  std::vector<int> selected;       // the result, increasing column order
  std::vector<int> per_group;      // selected columns per group (groups' order)
  double candidates_error = 0.0;   // cross-validated balanced error on PC_1
  double selected_error = 0.0;     // ... on the result
  int fits = 0;                    // boosted classifiers trained
};

// Balanced error (the mean of the error on positives and the error on negatives) of Gentle
// AdaBoost on `columns` of `samples` under `folds`-fold cross-validation with stratified,
// seeded folds. `samples` n x d CV_32F, `labels` n values 0/1 with at least `folds` of each.
double CrossValidatedError(const cv::Mat& samples, const std::vector<int>& labels,
                           const std::vector<int>& columns, const FeatureSelectionOptions& options);

// Seed §4.2 for one binary target: `samples` n x d CV_32F (rows: objects, columns: the
// description), `labels` n values 1 (the class) or 0, `groups` the column ranges of the feature
// groups to select from (columns outside every group are never selected, so a subset of the
// groups restricts the selection, as the ablation of seed Table 6.5 does). InvalidArgument for
// sizes that disagree, groups outside the columns or overlapping, or fewer than `folds`
// positives or negatives.
StatusOr<std::vector<int>> SelectFeatures(const cv::Mat& samples, const std::vector<int>& labels,
                                          const std::vector<FeatureGroup>& groups,
                                          const FeatureSelectionOptions& options,
                                          FeatureSelectionSummary* summary = nullptr);

}  // namespace placerec
