// The PostgreSQL store against a real throw-away cluster (scripts/pg.sh): the same contract as the
// SQLite store (round trip, exact counts, refused input changes nothing, digests equal to the
// SQLite store's for the same map), its own refusals (foreign and newer databases), the change
// feed other servers follow, and a lost connection. Skips only when the PostgreSQL binaries are
// missing.
#include "common/storage/postgres_store.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "common/storage/postgres_testing.h"
#include "common/storage/sqlite_store.h"
#include "common/storage/storage_testing.h"

namespace placerec {
namespace {

using testing_postgres::ExecPg;
using testing_postgres::QueryPg;
using testing_postgres::TestCluster;
using testing_storage::ExpectSameLandmark;
using testing_storage::ExplicitLandmark;

Place MakePlace(const std::string& robot, int64_t sequence) {
  Place place;
  place.robot = robot;
  place.sequence = sequence;
  place.utime = 1700000000000000 + sequence * 100000;
  place.image_width = 640 + static_cast<int>(sequence % 3);
  return place;
}

std::vector<Landmark> MakeLandmarks(int first, int count) {
  std::vector<Landmark> landmarks;
  for (int i = 0; i < count; ++i) landmarks.push_back(ExplicitLandmark(first + i));
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

// One cluster for the whole suite; each test gets a database of its own.
class PostgresStoreTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    StatusOr<std::unique_ptr<TestCluster>> cluster =
        TestCluster::Start(std::string(PLACEREC_SOURCE_DIR) + "/scripts/pg.sh");
    if (cluster.ok()) {
      cluster_ = std::move(*cluster).release();
    } else {
      skip_reason_ = cluster.status().ToString();
    }
  }
  static void TearDownTestSuite() {
    delete cluster_;
    cluster_ = nullptr;
  }

  void SetUp() override {
    if (cluster_ == nullptr) {
      if (Contains(skip_reason_, "binaries are missing")) GTEST_SKIP() << skip_reason_;
      FAIL() << skip_reason_;
    }
    ASSERT_TRUE(cluster_->Up()) << "the cluster does not run";
    std::string name = ::testing::UnitTest::GetInstance()->current_test_info()->name();
    for (char& c : name) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    StatusOr<std::string> url = cluster_->CreateDatabase(name);
    ASSERT_TRUE(url.ok()) << url.status().ToString();
    url_ = *url;
  }

  std::unique_ptr<LandmarkStore> Open() const {
    StatusOr<std::unique_ptr<LandmarkStore>> store =
        OpenPostgresStore(url_, PostgresStoreOptions());
    EXPECT_TRUE(store.ok()) << store.status().ToString();
    return store.ok() ? std::move(store).value() : nullptr;
  }

  std::unique_ptr<PostgresChangeFeed> OpenFeed() const {
    StatusOr<std::unique_ptr<PostgresChangeFeed>> feed =
        PostgresChangeFeed::Open(url_, PostgresStoreOptions());
    EXPECT_TRUE(feed.ok()) << feed.status().ToString();
    return feed.ok() ? std::move(feed).value() : nullptr;
  }

  static TestCluster* cluster_;
  static std::string skip_reason_;
  std::string url_;
};

TestCluster* PostgresStoreTest::cluster_ = nullptr;
std::string PostgresStoreTest::skip_reason_;

TEST(PostgresStoreOptionsTest, DefaultsPassAndBadValuesFail) {
  std::string error;
  EXPECT_TRUE(PostgresStoreOptions().Check(&error)) << error;
  PostgresStoreOptions bad;
  bad.connect_timeout_s = 0;
  EXPECT_FALSE(bad.Check(&error));
  EXPECT_TRUE(Contains(error, "connect_timeout_s"));
  EXPECT_EQ(OpenPostgresStore("postgresql:///x", bad).status().code(),
            StatusCode::kInvalidArgument);
  PostgresStoreOptions no_wait;
  no_wait.insert_timeout_ms = 0;
  EXPECT_FALSE(no_wait.Check(&error));
  EXPECT_TRUE(Contains(error, "insert_timeout_ms"));
  EXPECT_EQ(OpenPostgresStore("map.db", PostgresStoreOptions()).status().code(),
            StatusCode::kInvalidArgument);
  EXPECT_TRUE(IsPostgresUrl("postgresql:///placerec?host=/tmp/x"));
  EXPECT_TRUE(IsPostgresUrl("postgres://user@db.example/site"));
  EXPECT_FALSE(IsPostgresUrl("map.db"));
  EXPECT_FALSE(IsPostgresUrl("/var/lib/postgresql.db"));
}

TEST(PostgresStoreOpenTest, AnUnreachableDatabaseIsAnIoError) {
  StatusOr<std::unique_ptr<LandmarkStore>> store = OpenPostgresStore(
      "postgresql:///placerec?host=/nonexistent-placerec&user=postgres", PostgresStoreOptions());
  ASSERT_FALSE(store.ok());
  EXPECT_EQ(store.status().code(), StatusCode::kIoError);
  EXPECT_TRUE(Contains(store.status().message(), "cannot connect")) << store.status().message();
  // Messages never show a password.
  store = OpenPostgresStore(
      "postgresql://placerec:topsecret@/placerec?host=/nonexistent-placerec&password=othersecret",
      PostgresStoreOptions());
  ASSERT_FALSE(store.ok());
  EXPECT_FALSE(Contains(store.status().message(), "topsecret")) << store.status().message();
  EXPECT_FALSE(Contains(store.status().message(), "othersecret")) << store.status().message();
  EXPECT_TRUE(Contains(store.status().message(), "postgresql://placerec@/placerec?"))
      << store.status().message();
}

TEST_F(PostgresStoreTest, WritesAndReadsBackAfterReopenWithTheSqliteDigest) {
  Place first = MakePlace("alpha", 10);
  Place second = MakePlace("beta", 3);
  Place empty = MakePlace("beta", 4);
  std::vector<Landmark> first_landmarks = MakeLandmarks(0, 3);
  std::vector<Landmark> second_landmarks = MakeLandmarks(5, 2);
  first_landmarks[1].object_class = "building";
  first_landmarks[1].class_confidence = 0.8125f;
  second_landmarks[0].descriptors = cv::Mat();  // a landmark without descriptors
  second_landmarks[0].keypoints.clear();
  {
    std::unique_ptr<LandmarkStore> store = Open();
    ASSERT_NE(store, nullptr);
    EXPECT_EQ(store->Describe(), url_);
    ExpectCounts(*store, 0, 0, 0);
    ASSERT_TRUE(store->AddPlace(&first, &first_landmarks).ok());
    ASSERT_TRUE(store->AddPlace(&second, &second_landmarks).ok());
    ASSERT_TRUE(store->AddPlace(&empty, nullptr).ok());
  }
  EXPECT_TRUE(first.id.IsValid());
  EXPECT_LT(first.id, second.id);
  EXPECT_LT(second.id, empty.id);
  EXPECT_EQ(first.num_landmarks, 3);
  EXPECT_EQ(empty.num_landmarks, 0);
  std::vector<Landmark> all = first_landmarks;
  all.insert(all.end(), second_landmarks.begin(), second_landmarks.end());
  for (size_t i = 0; i < all.size(); ++i) {
    EXPECT_TRUE(all[i].id.IsValid());
    if (i > 0) {
      EXPECT_LT(all[i - 1].id, all[i].id);
    }
    EXPECT_EQ(all[i].place, i < 3 ? first.id : second.id);
  }

  std::unique_ptr<LandmarkStore> store = Open();
  ASSERT_NE(store, nullptr);
  const Contents contents = ReadAll(*store);
  ASSERT_EQ(contents.places.size(), 3u);
  EXPECT_EQ(contents.places[0], first);
  EXPECT_EQ(contents.places[1], second);
  EXPECT_EQ(contents.places[2], empty);
  ASSERT_EQ(contents.landmarks.size(), all.size());
  int64_t descriptors = 0;
  for (size_t i = 0; i < all.size(); ++i) {
    SCOPED_TRACE(i);
    ExpectSameLandmark(all[i], contents.landmarks[i]);
    descriptors += all[i].descriptors.rows;
  }
  ExpectCounts(*store, 3, 5, descriptors);

  // The same map in SQLite (same ids, as both start at 1) has the same digest.
  StatusOr<std::unique_ptr<LandmarkStore>> sqlite = OpenSqliteStore(":memory:", {});
  ASSERT_TRUE(sqlite.ok());
  for (const Place& original : contents.places) {
    Place place = original;
    place.id = PlaceId();
    std::vector<Landmark> landmarks;
    for (const Landmark& landmark : contents.landmarks) {
      if (landmark.place == original.id) landmarks.push_back(landmark);
    }
    ASSERT_TRUE((*sqlite)->AddPlace(&place, &landmarks).ok());
    ASSERT_EQ(place.id, original.id);
  }
  EXPECT_EQ(ChecksumOf(*store), ChecksumOf(**sqlite));
  // And one changed field changes it.
  const uint64_t before = ChecksumOf(*store);
  ASSERT_TRUE(ExecPg(url_, "UPDATE places SET utime = utime + 1 WHERE id = " +
                               std::to_string(second.id.value()))
                  .ok());
  EXPECT_NE(ChecksumOf(*store), before);
}

TEST_F(PostgresStoreTest, ThumbnailsRoundTripApartFromPlaces) {
  std::unique_ptr<LandmarkStore> store = Open();
  ASSERT_NE(store, nullptr);
  Place with = MakePlace("r", 1);
  with.thumbnail = {0xff, 0xd8, 0x00, 0x01, 0xfe};
  ASSERT_TRUE(store->AddPlace(&with, nullptr).ok());
  Place without = MakePlace("r", 2);
  ASSERT_TRUE(store->AddPlace(&without, nullptr).ok());
  store.reset();
  std::unique_ptr<LandmarkStore> reopened = Open();
  ASSERT_NE(reopened, nullptr);
  EXPECT_EQ(*reopened->LoadThumbnail(with.id), with.thumbnail);
  EXPECT_TRUE(reopened->LoadThumbnail(without.id)->empty());
  std::vector<Place> places;
  ASSERT_TRUE(reopened->LoadPlaces([&places](const Place& p) { places.push_back(p); }).ok());
  ASSERT_EQ(places.size(), 2u);
  EXPECT_TRUE(places[0].thumbnail.empty());
}

TEST_F(PostgresStoreTest, DuplicateAndInvalidInputAreRefusedAndChangeNothing) {
  std::unique_ptr<LandmarkStore> store = Open();
  ASSERT_NE(store, nullptr);
  Place place = MakePlace("r", 7);
  std::vector<Landmark> landmarks = MakeLandmarks(0, 2);
  ASSERT_TRUE(store->AddPlace(&place, &landmarks).ok());
  const uint64_t before = ChecksumOf(*store);

  // The same robot and sequence again (UNIQUE(robot, sequence) is the arbiter between servers).
  Place again = MakePlace("r", 7);
  std::vector<Landmark> more = MakeLandmarks(3, 2);
  Status status = store->AddPlace(&again, &more);
  EXPECT_EQ(status.code(), StatusCode::kInvalidArgument);
  EXPECT_TRUE(Contains(status.message(), "already stored")) << status.message();
  EXPECT_FALSE(again.id.IsValid());
  EXPECT_FALSE(more[0].id.IsValid());

  // A sighting of a landmark that is not in the map.
  Place sees = MakePlace("r", 8);
  sees.seen_landmarks = {LandmarkId(987654)};
  status = store->AddPlace(&sees, nullptr);
  EXPECT_EQ(status.code(), StatusCode::kInvalidArgument);
  EXPECT_TRUE(Contains(status.message(), "not in the map")) << status.message();

  // Input the store validates before writing.
  Place bad_robot = MakePlace("", 9);
  EXPECT_EQ(store->AddPlace(&bad_robot, nullptr).code(), StatusCode::kInvalidArgument);
  Place bad_landmarks = MakePlace("r", 10);
  std::vector<Landmark> wrong = MakeLandmarks(0, 1);
  wrong[0].keypoints.pop_back();
  EXPECT_EQ(store->AddPlace(&bad_landmarks, &wrong).code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(store->AddPlace(nullptr, nullptr).code(), StatusCode::kInvalidArgument);

  ExpectCounts(*store, 1, 2, 2 + 3);
  EXPECT_EQ(ChecksumOf(*store), before);
  // The store goes on after refusals.
  Place next = MakePlace("r", 8);
  next.seen_landmarks = {landmarks[1].id};
  ASSERT_TRUE(store->AddPlace(&next, nullptr).ok());
  const Contents contents = ReadAll(*store);
  ASSERT_EQ(contents.places.size(), 2u);
  EXPECT_EQ(contents.places[1].seen_landmarks, std::vector<LandmarkId>{landmarks[1].id});
}

TEST_F(PostgresStoreTest, ForeignNewerAndDamagedMapsAreRefused) {
  // Tables of something else: refused, nothing created.
  ASSERT_TRUE(ExecPg(url_, "CREATE TABLE invoices(id INT)").ok());
  StatusOr<std::unique_ptr<LandmarkStore>> store = OpenPostgresStore(url_, {});
  ASSERT_FALSE(store.ok());
  EXPECT_EQ(store.status().code(), StatusCode::kIoError);
  EXPECT_TRUE(Contains(store.status().message(), "not a placerec map")) << store.status().message();
  EXPECT_EQ(QueryPg(url_,
                    "SELECT COUNT(*) FROM information_schema.tables WHERE table_name = "
                    "'places'"),
            "0");
  ASSERT_TRUE(ExecPg(url_, "DROP TABLE invoices").ok());

  // A map of a newer schema version.
  std::unique_ptr<LandmarkStore> made = Open();
  ASSERT_NE(made, nullptr);
  Place place = MakePlace("r", 1);
  std::vector<Landmark> landmarks = MakeLandmarks(0, 2);
  ASSERT_TRUE(made->AddPlace(&place, &landmarks).ok());
  made.reset();
  ASSERT_TRUE(ExecPg(url_, "UPDATE meta SET value = '99' WHERE key = 'schema_version'").ok());
  store = OpenPostgresStore(url_, {});
  ASSERT_FALSE(store.ok());
  EXPECT_TRUE(Contains(store.status().message(), "upgrade placerec")) << store.status().message();
  ASSERT_TRUE(ExecPg(url_, "UPDATE meta SET value = '2' WHERE key = 'schema_version'").ok());

  // A damaged landmark stops the scan with an IoError naming it.
  ASSERT_TRUE(ExecPg(url_, "UPDATE landmarks SET keypoints = '\\x0001'::bytea WHERE id = " +
                               std::to_string(landmarks[1].id.value()))
                  .ok());
  std::unique_ptr<LandmarkStore> reopened = Open();
  ASSERT_NE(reopened, nullptr);
  const Status loaded = reopened->LoadLandmarks([](Landmark&&) {});
  EXPECT_EQ(loaded.code(), StatusCode::kIoError);
  EXPECT_TRUE(Contains(loaded.message(),
                       "landmark " + std::to_string(landmarks[1].id.value()) + " is corrupt"))
      << loaded.message();
}

TEST_F(PostgresStoreTest, TheChangeFeedDeliversOtherConnectionsPlaces) {
  std::unique_ptr<PostgresChangeFeed> feed = OpenFeed();
  ASSERT_NE(feed, nullptr);
  std::unique_ptr<LandmarkStore> writer = Open();
  ASSERT_NE(writer, nullptr);
  StatusOr<int> nothing = feed->Wait(50);
  ASSERT_TRUE(nothing.ok());
  EXPECT_EQ(*nothing, 0);

  std::vector<Place> places;
  std::vector<std::vector<Landmark>> landmarks;
  for (int i = 0; i < 5; ++i) {
    places.push_back(MakePlace("writer", i));
    landmarks.push_back(MakeLandmarks(i, i % 3));
    ASSERT_TRUE(writer->AddPlace(&places.back(), &landmarks.back()).ok());
  }
  // Notified within a second of the commit.
  int arrived = 0;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(1);
  while (arrived < 5 && std::chrono::steady_clock::now() < deadline) {
    StatusOr<int> got = feed->Wait(100);
    ASSERT_TRUE(got.ok()) << got.status().ToString();
    arrived += *got;
  }
  EXPECT_EQ(arrived, 5);

  // Fetched in batches of two, in id order, whole.
  std::vector<CommittedPlace> fetched;
  PlaceId after;
  while (true) {
    StatusOr<std::vector<CommittedPlace>> batch = feed->FetchAfter(after, 2);
    ASSERT_TRUE(batch.ok()) << batch.status().ToString();
    for (CommittedPlace& place : *batch) {
      after = place.place.id;
      fetched.push_back(std::move(place));
    }
    if (batch->size() < 2) break;
  }
  ASSERT_EQ(fetched.size(), 5u);
  for (size_t i = 0; i < fetched.size(); ++i) {
    SCOPED_TRACE(i);
    EXPECT_EQ(fetched[i].place, places[i]);
    ASSERT_EQ(fetched[i].landmarks.size(), landmarks[i].size());
    for (size_t k = 0; k < landmarks[i].size(); ++k) {
      ExpectSameLandmark(landmarks[i][k], fetched[i].landmarks[k]);
    }
  }
  StatusOr<std::vector<CommittedPlace>> none = feed->FetchAfter(places.back().id, 10);
  ASSERT_TRUE(none.ok());
  EXPECT_TRUE(none->empty());
}

// Ids become visible in increasing order even with two writers at once, so that following "every
// place above the last one seen" misses nothing.
TEST_F(PostgresStoreTest, AFollowerOfTwoConcurrentWritersMissesNothing) {
  std::unique_ptr<LandmarkStore> a = Open();
  std::unique_ptr<LandmarkStore> b = Open();
  std::unique_ptr<PostgresChangeFeed> feed = OpenFeed();
  ASSERT_NE(a, nullptr);
  ASSERT_NE(b, nullptr);
  ASSERT_NE(feed, nullptr);
  constexpr int kPerWriter = 40;
  std::atomic<bool> writers_ok{true};
  std::atomic<int> writers_done{0};
  std::set<int64_t> written;
  std::mutex written_mutex;
  const auto write = [&](LandmarkStore* store, const std::string& robot) {
    for (int i = 0; i < kPerWriter; ++i) {
      Place place = MakePlace(robot, i);
      std::vector<Landmark> landmarks = MakeLandmarks(i, 1 + i % 2);
      if (!store->AddPlace(&place, &landmarks).ok()) writers_ok = false;
      std::lock_guard lock(written_mutex);
      written.insert(place.id.value());
    }
    ++writers_done;
  };
  std::thread first(write, a.get(), "a");
  std::thread second(write, b.get(), "b");
  std::set<int64_t> followed;
  PlaceId last;
  bool increasing = true;
  while (true) {
    const bool done = writers_done.load() == 2;
    StatusOr<int> got = feed->Wait(20);
    ASSERT_TRUE(got.ok());
    StatusOr<std::vector<CommittedPlace>> batch = feed->FetchAfter(last, 1000);
    ASSERT_TRUE(batch.ok()) << batch.status().ToString();
    for (const CommittedPlace& place : *batch) {
      if (!(last < place.place.id)) increasing = false;
      last = place.place.id;
      followed.insert(place.place.id.value());
      EXPECT_EQ(static_cast<int>(place.landmarks.size()), place.place.num_landmarks);
    }
    if (done) break;
  }
  first.join();
  second.join();
  EXPECT_TRUE(writers_ok);
  EXPECT_TRUE(increasing);
  EXPECT_EQ(written.size(), 2u * kPerWriter);
  EXPECT_EQ(followed, written);
}

// A map opened while others insert: the landmarks read belong to the places read.
TEST_F(PostgresStoreTest, LoadLandmarksStopsAtTheLoadedPlaces) {
  std::unique_ptr<LandmarkStore> reader = Open();
  std::unique_ptr<LandmarkStore> writer = Open();
  Place first = MakePlace("w", 1);
  std::vector<Landmark> first_landmarks = MakeLandmarks(0, 2);
  ASSERT_TRUE(writer->AddPlace(&first, &first_landmarks).ok());
  std::vector<Place> places;
  ASSERT_TRUE(reader->LoadPlaces([&places](const Place& p) { places.push_back(p); }).ok());
  Place later = MakePlace("w", 2);
  std::vector<Landmark> later_landmarks = MakeLandmarks(3, 2);
  ASSERT_TRUE(writer->AddPlace(&later, &later_landmarks).ok());
  std::vector<Landmark> landmarks;
  ASSERT_TRUE(reader->LoadLandmarks([&](Landmark&& l) { landmarks.push_back(std::move(l)); }).ok());
  ASSERT_EQ(places.size(), 1u);
  ASSERT_EQ(landmarks.size(), 2u);
  for (const Landmark& landmark : landmarks) EXPECT_EQ(landmark.place, first.id);
}

// The database goes away: calls fail with IoError and change nothing; when it is back, the same
// store object works again without being reopened.
TEST_F(PostgresStoreTest, ALostConnectionIsAnIoErrorAndTheStoreReconnects) {
  std::unique_ptr<LandmarkStore> store = Open();
  std::unique_ptr<PostgresChangeFeed> feed = OpenFeed();
  ASSERT_NE(store, nullptr);
  ASSERT_NE(feed, nullptr);
  Place place = MakePlace("r", 1);
  std::vector<Landmark> landmarks = MakeLandmarks(0, 2);
  ASSERT_TRUE(store->AddPlace(&place, &landmarks).ok());

  ASSERT_TRUE(cluster_->Down());
  Place lost = MakePlace("r", 2);
  std::vector<Landmark> lost_landmarks = MakeLandmarks(2, 1);
  const Status refused = store->AddPlace(&lost, &lost_landmarks);
  EXPECT_EQ(refused.code(), StatusCode::kIoError) << refused.ToString();
  EXPECT_FALSE(lost.id.IsValid());
  EXPECT_FALSE(lost_landmarks[0].id.IsValid());
  EXPECT_FALSE(store->Counts().ok());
  StatusOr<int> waited = feed->Wait(200);
  if (waited.ok()) waited = feed->Wait(200);  // the close may take one more read
  EXPECT_FALSE(waited.ok());

  ASSERT_TRUE(cluster_->Up());
  ASSERT_TRUE(store->AddPlace(&lost, &lost_landmarks).ok());
  EXPECT_LT(place.id, lost.id);
  ExpectCounts(*store, 2, 3, 2 + 3 + 4);

  // A restart between two calls: the connection looks fine until used; the next insert opens it
  // again and succeeds at once.
  ASSERT_TRUE(cluster_->Down());
  ASSERT_TRUE(cluster_->Up());
  Place after_restart = MakePlace("r", 3);
  const Status stored = store->AddPlace(&after_restart, nullptr);
  EXPECT_TRUE(stored.ok()) << stored.ToString();
  ExpectCounts(*store, 3, 3, 2 + 3 + 4);
}

// Another server stopped (or cut off) inside its insert keeps the map's insert lock until
// PostgreSQL ends its session. An insert here used to wait for it with no bound, holding the
// store, and with it this server's workers, queries and shutdown; it now fails after the insert
// timeout, stores nothing, and succeeds once the lock is free.
TEST_F(PostgresStoreTest, AnInsertLockHeldElsewhereFailsTheInsertAfterTheTimeout) {
  PostgresStoreOptions options;
  options.insert_timeout_ms = 300;
  StatusOr<std::unique_ptr<LandmarkStore>> opened = OpenPostgresStore(url_, options);
  ASSERT_TRUE(opened.ok()) << opened.status().ToString();
  LandmarkStore& store = **opened;
  PGconn* peer = PQconnectdb(url_.c_str());
  ASSERT_EQ(PQstatus(peer), CONNECTION_OK) << PQerrorMessage(peer);
  const std::string lock =
      "BEGIN; SELECT pg_advisory_xact_lock(" + std::to_string(kPostgresInsertLockKey) + ")";
  PGresult* locked = PQexec(peer, lock.c_str());
  EXPECT_EQ(PQresultStatus(locked), PGRES_TUPLES_OK) << PQerrorMessage(peer);
  PQclear(locked);

  Place place = MakePlace("r", 1);
  std::vector<Landmark> landmarks = MakeLandmarks(0, 2);
  const auto start = std::chrono::steady_clock::now();
  const Status refused = store.AddPlace(&place, &landmarks);
  const double waited_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_EQ(refused.code(), StatusCode::kIoError) << refused.ToString();
  EXPECT_TRUE(Contains(refused.message(), "another server's insert holds the lock"))
      << refused.ToString();
  EXPECT_LT(waited_s, 30.0);
  EXPECT_FALSE(place.id.IsValid());
  ExpectCounts(store, 0, 0, 0);

  PQclear(PQexec(peer, "ROLLBACK"));
  PQfinish(peer);
  const Status stored = store.AddPlace(&place, &landmarks);
  EXPECT_TRUE(stored.ok()) << stored.ToString();
  ExpectCounts(store, 1, 2, 2 + 3);
}

}  // namespace
}  // namespace placerec
