// The map tools (tools/map_tools.h) on a real map: the first 20 frames of corridor_loop from
// ../shared/data, built by the evaluation into a map file as a server would build it.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "common/eval/run.h"
#include "common/pipeline/place_map.h"
#include "common/storage/sqlite_store.h"
#include "common/util/paths.h"
#include "tools/eval_runner.h"
#include "tools/map_tools.h"

namespace placerec {
namespace {

constexpr int kFrames = 20;

std::string Temp(const std::string& name) {
  return ::testing::TempDir() + "/placerec_map_e2e_" + name + "_" + std::to_string(getpid());
}

void RemoveMap(const std::string& path) {
  for (const char* suffix : {"", "-wal", "-shm"}) std::filesystem::remove(path + suffix);
}

StatusOr<uint64_t> Checksum(const std::string& path) {
  SqliteStoreOptions options;
  options.must_exist = true;
  StatusOr<std::unique_ptr<LandmarkStore>> store = OpenSqliteStore(path, options);
  if (!store.ok()) return store.status();
  return (*store)->Checksum();
}

TEST(MapToolsEndToEndTest, CorridorLoopMapInfoCheckExportMergePrune) {
  const std::string dataset = DataDir("", PLACEREC_DEFAULT_DATA_DIR) + "/rtabmap_indoor";
  if (!PathExists(dataset + "/runs/corridor_loop.frames.csv")) {
    GTEST_SKIP() << "needs " << dataset << "/runs/corridor_loop.frames.csv (shared data)";
  }
  StatusOr<placerec::Run> run = LoadRun(dataset, "corridor_loop");
  ASSERT_TRUE(run.ok()) << run.status().ToString();
  const std::string map = Temp("map.db");
  const std::string merged = Temp("merged.db");
  const std::string out = Temp("export");
  RemoveMap(map);
  RemoveMap(merged);
  std::filesystem::remove_all(out);
  EvalOptions eval;
  eval.progress = false;
  eval.pictures = 0;
  eval.db_path = map;
  eval.max_frames = kFrames;
  ASSERT_TRUE(EvaluateRun(*run, RecognizerOptions(), eval).ok());

  StatusOr<MapInfo> info = ReadMapInfo(map);
  ASSERT_TRUE(info.ok()) << info.status().ToString();
  // Not every frame becomes a place (a frame may store nothing new).
  const int64_t places = info->places;
  EXPECT_GT(places, kFrames / 2);
  EXPECT_LE(places, kFrames);
  EXPECT_GT(info->landmarks, places);
  ASSERT_EQ(info->robots.size(), 1u);
  EXPECT_EQ(info->robots[0].places, places);
  EXPECT_EQ(info->robots[0].landmarks, info->landmarks);
  StatusOr<CheckReport> check = CheckMap(map);
  ASSERT_TRUE(check.ok());
  EXPECT_TRUE(check->ok());
  EXPECT_EQ(check->landmarks, info->landmarks);
  StatusOr<ExportReport> exported = ExportMap(map, out);
  ASSERT_TRUE(exported.ok()) << exported.status().ToString();
  EXPECT_EQ(exported->places, places);
  EXPECT_TRUE(PathExists(out + "/route.png"));
  // Every place of a map built by the pipeline keeps its thumbnail (schema v3).
  EXPECT_EQ(exported->thumbnails, places);
  EXPECT_TRUE(PathExists(out + "/contact_sheet.jpg"));

  // The map merged with itself: twice the places, the second robot renamed, each half whole.
  StatusOr<MergeReport> merge = MergeMaps(map, map, merged, MergeOptions());
  ASSERT_TRUE(merge.ok()) << merge.status().ToString();
  EXPECT_EQ(merge->places, 2 * places);
  EXPECT_EQ(merge->landmarks, 2 * info->landmarks);
  ASSERT_EQ(merge->renamed.size(), 1u);
  EXPECT_EQ(merge->renamed[0].second, info->robots[0].robot + ".b");
  check = CheckMap(merged);
  ASSERT_TRUE(check.ok());
  EXPECT_TRUE(check->ok());
  PruneOptions prune;
  prune.robot = merge->renamed[0].second;
  StatusOr<PruneReport> pruned = PruneMap(merged, prune);
  ASSERT_TRUE(pruned.ok()) << pruned.status().ToString();
  EXPECT_EQ(pruned->places, places);
  EXPECT_EQ(*Checksum(merged), *Checksum(map));

  // Pruning the first half by time; the rest opens as a server would open it.
  prune = PruneOptions();
  prune.before_utime = run->frames[kFrames / 2].utime;
  StatusOr<std::vector<PlaceSummary>> summaries = ReadPlaceSummaries(merged);
  ASSERT_TRUE(summaries.ok());
  int64_t early = 0;
  for (const PlaceSummary& place : *summaries) early += place.utime < prune.before_utime ? 1 : 0;
  EXPECT_GT(early, 0);
  pruned = PruneMap(merged, prune);
  ASSERT_TRUE(pruned.ok());
  EXPECT_EQ(pruned->places, early);
  SqliteStoreOptions options;
  StatusOr<std::unique_ptr<LandmarkStore>> store = OpenSqliteStore(merged, options);
  ASSERT_TRUE(store.ok());
  StatusOr<std::unique_ptr<PlaceMap>> opened =
      PlaceMap::Open(std::move(*store), RecognizerOptions().index);
  ASSERT_TRUE(opened.ok()) << opened.status().ToString();
  EXPECT_EQ((*opened)->Counts().places, places - early);
  opened->reset();

  RemoveMap(map);
  RemoveMap(merged);
  std::filesystem::remove_all(out);
}

}  // namespace
}  // namespace placerec
