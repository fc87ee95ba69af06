// Tests of the object classes in recognition (object_classes.h): loading the shipped object
// classifiers, the class a background or structured object gets, and which labels the map
// leaves out.
#include "common/pipeline/object_classes.h"

#include <algorithm>
#include <cmath>
#include <memory>
#include <string>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "common/organization/filter_bank.h"
#include "common/organization/scene_organizer.h"

namespace placerec {
namespace {

std::unique_ptr<ObjectClassLabeler> LoadShipped(const ObjectClassOptions& options) {
  StatusOr<std::unique_ptr<ObjectClassLabeler>> labeler = ObjectClassLabeler::Load(options);
  EXPECT_TRUE(labeler.ok()) << labeler.status().ToString();
  return labeler.ok() ? std::move(*labeler) : nullptr;
}

// A 320x240 frame of random texture, its filter bank, and an object filling `box`.
struct Scene {
  Scene() {
    cv::Mat bgr(240, 320, CV_8UC3);
    cv::randu(bgr, cv::Scalar::all(0), cv::Scalar::all(255));
    cv::Mat lab;
    bgr.convertTo(lab, CV_32F, 1.0 / 255.0);
    cv::cvtColor(lab, lab, cv::COLOR_BGR2Lab);
    filter_bank = ComputeFilterBank(lab);
  }
  SceneObject Object(cv::Rect box, SegmentClass segment_class) const {
    SceneObject object;
    object.segment_class = segment_class;
    object.box = box;
    object.working_box = box;
    object.mask = cv::Mat(box.size(), CV_8U, cv::Scalar(255));
    return object;
  }
  cv::Mat filter_bank;
};

TEST(ObjectClassesTest, OptionsAreChecked) {
  std::string error;
  EXPECT_TRUE(ObjectClassOptions().Check(&error)) << error;
  ObjectClassOptions bad;
  bad.min_movable_confidence = 1.5;
  EXPECT_FALSE(bad.Check(&error));
  bad = ObjectClassOptions();
  bad.movable_classes.push_back("");
  EXPECT_FALSE(bad.Check(&error));
}

TEST(ObjectClassesTest, MissingModelsSayWhatToDo) {
  ObjectClassOptions options;
  options.models_dir = "/nonexistent/placerec/objects/all";
  StatusOr<std::unique_ptr<ObjectClassLabeler>> labeler = ObjectClassLabeler::Load(options);
  ASSERT_FALSE(labeler.ok());
  EXPECT_NE(labeler.status().message().find("placerec-train objects"), std::string::npos)
      << labeler.status().message();
}

// Background segments keep the segmentation's class (seed §3.4); structured ones get one of the
// structured classes (one-per-class over them, seed §6.2.1); confidences are probabilities.
TEST(ObjectClassesTest, BackgroundKeepsItsClassStructuredGetsAnObjectClass) {
  const std::unique_ptr<ObjectClassLabeler> labeler = LoadShipped(ObjectClassOptions());
  ASSERT_NE(labeler, nullptr);
  const Scene scene;
  const ObjectLabel sky =
      labeler->Classify(scene.filter_bank, scene.Object({0, 0, 320, 60}, SegmentClass::kSky));
  EXPECT_EQ(sky.name, "sky");  // however unlike sky random texture is
  EXPECT_GE(sky.confidence, 0.0f);
  EXPECT_LE(sky.confidence, 1.0f);

  const ObjectLabel thing = labeler->Classify(
      scene.filter_bank, scene.Object({100, 80, 60, 90}, SegmentClass::kStructured));
  ASSERT_FALSE(thing.name.empty());
  for (const char* background : {"sky", "tree", "road", "grass", "water"}) {
    EXPECT_NE(thing.name, background);
  }
  EXPECT_GE(thing.confidence, 0.0f);
  EXPECT_LE(thing.confidence, 1.0f);

  // Nothing to describe: no class.
  SceneObject empty = scene.Object({10, 10, 20, 20}, SegmentClass::kStructured);
  empty.mask.setTo(0);
  EXPECT_TRUE(labeler->Classify(scene.filter_bank, empty).name.empty());
  EXPECT_TRUE(labeler->Classify(cv::Mat(), scene.Object({10, 10, 20, 20}, SegmentClass::kSky))
                  .name.empty());
  // A box outside the frame is not read.
  EXPECT_TRUE(
      labeler
          ->Classify(scene.filter_bank, scene.Object({300, 220, 40, 40}, SegmentClass::kStructured))
          .name.empty());
}

// At texton stride 1 and the description's own Poisson grid, the labeler reads exactly the
// description the classifiers were trained on (DescribeObjectInFeatures).
TEST(ObjectClassesTest, FullResolutionLabelIsTheTrainedDescriptionsDecision) {
  ObjectClassOptions options;
  options.texton_stride = 1;
  options.description = ObjectDescriptionOptions();
  const std::unique_ptr<ObjectClassLabeler> labeler = LoadShipped(options);
  ASSERT_NE(labeler, nullptr);
  const Scene scene;
  const SceneObject object = scene.Object({100, 80, 60, 90}, SegmentClass::kStructured);
  cv::Mat mask = cv::Mat::zeros(scene.filter_bank.size(), CV_8U);
  object.mask.copyTo(mask(object.working_box));
  StatusOr<TextonModel> textons = LoadTextons(DefaultModelsDir() + "/objects/textons.yml");
  ASSERT_TRUE(textons.ok());
  StatusOr<ObjectDescription> description = DescribeObjectInFeatures(
      scene.filter_bank, mask, TextonAssigner(*textons), ObjectDescriptionOptions());
  ASSERT_TRUE(description.ok());
  const std::vector<float> values = description->Concatenated();
  const cv::Mat scores = labeler->classifier().Scores(
      cv::Mat(1, static_cast<int>(values.size()), CV_32F, const_cast<float*>(values.data())));
  const ObjectLabel label = labeler->Classify(scene.filter_bank, object);
  const std::vector<std::string>& names = labeler->classifier().names();
  const int c = static_cast<int>(std::find(names.begin(), names.end(), label.name) - names.begin());
  ASSERT_LT(c, static_cast<int>(names.size()));
  EXPECT_FLOAT_EQ(label.confidence, 1.0f / (1.0f + std::exp(-2.0f * scores.at<float>(0, c))));
  for (int other = 0; other < scores.cols; ++other) {
    const std::string& name = names[static_cast<size_t>(other)];
    if (name == "sky" || name == "tree" || name == "road" || name == "grass" || name == "water") {
      continue;
    }
    EXPECT_LE(scores.at<float>(0, other), scores.at<float>(0, c)) << name;
  }
}

// The segmentation's texton map (same textons, same grid) gives the label the labeler's own
// assignment gives; a map of other textons or another grid is not read.
TEST(ObjectClassesTest, TheSegmentationsTextonMapIsReadWhereItFits) {
  const std::unique_ptr<ObjectClassLabeler> labeler = LoadShipped(ObjectClassOptions());
  ASSERT_NE(labeler, nullptr);
  const Scene scene;
  const SceneObject object = scene.Object({60, 40, 120, 100}, SegmentClass::kStructured);
  StatusOr<TextonModel> model = LoadTextons(DefaultModelsDir() + "/objects/textons.yml");
  ASSERT_TRUE(model.ok());
  const TextonAssigner assigner(*model);
  const int stride = ObjectClassOptions().texton_stride;
  const TextonMap map = ComputeTextonMap(scene.filter_bank, assigner, stride);
  const ObjectLabel own = labeler->Classify(scene.filter_bank, object);
  ASSERT_FALSE(own.name.empty());
  const ObjectLabel read = labeler->Classify(scene.filter_bank, object, &map);
  EXPECT_EQ(read.name, own.name);
  EXPECT_EQ(read.confidence, own.confidence);

  // Every id 0: a map the labeler reads changes the description; one it must not read does not.
  TextonMap flat = map;
  flat.ids = cv::Mat::zeros(map.ids.size(), map.ids.type());
  const ObjectLabel from_flat = labeler->Classify(scene.filter_bank, object, &flat);
  EXPECT_NE(from_flat.confidence, own.confidence) << "the fitting map was not read";
  TextonMap other_model = flat;  // shares flat's ids, which stay zero
  other_model.model ^= 1;
  EXPECT_EQ(labeler->Classify(scene.filter_bank, object, &other_model).confidence, own.confidence);
  TextonMap other_grid = ComputeTextonMap(scene.filter_bank, assigner, stride + 1);
  other_grid.ids.setTo(0);
  EXPECT_EQ(labeler->Classify(scene.filter_bank, object, &other_grid).confidence, own.confidence);
  const TextonMap empty;
  EXPECT_EQ(labeler->Classify(scene.filter_bank, object, &empty).confidence, own.confidence);
}

TEST(ObjectClassesTest, OnlySureMovableLabelsAreLeftOutAndOnlyWhenAsked) {
  ObjectClassOptions options;
  const std::unique_ptr<ObjectClassLabeler> keep = LoadShipped(options);
  options.drop_movable = true;
  options.min_movable_confidence = 0.6;
  const std::unique_ptr<ObjectClassLabeler> drop = LoadShipped(options);
  ASSERT_NE(keep, nullptr);
  ASSERT_NE(drop, nullptr);
  EXPECT_FALSE(keep->LeaveOut({"car", 0.9f}));
  EXPECT_TRUE(drop->LeaveOut({"car", 0.9f}));
  EXPECT_TRUE(drop->LeaveOut({"body", 0.6f}));
  EXPECT_FALSE(drop->LeaveOut({"car", 0.5f}));
  EXPECT_FALSE(drop->LeaveOut({"building", 0.99f}));
  EXPECT_FALSE(drop->LeaveOut({"", 0.0f}));
  EXPECT_FALSE(drop->LeaveOut({"not-a-class", 1.0f}));
}

}  // namespace
}  // namespace placerec
