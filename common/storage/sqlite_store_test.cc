#include "common/storage/sqlite_store.h"

#include <gtest/gtest.h>
#include <signal.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "common/storage/sqlite_db.h"
#include "common/storage/storage_testing.h"

namespace placerec {
namespace {

using testing_storage::ExecSql;
using testing_storage::ExpectSameLandmark;
using testing_storage::QuerySql;
using testing_storage::TempMap;

bool FileExists(const std::string& path) { return std::ifstream(path).good(); }

std::unique_ptr<LandmarkStore> Open(const std::string& path,
                                    const SqliteStoreOptions& options = SqliteStoreOptions()) {
  StatusOr<std::unique_ptr<LandmarkStore>> store = OpenSqliteStore(path, options);
  EXPECT_TRUE(store.ok()) << store.status().ToString();
  return store.ok() ? std::move(store).value() : nullptr;
}

Place MakePlace(const std::string& robot, int64_t sequence) {
  Place place;
  place.robot = robot;
  place.sequence = sequence;
  place.utime = 1700000000000000 + sequence * 100000;
  place.image_width = 640 + static_cast<int>(sequence % 3);
  return place;
}

// A landmark with `num_descriptors` random descriptors; everything depends only on `seed`.
Landmark MakeLandmark(int seed, int num_descriptors) {
  cv::RNG rng(static_cast<uint64_t>(seed) + 1);
  Landmark landmark;
  landmark.sift_count = num_descriptors + seed % 5;
  if (seed % 3 == 1) landmark.colour.peaks = {0.125f + 0.01f * static_cast<float>(seed)};
  if (seed % 3 == 2) landmark.colour.peaks = {-0.4375f, 0.3f + 0.001f * static_cast<float>(seed)};
  landmark.segment_class = seed % 2 == 0 ? SegmentClass::kStructured : SegmentClass::kTree;
  landmark.box = cv::Rect(seed, 2 * seed + 1, 30 + seed, 17);
  landmark.descriptors.create(num_descriptors, 128, CV_8U);
  rng.fill(landmark.descriptors, cv::RNG::UNIFORM, 0, 256);
  for (int i = 0; i < num_descriptors; ++i) {
    landmark.keypoints.emplace_back(rng.uniform(0.f, 640.f), rng.uniform(0.f, 480.f),
                                    rng.uniform(1.f, 30.f), rng.uniform(0.f, 360.f));
  }
  return landmark;
}

std::vector<Landmark> MakeLandmarks(int first_seed, int count, int num_descriptors) {
  std::vector<Landmark> landmarks;
  landmarks.reserve(count);
  for (int i = 0; i < count; ++i) {
    landmarks.push_back(MakeLandmark(first_seed + i, num_descriptors));
  }
  return landmarks;
}

struct Contents {
  std::vector<Place> places;
  std::vector<Landmark> landmarks;
};

Contents ReadAll(const LandmarkStore& store) {
  Contents contents;
  const Status places =
      store.LoadPlaces([&contents](const Place& place) { contents.places.push_back(place); });
  EXPECT_TRUE(places.ok()) << places.ToString();
  const Status landmarks = store.LoadLandmarks(
      [&contents](Landmark&& landmark) { contents.landmarks.push_back(std::move(landmark)); });
  EXPECT_TRUE(landmarks.ok()) << landmarks.ToString();
  return contents;
}

void ExpectCounts(const LandmarkStore& store, int64_t places, int64_t landmarks,
                  int64_t descriptors) {
  StatusOr<StoreCounts> counts = store.Counts();
  ASSERT_TRUE(counts.ok()) << counts.status().ToString();
  EXPECT_EQ(counts->places, places);
  EXPECT_EQ(counts->landmarks, landmarks);
  EXPECT_EQ(counts->descriptors, descriptors);
}

uint64_t ChecksumOf(const LandmarkStore& store) {
  StatusOr<uint64_t> checksum = store.Checksum();
  EXPECT_TRUE(checksum.ok()) << checksum.status().ToString();
  return checksum.ok() ? *checksum : 0;
}

bool Contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

TEST(SqliteStoreOptionsTest, DefaultsPassAndBadValuesFail) {
  std::string error;
  EXPECT_TRUE(SqliteStoreOptions().Check(&error)) << error;
  SqliteStoreOptions bad;
  bad.busy_timeout_ms = -1;
  EXPECT_FALSE(bad.Check(&error));
  EXPECT_TRUE(Contains(error, "busy_timeout_ms"));
  StatusOr<std::unique_ptr<LandmarkStore>> store = OpenSqliteStore(":memory:", bad);
  EXPECT_EQ(store.status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(OpenSqliteStore("", SqliteStoreOptions()).status().code(),
            StatusCode::kInvalidArgument);
}

TEST(SqliteStoreTest, WritesAndReadsBackAfterReopen) {
  TempMap map("roundtrip");
  Place first = MakePlace("alpha", 10);
  Place second = MakePlace("beta", 3);
  std::vector<Landmark> first_landmarks = MakeLandmarks(0, 3, 12);
  std::vector<Landmark> second_landmarks = MakeLandmarks(10, 2, 40);
  first_landmarks[1].object_class = "building";
  first_landmarks[1].class_confidence = 0.8125f;
  second_landmarks[0].object_class = "car";
  second_landmarks[0].class_confidence = 1.0f;
  {
    std::unique_ptr<LandmarkStore> store = Open(map.path());
    ASSERT_NE(store, nullptr);
    EXPECT_EQ(store->Describe(), "sqlite:" + map.path());
    ASSERT_TRUE(store->AddPlace(&first, &first_landmarks).ok());
    ASSERT_TRUE(store->AddPlace(&second, &second_landmarks).ok());
  }
  // Ids are valid, increasing, and tie the landmarks to their place.
  EXPECT_TRUE(first.id.IsValid());
  EXPECT_LT(first.id, second.id);
  EXPECT_EQ(first.num_landmarks, 3);
  EXPECT_EQ(second.num_landmarks, 2);
  std::vector<Landmark> all = first_landmarks;
  all.insert(all.end(), second_landmarks.begin(), second_landmarks.end());
  for (size_t i = 0; i < all.size(); ++i) {
    EXPECT_TRUE(all[i].id.IsValid());
    if (i > 0) {
      EXPECT_LT(all[i - 1].id, all[i].id);
    }
    EXPECT_EQ(all[i].place, i < 3 ? first.id : second.id);
  }

  std::unique_ptr<LandmarkStore> store = Open(map.path());
  ASSERT_NE(store, nullptr);
  const Contents contents = ReadAll(*store);
  ASSERT_EQ(contents.places.size(), 2u);
  EXPECT_EQ(contents.places[0], first);
  EXPECT_EQ(contents.places[1], second);
  ASSERT_EQ(contents.landmarks.size(), 5u);
  for (size_t i = 0; i < all.size(); ++i) {
    SCOPED_TRACE(i);
    ExpectSameLandmark(all[i], contents.landmarks[i]);
  }
  ExpectCounts(*store, 2, 5, 3 * 12 + 2 * 40);
}

TEST(SqliteStoreTest, CountsAreExactAfterEachOperation) {
  std::unique_ptr<LandmarkStore> store = Open(":memory:");
  ASSERT_NE(store, nullptr);
  ExpectCounts(*store, 0, 0, 0);
  Place place = MakePlace("r", 1);
  std::vector<Landmark> landmarks = MakeLandmarks(0, 2, 9);
  ASSERT_TRUE(store->AddPlace(&place, &landmarks).ok());
  ExpectCounts(*store, 1, 2, 18);
  place = MakePlace("r", 2);
  landmarks = MakeLandmarks(5, 3, 40);
  ASSERT_TRUE(store->AddPlace(&place, &landmarks).ok());
  ExpectCounts(*store, 2, 5, 18 + 120);
  // A place without landmarks (null list) counts as a place only.
  place = MakePlace("r", 3);
  ASSERT_TRUE(store->AddPlace(&place, nullptr).ok());
  EXPECT_EQ(place.num_landmarks, 0);
  ExpectCounts(*store, 3, 5, 138);
  // Reading changes nothing.
  ReadAll(*store);
  ExpectCounts(*store, 3, 5, 138);
}

TEST(SqliteStoreTest, DuplicatePlaceIsRejectedAndChangesNothing) {
  std::unique_ptr<LandmarkStore> store = Open(":memory:");
  ASSERT_NE(store, nullptr);
  Place place = MakePlace("r", 7);
  std::vector<Landmark> landmarks = MakeLandmarks(0, 2, 10);
  ASSERT_TRUE(store->AddPlace(&place, &landmarks).ok());
  const uint64_t before = ChecksumOf(*store);

  Place again = MakePlace("r", 7);
  again.utime += 1;
  std::vector<Landmark> more = MakeLandmarks(3, 4, 10);
  const Status status = store->AddPlace(&again, &more);
  EXPECT_EQ(status.code(), StatusCode::kInvalidArgument);
  EXPECT_TRUE(Contains(status.message(), "place robot/sequence already stored"))
      << status.message();
  EXPECT_FALSE(again.id.IsValid());
  for (const Landmark& landmark : more) EXPECT_FALSE(landmark.id.IsValid());
  ExpectCounts(*store, 1, 2, 20);
  EXPECT_EQ(ChecksumOf(*store), before);

  // The same sequence from another robot is a different place.
  Place other = MakePlace("s", 7);
  EXPECT_TRUE(store->AddPlace(&other, &more).ok());
  ExpectCounts(*store, 2, 6, 60);
}

TEST(SqliteStoreTest, InvalidInputIsRejectedAndWritesNothing) {
  std::unique_ptr<LandmarkStore> store = Open(":memory:");
  ASSERT_NE(store, nullptr);
  const uint64_t empty = ChecksumOf(*store);

  const auto expect_rejected = [&](Place place, std::vector<Landmark> landmarks,
                                   const std::string& message) {
    SCOPED_TRACE(message);
    const Status status = store->AddPlace(&place, &landmarks);
    EXPECT_EQ(status.code(), StatusCode::kInvalidArgument);
    EXPECT_TRUE(Contains(status.message(), message)) << status.message();
    EXPECT_FALSE(place.id.IsValid());
    for (const Landmark& landmark : landmarks) EXPECT_FALSE(landmark.id.IsValid());
    ExpectCounts(*store, 0, 0, 0);
    EXPECT_EQ(ChecksumOf(*store), empty);
  };

  // The second landmark is the bad one, so a half-written place would show in the counts.
  std::vector<Landmark> wrong_type = MakeLandmarks(0, 2, 5);
  wrong_type[1].descriptors.convertTo(wrong_type[1].descriptors, CV_32F);
  expect_rejected(MakePlace("r", 1), wrong_type, "landmark 1: descriptors must be CV_8U");

  std::vector<Landmark> wrong_columns = MakeLandmarks(0, 2, 5);
  wrong_columns[1].descriptors = cv::Mat::zeros(5, 64, CV_8U);
  expect_rejected(MakePlace("r", 1), wrong_columns, "64 columns, expected 128");

  std::vector<Landmark> not_continuous = MakeLandmarks(0, 2, 5);
  const cv::Mat wide = cv::Mat::zeros(5, 256, CV_8U);
  not_continuous[1].descriptors = wide.colRange(0, 128);
  expect_rejected(MakePlace("r", 1), not_continuous, "not continuous");

  std::vector<Landmark> keypoint_mismatch = MakeLandmarks(0, 2, 5);
  keypoint_mismatch[1].keypoints.pop_back();
  expect_rejected(MakePlace("r", 1), keypoint_mismatch, "4 keypoints for 5 descriptors");

  std::vector<Landmark> negative_count = MakeLandmarks(0, 2, 5);
  negative_count[1].sift_count = -1;
  expect_rejected(MakePlace("r", 1), negative_count, "sift_count is negative");

  std::vector<Landmark> bad_class = MakeLandmarks(0, 2, 5);
  bad_class[1].object_class = "car'; DROP TABLE places";
  expect_rejected(MakePlace("r", 1), bad_class, "object class may hold only");
  bad_class[1].object_class = std::string(kMaxObjectClassLength + 1, 'a');
  expect_rejected(MakePlace("r", 1), bad_class, "object class is 33 bytes");
  bad_class[1].object_class = "car";
  bad_class[1].class_confidence = 1.5f;
  expect_rejected(MakePlace("r", 1), bad_class, "class confidence must be in [0, 1]");
  bad_class[1].object_class.clear();
  bad_class[1].class_confidence = 0.5f;
  expect_rejected(MakePlace("r", 1), bad_class, "and 0 without a class");

  expect_rejected(MakePlace("", 1), MakeLandmarks(0, 1, 5), "robot id is empty");
  expect_rejected(MakePlace(std::string(kMaxRobotIdLength + 1, 'x'), 1), MakeLandmarks(0, 1, 5),
                  "robot id is 65 bytes");

  EXPECT_EQ(store->AddPlace(nullptr, nullptr).code(), StatusCode::kInvalidArgument);

  // The longest allowed robot id is fine.
  Place longest = MakePlace(std::string(kMaxRobotIdLength, 'x'), 1);
  std::vector<Landmark> landmarks = MakeLandmarks(0, 1, 5);
  EXPECT_TRUE(store->AddPlace(&longest, &landmarks).ok());
  ExpectCounts(*store, 1, 1, 5);
}

// A place that saw stored landmarks again (the seed's scene sets) keeps them across a reopen; a
// sighting of a landmark the map does not hold is refused and writes nothing.
TEST(SqliteStoreTest, SightingsRoundTripAndNameStoredLandmarks) {
  TempMap map("sightings");
  Place first = MakePlace("a", 1);
  std::vector<Landmark> landmarks = MakeLandmarks(0, 3, 4);
  Place second = MakePlace("b", 1);
  {
    std::unique_ptr<LandmarkStore> store = Open(map.path());
    ASSERT_NE(store, nullptr);
    ASSERT_TRUE(store->AddPlace(&first, &landmarks).ok());
    second.seen_landmarks = {landmarks[0].id, landmarks[2].id};
    ASSERT_TRUE(store->AddPlace(&second, nullptr).ok());
    const uint64_t before = ChecksumOf(*store);

    Place missing = MakePlace("b", 2);
    missing.seen_landmarks = {LandmarkId(999)};
    const Status status = store->AddPlace(&missing, nullptr);
    EXPECT_EQ(status.code(), StatusCode::kInvalidArgument);
    EXPECT_TRUE(Contains(status.message(), "landmark 999, which is not in the map"))
        << status.message();
    Place unordered = MakePlace("b", 3);
    unordered.seen_landmarks = {landmarks[2].id, landmarks[0].id};
    EXPECT_EQ(store->AddPlace(&unordered, nullptr).code(), StatusCode::kInvalidArgument);
    EXPECT_EQ(ChecksumOf(*store), before);
    ExpectCounts(*store, 2, 3, 12);
  }
  std::unique_ptr<LandmarkStore> store = Open(map.path());
  ASSERT_NE(store, nullptr);
  const Contents contents = ReadAll(*store);
  ASSERT_EQ(contents.places.size(), 2u);
  EXPECT_EQ(contents.places[0], first);
  EXPECT_EQ(contents.places[1], second);
  EXPECT_EQ(contents.places[1].seen_landmarks,
            (std::vector<LandmarkId>{landmarks[0].id, landmarks[2].id}));
}

TEST(SqliteStoreTest, ThumbnailsRoundTripApartFromPlaces) {
  TempMap map("thumbnails");
  std::vector<uint8_t> jpeg(3000);
  for (size_t i = 0; i < jpeg.size(); ++i) jpeg[i] = static_cast<uint8_t>(i * 7);
  {
    std::unique_ptr<LandmarkStore> store = Open(map.path());
    Place with;
    with.robot = "r";
    with.sequence = 1;
    with.thumbnail = jpeg;
    ASSERT_TRUE(store->AddPlace(&with, nullptr).ok());
    Place without;
    without.robot = "r";
    without.sequence = 2;
    ASSERT_TRUE(store->AddPlace(&without, nullptr).ok());
    Place too_big;
    too_big.robot = "r";
    too_big.sequence = 3;
    too_big.thumbnail.resize(kMaxThumbnailBytes + 1);
    EXPECT_EQ(store->AddPlace(&too_big, nullptr).code(), StatusCode::kInvalidArgument);
  }
  std::unique_ptr<LandmarkStore> store = Open(map.path());
  EXPECT_EQ(*store->LoadThumbnail(PlaceId(1)), jpeg);
  EXPECT_TRUE(store->LoadThumbnail(PlaceId(2))->empty());
  EXPECT_TRUE(store->LoadThumbnail(PlaceId(99))->empty());
  std::vector<Place> places;
  ASSERT_TRUE(store->LoadPlaces([&places](const Place& place) { places.push_back(place); }).ok());
  ASSERT_EQ(places.size(), 2u);
  EXPECT_TRUE(places[0].thumbnail.empty());  // LoadPlaces leaves pictures in the store
}

TEST(SqliteStoreTest, LandmarkWithoutDescriptorsRoundTrips) {
  std::unique_ptr<LandmarkStore> store = Open(":memory:");
  ASSERT_NE(store, nullptr);
  Place place = MakePlace("r", 1);
  std::vector<Landmark> landmarks(1);
  landmarks[0].sift_count = 12;
  ASSERT_TRUE(store->AddPlace(&place, &landmarks).ok());
  const Contents contents = ReadAll(*store);
  ASSERT_EQ(contents.landmarks.size(), 1u);
  EXPECT_EQ(contents.landmarks[0].descriptors.rows, 0);
  EXPECT_EQ(contents.landmarks[0].descriptors.cols, 128);
  EXPECT_TRUE(contents.landmarks[0].keypoints.empty());
  EXPECT_TRUE(contents.landmarks[0].colour.peaks.empty());
  EXPECT_EQ(contents.landmarks[0].sift_count, 12);
  ExpectCounts(*store, 1, 1, 0);
}

TEST(SqliteStoreTest, ChecksumFollowsContent) {
  TempMap map("checksum");
  std::unique_ptr<LandmarkStore> file = Open(map.path());
  std::unique_ptr<LandmarkStore> memory = Open(":memory:");
  ASSERT_NE(file, nullptr);
  ASSERT_NE(memory, nullptr);
  EXPECT_EQ(ChecksumOf(*file), ChecksumOf(*memory));

  uint64_t previous = ChecksumOf(*file);
  for (int sequence = 0; sequence < 3; ++sequence) {
    for (LandmarkStore* store : {file.get(), memory.get()}) {
      Place place = MakePlace("r", sequence);
      std::vector<Landmark> landmarks = MakeLandmarks(sequence * 10, 2, 8);
      ASSERT_TRUE(store->AddPlace(&place, &landmarks).ok());
    }
    const uint64_t now = ChecksumOf(*file);
    EXPECT_NE(now, previous);
    EXPECT_EQ(now, ChecksumOf(*memory));
    previous = now;
  }

  // One descriptor byte more or less makes a different map.
  std::unique_ptr<LandmarkStore> changed = Open(":memory:");
  ASSERT_NE(changed, nullptr);
  for (int sequence = 0; sequence < 3; ++sequence) {
    Place place = MakePlace("r", sequence);
    std::vector<Landmark> landmarks = MakeLandmarks(sequence * 10, 2, 8);
    if (sequence == 2) landmarks[1].descriptors.at<uint8_t>(3, 7) ^= 1;
    ASSERT_TRUE(changed->AddPlace(&place, &landmarks).ok());
  }
  EXPECT_NE(ChecksumOf(*changed), previous);

  // So does a change made behind the store's back.
  file.reset();
  ExecSql(map.path(), "UPDATE places SET utime = utime + 1 WHERE id = 2");
  file = Open(map.path());
  ASSERT_NE(file, nullptr);
  EXPECT_NE(ChecksumOf(*file), previous);
}

TEST(SqliteStoreTest, NewFileHasCurrentVersionAndWalJournal) {
  TempMap map("fresh");
  ASSERT_NE(Open(map.path()), nullptr);
  EXPECT_EQ(QuerySql(map.path(), "SELECT value FROM meta WHERE key = 'schema_version'"),
            std::to_string(kSqliteSchemaVersion));
  EXPECT_EQ(QuerySql(map.path(), "PRAGMA journal_mode"), "wal");
  // Opening again neither fails nor changes the version.
  ASSERT_NE(Open(map.path()), nullptr);
  EXPECT_EQ(QuerySql(map.path(), "SELECT COUNT(*) FROM meta"), "1");
}

TEST(SqliteStoreTest, RefusesNewerSchemaVersion) {
  TempMap map("newer");
  ASSERT_NE(Open(map.path()), nullptr);
  ExecSql(map.path(), "UPDATE meta SET value = '999' WHERE key = 'schema_version'");
  StatusOr<std::unique_ptr<LandmarkStore>> store =
      OpenSqliteStore(map.path(), SqliteStoreOptions());
  ASSERT_FALSE(store.ok());
  const std::string& message = store.status().message();
  EXPECT_TRUE(Contains(message, "schema version 999")) << message;
  EXPECT_TRUE(Contains(message, "up to " + std::to_string(kSqliteSchemaVersion))) << message;
  EXPECT_TRUE(Contains(message, "upgrade placerec")) << message;
  // The file is left as it was.
  EXPECT_EQ(QuerySql(map.path(), "SELECT value FROM meta WHERE key = 'schema_version'"), "999");
}

TEST(SqliteStoreTest, RefusesFilesThatAreNotPlacerecMaps) {
  TempMap random_bytes("random");
  {
    std::mt19937 rng(7);
    std::ofstream out(random_bytes.path(), std::ios::binary);
    for (int i = 0; i < 8192; ++i) out.put(static_cast<char>(rng() & 0xff));
  }
  StatusOr<std::unique_ptr<LandmarkStore>> store =
      OpenSqliteStore(random_bytes.path(), SqliteStoreOptions());
  ASSERT_FALSE(store.ok());
  EXPECT_EQ(store.status().code(), StatusCode::kIoError);
  EXPECT_TRUE(Contains(store.status().message(), "not a SQLite database"))
      << store.status().message();

  TempMap foreign("foreign");
  ExecSql(foreign.path(), "CREATE TABLE things(id INTEGER PRIMARY KEY, name TEXT)");
  store = OpenSqliteStore(foreign.path(), SqliteStoreOptions());
  ASSERT_FALSE(store.ok());
  EXPECT_TRUE(Contains(store.status().message(), "not a placerec map")) << store.status().message();
  // Still only the foreign table: nothing was created in it.
  EXPECT_EQ(QuerySql(foreign.path(), "SELECT COUNT(*) FROM sqlite_master"), "1");

  TempMap no_version("no_version");
  ExecSql(no_version.path(), "CREATE TABLE meta(key TEXT PRIMARY KEY, value TEXT)");
  store = OpenSqliteStore(no_version.path(), SqliteStoreOptions());
  ASSERT_FALSE(store.ok());
  EXPECT_TRUE(Contains(store.status().message(), "no schema_version")) << store.status().message();
}

TEST(SqliteStoreTest, MustExist) {
  TempMap map("must_exist");
  SqliteStoreOptions options;
  options.must_exist = true;
  StatusOr<std::unique_ptr<LandmarkStore>> store = OpenSqliteStore(map.path(), options);
  ASSERT_FALSE(store.ok());
  EXPECT_EQ(store.status().code(), StatusCode::kNotFound);
  EXPECT_FALSE(FileExists(map.path()));
  EXPECT_FALSE(OpenSqliteStore(":memory:", options).ok());

  ASSERT_NE(Open(map.path()), nullptr);  // creates it
  EXPECT_NE(Open(map.path(), options), nullptr);
}

TEST(SqliteStoreTest, DataSurvivesDestroyWithoutClose) {
  TempMap map("destroy");
  Place place = MakePlace("r", 1);
  std::vector<Landmark> landmarks = MakeLandmarks(0, 3, 20);
  std::unique_ptr<LandmarkStore> store = Open(map.path());
  ASSERT_NE(store, nullptr);
  ASSERT_TRUE(store->AddPlace(&place, &landmarks).ok());
  const uint64_t checksum = ChecksumOf(*store);
  store.reset();

  store = Open(map.path());
  ASSERT_NE(store, nullptr);
  ExpectCounts(*store, 1, 3, 60);
  EXPECT_EQ(ChecksumOf(*store), checksum);
}

// "A killed server loses no acknowledged landmark": a child process adds a place, acknowledges it
// through a pipe and is killed with SIGKILL while the map is still open (no destructor runs).
TEST(SqliteStoreTest, DataSurvivesKilledProcess) {
  TempMap map("killed");
  int ack[2];
  ASSERT_EQ(pipe(ack), 0);
  const pid_t child = fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    close(ack[0]);
    StatusOr<std::unique_ptr<LandmarkStore>> store =
        OpenSqliteStore(map.path(), SqliteStoreOptions());
    char reply = '0';
    if (store.ok()) {
      Place place = MakePlace("r", 1);
      std::vector<Landmark> landmarks = MakeLandmarks(0, 4, 25);
      if ((*store)->AddPlace(&place, &landmarks).ok()) reply = '1';
    }
    if (write(ack[1], &reply, 1) != 1) _exit(2);
    for (;;) pause();
  }
  close(ack[1]);
  char reply = 0;
  ASSERT_EQ(read(ack[0], &reply, 1), 1);
  close(ack[0]);
  kill(child, SIGKILL);
  int wait_status = 0;
  ASSERT_EQ(waitpid(child, &wait_status, 0), child);
  EXPECT_TRUE(WIFSIGNALED(wait_status));
  ASSERT_EQ(reply, '1');

  std::unique_ptr<LandmarkStore> store = Open(map.path());
  ASSERT_NE(store, nullptr);
  ExpectCounts(*store, 1, 4, 100);
  const Contents contents = ReadAll(*store);
  const std::vector<Landmark> expected = MakeLandmarks(0, 4, 25);
  ASSERT_EQ(contents.landmarks.size(), 4u);
  for (size_t i = 0; i < expected.size(); ++i) {
    EXPECT_EQ(cv::countNonZero(contents.landmarks[i].descriptors != expected[i].descriptors), 0);
  }
}

std::string Repeat(const std::string& text, int times) {
  std::string repeated;
  for (int i = 0; i < times; ++i) repeated += text;
  return repeated;
}

// Writes one place of robot "r" with three landmarks (ids 1-3, six descriptors each) to `path`.
void WriteOnePlace(const std::string& path) {
  std::unique_ptr<LandmarkStore> store = Open(path);
  ASSERT_NE(store, nullptr);
  Place place = MakePlace("r", 1);
  std::vector<Landmark> landmarks = MakeLandmarks(0, 3, 6);
  ASSERT_TRUE(store->AddPlace(&place, &landmarks).ok());
  ASSERT_EQ(landmarks[1].id.value(), 2);
}

TEST(SqliteStoreTest, DamagedLandmarkIsAnIoErrorNamingIt) {
  TempMap map("damaged");
  WriteOnePlace(map.path());
  const std::string kDamage[] = {
      "UPDATE landmarks SET descriptors = zeroblob(10) WHERE id = 2",
      "UPDATE landmarks SET keypoints = zeroblob(3) WHERE id = 2",
      "UPDATE landmarks SET colour_peaks = zeroblob(5) WHERE id = 2",
      "UPDATE landmarks SET segment_class = 99 WHERE id = 2",
      "UPDATE landmarks SET num_descriptors = NULL WHERE id = 2",
      "UPDATE landmarks SET object_class = 'no spaces' WHERE id = 2",
      "UPDATE landmarks SET object_class = X'00' WHERE id = 2",
      "UPDATE landmarks SET object_class = 'car', class_confidence = 2 WHERE id = 2",
      "UPDATE landmarks SET class_confidence = 'sure' WHERE id = 2",
      // A NaN keypoint angle indexed outside the orientation histogram of matching.
      "UPDATE landmarks SET keypoints = x'" + Repeat("0000c07f", 24) + "' WHERE id = 2",
  };
  for (const std::string& damage : kDamage) {
    SCOPED_TRACE(damage);
    TempMap copy("damaged_copy");
    {
      std::ifstream in(map.path(), std::ios::binary);
      std::ofstream out(copy.path(), std::ios::binary);
      out << in.rdbuf();
    }
    ExecSql(copy.path(), damage.c_str());
    std::unique_ptr<LandmarkStore> store = Open(copy.path());
    ASSERT_NE(store, nullptr);
    int visited = 0;
    const Status status = store->LoadLandmarks([&visited](Landmark&&) { ++visited; });
    EXPECT_EQ(status.code(), StatusCode::kIoError);
    EXPECT_TRUE(Contains(status.message(), "landmark 2 is corrupt")) << status.message();
    EXPECT_EQ(visited, 1);  // the landmark before the damaged one
    EXPECT_EQ(store->Checksum().status().code(), StatusCode::kIoError);
  }
}

std::string ReadFileBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

void CopyFile(const std::string& from, const std::string& to) {
  std::ifstream in(from, std::ios::binary);
  std::ofstream out(to, std::ios::binary);
  out << in.rdbuf();
}

// A map whose rows carry an id below 1 (no build writes one) was served until the index met it,
// which aborted the server on a CHECK. Now the store refuses the row as damage.
TEST(SqliteStoreTest, IdsBelowOneAreDamage) {
  TempMap map("negative_ids");
  WriteOnePlace(map.path());
  {
    TempMap copy("negative_landmark");
    CopyFile(map.path(), copy.path());
    ExecSql(copy.path(), "UPDATE landmarks SET id = -7 WHERE id = 2");
    std::unique_ptr<LandmarkStore> store = Open(copy.path());
    ASSERT_NE(store, nullptr);
    const Status status = store->LoadLandmarks([](Landmark&&) {});
    EXPECT_EQ(status.code(), StatusCode::kIoError);
    EXPECT_TRUE(Contains(status.message(), "landmark -7 is corrupt")) << status.message();
  }
  {
    TempMap copy("negative_place");
    CopyFile(map.path(), copy.path());
    ExecSql(copy.path(),
            "INSERT INTO places(id, robot, sequence, utime, num_landmarks, image_width) "
            "VALUES(-3, 'x', 9, 0, 0, 640)");
    std::unique_ptr<LandmarkStore> store = Open(copy.path());
    ASSERT_NE(store, nullptr);
    const Status status = store->LoadPlaces([](const Place&) {});
    EXPECT_EQ(status.code(), StatusCode::kIoError);
    EXPECT_TRUE(Contains(status.message(), "place -3 is corrupt")) << status.message();
  }
}

// A small stand-in for place p's thumbnail.
std::vector<uint8_t> PictureOf(int p) {
  std::vector<uint8_t> bytes(200 + p);
  for (size_t i = 0; i < bytes.size(); ++i) bytes[i] = static_cast<uint8_t>(p * 31 + i);
  return bytes;
}

// Issue 23 item 6: 4 KB of random bytes in a page of the map; the store opened it and served
// what it could read. Now opening refuses it, saying what to do, and RepairSqliteMap keeps
// exactly the places that read back whole.
TEST(SqliteStoreTest, RandomBytesInAPageAreRefusedAtOpenAndRepairDropsTheDamagedPlaces) {
  constexpr int kPlaces = 12;
  constexpr int kLandmarksPerPlace = 2;
  TempMap map("page");
  {
    std::unique_ptr<LandmarkStore> store = Open(map.path());
    ASSERT_NE(store, nullptr);
    for (int p = 0; p < kPlaces; ++p) {
      Place place = MakePlace("r", p);
      place.thumbnail = PictureOf(p);
      std::vector<Landmark> landmarks = MakeLandmarks(10 * p, kLandmarksPerPlace, 60);
      ASSERT_TRUE(store->AddPlace(&place, &landmarks).ok());
    }
  }  // closed: checkpointed into the one file
  TempMap copy("page_copy");
  CopyFile(map.path(), copy.path());
  std::string bytes = ReadFileBytes(copy.path());
  constexpr size_t kPage = 4096;
  ASSERT_EQ(bytes.size() % kPage, 0u);
  const size_t pages = bytes.size() / kPage;
  ASSERT_GT(pages, 20u);
  std::mt19937 random(7);
  const size_t damaged_page = pages * 2 / 3;
  for (size_t i = 0; i < kPage; ++i) bytes[damaged_page * kPage + i] = static_cast<char>(random());
  {
    std::ofstream out(copy.path(), std::ios::binary | std::ios::trunc);
    out << bytes;
  }

  StatusOr<std::unique_ptr<LandmarkStore>> refused = OpenSqliteStore(copy.path(), {});
  ASSERT_FALSE(refused.ok()) << "a damaged map was opened";
  EXPECT_EQ(refused.status().code(), StatusCode::kIoError);
  EXPECT_TRUE(Contains(refused.status().message(), "is damaged (SQLite quick_check: "))
      << refused.status().message();
  EXPECT_TRUE(Contains(refused.status().message(), "restore the map from a backup"));
  EXPECT_TRUE(Contains(refused.status().message(), "--repair"));
  EXPECT_EQ(ReadFileBytes(copy.path()), bytes);  // the refusal changed nothing

  StatusOr<MapRepairReport> report = RepairSqliteMap(copy.path(), {});
  ASSERT_TRUE(report.ok()) << report.status().ToString();
  EXPECT_TRUE(report->rewritten);
  EXPECT_FALSE(report->problems.empty());
  EXPECT_GT(report->places_dropped, 0) << report->problems;
  EXPECT_LT(report->places_dropped, kPlaces);
  EXPECT_EQ(report->places_kept + report->places_dropped, kPlaces);
  EXPECT_EQ(report->landmarks_kept, report->places_kept * kLandmarksPerPlace);
  EXPECT_EQ(report->damaged_copy, copy.path() + ".damaged");
  EXPECT_EQ(ReadFileBytes(report->damaged_copy), bytes);
  for (const char* suffix : {"", "-wal", "-shm"}) {
    std::remove((report->damaged_copy + suffix).c_str());
  }

  // The repaired map opens, passes the check, and holds the kept places exactly.
  EXPECT_EQ(QuerySql(copy.path(), "PRAGMA integrity_check"), "ok");
  std::unique_ptr<LandmarkStore> repaired = Open(copy.path());
  ASSERT_NE(repaired, nullptr);
  const Contents contents = ReadAll(*repaired);
  ASSERT_EQ(static_cast<int64_t>(contents.places.size()), report->places_kept);
  ASSERT_EQ(contents.landmarks.size(), contents.places.size() * kLandmarksPerPlace);
  int64_t pictures_kept = 0;
  for (size_t i = 0; i < contents.places.size(); ++i) {
    const Place& place = contents.places[i];
    EXPECT_EQ(place.robot, "r");
    const int p = static_cast<int>(place.sequence);
    EXPECT_EQ(place.utime, MakePlace("r", p).utime);
    std::vector<Landmark> expected = MakeLandmarks(10 * p, kLandmarksPerPlace, 60);
    for (int k = 0; k < kLandmarksPerPlace; ++k) {
      Landmark& e = expected[k];
      const Landmark& actual = contents.landmarks[i * kLandmarksPerPlace + k];
      e.id = actual.id;
      e.place = place.id;
      testing_storage::ExpectSameLandmark(e, actual);
    }
    // A kept place keeps its picture, unless the damage took that picture's row.
    const std::vector<uint8_t> picture = *repaired->LoadThumbnail(place.id);
    if (!picture.empty()) {
      EXPECT_EQ(picture, PictureOf(p)) << "place " << p;
      ++pictures_kept;
    }
  }
  EXPECT_GE(pictures_kept, report->places_kept - 1) << "the repair dropped the places' pictures";
  repaired.reset();

  // A whole map is left alone.
  for (const std::string& whole : {copy.path(), map.path()}) {
    const std::string before = ReadFileBytes(whole);
    StatusOr<MapRepairReport> again = RepairSqliteMap(whole, {});
    ASSERT_TRUE(again.ok()) << again.status().ToString();
    EXPECT_FALSE(again->rewritten);
    EXPECT_EQ(again->places_dropped, 0);
    EXPECT_TRUE(again->problems.empty()) << again->problems;
    EXPECT_EQ(ReadFileBytes(whole), before);
  }
  EXPECT_EQ(RepairSqliteMap(copy.path() + ".missing", {}).status().code(), StatusCode::kNotFound);
}

// Writes a map at `path`: robot "r", places 0-2 with MakeLandmarks(10 * p, 2, 6).
void WriteMapOfThreePlaces(const std::string& path) {
  std::unique_ptr<LandmarkStore> store = Open(path);
  ASSERT_NE(store, nullptr);
  for (int p = 0; p < 3; ++p) {
    Place place = MakePlace("r", p);
    std::vector<Landmark> landmarks = MakeLandmarks(10 * p, 2, 6);
    ASSERT_TRUE(store->AddPlace(&place, &landmarks).ok());
  }
}

// A map held open by a child process as a server holds it (OpenSqliteStore), which stores one
// more place on request; stopped (killed) by Stop or at the end.
class ServerProcess {
 public:
  explicit ServerProcess(const std::string& path) {
    if (pipe(ask_) != 0 || pipe(reply_) != 0) return;
    pid_ = fork();
    if (pid_ == 0) Serve(path);
    close(ask_[0]);
    close(reply_[1]);
    char reply = 0;
    opened_ = read(reply_[0], &reply, 1) == 1 && reply == '1';
  }
  ~ServerProcess() { Stop(); }

  bool opened() const { return opened_; }

  // Whether the child stored place `sequence` of robot "r" (two landmarks).
  bool AddPlace(int sequence) {
    const char ask = static_cast<char>(sequence);
    char reply = 0;
    return write(ask_[1], &ask, 1) == 1 && read(reply_[0], &reply, 1) == 1 && reply == '1';
  }

  // Kills the child at once, as a killed server.
  void Stop() {
    if (pid_ <= 0) return;
    kill(pid_, SIGKILL);
    int status = 0;
    waitpid(pid_, &status, 0);
    close(ask_[1]);
    close(reply_[0]);
    pid_ = -1;
  }

 private:
  [[noreturn]] void Serve(const std::string& path) {
    close(ask_[1]);
    close(reply_[0]);
    StatusOr<std::unique_ptr<LandmarkStore>> store = OpenSqliteStore(path, SqliteStoreOptions());
    char reply = store.ok() ? '1' : '0';
    if (write(reply_[1], &reply, 1) != 1) _exit(2);
    char ask = 0;
    while (read(ask_[0], &ask, 1) == 1) {
      Place place = MakePlace("r", ask);
      std::vector<Landmark> landmarks = MakeLandmarks(10 * ask, 2, 6);
      reply = store.ok() && (*store)->AddPlace(&place, &landmarks).ok() ? '1' : '0';
      if (write(reply_[1], &reply, 1) != 1) _exit(2);
    }
    _exit(0);
  }

  int ask_[2] = {-1, -1};
  int reply_[2] = {-1, -1};
  pid_t pid_ = -1;
  bool opened_ = false;
};

// A map reopened by one process (a server) while a tool in another process opens and closes a
// connection of its own (placerec-map index, prune --dry-run): the server's commits after that
// survive a kill. The store used to read the file ahead through a descriptor of its own after
// its connection took its lock on the map; closing that descriptor dropped the lock, so the tool's
// connection took itself for the last one and deleted the -wal the server went on committing to.
TEST(SqliteStoreTest, AnotherProcessClosingItsConnectionLeavesAnOpenMapsCommitsAlone) {
  TempMap map("held");
  WriteMapOfThreePlaces(map.path());
  ServerProcess server(map.path());
  ASSERT_TRUE(server.opened());
  ExecSql(map.path(), "SELECT COUNT(*) FROM places");  // a tool's connection, opened and closed
  EXPECT_TRUE(FileExists(map.path() + "-wal")) << "the open map's -wal was deleted";
  ASSERT_TRUE(server.AddPlace(3));
  server.Stop();

  std::unique_ptr<LandmarkStore> store = Open(map.path());
  ASSERT_NE(store, nullptr);
  ExpectCounts(*store, 4, 8, 48);
}

// A map held open by a server in another process: SqliteOpenElsewhere sees it under its own name
// and through a symbolic link (SQLite follows the link; prune through a link used to change a
// map under its server), and repair, which moves the map's files, refuses it.
TEST(SqliteStoreTest, AMapHeldByAnotherProcessIsSeenThroughALinkAndNotRepaired) {
  TempMap map("held_repair");
  WriteMapOfThreePlaces(map.path());
  const std::string link = map.path() + ".link";
  std::filesystem::remove(link);
  std::filesystem::create_symlink(map.path(), link);
  ServerProcess server(map.path());
  ASSERT_TRUE(server.opened());
  const StatusOr<bool> direct = SqliteOpenElsewhere(map.path());
  const StatusOr<bool> linked = SqliteOpenElsewhere(link);
  // A whole map held open (by a server, a gateway reading pictures) needs no repair: left alone.
  const StatusOr<MapRepairReport> whole = RepairSqliteMap(map.path(), SqliteStoreOptions());
  // A damaged one would be rewritten under its holder: refused.
  ExecSql(map.path(), "UPDATE landmarks SET segment_class = 999 WHERE id = 1");
  const StatusOr<MapRepairReport> repaired = RepairSqliteMap(map.path(), SqliteStoreOptions());
  server.Stop();
  ASSERT_TRUE(direct.ok()) << direct.status().ToString();
  ASSERT_TRUE(linked.ok()) << linked.status().ToString();
  EXPECT_TRUE(*direct);
  EXPECT_TRUE(*linked);
  ASSERT_TRUE(whole.ok()) << whole.status().ToString();
  EXPECT_FALSE(whole->rewritten);
  ASSERT_FALSE(repaired.ok());
  EXPECT_TRUE(Contains(repaired.status().message(), "open in another process"))
      << repaired.status().ToString();
  // Closed by its server: not held, and the repair drops the damaged place.
  EXPECT_FALSE(*SqliteOpenElsewhere(link));
  const StatusOr<MapRepairReport> rewritten = RepairSqliteMap(map.path(), SqliteStoreOptions());
  ASSERT_TRUE(rewritten.ok()) << rewritten.status().ToString();
  EXPECT_TRUE(rewritten->rewritten);
  EXPECT_EQ(rewritten->places_kept, 2);
  std::filesystem::remove(link);
  for (const char* suffix : {"", "-wal", "-shm"}) {
    std::filesystem::remove(map.path() + ".damaged" + suffix);
  }
}

// The same as a map of schema v1.
void WriteV1MapOfThreePlaces(const std::string& path) {
  WriteMapOfThreePlaces(path);
  testing_storage::DowngradeMapToSchemaV1(path);
}

// Expects the landmarks WriteMapOfThreePlaces gave its third place (MakeLandmarks(20, 2, 6)) as
// those of contents.places[place] from contents.landmarks[first] on.
void ExpectThirdPlacesLandmarks(const Contents& contents, size_t place, size_t first) {
  ASSERT_LT(place, contents.places.size());
  ASSERT_LE(first + 2, contents.landmarks.size());
  std::vector<Landmark> expected = MakeLandmarks(20, 2, 6);
  for (size_t k = 0; k < 2; ++k) {
    expected[k].id = contents.landmarks[first + k].id;
    expected[k].place = contents.places[place].id;
    ExpectSameLandmark(expected[k], contents.landmarks[first + k]);
  }
}

// Repairs the map at `path`, which is whole: nothing dropped, `places` and `landmarks` kept, the
// file untouched.
void ExpectRepairLeavesTheMapAlone(const std::string& path, int64_t places, int64_t landmarks) {
  const std::string before = ReadFileBytes(path);
  StatusOr<MapRepairReport> report = RepairSqliteMap(path, {});
  ASSERT_TRUE(report.ok()) << report.status().ToString();
  EXPECT_FALSE(report->rewritten) << report->problems;
  EXPECT_EQ(report->places_dropped, 0) << report->problems;
  EXPECT_EQ(report->places_kept, places);
  EXPECT_EQ(report->landmarks_kept, landmarks);
  EXPECT_TRUE(ReadFileBytes(path) == before) << "the whole map was changed";
}

// Damages the landmarks of place `place_id` and repairs the map at `path`: rewritten without
// that place, `kept` places kept. The report, its damaged copy removed; empty notes and problems
// when the repair failed (the test has failed then).
MapRepairReport RepairWithAPlaceDamaged(const std::string& path, int64_t place_id, int64_t kept) {
  ExecSql(path,
          ("UPDATE landmarks SET keypoints = x'00' WHERE place_id = " + std::to_string(place_id))
              .c_str());
  StatusOr<MapRepairReport> report = RepairSqliteMap(path, {});
  EXPECT_TRUE(report.ok()) << report.status().ToString();
  if (!report.ok()) return MapRepairReport();
  EXPECT_TRUE(report->rewritten);
  EXPECT_EQ(report->places_dropped, 1);
  EXPECT_EQ(report->places_kept, kept);
  for (const char* suffix : {"", "-wal", "-shm"}) {
    std::remove((report->damaged_copy + suffix).c_str());
  }
  return *report;
}

// A map of schema v1 (written before object classes, sightings and thumbnails) that a server
// is asked to repair: the repair reads it as it is, keeps every place and leaves the whole map
// alone (it read the v1 map with v2's columns, found every place unreadable and rewrote it empty).
TEST(SqliteStoreTest, RepairReadsAnOlderMapAndKeepsItsPlaces) {
  TempMap map("repair_v1");
  WriteV1MapOfThreePlaces(map.path());
  ASSERT_EQ(QuerySql(map.path(), "SELECT value FROM meta WHERE key = 'schema_version'"), "1");
  ExpectRepairLeavesTheMapAlone(map.path(), 3, 6);
  // A damaged v1 map: the readable places are written to a map of the current schema.
  RepairWithAPlaceDamaged(map.path(), 2, 2);
  EXPECT_EQ(QuerySql(map.path(), "SELECT value FROM meta WHERE key = 'schema_version'"),
            std::to_string(kSqliteSchemaVersion));
  std::unique_ptr<LandmarkStore> store = Open(map.path());
  ASSERT_NE(store, nullptr);
  const Contents contents = ReadAll(*store);
  ASSERT_EQ(contents.places.size(), 2u);
  ASSERT_EQ(contents.landmarks.size(), 4u);
  ExpectThirdPlacesLandmarks(contents, 1, 2);
}

// A store opened read-only reads a map of an older schema as it is (the inspection tools' way):
// places and landmarks come back, nothing can be added, and the file is not changed (not
// upgraded, no journal mode set).
TEST(SqliteStoreTest, ReadOnlyStoreReadsAnOlderMapAndChangesNothing) {
  TempMap map("read_only_v1");
  WriteV1MapOfThreePlaces(map.path());
  const std::string before = ReadFileBytes(map.path());
  {
    SqliteStoreOptions options;
    options.read_only = true;
    StatusOr<std::unique_ptr<LandmarkStore>> store = OpenSqliteStore(map.path(), options);
    ASSERT_TRUE(store.ok()) << store.status().ToString();
    const Contents contents = ReadAll(**store);
    ASSERT_EQ(contents.places.size(), 3u);
    ASSERT_EQ(contents.landmarks.size(), 6u);
    ExpectThirdPlacesLandmarks(contents, 2, 4);
    StatusOr<std::vector<uint8_t>> thumbnail = (*store)->LoadThumbnail(contents.places[0].id);
    ASSERT_TRUE(thumbnail.ok()) << thumbnail.status().ToString();
    EXPECT_TRUE(thumbnail->empty());
    StatusOr<StoreCounts> counts = (*store)->Counts();
    ASSERT_TRUE(counts.ok());
    EXPECT_EQ(counts->places, 3);
    EXPECT_TRUE((*store)->Checksum().ok());
    Place place = MakePlace("r", 9);
    std::vector<Landmark> landmarks = MakeLandmarks(90, 1, 6);
    const Status added = (*store)->AddPlace(&place, &landmarks);
    EXPECT_FALSE(added.ok());
    EXPECT_NE(added.message().find("reading only"), std::string::npos) << added.ToString();
  }
  EXPECT_TRUE(ReadFileBytes(map.path()) == before) << "the map was changed";
  EXPECT_EQ(QuerySql(map.path(), "SELECT value FROM meta WHERE key = 'schema_version'"), "1");

  // A server upgrading the map while the read-only store is open (the gateway beside it): the
  // store reads the new version, and a place stored since has its thumbnail.
  SqliteStoreOptions read_only;
  read_only.read_only = true;
  StatusOr<std::unique_ptr<LandmarkStore>> reader = OpenSqliteStore(map.path(), read_only);
  ASSERT_TRUE(reader.ok()) << reader.status().ToString();
  {
    std::unique_ptr<LandmarkStore> server = Open(map.path());  // upgrades to the current schema
    ASSERT_NE(server, nullptr);
    Place place = MakePlace("r", 9);
    place.thumbnail = {0xff, 0xd8, 0xff, 0xd9};
    std::vector<Landmark> landmarks = MakeLandmarks(90, 1, 6);
    ASSERT_TRUE(server->AddPlace(&place, &landmarks).ok());
    StatusOr<std::vector<uint8_t>> seen = (*reader)->LoadThumbnail(place.id);
    ASSERT_TRUE(seen.ok()) << seen.status().ToString();
    EXPECT_EQ(*seen, place.thumbnail);
  }
  reader->reset();
  // What is not there is not created.
  SqliteStoreOptions options;
  options.read_only = true;
  EXPECT_EQ(OpenSqliteStore(map.path() + ".missing", options).status().code(),
            StatusCode::kNotFound);
  std::error_code ignored;
  EXPECT_FALSE(std::filesystem::exists(map.path() + ".missing", ignored));
}

// A place whose capture time lies outside 0 .. kMaxUtime (an old build wrote such times) is
// served by the server (its time used as the nearest end of the range), so a repair keeps it: a
// whole map stays untouched, and a map rewritten for other damage keeps the place with the time
// the server uses. (The repair counted it as damaged: it rewrote a whole map and dropped it.)
TEST(SqliteStoreTest, RepairKeepsAPlaceWhoseTimeIsOutOfRange) {
  TempMap map("repair_time");
  WriteMapOfThreePlaces(map.path());
  ExecSql(map.path(), "UPDATE places SET utime = -5 WHERE id = 1");
  ExpectRepairLeavesTheMapAlone(map.path(), 3, 6);

  // Damage elsewhere: the rewrite keeps the place, at the time the server used for it.
  const MapRepairReport report = RepairWithAPlaceDamaged(map.path(), 3, 2);
  EXPECT_NE(report.notes.find("place 1: capture time -5 us"), std::string::npos) << report.notes;
  std::unique_ptr<LandmarkStore> store = Open(map.path());
  ASSERT_NE(store, nullptr);
  const Contents contents = ReadAll(*store);
  ASSERT_EQ(contents.places.size(), 2u);
  EXPECT_EQ(contents.places[0].sequence, 0);
  EXPECT_EQ(contents.places[0].utime, 0);
  EXPECT_EQ(contents.places[1].sequence, 1);
}

// A repair that rewrites the map keeps the sightings (the places that saw a stored landmark
// again, seed §5.7 step 5) of the places it keeps, under the landmarks' new ids; a sighting of a
// dropped place's landmark goes with it. (It wrote every place without its sightings.)
TEST(SqliteStoreTest, RepairKeepsTheSightingsOfTheKeptPlaces) {
  TempMap map("repair_sightings");
  {
    std::unique_ptr<LandmarkStore> store = Open(map.path());
    ASSERT_NE(store, nullptr);
    std::vector<std::vector<Landmark>> stored;
    for (int p = 0; p < 4; ++p) {
      Place place = MakePlace("r", p);
      if (p == 2) place.seen_landmarks = {stored[0][1].id, stored[1][0].id};
      if (p == 3) place.seen_landmarks = {stored[0][0].id, stored[2][1].id};
      std::vector<Landmark> landmarks = MakeLandmarks(10 * p, 2, 6);
      ASSERT_TRUE(store->AddPlace(&place, &landmarks).ok());
      stored.push_back(landmarks);
    }
  }
  // Place 2 (the second) gets a landmark whose keypoints no longer fit its descriptors, and
  // place 4 a sighting that names no landmark: text the key takes beside the integer 1.
  ExecSql(map.path(),
          "UPDATE landmarks SET keypoints = x'00' WHERE place_id = 2; "
          "INSERT INTO sightings(place_id, landmark_id) VALUES(4, '1abc')");
  StatusOr<MapRepairReport> report = RepairSqliteMap(map.path(), {});
  ASSERT_TRUE(report.ok()) << report.status().ToString();
  ASSERT_TRUE(report->rewritten);
  EXPECT_EQ(report->places_dropped, 1);
  EXPECT_EQ(report->places_kept, 3);
  for (const char* suffix : {"", "-wal", "-shm"}) {
    std::remove((report->damaged_copy + suffix).c_str());
  }
  std::unique_ptr<LandmarkStore> store = Open(map.path());
  ASSERT_NE(store, nullptr);
  const Contents contents = ReadAll(*store);
  ASSERT_EQ(contents.places.size(), 3u);
  ASSERT_EQ(contents.landmarks.size(), 6u);
  // Kept: the places of sequence 0, 2 and 3, now ids 1, 2, 3 with landmarks 1-2, 3-4, 5-6.
  EXPECT_EQ(contents.places[1].sequence, 2);
  EXPECT_EQ(contents.places[1].seen_landmarks, std::vector<LandmarkId>{LandmarkId(2)});
  EXPECT_EQ(contents.places[2].sequence, 3);
  EXPECT_EQ(contents.places[2].seen_landmarks,
            (std::vector<LandmarkId>{LandmarkId(1), LandmarkId(4)}));
}

// Issue 23 item 8: a read-only map was opened, and every insert failed later (status 7). Now
// opening refuses it. Root may write any file, so as root the store is opened in a child process
// that has given up root for user nobody (65534); the file is made read-only (0444) as well.
TEST(SqliteStoreTest, ReadOnlyMapIsRefusedAtOpen) {
  TempMap map("readonly");
  {
    std::unique_ptr<LandmarkStore> store = Open(map.path());
    ASSERT_NE(store, nullptr);
    Place place = MakePlace("r", 1);
    std::vector<Landmark> landmarks = MakeLandmarks(0, 2, 6);
    ASSERT_TRUE(store->AddPlace(&place, &landmarks).ok());
  }
  ASSERT_EQ(chmod(map.path().c_str(), 0444), 0);
  const std::string before = ReadFileBytes(map.path());
  int pipe_fds[2];
  ASSERT_EQ(pipe(pipe_fds), 0);
  const pid_t child = fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    close(pipe_fds[0]);
    if (getuid() == 0 && (setgid(65534) != 0 || setuid(65534) != 0)) _exit(3);
    StatusOr<std::unique_ptr<LandmarkStore>> store = OpenSqliteStore(map.path(), {});
    const std::string said = store.ok() ? "opened" : store.status().ToString();
    const ssize_t written = write(pipe_fds[1], said.data(), said.size());
    _exit(written == static_cast<ssize_t>(said.size()) ? 0 : 4);
  }
  close(pipe_fds[1]);
  std::string said;
  char buffer[512];
  ssize_t n = 0;
  while ((n = read(pipe_fds[0], buffer, sizeof(buffer))) > 0) said.append(buffer, n);
  close(pipe_fds[0]);
  int status = 0;
  ASSERT_EQ(waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFEXITED(status));
  ASSERT_EQ(WEXITSTATUS(status), 0) << "the child could not give up root or report";
  EXPECT_TRUE(Contains(said, "cannot be written")) << said;
  EXPECT_TRUE(Contains(said, map.path())) << said;
  EXPECT_EQ(ReadFileBytes(map.path()), before);
  chmod(map.path().c_str(), 0644);
}

TEST(SqliteStoreTest, InMemoryStoresAreSeparate) {
  std::unique_ptr<LandmarkStore> a = Open(":memory:");
  std::unique_ptr<LandmarkStore> b = Open(":memory:");
  ASSERT_NE(a, nullptr);
  ASSERT_NE(b, nullptr);
  EXPECT_EQ(a->Describe(), "sqlite::memory:");
  Place place = MakePlace("r", 1);
  std::vector<Landmark> landmarks = MakeLandmarks(0, 1, 3);
  ASSERT_TRUE(a->AddPlace(&place, &landmarks).ok());
  ExpectCounts(*a, 1, 1, 3);
  ExpectCounts(*b, 0, 0, 0);
}

// The server's status thread reads counts while a worker writes.
TEST(SqliteStoreTest, CountsFromAnotherThreadWhileWriting) {
  TempMap map("threads");
  SqliteStoreOptions options;
  options.synchronous_full = false;
  std::unique_ptr<LandmarkStore> store = Open(map.path(), options);
  ASSERT_NE(store, nullptr);
  constexpr int64_t kPlaces = 40;
  std::atomic<bool> writer_ok{true};
  std::thread writer([&] {
    for (int i = 0; i < kPlaces; ++i) {
      Place place = MakePlace("r", i);
      std::vector<Landmark> landmarks = MakeLandmarks(i, 2, 4);
      if (!store->AddPlace(&place, &landmarks).ok()) writer_ok = false;
    }
  });
  int64_t last_places = 0;
  for (int i = 0; i < 200; ++i) {
    StatusOr<StoreCounts> counts = store->Counts();
    ASSERT_TRUE(counts.ok()) << counts.status().ToString();
    // Each place is committed whole: always 2 landmarks and 8 descriptors per place.
    EXPECT_EQ(counts->landmarks, 2 * counts->places);
    EXPECT_EQ(counts->descriptors, 8 * counts->places);
    EXPECT_GE(counts->places, last_places);
    last_places = counts->places;
    ASSERT_TRUE(store->Checksum().ok());
  }
  writer.join();
  EXPECT_TRUE(writer_ok);
  ExpectCounts(*store, kPlaces, 2 * kPlaces, 8 * kPlaces);
}

}  // namespace
}  // namespace placerec
