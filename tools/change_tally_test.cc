#include "tools/change_tally.h"

#include <gtest/gtest.h>

namespace placerec {
namespace {

TEST(ClassAgreesTest, NamesTheModelsClassesOfThePastedObjects) {
  EXPECT_TRUE(ClassAgrees("car", "car"));
  EXPECT_TRUE(ClassAgrees("pedestrian", "body"));
  EXPECT_TRUE(ClassAgrees("bicyclist", "bicycle"));
  EXPECT_TRUE(ClassAgrees("bicyclist", "body"));
  EXPECT_TRUE(ClassAgrees("signsymbol", "sign"));
  EXPECT_FALSE(ClassAgrees("pedestrian", "pedestrian"));  // no model class of that name
  EXPECT_FALSE(ClassAgrees("car", "building"));
  EXPECT_FALSE(ClassAgrees("car", ""));
  EXPECT_FALSE(ClassAgrees("", ""));
}

// Counts are of the found objects with a class of at least each confidence.
TEST(ClassTallyTest, CountsLabelledAndAgreeingByConfidence) {
  ClassTally tally;
  tally.Add("car", "car", 0.95f);
  tally.Add("pedestrian", "bird", 0.55f);
  tally.Add("signsymbol", "", 0.f);
  tally.Add("pedestrian", "body", 0.75f);
  const nlohmann::json j = ClassTallyJson(tally);
  EXPECT_EQ(j["found"], 4);
  EXPECT_EQ(j["labelled"], 3);
  EXPECT_EQ(j["agreeing"], 2);
  ASSERT_EQ(j["at_confidence"].size(), 5u);
  EXPECT_FLOAT_EQ(j["at_confidence"][0]["min_confidence"].get<float>(), 0.5f);
  EXPECT_EQ(j["at_confidence"][0]["labelled"], 3);
  EXPECT_EQ(j["at_confidence"][1]["labelled"], 2);  // 0.6: the bird goes
  EXPECT_EQ(j["at_confidence"][1]["agreeing"], 2);
  EXPECT_EQ(j["at_confidence"][3]["labelled"], 1);  // 0.8: only the car
  EXPECT_EQ(j["at_confidence"][4]["agreeing"], 1);
}

}  // namespace
}  // namespace placerec
