// The mapping of dataset class names to the background classes of seed §3.4
// (BackgroundClassOfName, the one place it is written) and of the shared datasets' classes to
// the structured classifiers (StructuredClassIndex), on made-up tables and, when the shared
// data is there, on the three labelled outdoor datasets' own classes.txt.
#include <map>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "common/training/background_training.h"
#include "common/training/labelled_dataset.h"
#include "common/util/paths.h"

namespace placerec {
namespace {

TEST(BackgroundClassOfNameTest, BackgroundNamesAndAliasesMapOthersAreStructured) {
  EXPECT_EQ(BackgroundClassOfName("sky"), SegmentClass::kSky);
  EXPECT_EQ(BackgroundClassOfName("tree"), SegmentClass::kTree);
  EXPECT_EQ(BackgroundClassOfName("road"), SegmentClass::kRoad);
  EXPECT_EQ(BackgroundClassOfName("grass"), SegmentClass::kGrass);
  EXPECT_EQ(BackgroundClassOfName("water"), SegmentClass::kWater);
  EXPECT_EQ(BackgroundClassOfName("pavement"), SegmentClass::kRoad);  // camvid's ground
  for (const char* name : {"building", "mountain", "foreground", "car", "Sky", "", "unknown"}) {
    EXPECT_EQ(BackgroundClassOfName(name), SegmentClass::kStructured) << name;
  }
}

TEST(ClassTableTest, BackgroundClassGoesByNameUnlistedIdsAreStructured) {
  ClassTable table;
  table.names = {{0, "sky"}, {3, "road"}, {4, "pavement"}, {8, "car"}, {255, "unlabelled"}};
  EXPECT_EQ(table.BackgroundClass(0), SegmentClass::kSky);
  EXPECT_EQ(table.BackgroundClass(3), SegmentClass::kRoad);
  EXPECT_EQ(table.BackgroundClass(4), SegmentClass::kRoad);
  EXPECT_EQ(table.BackgroundClass(8), SegmentClass::kStructured);
  EXPECT_EQ(table.BackgroundClass(7), SegmentClass::kStructured);
  EXPECT_TRUE(table.IsUnlabelled(255));
}

// Dataset class name -> background class name, for the background classes of `dir`.
std::map<std::string, std::string> BackgroundClassesOf(const std::string& dir) {
  StatusOr<ClassTable> table = ReadClassTable(dir);
  EXPECT_TRUE(table.ok()) << table.status().ToString();
  std::map<std::string, std::string> out;
  if (!table.ok()) return out;
  for (const auto& [id, name] : table->names) {
    if (IsBackground(table->BackgroundClass(id))) {
      out[name] = SegmentClassName(table->BackgroundClass(id));
    }
  }
  return out;
}

// What each shared outdoor dataset contributes to the background classes (shared/data/README.md).
TEST(ClassTableTest, SharedOutdoorDatasetsMapToTheBackgroundClasses) {
  const std::string data = DataDir("", PLACEREC_DEFAULT_DATA_DIR);
  if (!PathExists(data + "/camvid/classes.txt") || !PathExists(data + "/msrc_v2/classes.txt") ||
      !PathExists(data + "/stanford_background/classes.txt")) {
    GTEST_SKIP() << "needs " << data << " (the shared evaluation data); set PLACEREC_DATA";
  }
  using Map = std::map<std::string, std::string>;
  EXPECT_EQ(BackgroundClassesOf(data + "/stanford_background"), (Map{{"sky", "sky"},
                                                                     {"tree", "tree"},
                                                                     {"road", "road"},
                                                                     {"grass", "grass"},
                                                                     {"water", "water"}}));
  EXPECT_EQ(BackgroundClassesOf(data + "/msrc_v2"), (Map{{"sky", "sky"},
                                                         {"tree", "tree"},
                                                         {"road", "road"},
                                                         {"grass", "grass"},
                                                         {"water", "water"}}));
  EXPECT_EQ(BackgroundClassesOf(data + "/camvid"),
            (Map{{"sky", "sky"}, {"tree", "tree"}, {"road", "road"}, {"pavement", "road"}}));
}

TEST(StructuredClassIndexTest, NamedClassesAndTheCatchAllOfDatasetsWithoutIt) {
  const std::vector<std::string> names = {"building", "mountain", "foreground"};
  ClassTable stanford;
  stanford.names = {{0, "sky"},      {1, "tree"},       {4, "water"},    {5, "building"},
                    {6, "mountain"}, {7, "foreground"}, {255, "unknown"}};
  EXPECT_EQ(StructuredClassIndex(names, stanford), (std::map<int, int>{{5, 0}, {6, 1}, {7, 2}}));
  ClassTable camvid;
  camvid.names = {{0, "sky"},      {1, "building"}, {2, "pole"},        {3, "road"},
                  {4, "pavement"}, {8, "car"},      {255, "unlabelled"}};
  // No mountain; pole and car are foreground; pavement is road, not structured.
  EXPECT_EQ(StructuredClassIndex(names, camvid), (std::map<int, int>{{1, 0}, {2, 2}, {8, 2}}));
  // Without the catch-all in the list, classes not named stay without a structured classifier.
  EXPECT_EQ(StructuredClassIndex({"building"}, camvid), (std::map<int, int>{{1, 0}}));
  EXPECT_TRUE(StructuredClassIndex({}, camvid).empty());
}

}  // namespace
}  // namespace placerec
