// Tests of the feature selection (seed §4.2) and the per-class classifiers with one-per-class
// decision, on synthetic data whose informative columns are known: the gains of eq. 4.8 on
// features that copy, predict or ignore the label, the selection finding the informative
// column of every group and dropping a redundant copy and most noise, and the classifiers
// telling three classes apart and surviving a save and load.

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <regex>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/ml.hpp>

#include "common/classification/feature_selection.h"
#include "common/classification/object_classifier.h"
#include "common/util/paths.h"

namespace placerec {
namespace {

// Columns: "appearance" 0..19 (mean-gain candidates), "parts_layout" 20..119 (top 10), "shape"
// 120..129 (mean-gain candidates).
std::vector<FeatureGroup> SyntheticGroups() {
  return {{"appearance", 0, 20, 0}, {"parts_layout", 20, 120, 10}, {"shape", 120, 130, 0}};
}

constexpr int kColumns = 130;
constexpr int kAppearanceSignal = 3;
constexpr int kAppearanceCopy = 5;
constexpr int kPartsSignal = 47;
constexpr int kShapeSignal = 125;

// Uniform noise in [0, 1) everywhere; the label is 1 when at least two of the three signal
// columns exceed 0.5 (so each of them matters and none suffices), and column kAppearanceCopy
// repeats kAppearanceSignal. Row i's signal columns are drawn at random like the rest.
void MakeBinaryData(int n, uint64_t seed, cv::Mat* samples, std::vector<int>* labels) {
  std::mt19937_64 random(seed);
  std::uniform_real_distribution<float> uniform(0.0f, 1.0f);
  *samples = cv::Mat(n, kColumns, CV_32F);
  labels->assign(static_cast<size_t>(n), 0);
  for (int i = 0; i < n; ++i) {
    float* row = samples->ptr<float>(i);
    for (int c = 0; c < kColumns; ++c) row[c] = uniform(random);
    row[kAppearanceCopy] = row[kAppearanceSignal];
    const int votes =
        (row[kAppearanceSignal] > 0.5f) + (row[kPartsSignal] > 0.5f) + (row[kShapeSignal] > 0.5f);
    (*labels)[i] = votes >= 2 ? 1 : 0;
  }
}

std::vector<uint8_t> Codes(const std::vector<int>& values) {
  return std::vector<uint8_t>(values.begin(), values.end());
}

TEST(FeatureSelectionTest, DefaultOptionsPassCheck) {
  std::string error;
  EXPECT_TRUE(FeatureSelectionOptions().Check(&error)) << error;
  EXPECT_TRUE(ObjectClassifierOptions().Check(&error)) << error;
  FeatureSelectionOptions bad;
  bad.bins = 1;
  EXPECT_FALSE(bad.Check(&error));
  EXPECT_NE(error.find("bins"), std::string::npos);
  ObjectClassifierOptions bad_classifier;
  bad_classifier.selection.folds = 1;
  EXPECT_FALSE(bad_classifier.Check(&error));
}

TEST(FeatureSelectionTest, DescriptionGroupsCoverTheSeedsDescription) {
  const std::vector<FeatureGroup> groups = DescriptionGroups(150);
  ASSERT_EQ(groups.size(), 3u);
  EXPECT_EQ(groups[0].size(), 151);
  EXPECT_EQ(groups[1].size(), 3000);
  EXPECT_EQ(groups[1].top, 50);
  EXPECT_EQ(groups[2].size(), 30);
  EXPECT_EQ(groups[2].end, 3181);
}

TEST(FeatureSelectionTest, EntropyAndInformationGain) {
  const std::vector<uint8_t> t = Codes({0, 0, 1, 1, 0, 0, 1, 1});
  EXPECT_DOUBLE_EQ(Entropy(t), 1.0);
  // A copy of the label: G = I / H(X) = 1.
  EXPECT_DOUBLE_EQ(InformationGain(t, t), 1.0);
  // Independent of the label (each value half 0, half 1 labels): 0.
  EXPECT_DOUBLE_EQ(InformationGain(Codes({0, 1, 0, 1, 0, 1, 0, 1}), t), 0.0);
  // A constant: H(X) = 0, G = 0.
  EXPECT_DOUBLE_EQ(InformationGain(Codes({2, 2, 2, 2, 2, 2, 2, 2}), t), 0.0);
  // Four values that determine the label: I = 1 bit, H(X) = 2 bits, G = 0.5 (eq. 4.8 divides by
  // H(X), so a finer feature that tells as much gains less).
  EXPECT_DOUBLE_EQ(
      InformationGain(Codes({0, 1, 2, 3, 0, 1, 2, 3}), Codes({0, 0, 1, 1, 0, 0, 1, 1})), 0.5);
}

TEST(FeatureSelectionTest, DiscretisationGivesZeroItsOwnCode) {
  cv::Mat column(1, 10, CV_32F, cv::Scalar(0.0f));
  column.at<float>(7) = 0.25f;
  column.at<float>(8) = 0.5f;
  column.at<float>(9) = 0.75f;
  const std::vector<uint8_t> codes = DiscretiseFeature(column, 5);
  for (int i = 0; i < 7; ++i) EXPECT_EQ(codes[i], 0) << i;
  EXPECT_GT(codes[7], 0);
  EXPECT_LT(codes[7], codes[9]);
  EXPECT_LE(*std::max_element(codes.begin(), codes.end()), 4);
  // Ten distinct values in ten bins: ten codes 0..9 in order.
  cv::Mat ramp(1, 10, CV_32F);
  for (int i = 0; i < 10; ++i) ramp.at<float>(i) = static_cast<float>(9 - i);
  const std::vector<uint8_t> ramp_codes = DiscretiseFeature(ramp, 10);
  for (int i = 0; i < 10; ++i) EXPECT_EQ(ramp_codes[i], 9 - i);
}

TEST(FeatureSelectionTest, FindsTheInformativeFeatureOfEveryGroup) {
  cv::Mat samples;
  std::vector<int> labels;
  MakeBinaryData(400, 7, &samples, &labels);
  FeatureSelectionOptions options;
  FeatureSelectionSummary summary;
  StatusOr<std::vector<int>> selected =
      SelectFeatures(samples, labels, SyntheticGroups(), options, &summary);
  ASSERT_TRUE(selected.ok()) << selected.status().ToString();
  const std::vector<int>& s = *selected;
  auto has = [&](int c) { return std::find(s.begin(), s.end(), c) != s.end(); };
  // Stage 1 ranks the signal columns first within their groups.
  ASSERT_GE(summary.candidates.size(), 3u);
  EXPECT_TRUE(std::find(summary.candidates.begin(), summary.candidates.end(), kPartsSignal) !=
              summary.candidates.end());
  // The three informative columns survive (the appearance signal either as itself or its
  // copy, but not both), ...
  EXPECT_TRUE(has(kPartsSignal));
  EXPECT_TRUE(has(kShapeSignal));
  EXPECT_NE(has(kAppearanceSignal), has(kAppearanceCopy));
  // ... and the wrapper removes most of the noise the candidates held.
  EXPECT_LT(s.size(), summary.candidates.size() / 2);
  EXPECT_LE(s.size(), 10u);
  ASSERT_EQ(summary.per_group.size(), 3u);
  EXPECT_GE(summary.per_group[0], 1);
  EXPECT_GE(summary.per_group[1], 1);
  EXPECT_GE(summary.per_group[2], 1);
  // The selected subset classifies at least as well under cross-validation as the candidates,
  // and far better than chance.
  EXPECT_LE(summary.selected_error, summary.candidates_error);
  EXPECT_LT(summary.selected_error, 0.15);
  EXPECT_LT(CrossValidatedError(samples, labels, {kAppearanceSignal, kPartsSignal, kShapeSignal},
                                options),
            0.15);
  EXPECT_GT(CrossValidatedError(samples, labels, {0, 1, 2}, options), 0.35);
}

TEST(FeatureSelectionTest, GroupsRestrictTheSelection) {
  cv::Mat samples;
  std::vector<int> labels;
  MakeBinaryData(300, 11, &samples, &labels);
  // Appearance only (the first row of seed Table 6.5): nothing outside columns 0..19.
  StatusOr<std::vector<int>> selected =
      SelectFeatures(samples, labels, {SyntheticGroups()[0]}, FeatureSelectionOptions());
  ASSERT_TRUE(selected.ok()) << selected.status().ToString();
  ASSERT_FALSE(selected->empty());
  EXPECT_LT(selected->back(), 20);
}

TEST(FeatureSelectionTest, BadInputIsAnError) {
  cv::Mat samples;
  std::vector<int> labels;
  MakeBinaryData(50, 3, &samples, &labels);
  const FeatureSelectionOptions options;
  std::vector<int> short_labels(labels.begin(), labels.end() - 1);
  EXPECT_FALSE(SelectFeatures(samples, short_labels, SyntheticGroups(), options).ok());
  EXPECT_FALSE(SelectFeatures(samples, labels, {{"x", 100, 140, 0}}, options).ok());
  EXPECT_FALSE(SelectFeatures(samples, labels, {{"a", 0, 20, 0}, {"b", 10, 30, 0}}, options).ok());
  std::vector<int> one_positive(labels.size(), 0);
  one_positive[0] = 1;
  const Status status = SelectFeatures(samples, one_positive, SyntheticGroups(), options).status();
  EXPECT_FALSE(status.ok());
  EXPECT_NE(status.message().find("positives"), std::string::npos);
}

// Three classes, each told by its own column (> 0.7) in its own group; the rest noise.
void MakeClassData(int n, uint64_t seed, cv::Mat* samples, std::vector<int>* labels) {
  const int signal[3] = {2, 60, 127};
  std::mt19937_64 random(seed);
  std::uniform_real_distribution<float> uniform(0.0f, 1.0f);
  *samples = cv::Mat(n, kColumns, CV_32F);
  labels->assign(static_cast<size_t>(n), 0);
  for (int i = 0; i < n; ++i) {
    float* row = samples->ptr<float>(i);
    for (int c = 0; c < kColumns; ++c) row[c] = 0.7f * uniform(random);
    const int label = i % 3;
    row[signal[label]] = 0.7f + 0.3f * uniform(random);
    (*labels)[i] = label;
  }
}

TEST(ObjectClassifierTest, OnePerClassTellsClassesApartAndRoundTrips) {
  cv::Mat train;
  cv::Mat test;
  std::vector<int> train_labels;
  std::vector<int> test_labels;
  MakeClassData(240, 1, &train, &train_labels);
  MakeClassData(120, 2, &test, &test_labels);
  ObjectClassifierOptions options;
  options.weak_count = 40;
  std::vector<ObjectClassSummary> summary;
  int reported = 0;
  StatusOr<ObjectClassifier> classifier = ObjectClassifier::Train(
      train, train_labels, {"a", "b", "c"}, SyntheticGroups(), options, &summary,
      [&](int done, const ObjectClassSummary&) { reported = std::max(reported, done); });
  ASSERT_TRUE(classifier.ok()) << classifier.status().ToString();
  EXPECT_EQ(reported, 3);
  ASSERT_EQ(summary.size(), 3u);
  // Each class's selection keeps its own signal column.
  const int signal[3] = {2, 60, 127};
  for (int c = 0; c < 3; ++c) {
    const std::vector<int>& columns = classifier->columns(c);
    EXPECT_TRUE(std::find(columns.begin(), columns.end(), signal[c]) != columns.end()) << c;
    EXPECT_LT(columns.size(), 20u) << c;
    EXPECT_EQ(summary[c].positives, 80);
  }
  const cv::Mat scores = classifier->Scores(test);
  const std::vector<int> decided = ObjectClassifier::Decide(scores);
  int correct = 0;
  for (size_t i = 0; i < decided.size(); ++i) correct += decided[i] == test_labels[i];
  EXPECT_GE(correct, 114);  // 95 %
  // Restricted to classes a and b, no row is given c.
  const std::vector<int> restricted = ObjectClassifier::Decide(scores, {true, true, false});
  EXPECT_EQ(std::count(restricted.begin(), restricted.end(), 2), 0);

  const std::string dir = ::testing::TempDir() + "/placerec_object_classifier_test";
  ASSERT_TRUE(classifier->Save(dir).ok());
  StatusOr<ObjectClassifier> loaded = ObjectClassifier::Load(dir);
  ASSERT_TRUE(loaded.ok()) << loaded.status().ToString();
  EXPECT_EQ(loaded->names(), classifier->names());
  for (int c = 0; c < 3; ++c) EXPECT_EQ(loaded->columns(c), classifier->columns(c));
  EXPECT_EQ(cv::norm(loaded->Scores(test), scores, cv::NORM_INF), 0.0);
  EXPECT_FALSE(ObjectClassifier::Load(dir + "/missing").ok());

  // A damaged model file whose leaf values are NaN loaded, and NaN then took every class
  // decision (class 0 won: no score compares greater than NaN). It is refused now.
  {
    const std::string file = dir + "/objects_1.yml.gz";
    const std::string text = dir + "/damaged.yml";
    cv::Algorithm::load<cv::ml::Boost>(file)->save(text);
    std::ifstream in(text);
    const std::string yaml((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const std::string nan =
        std::regex_replace(yaml, std::regex("value:[ ]*[-+0-9.eE]+"), "value: .nan");
    ASSERT_NE(nan, yaml);
    std::ofstream(text, std::ios::trunc) << nan;
    cv::Algorithm::load<cv::ml::Boost>(text)->save(file);
  }
  const StatusOr<ObjectClassifier> damaged = ObjectClassifier::Load(dir);
  EXPECT_FALSE(damaged.ok());
  EXPECT_NE(damaged.status().message().find("not finite"), std::string::npos)
      << damaged.status().message();

  // A split on the variable just past the last: OpenCV's reader lets it through, and the
  // classifier then read past each sample (a segmentation fault in `placerec-eval classify`).
  ASSERT_TRUE(classifier->Save(dir).ok());
  {
    const std::string file = dir + "/objects_1.yml.gz";
    const std::string text = dir + "/damaged.yml";
    cv::Algorithm::load<cv::ml::Boost>(file)->save(text);
    std::ifstream in(text);
    const std::string yaml((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const std::string past = std::regex_replace(
        yaml, std::regex("var:[ ]*[0-9]+"), "var: " + std::to_string(classifier->columns(1).size()),
        std::regex_constants::format_first_only);
    ASSERT_NE(past, yaml);
    std::ofstream(text, std::ios::trunc) << past;
    const cv::Ptr<cv::ml::Boost> reread = cv::Algorithm::load<cv::ml::Boost>(text);
    ASSERT_FALSE(reread.empty());
    reread->save(file);
  }
  const StatusOr<ObjectClassifier> past_last = ObjectClassifier::Load(dir);
  EXPECT_FALSE(past_last.ok());
  EXPECT_NE(past_last.status().message().find("splits on variables"), std::string::npos)
      << past_last.status().message();
  std::filesystem::remove_all(dir);
}

TEST(ObjectClassifierTest, BadInputIsAnError) {
  cv::Mat train;
  std::vector<int> labels;
  MakeClassData(30, 1, &train, &labels);
  const ObjectClassifierOptions options;
  // A label outside the names.
  EXPECT_FALSE(ObjectClassifier::Train(train, labels, {"a", "b"}, SyntheticGroups(), options).ok());
  // A class with too few objects names itself.
  std::vector<int> few = labels;
  for (int& l : few) l = l == 2 ? 0 : l;
  few[0] = 2;
  const Status status =
      ObjectClassifier::Train(train, few, {"a", "b", "c"}, SyntheticGroups(), options).status();
  EXPECT_FALSE(status.ok());
  EXPECT_NE(status.message().find("class c"), std::string::npos);
}

}  // namespace
}  // namespace placerec
