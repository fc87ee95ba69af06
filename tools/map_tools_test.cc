#include "tools/map_tools.h"

#include <sys/wait.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include <opencv2/imgcodecs.hpp>

#include "common/pipeline/place_map.h"
#include "common/storage/sqlite_store.h"
#include "common/storage/storage_testing.h"

namespace placerec {
namespace {

using testing_storage::ExpectSameLandmark;
using testing_storage::ExplicitLandmark;
using testing_storage::QuerySql;
using testing_storage::TempMap;

constexpr int64_t kDay = 86400LL * 1000000;         // microseconds
constexpr int64_t kStart = 1764547200LL * 1000000;  // 2025-12-01T00:00:00Z

std::unique_ptr<LandmarkStore> Open(const std::string& path) {
  SqliteStoreOptions options;
  options.synchronous_full = false;
  StatusOr<std::unique_ptr<LandmarkStore>> store = OpenSqliteStore(path, options);
  EXPECT_TRUE(store.ok()) << store.status().ToString();
  return store.ok() ? std::move(*store) : nullptr;
}

// Adds a place of `robot` with `count` landmarks (classes from `classes`, cycled; "" leaves one
// unclassified) seeing `seen`; returns its landmarks with their ids.
std::vector<Landmark> AddPlace(LandmarkStore* store, const std::string& robot, int64_t sequence,
                               int64_t utime, int count, const std::vector<std::string>& classes,
                               std::vector<LandmarkId> seen = {}) {
  Place place;
  place.robot = robot;
  place.sequence = sequence;
  place.utime = utime;
  place.image_width = 640;
  place.seen_landmarks = std::move(seen);
  if (robot == "left") {  // left's camera keeps thumbnails, right's map predates them
    const cv::Mat picture(12, 16, CV_8UC3, cv::Scalar(40, 80, 120 + sequence));
    cv::imencode(".jpg", picture, place.thumbnail);
  }
  std::vector<Landmark> landmarks;
  for (int i = 0; i < count; ++i) {
    Landmark landmark = ExplicitLandmark(i + static_cast<int>(sequence % 3));
    const std::string& name = classes[static_cast<size_t>(i) % classes.size()];
    if (!name.empty()) {
      landmark.object_class = name;
      landmark.class_confidence = 0.75f;
    }
    landmarks.push_back(std::move(landmark));
  }
  const Status added = store->AddPlace(&place, &landmarks);
  EXPECT_TRUE(added.ok()) << added.ToString();
  return landmarks;
}

// Map "site": robot "left" with 3 places on day 0, 1, 2 (2 landmarks each: building, sign),
// robot "right" with 2 places on day 1 (1 landmark, unclassified); right's second place sees the
// first landmark of left's first place.
void BuildSite(const std::string& path) {
  std::unique_ptr<LandmarkStore> store = Open(path);
  ASSERT_NE(store, nullptr);
  const std::vector<Landmark> first =
      AddPlace(store.get(), "left", 0, kStart, 2, {"building", "sign"});
  AddPlace(store.get(), "left", 1, kStart + kDay, 2, {"building", "sign"});
  AddPlace(store.get(), "right", 0, kStart + kDay + 5, 1, {""});
  AddPlace(store.get(), "right", 1, kStart + kDay + 10, 1, {""}, {first[0].id});
  AddPlace(store.get(), "left", 2, kStart + 2 * kDay, 2, {"building", "sign"});
}

std::vector<Place> Places(const std::string& path) {
  std::vector<Place> places;
  std::unique_ptr<LandmarkStore> store = Open(path);
  EXPECT_TRUE(store->LoadPlaces([&](const Place& place) { places.push_back(place); }).ok());
  return places;
}

std::vector<Landmark> Landmarks(const std::string& path) {
  std::vector<Landmark> landmarks;
  std::unique_ptr<LandmarkStore> store = Open(path);
  EXPECT_TRUE(
      store->LoadLandmarks([&](Landmark&& landmark) { landmarks.push_back(landmark); }).ok());
  return landmarks;
}

TEST(MapToolsTest, InfoCountsByRobotAndClass) {
  TempMap map("info");
  BuildSite(map.path());
  StatusOr<MapInfo> info = ReadMapInfo(map.path());
  ASSERT_TRUE(info.ok()) << info.status().ToString();
  EXPECT_EQ(info->schema_version, kSqliteSchemaVersion);
  EXPECT_EQ(info->places, 5);
  EXPECT_EQ(info->landmarks, 8);
  EXPECT_EQ(info->sightings, 1);
  EXPECT_GT(info->file_bytes, 0);
  ASSERT_EQ(info->robots.size(), 2u);
  EXPECT_EQ(info->robots[0].robot, "left");
  EXPECT_EQ(info->robots[0].places, 3);
  EXPECT_EQ(info->robots[0].landmarks, 6);
  EXPECT_EQ(info->robots[0].last_utime - info->robots[0].first_utime, 2 * kDay);
  EXPECT_EQ(info->robots[1].robot, "right");
  EXPECT_EQ(info->robots[1].landmarks, 2);
  ASSERT_EQ(info->classes.size(), 3u);
  EXPECT_EQ(info->classes[0].object_class, "");  // unclassified first
  EXPECT_EQ(info->classes[0].landmarks, 2);
  EXPECT_EQ(info->classes[1].object_class, "building");
  EXPECT_EQ(info->classes[1].landmarks, 3);
  int64_t descriptors = 0;
  for (const ClassInfo& item : info->classes) descriptors += item.descriptors;
  EXPECT_EQ(descriptors, info->descriptors);
  const nlohmann::json json = info->ToJson();
  EXPECT_EQ(json["robots"][0]["places"], 3);
  EXPECT_TRUE(json["classes"][0]["class"].is_null());
  EXPECT_NE(info->ToText().find("left"), std::string::npos);

  EXPECT_EQ(ReadMapInfo(map.path() + ".missing").status().code(), StatusCode::kNotFound);
}

TEST(MapToolsTest, ExportWritesPlacesCsvAndRoutePicture) {
  TempMap map("export");
  BuildSite(map.path());
  const std::string out = ::testing::TempDir() + "/placerec_map_export_" + std::to_string(getpid());
  std::filesystem::remove_all(out);
  StatusOr<ExportReport> report = ExportMap(map.path(), out);
  ASSERT_TRUE(report.ok()) << report.status().ToString();
  EXPECT_EQ(report->places, 5);
  EXPECT_EQ(report->robots, 2);
  std::ifstream csv(out + "/places.csv");
  std::vector<std::string> lines;
  for (std::string line; std::getline(csv, line);) lines.push_back(line);
  ASSERT_EQ(lines.size(), 6u);
  EXPECT_EQ(lines[0], "id,robot,sequence,utime,landmarks,descriptors,classes,thumbnail");
  EXPECT_EQ(lines[1].substr(0, 7), "1,left,");
  EXPECT_NE(lines[1].find(",2,"), std::string::npos);
  EXPECT_NE(lines[1].find(",building:1;sign:1,thumbnails/1.jpg"), std::string::npos) << lines[1];
  EXPECT_EQ(lines[3].substr(lines[3].size() - 16), ",unclassified:1,") << lines[3];
  const cv::Mat picture = cv::imread(out + "/route.png");
  EXPECT_FALSE(picture.empty());
  EXPECT_GT(picture.cols, 1000);
  // Left's three places keep thumbnails, right's two do not.
  EXPECT_EQ(report->thumbnails, 3);
  const cv::Mat thumbnail = cv::imread(out + "/thumbnails/1.jpg");
  EXPECT_EQ(thumbnail.cols, 16);
  EXPECT_FALSE(std::filesystem::exists(out + "/thumbnails/3.jpg"));
  EXPECT_EQ(report->contact_sheet_path, out + "/contact_sheet.jpg");
  const cv::Mat sheet = cv::imread(report->contact_sheet_path);
  EXPECT_EQ(sheet.cols, 3 * 162);

  // Exported again into the same folder after a prune, the pictures of the places gone go too
  // (files the earlier export's places.csv did not list stay).
  std::ofstream(out + "/thumbnails/notes.txt") << "mine";
  std::ofstream(out + "/thumbnails/77.jpg") << "mine too";  // no export listed it
  PruneOptions prune;
  prune.robot = "left";
  ASSERT_TRUE(PruneMap(map.path(), prune).ok());
  report = ExportMap(map.path(), out);
  ASSERT_TRUE(report.ok()) << report.status().ToString();
  EXPECT_EQ(report->thumbnails, 0);
  EXPECT_FALSE(std::filesystem::exists(out + "/thumbnails/1.jpg"));
  EXPECT_FALSE(std::filesystem::exists(out + "/contact_sheet.jpg"));
  EXPECT_TRUE(std::filesystem::exists(out + "/thumbnails/notes.txt"));
  EXPECT_TRUE(std::filesystem::exists(out + "/thumbnails/77.jpg"));
  std::filesystem::remove_all(out);
}

TEST(MapToolsTest, PruneByRobotDropsItsPlacesLandmarksAndSightings) {
  TempMap map("prune_robot");
  BuildSite(map.path());
  PruneOptions options;
  // A robot the map does not have (a misspelt id) prunes nothing, and the report names the
  // robots it has (a scheduled prune of a robot already gone is no error).
  options.robot = "lfet";
  const StatusOr<PruneReport> misspelt = PruneMap(map.path(), options);
  ASSERT_TRUE(misspelt.ok()) << misspelt.status().ToString();
  EXPECT_TRUE(misspelt->robot_unknown);
  EXPECT_EQ(misspelt->robots, (std::vector<std::string>{"left", "right"}));
  EXPECT_EQ(misspelt->places, 0);
  options.robot = "left";
  StatusOr<PruneReport> report = PruneMap(map.path(), options);
  ASSERT_TRUE(report.ok()) << report.status().ToString();
  EXPECT_FALSE(report->robot_unknown);
  EXPECT_EQ(report->places, 3);
  EXPECT_EQ(report->landmarks, 6);
  EXPECT_EQ(report->sightings, 1);  // right's sighting of left's landmark
  EXPECT_EQ(report->places_kept, 2);
  EXPECT_EQ(report->landmarks_kept, 2);
  const std::vector<Place> places = Places(map.path());
  ASSERT_EQ(places.size(), 2u);
  for (const Place& place : places) {
    EXPECT_EQ(place.robot, "right");
    EXPECT_TRUE(place.seen_landmarks.empty());
  }
  EXPECT_EQ(QuerySql(map.path(), "SELECT COUNT(*) FROM sightings"), "0");
  EXPECT_EQ(QuerySql(map.path(), "SELECT COUNT(*) FROM thumbnails"), "0");  // left's went too
  StatusOr<CheckReport> check = CheckMap(map.path());
  ASSERT_TRUE(check.ok());
  EXPECT_TRUE(check->ok()) << check->problems.front();

  // The server's next start: the pruned map opens and answers from what is left.
  SqliteStoreOptions store_options;
  StatusOr<std::unique_ptr<LandmarkStore>> store = OpenSqliteStore(map.path(), store_options);
  ASSERT_TRUE(store.ok());
  StatusOr<std::unique_ptr<PlaceMap>> place_map =
      PlaceMap::Open(std::move(*store), LandmarkIndexOptions());
  ASSERT_TRUE(place_map.ok()) << place_map.status().ToString();
  EXPECT_EQ((*place_map)->Counts().places, 2);
  EXPECT_EQ((*place_map)->Counts().landmarks, 2);
  const std::vector<Landmark> kept = Landmarks(map.path());
  ASSERT_EQ(kept.size(), 2u);
  MapLookup lookup;
  lookup.recent.robot = "someone-else";
  lookup.recent.utime = kStart + 3 * kDay;
  IndexQuery query;
  query.sift_count = kept[0].sift_count;
  query.colour = kept[0].colour;
  query.descriptors = kept[0].descriptors.clone();
  lookup.objects.push_back(query);
  lookup.object_keypoints.push_back(kept[0].keypoints);
  lookup.image_width = 640;
  const MapLookupResult result = (*place_map)->Lookup(lookup, LoopDecisionOptions());
  ASSERT_FALSE(result.places.empty());
  EXPECT_EQ(result.places[0].place.robot, "right");
}

TEST(MapToolsTest, PruneBeforeADateAndDryRun) {
  TempMap map("prune_before");
  BuildSite(map.path());
  const std::string before = QuerySql(map.path(), "SELECT COUNT(*) FROM landmarks");
  PruneOptions options;
  StatusOr<int64_t> cut = ParseTimeArgument("2025-12-02");  // day 1, midnight
  ASSERT_TRUE(cut.ok());
  options.before_utime = *cut + 1;  // left's day-1 place too, not right's (5 us later)
  options.dry_run = true;
  StatusOr<PruneReport> dry = PruneMap(map.path(), options);
  ASSERT_TRUE(dry.ok()) << dry.status().ToString();
  EXPECT_EQ(dry->places, 2);
  EXPECT_EQ(dry->sightings, 1);
  EXPECT_EQ(QuerySql(map.path(), "SELECT COUNT(*) FROM landmarks"), before);  // unchanged
  EXPECT_EQ(Places(map.path()).size(), 5u);
  options.dry_run = false;
  StatusOr<PruneReport> report = PruneMap(map.path(), options);
  ASSERT_TRUE(report.ok());
  EXPECT_EQ(report->places, 2);
  EXPECT_EQ(report->landmarks, 4);
  EXPECT_EQ(report->places_by_robot.at("left"), 2);
  EXPECT_EQ(Places(map.path()).size(), 3u);
  EXPECT_EQ(Landmarks(map.path()).size(), 4u);

  PruneOptions nothing;
  EXPECT_EQ(PruneMap(map.path(), nothing).status().code(), StatusCode::kInvalidArgument);
}

TEST(MapToolsTest, PruneRefusesAMapHeldOpenAndLeavesItUnchanged) {
  TempMap map("prune_held");
  BuildSite(map.path());
  std::unique_ptr<LandmarkStore> server = Open(map.path());  // as a running server holds it
  ASSERT_NE(server, nullptr);
  const StatusOr<uint64_t> checksum = server->Checksum();
  PruneOptions options;
  options.robot = "left";
  const StatusOr<PruneReport> report = PruneMap(map.path(), options);
  ASSERT_FALSE(report.ok());
  EXPECT_NE(report.status().message().find("open in another process"), std::string::npos)
      << report.status().ToString();
  // Reading commands (and a dry run) still work, and the holder can go on writing.
  EXPECT_TRUE(ReadMapInfo(map.path()).ok());
  PruneOptions dry = options;
  dry.dry_run = true;
  const StatusOr<PruneReport> counted = PruneMap(map.path(), dry);
  ASSERT_TRUE(counted.ok()) << counted.status().ToString();
  EXPECT_EQ(counted->places, 3);
  EXPECT_EQ(*server->Checksum(), *checksum);
  AddPlace(server.get(), "left", 3, kStart + 3 * kDay, 1, {"sign"});
  server.reset();
  EXPECT_TRUE(PruneMap(map.path(), options).ok());  // closed: allowed
}

// A server in another process holds its map open while it is idle (WAL mode: its connection
// locks the shared-memory file, MAP-shm, and holds a shared lock on the map file). Prune must
// refuse the map: changed under a server, the map was left corrupt.
TEST(MapToolsTest, PruneRefusesAMapHeldOpenByAnotherProcess) {
  TempMap map("prune_held_elsewhere");
  BuildSite(map.path());
  int ready[2], done[2];
  ASSERT_EQ(pipe(ready), 0);
  ASSERT_EQ(pipe(done), 0);
  const pid_t child = fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    // The holder: the map opened as the server opens it, idle, until the parent is done.
    std::unique_ptr<LandmarkStore> holder = Open(map.path());
    const bool opened = holder != nullptr && holder->Checksum().ok();
    char byte = opened ? 1 : 0;
    if (write(ready[1], &byte, 1) != 1) _exit(2);
    if (read(done[0], &byte, 1) != 1) _exit(3);
    holder.reset();
    _exit(opened ? 0 : 1);
  }
  char byte = 0;
  ASSERT_EQ(read(ready[0], &byte, 1), 1);
  ASSERT_EQ(byte, 1) << "the holder could not open the map";
  PruneOptions options;
  options.robot = "left";
  const StatusOr<PruneReport> report = PruneMap(map.path(), options);
  byte = 0;
  ASSERT_EQ(write(done[1], &byte, 1), 1);
  int status = 0;
  ASSERT_EQ(waitpid(child, &status, 0), child);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << status;
  for (const int fd : {ready[0], ready[1], done[0], done[1]}) close(fd);
  ASSERT_FALSE(report.ok()) << "pruned " << report->places << " places under another process";
  EXPECT_NE(report.status().message().find("open in another process"), std::string::npos)
      << report.status().ToString();
  const StatusOr<MapInfo> info = ReadMapInfo(map.path());
  ASSERT_TRUE(info.ok()) << info.status().ToString();
  EXPECT_TRUE(PruneMap(map.path(), options).ok());  // the holder is gone: allowed
}

// The descriptor index's neighbours of every stored descriptor, and their distances.
std::string IndexAnswers(const std::string& path) {
  StatusOr<std::unique_ptr<PlaceMap>> map = PlaceMap::Open(Open(path), LandmarkIndexOptions());
  EXPECT_TRUE(map.ok());
  std::ostringstream text;
  for (const Landmark& landmark : Landmarks(path)) {
    std::vector<std::vector<DescriptorIndex::Neighbour>> neighbours;
    (*map)->index().descriptor_index().Search(landmark.descriptors, 3, &neighbours);
    for (const auto& list : neighbours) {
      for (const auto& n : list) text << n.owner << ":" << n.row << ":" << n.distance << " ";
    }
    text << "\n";
  }
  return text.str();
}

TEST(MapToolsTest, IndexWritesTheSnapshotThatAPruneMakesStale) {
  TempMap map("index");
  BuildSite(map.path());
  const std::string fresh = IndexAnswers(map.path());
  StatusOr<IndexSnapshotReport> report = WriteIndexSnapshot(map.path());
  ASSERT_TRUE(report.ok()) << report.status().ToString();
  EXPECT_TRUE(report->written);
  EXPECT_FALSE(report->started_from_snapshot);
  EXPECT_EQ(report->snapshot, map.path() + ".index");
  EXPECT_EQ(report->descriptors, ReadMapInfo(map.path())->descriptors);
  // Up to date: opened from it, nothing to write.
  report = WriteIndexSnapshot(map.path());
  ASSERT_TRUE(report.ok());
  EXPECT_TRUE(report->started_from_snapshot);
  EXPECT_FALSE(report->written);
  EXPECT_EQ(IndexAnswers(map.path()), fresh);

  // Pruning the first place leaves the snapshot stale: ignored, the map indexed afresh.
  PruneOptions options;
  options.before_utime = kStart + 1;
  ASSERT_TRUE(PruneMap(map.path(), options).ok());
  {
    StatusOr<std::unique_ptr<PlaceMap>> opened =
        PlaceMap::Open(Open(map.path()), LandmarkIndexOptions());
    ASSERT_TRUE(opened.ok());
    EXPECT_FALSE((*opened)->snapshot_load().used) << (*opened)->snapshot_load().message;
  }
  report = WriteIndexSnapshot(map.path());
  ASSERT_TRUE(report.ok());
  EXPECT_FALSE(report->started_from_snapshot);
  EXPECT_TRUE(report->written);

  // Pruned to nothing, the map's snapshot is stale and goes.
  PruneOptions everything;
  everything.before_utime = kStart + 100 * kDay;
  ASSERT_TRUE(PruneMap(map.path(), everything).ok());
  report = WriteIndexSnapshot(map.path());
  ASSERT_TRUE(report.ok()) << report.status().ToString();
  EXPECT_FALSE(report->written);
  EXPECT_EQ(report->descriptors, 0);
  EXPECT_TRUE(report->removed_stale);
  EXPECT_FALSE(std::filesystem::exists(report->snapshot));

  // An empty database is no map to prune.
  TempMap empty("prune_empty");
  std::ofstream(empty.path()).flush();
  PruneOptions some;
  some.robot = "left";
  const StatusOr<PruneReport> pruned_empty = PruneMap(empty.path(), some);
  ASSERT_FALSE(pruned_empty.ok());
  EXPECT_NE(pruned_empty.status().message().find("holds no placerec map"), std::string::npos)
      << pruned_empty.status().message();

  // A missing map is an error, and no snapshot appears for it.
  TempMap missing("index_missing");
  EXPECT_FALSE(WriteIndexSnapshot(missing.path()).ok());
  EXPECT_FALSE(std::ifstream(missing.path() + ".index").good());
}

TEST(MapToolsTest, ParseTimeArgument) {
  EXPECT_EQ(*ParseTimeArgument("1764547200000000"), 1764547200LL * 1000000);
  EXPECT_EQ(*ParseTimeArgument("2025-12-01"), 1764547200LL * 1000000);
  EXPECT_EQ(*ParseTimeArgument("2025-12-01T01:02"), (1764547200LL + 3720) * 1000000);
  EXPECT_EQ(*ParseTimeArgument("2025-12-01T01:02:03Z"), (1764547200LL + 3723) * 1000000);
  EXPECT_FALSE(ParseTimeArgument("yesterday").ok());
  EXPECT_FALSE(ParseTimeArgument("2025-13-01").ok());
  // Days a month does not have are refused, not rolled over.
  EXPECT_FALSE(ParseTimeArgument("2011-02-29").ok());
  EXPECT_FALSE(ParseTimeArgument("2011-02-30").ok());
  EXPECT_FALSE(ParseTimeArgument("2011-04-31").ok());
  EXPECT_FALSE(ParseTimeArgument("2100-02-29").ok());
  EXPECT_EQ(*ParseTimeArgument("2012-02-29"), 1330473600LL * 1000000);
  EXPECT_EQ(*ParseTimeArgument("2000-02-29"), 951782400LL * 1000000);
  EXPECT_TRUE(ParseTimeArgument("2011-12-31T23:59:59Z").ok());
  EXPECT_FALSE(ParseTimeArgument("2025-12-01T01").ok());
}

TEST(MapToolsTest, MergedRobotIdRule) {
  EXPECT_EQ(MergedRobotId("r", {"a"}, {"a", "r"}, ".b"), "r");
  EXPECT_EQ(MergedRobotId("r", {"r"}, {"r"}, ".b"), "r.b");
  EXPECT_EQ(MergedRobotId("r", {"r", "r.b"}, {"r", "r.b"}, ".b"), "r.b2");
}

std::string ThisHost() {
  char name[256] = {};
  gethostname(name, sizeof(name) - 1);
  return name[0] == '\0' ? "localhost" : name;
}

// The work file a merge into `out` by process `pid` of this machine writes.
std::string WorkFile(const std::string& out, pid_t pid) {
  return out + ".merging." + ThisHost() + "." + std::to_string(pid);
}

// A process id that no process has now: a child that exited and was reaped.
pid_t DeadPid() {
  const pid_t child = fork();
  if (child == 0) _exit(0);
  EXPECT_EQ(waitpid(child, nullptr, 0), child);
  return child;
}

// Two merges into the same output at once: neither removes the other's work in progress (one
// had reported a map written that the other had replaced with its own half-written one).
TEST(MapToolsTest, MergeLeavesAnotherMergesWorkAlone) {
  TempMap a("merge_race_a");
  TempMap b("merge_race_b");
  TempMap c("merge_race_c");
  BuildSite(a.path());
  BuildSite(b.path());
  const std::vector<std::string> others = {c.path() + ".merging", WorkFile(c.path(), 1)};
  for (const std::string& other : others) std::ofstream(other) << "another merge's work";
  StatusOr<MergeReport> report = MergeMaps(a.path(), b.path(), c.path(), MergeOptions());
  ASSERT_TRUE(report.ok()) << report.status().ToString();
  for (const std::string& other : others) {
    std::ifstream in(other);
    std::string text;
    std::getline(in, text);
    EXPECT_EQ(text, "another merge's work") << other;
    std::filesystem::remove(other);
  }
  // The second merge into the same output is refused and leaves the first's map whole.
  StatusOr<MergeReport> again = MergeMaps(a.path(), b.path(), c.path(), MergeOptions());
  EXPECT_FALSE(again.ok());
  EXPECT_EQ(Places(c.path()).size(), 2 * Places(a.path()).size());
}

// An earlier map C whose writer was killed left C-wal beside it; C itself was removed. The merge
// into C is refused: SQLite would replay that log onto the merged map.
TEST(MapToolsTest, MergeRefusesAnOutputWithAnEarlierMapsLog) {
  TempMap a("merge_stale_a");
  TempMap b("merge_stale_b");
  TempMap c("merge_stale_c");
  BuildSite(a.path());
  BuildSite(b.path());
  std::filesystem::copy_file(a.path(), c.path());
  std::ofstream(c.path() + "-wal") << "an earlier map's log";
  std::filesystem::remove(c.path());
  StatusOr<MergeReport> report = MergeMaps(a.path(), b.path(), c.path(), MergeOptions());
  ASSERT_FALSE(report.ok());
  EXPECT_NE(report.status().message().find("-wal exists"), std::string::npos)
      << report.status().ToString();
  EXPECT_FALSE(std::filesystem::exists(c.path()));
  std::filesystem::remove(c.path() + "-wal");
  EXPECT_TRUE(MergeMaps(a.path(), b.path(), c.path(), MergeOptions()).ok());
}

// A dangling symbolic link at C is a taken name: refused before any work, the link left alone.
TEST(MapToolsTest, MergeRefusesADanglingLinkAtTheOutput) {
  TempMap a("merge_link_a");
  TempMap b("merge_link_b");
  TempMap c("merge_link_c");
  BuildSite(a.path());
  BuildSite(b.path());
  std::filesystem::create_symlink(c.path() + ".nowhere", c.path());
  StatusOr<MergeReport> report = MergeMaps(a.path(), b.path(), c.path(), MergeOptions());
  ASSERT_FALSE(report.ok());
  EXPECT_EQ(report.status().code(), StatusCode::kInvalidArgument) << report.status().ToString();
  EXPECT_NE(report.status().message().find("exists"), std::string::npos)
      << report.status().ToString();
  EXPECT_TRUE(std::filesystem::is_symlink(std::filesystem::symlink_status(c.path())));
  std::filesystem::remove(c.path());
}

// A merge that was killed left C.merging.HOST.<pid> (and its -wal): the next merge into C removes
// them, while a running process's work file, another machine's, files that only look alike and
// an input stay.
TEST(MapToolsTest, MergeRemovesWhatAKilledMergeLeft) {
  TempMap b("merge_killed_b");
  TempMap c("merge_killed_c");
  const pid_t dead = DeadPid();
  ASSERT_GT(dead, 0);
  // Input A is itself named like a killed merge's work file (a user salvaging one).
  const std::string a = WorkFile(c.path(), DeadPid());
  BuildSite(a);
  BuildSite(b.path());
  const std::string killed = WorkFile(c.path(), dead);
  for (const char* suffix : {"", "-wal"}) std::ofstream(killed + suffix) << "a killed merge's";
  const std::vector<std::string> kept = {
      WorkFile(c.path(), 1),  // pid 1 runs as long as the machine
      c.path() + ".merging.another-host." + std::to_string(dead), killed + ".bak",
      c.path() + ".merging." + ThisHost() + ".0" + std::to_string(dead),
      WorkFile(c.path() + "2", dead)};
  for (const std::string& file : kept) std::ofstream(file) << "not a killed merge's";
  StatusOr<MergeReport> report = MergeMaps(a, b.path(), c.path(), MergeOptions());
  ASSERT_TRUE(report.ok()) << report.status().ToString();
  EXPECT_FALSE(std::filesystem::exists(killed));
  EXPECT_FALSE(std::filesystem::exists(killed + "-wal"));
  EXPECT_EQ(report->removed_work_files, std::vector<std::string>{killed});
  for (const std::string& file : kept) {
    EXPECT_TRUE(std::filesystem::exists(file)) << file;
    std::filesystem::remove(file);
  }
  EXPECT_EQ(Places(a).size(), 5u);
  EXPECT_EQ(Places(c.path()).size(), 10u);
  for (const char* suffix : {"", "-wal", "-shm"}) std::filesystem::remove(a + suffix);
}

TEST(MapToolsTest, MergeKeepsBothMapsContentsAndRobotsApart) {
  TempMap a("merge_a");
  TempMap b("merge_b");
  TempMap c("merge_c");
  BuildSite(a.path());
  {
    std::unique_ptr<LandmarkStore> store = Open(b.path());
    const std::vector<Landmark> first = AddPlace(store.get(), "right", 0, kStart, 3, {"car"});
    AddPlace(store.get(), "night", 0, kStart + 1, 0, {""});
    AddPlace(store.get(), "night", 1, kStart + 2, 2, {"sign"}, {first[1].id, first[2].id});
  }
  StatusOr<MergeReport> report = MergeMaps(a.path(), b.path(), c.path(), MergeOptions());
  ASSERT_TRUE(report.ok()) << report.status().ToString();
  EXPECT_EQ(report->places, 8);
  EXPECT_EQ(report->landmarks, 13);
  ASSERT_EQ(report->renamed.size(), 1u);
  EXPECT_EQ(report->renamed[0], std::make_pair(std::string("right"), std::string("right.b")));
  EXPECT_FALSE(std::filesystem::exists(WorkFile(c.path(), getpid())));

  // Content preserved: C's places and landmarks are A's then B's, ids shifted, B's robot renamed,
  // sightings following their landmarks.
  const std::vector<Place> pa = Places(a.path()), pb = Places(b.path()), pc = Places(c.path());
  const std::vector<Landmark> la = Landmarks(a.path()), lb = Landmarks(b.path()),
                              lc = Landmarks(c.path());
  ASSERT_EQ(pc.size(), pa.size() + pb.size());
  ASSERT_EQ(lc.size(), la.size() + lb.size());
  const int64_t place_shift = static_cast<int64_t>(pa.size());
  const int64_t landmark_shift = static_cast<int64_t>(la.size());
  for (size_t i = 0; i < pc.size(); ++i) {
    Place expected = i < pa.size() ? pa[i] : pb[i - pa.size()];
    if (i >= pa.size()) {
      expected.id = PlaceId(expected.id.value() + place_shift);
      if (expected.robot == "right") expected.robot = "right.b";
      for (LandmarkId& seen : expected.seen_landmarks) {
        seen = LandmarkId(seen.value() + landmark_shift);
      }
    }
    EXPECT_EQ(pc[i], expected) << i;
  }
  for (size_t i = 0; i < lc.size(); ++i) {
    Landmark expected = i < la.size() ? la[i] : lb[i - la.size()];
    if (i >= la.size()) {
      expected.id = LandmarkId(expected.id.value() + landmark_shift);
      expected.place = PlaceId(expected.place.value() + place_shift);
    }
    ExpectSameLandmark(expected, lc[i]);
  }
  // Thumbnails follow their places: A's left places 1..3 keep theirs.
  EXPECT_EQ(QuerySql(c.path(), "SELECT group_concat(place_id) FROM thumbnails"), "1,2,5");
  EXPECT_EQ(*Open(c.path())->LoadThumbnail(PlaceId(5)), *Open(a.path())->LoadThumbnail(PlaceId(5)));
  EXPECT_TRUE(Open(c.path())->LoadThumbnail(PlaceId(3))->empty());

  // Which is what the checksums of the parts say: C less B's places is A.
  StatusOr<CheckReport> check = CheckMap(c.path());
  ASSERT_TRUE(check.ok());
  EXPECT_TRUE(check->ok());
  PruneOptions drop_b;
  drop_b.robot = "right.b";
  ASSERT_TRUE(PruneMap(c.path(), drop_b).ok());
  drop_b.robot = "night";
  ASSERT_TRUE(PruneMap(c.path(), drop_b).ok());
  EXPECT_EQ(*Open(c.path())->Checksum(), *Open(a.path())->Checksum());

  // An existing --out is refused and kept.
  const std::string c_before = QuerySql(c.path(), "SELECT COUNT(*) FROM places");
  EXPECT_EQ(MergeMaps(a.path(), b.path(), c.path(), MergeOptions()).status().code(),
            StatusCode::kInvalidArgument);
  EXPECT_EQ(QuerySql(c.path(), "SELECT COUNT(*) FROM places"), c_before);
}

TEST(MapToolsTest, MergeRefusesARenamedRobotIdOverTheLimit) {
  TempMap a("merge_long_a");
  TempMap b("merge_long_b");
  TempMap c("merge_long_c");
  const std::string robot(46, 'r');
  {
    std::unique_ptr<LandmarkStore> store = Open(a.path());
    AddPlace(store.get(), robot, 0, kStart, 1, {"sign"});
  }
  {
    std::unique_ptr<LandmarkStore> store = Open(b.path());
    AddPlace(store.get(), robot, 0, kStart, 1, {"sign"});
  }
  const StatusOr<MergeReport> report = MergeMaps(a.path(), b.path(), c.path(), MergeOptions());
  ASSERT_FALSE(report.ok());
  EXPECT_NE(report.status().message().find("47-byte"), std::string::npos)
      << report.status().ToString();
  EXPECT_FALSE(std::filesystem::exists(c.path()));
  EXPECT_FALSE(std::filesystem::exists(WorkFile(c.path(), getpid())));
  MergeOptions short_suffix;
  short_suffix.suffix = "b";
  EXPECT_TRUE(MergeMaps(a.path(), b.path(), c.path(), short_suffix).ok());
  short_suffix.suffix = "@b";
  std::string error;
  EXPECT_FALSE(short_suffix.Check(&error));
}

TEST(MapToolsTest, CheckFindsADamagedLandmark) {
  TempMap map("check");
  BuildSite(map.path());
  StatusOr<CheckReport> whole = CheckMap(map.path());
  ASSERT_TRUE(whole.ok()) << whole.status().ToString();
  EXPECT_TRUE(whole->ok());
  EXPECT_EQ(whole->places, 5);
  EXPECT_EQ(whole->landmarks, 8);
  testing_storage::ExecSql(map.path(), "UPDATE landmarks SET descriptors = x'0102' WHERE id = 3");
  testing_storage::ExecSql(map.path(), "UPDATE places SET num_landmarks = 7 WHERE id = 2");
  StatusOr<CheckReport> damaged = CheckMap(map.path());
  ASSERT_TRUE(damaged.ok());
  ASSERT_FALSE(damaged->ok());
  std::string all;
  for (const std::string& problem : damaged->problems) all += problem + "\n";
  EXPECT_NE(all.find("landmark 3"), std::string::npos) << all;
  EXPECT_NE(all.find("place 2 lists 7 landmarks but has 2"), std::string::npos) << all;
  EXPECT_EQ(CheckMap(map.path() + ".missing").status().code(), StatusCode::kNotFound);
}

// A capture time outside 0 .. kMaxUtime (an old build wrote such times) is no damage: the server
// serves the place with the nearest end of the range. check names it without calling the map
// damaged (it sent the user to --repair, which dropped the place).
TEST(MapToolsTest, CheckNamesATimeOutOfRangeWithoutCallingTheMapDamaged) {
  TempMap map("check_time");
  BuildSite(map.path());
  testing_storage::ExecSql(map.path(), "UPDATE places SET utime = -5 WHERE id = 2");
  StatusOr<CheckReport> report = CheckMap(map.path());
  ASSERT_TRUE(report.ok()) << report.status().ToString();
  EXPECT_TRUE(report->ok()) << report->problems[0];
  EXPECT_EQ(report->places, 5);
  ASSERT_EQ(report->notes.size(), 1u);
  EXPECT_NE(report->notes[0].find("place 2"), std::string::npos) << report->notes[0];
  EXPECT_NE(report->notes[0].find("-5"), std::string::npos) << report->notes[0];
}

// A time of 0 is a limit like any other: with --robot it drops nothing of that robot (it meant
// "no time limit", so the robot's whole history went).
TEST(MapToolsTest, PruneBeforeTimeZeroDropsNothing) {
  TempMap map("prune_zero");
  BuildSite(map.path());
  PruneOptions options;
  options.robot = "left";
  options.before_utime = 0;
  std::string error;
  ASSERT_TRUE(options.Check(&error)) << error;
  StatusOr<PruneReport> report = PruneMap(map.path(), options);
  ASSERT_TRUE(report.ok()) << report.status().ToString();
  EXPECT_EQ(report->places, 0);
  EXPECT_EQ(Places(map.path()).size(), 5u);
  PruneOptions any_robot;
  any_robot.before_utime = 0;
  EXPECT_TRUE(any_robot.Check(&error)) << error;
  EXPECT_FALSE(PruneOptions().Check(&error));
}

// merge writes a place whose capture time lies outside the range (an old build wrote such
// times; check calls the map whole, the server serves it) with the time the server uses; the
// merge was refused.
TEST(MapToolsTest, MergeWritesATimeOutOfRangeAsTheServerUsesIt) {
  TempMap a("merge_time_a");
  TempMap b("merge_time_b");
  TempMap c("merge_time_c");
  BuildSite(a.path());
  {
    std::unique_ptr<LandmarkStore> store = Open(b.path());
    AddPlace(store.get(), "night", 0, kStart, 1, {"sign"});
  }
  testing_storage::ExecSql(b.path(), "UPDATE places SET utime = -5 WHERE id = 1");
  StatusOr<MergeReport> report = MergeMaps(a.path(), b.path(), c.path(), MergeOptions());
  ASSERT_TRUE(report.ok()) << report.status().ToString();
  EXPECT_EQ(report->b.times_moved, 1);
  EXPECT_EQ(report->a.times_moved, 0);
  const std::vector<Place> places = Places(c.path());
  ASSERT_EQ(places.size(), 6u);
  EXPECT_EQ(places.back().robot, "night");
  EXPECT_EQ(places.back().utime, 0);
}

// check and merge only read: a map of an older schema stays as it is (they upgraded it in place,
// as the server does, so that a backup looked at was changed).
TEST(MapToolsTest, CheckAndMergeLeaveAnOlderMapAsItIs) {
  TempMap old_map("check_v1");
  TempMap other("check_v1_other");
  TempMap merged("check_v1_merged");
  BuildSite(old_map.path());
  {
    std::unique_ptr<LandmarkStore> store = Open(other.path());
    ASSERT_NE(store, nullptr);
    AddPlace(store.get(), "third", 0, kStart, 1, {"sign"});
  }
  testing_storage::DowngradeMapToSchemaV1(old_map.path());
  auto version = [](const std::string& path) {
    return QuerySql(path, "SELECT value FROM meta WHERE key = 'schema_version'");
  };
  ASSERT_EQ(version(old_map.path()), "1");

  StatusOr<CheckReport> report = CheckMap(old_map.path());
  ASSERT_TRUE(report.ok()) << report.status().ToString();
  EXPECT_TRUE(report->ok()) << (report->problems.empty() ? "" : report->problems[0]);
  EXPECT_EQ(report->places, 5);
  EXPECT_EQ(report->landmarks, 8);
  EXPECT_EQ(version(old_map.path()), "1");

  StatusOr<MergeReport> merge = MergeMaps(old_map.path(), other.path(), merged.path(), {});
  ASSERT_TRUE(merge.ok()) << merge.status().ToString();
  EXPECT_EQ(merge->places, 6);
  EXPECT_EQ(version(old_map.path()), "1");
  EXPECT_EQ(version(merged.path()), std::to_string(kSqliteSchemaVersion));
  // The v1 map's landmarks are unclassified in the merged map; the other map's keep their class.
  const std::vector<Landmark> landmarks = Landmarks(merged.path());
  ASSERT_EQ(landmarks.size(), 9u);
  for (size_t i = 0; i < 8; ++i) EXPECT_EQ(landmarks[i].object_class, "") << i;
  EXPECT_EQ(landmarks[8].object_class, "sign");
}

}  // namespace
}  // namespace placerec
