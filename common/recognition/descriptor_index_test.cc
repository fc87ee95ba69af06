// Snapshots of the descriptor index: a tree loaded from a snapshot (and extended) answers exactly
// as the tree grown by insertion; a stale, foreign or damaged snapshot is ignored.
#include "common/recognition/descriptor_index.h"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <limits>
#include <memory>
#include <random>
#include <sstream>
#include <string>
#include <tuple>
#include <vector>

#include <gtest/gtest.h>
#include <xxhash.h>
#include <flann/flann.hpp>

#include "common/recognition/recognition_test_util.h"

namespace placerec {
namespace {

using recognition_test::Noisy;
using recognition_test::RandomDescriptors;

// Blocks of descriptors drawn around a few shared centres, so that many points are close and
// the approximate search depends on the shape of the tree.
std::vector<cv::Mat> MakeBlocks(int count, uint32_t seed) {
  std::mt19937 rng(seed);
  const cv::Mat centres = RandomDescriptors(8, &rng);
  std::uniform_int_distribution<int> rows(1, 40);
  std::uniform_int_distribution<int> centre(0, centres.rows - 1);
  std::vector<cv::Mat> blocks;
  for (int b = 0; b < count; ++b) {
    cv::Mat block(rows(rng), 128, CV_8U);
    for (int r = 0; r < block.rows; ++r) {
      Noisy(centres.row(centre(rng)), &rng, 40).copyTo(block.row(r));
    }
    blocks.push_back(block);
  }
  return blocks;
}

cv::Mat Queries(const std::vector<cv::Mat>& blocks, uint32_t seed) {
  std::mt19937 rng(seed);
  cv::Mat queries;
  for (size_t b = 0; b < blocks.size(); b += 3) queries.push_back(Noisy(blocks[b], &rng, 20));
  return queries;
}

// Every neighbour of every query: owner, row, distance.
std::vector<std::tuple<int32_t, int32_t, float>> Answers(const DescriptorIndex& index,
                                                         const cv::Mat& queries) {
  std::vector<std::vector<DescriptorIndex::Neighbour>> neighbours;
  index.Search(queries, 3, &neighbours);
  std::vector<std::tuple<int32_t, int32_t, float>> answers;
  for (const auto& list : neighbours) {
    for (const DescriptorIndex::Neighbour& n : list)
      answers.emplace_back(n.owner, n.row, n.distance);
    answers.emplace_back(-1, -1, 0.0f);  // end of this query's list
  }
  return answers;
}

// Owners 100, 101, ... in block order.
void AddBlocks(const std::vector<cv::Mat>& blocks, size_t first, size_t end,
               DescriptorIndex* index) {
  for (size_t b = first; b < end; ++b) index->Add(static_cast<int32_t>(100 + b), blocks[b]);
}

DescriptorIndexOptions FewChecks() {
  DescriptorIndexOptions options;
  options.checks = 4;  // far from exact: the answers show the shape of the tree
  return options;
}

class DescriptorSnapshotTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string pattern = ::testing::TempDir() + "placerec_snapshot_XXXXXX";
    ASSERT_NE(mkdtemp(pattern.data()), nullptr);
    dir_ = pattern;
    path_ = dir_ + "/map.db.index";
    blocks_ = MakeBlocks(60, 7);
    queries_ = Queries(blocks_, 8);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  // Saves a snapshot of an index grown from blocks [0, adds).
  void SaveGrown(size_t adds, const DescriptorIndexOptions& options = FewChecks()) {
    DescriptorIndex grown(options);
    AddBlocks(blocks_, 0, adds, &grown);
    ASSERT_TRUE(grown.SaveSnapshot(path_).ok());
  }

  // Opens an index of every block through FinishDeferred with the snapshot at path_.
  std::unique_ptr<DescriptorIndex> Reopen(SnapshotLoad* load,
                                          const DescriptorIndexOptions& options = FewChecks()) {
    auto index = std::make_unique<DescriptorIndex>(options);
    index->DeferInsertion();
    AddBlocks(blocks_, 0, blocks_.size(), index.get());
    *load = index->FinishDeferred(path_);
    return index;
  }

  std::vector<std::tuple<int32_t, int32_t, float>> GrownAnswers(
      const DescriptorIndexOptions& options = FewChecks()) {
    DescriptorIndex grown(options);
    AddBlocks(blocks_, 0, blocks_.size(), &grown);
    return Answers(grown, queries_);
  }

  std::string ReadFile() {
    std::ifstream in(path_, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
  }
  void WriteFile(const std::string& bytes) {
    std::ofstream(path_, std::ios::binary | std::ios::trunc) << bytes;
  }

  std::string dir_;
  std::string path_;
  std::vector<cv::Mat> blocks_;
  cv::Mat queries_;
};

// The index computes FLANN's distances with its own vector code: the answers (neighbours, their
// order and distances) must be those of a FLANN tree with FLANN's own L2, grown the same way.
TEST(DescriptorIndexTest, AnswersAsATreeWithFlannsOwnDistance) {
  const std::vector<cv::Mat> blocks = MakeBlocks(80, 11);
  const cv::Mat queries = Queries(blocks, 12);
  for (const int checks : {4, 32}) {
    DescriptorIndexOptions options;
    options.checks = checks;
    DescriptorIndex index(options);
    AddBlocks(blocks, 0, blocks.size(), &index);
    std::vector<std::vector<DescriptorIndex::Neighbour>> ours;
    index.Search(queries, 5, &ours);

    // FLANN alone: a one-point tree, then every other point inserted without rebuilds.
    cv::Mat all;
    for (const cv::Mat& block : blocks) all.push_back(block);
    std::vector<std::pair<int32_t, int32_t>> owner_row;
    for (size_t b = 0; b < blocks.size(); ++b) {
      for (int r = 0; r < blocks[b].rows; ++r) owner_row.emplace_back(100 + b, r);
    }
    flann::KDTreeIndex<flann::L2<unsigned char>> tree(
        flann::Matrix<unsigned char>(all.data, 1, 128), flann::KDTreeIndexParams(1));
    tree.buildIndex();
    size_t first = 1;
    for (const cv::Mat& block : blocks) {
      const size_t rows = static_cast<size_t>(block.rows);
      const size_t start = first == 1 ? 1 : 0;  // the first block's first row is in already
      if (rows > start) {
        tree.addPoints(flann::Matrix<unsigned char>(const_cast<unsigned char*>(block.ptr(start)),
                                                    rows - start, 128),
                       std::numeric_limits<float>::max());
      }
      first = 0;
    }
    std::vector<size_t> indices(queries.rows * 5);
    std::vector<float> distances(queries.rows * 5);
    flann::Matrix<size_t> index_matrix(indices.data(), queries.rows, 5);
    flann::Matrix<float> distance_matrix(distances.data(), queries.rows, 5);
    flann::SearchParams params(checks);
    params.cores = 1;
    tree.knnSearch(flann::Matrix<unsigned char>(queries.data, queries.rows, 128), index_matrix,
                   distance_matrix, 5, params);
    ASSERT_EQ(ours.size(), static_cast<size_t>(queries.rows));
    for (int q = 0; q < queries.rows; ++q) {
      ASSERT_EQ(ours[q].size(), 5u) << "query " << q;
      for (int j = 0; j < 5; ++j) {
        const auto [owner, row] = owner_row[index_matrix[q][j]];
        EXPECT_EQ(ours[q][j].owner, owner) << "checks " << checks << " query " << q << " #" << j;
        EXPECT_EQ(ours[q][j].row, row) << "checks " << checks << " query " << q << " #" << j;
        EXPECT_EQ(ours[q][j].distance, distance_matrix[q][j]);
      }
    }
  }
}

TEST_F(DescriptorSnapshotTest, TheEqualityCheckSeesTheShapeOfTheTree) {
  // Grown in another order, the same points answer differently with few checks: equal answers
  // below do mean the same tree.
  DescriptorIndex reversed(FewChecks());
  for (size_t b = blocks_.size(); b-- > 0;) reversed.Add(static_cast<int32_t>(100 + b), blocks_[b]);
  EXPECT_NE(Answers(reversed, queries_), GrownAnswers());
}

TEST_F(DescriptorSnapshotTest, WholeSnapshotAnswersAsTheGrownIndex) {
  SaveGrown(blocks_.size());
  SnapshotLoad load;
  const std::unique_ptr<DescriptorIndex> index = Reopen(&load);
  EXPECT_TRUE(load.used) << load.message;
  EXPECT_EQ(load.covered_adds, static_cast<int64_t>(blocks_.size()));
  EXPECT_EQ(load.inserted_points, 0);
  EXPECT_EQ(Answers(*index, queries_), GrownAnswers());
  // No temporary file is left beside it.
  EXPECT_EQ(std::distance(std::filesystem::directory_iterator(dir_),
                          std::filesystem::directory_iterator()),
            1);
}

TEST_F(DescriptorSnapshotTest, OlderSnapshotIsExtendedWithTheLaterBlocks) {
  SaveGrown(25);
  SnapshotLoad load;
  const std::unique_ptr<DescriptorIndex> index = Reopen(&load);
  EXPECT_TRUE(load.used) << load.message;
  EXPECT_EQ(load.covered_adds, 25);
  int later_points = 0;
  for (size_t b = 25; b < blocks_.size(); ++b) later_points += blocks_[b].rows;
  EXPECT_EQ(load.inserted_points, later_points);
  size_t all_points = 0;
  for (const cv::Mat& block : blocks_) all_points += block.rows;
  EXPECT_EQ(index->size(), all_points);
  EXPECT_EQ(Answers(*index, queries_), GrownAnswers());
  // Grown further after the load, it still follows the grown index.
  const std::vector<cv::Mat> more = MakeBlocks(10, 9);
  DescriptorIndex grown(FewChecks());
  AddBlocks(blocks_, 0, blocks_.size(), &grown);
  for (size_t b = 0; b < more.size(); ++b) {
    grown.Add(static_cast<int32_t>(500 + b), more[b]);
    index->Add(static_cast<int32_t>(500 + b), more[b]);
  }
  EXPECT_EQ(Answers(*index, queries_), Answers(grown, queries_));
  // And its own snapshot is as good.
  ASSERT_TRUE(index->SaveSnapshot(path_).ok());
  DescriptorIndex again(FewChecks());
  again.DeferInsertion();
  AddBlocks(blocks_, 0, blocks_.size(), &again);
  for (size_t b = 0; b < more.size(); ++b) again.Add(static_cast<int32_t>(500 + b), more[b]);
  const SnapshotLoad second = again.FinishDeferred(path_);
  EXPECT_TRUE(second.used) << second.message;
  EXPECT_EQ(second.inserted_points, 0);
  EXPECT_EQ(Answers(again, queries_), Answers(grown, queries_));
}

TEST_F(DescriptorSnapshotTest, SnapshotServesOtherSearchChecks) {
  // The tree does not depend on the checks; the search with the reader's checks does.
  SaveGrown(blocks_.size());
  DescriptorIndexOptions more_checks = FewChecks();
  more_checks.checks = 16;
  SnapshotLoad load;
  const std::unique_ptr<DescriptorIndex> index = Reopen(&load, more_checks);
  EXPECT_TRUE(load.used) << load.message;
  EXPECT_EQ(Answers(*index, queries_), GrownAnswers(more_checks));
}

TEST_F(DescriptorSnapshotTest, NoSnapshotOrNoPathGrowsTheIndex) {
  SnapshotLoad load;
  const std::unique_ptr<DescriptorIndex> index = Reopen(&load);
  EXPECT_FALSE(load.used);
  EXPECT_NE(load.message.find("there is none"), std::string::npos) << load.message;
  EXPECT_EQ(Answers(*index, queries_), GrownAnswers());

  DescriptorIndex unnamed(FewChecks());
  unnamed.DeferInsertion();
  AddBlocks(blocks_, 0, blocks_.size(), &unnamed);
  EXPECT_FALSE(unnamed.FinishDeferred("").used);
  EXPECT_EQ(Answers(unnamed, queries_), GrownAnswers());
}

TEST_F(DescriptorSnapshotTest, StaleSnapshotsAreIgnored) {
  const std::vector<std::tuple<int32_t, int32_t, float>> expected = GrownAnswers();
  struct Case {
    const char* what;
    std::function<void(DescriptorIndex*)> grow;
  };
  const std::vector<Case> cases = {
      // The map lost places since (pruned): the snapshot covers more than there is.
      {"more blocks than the map",
       [&](DescriptorIndex* i) {
         AddBlocks(blocks_, 0, blocks_.size(), i);
         i->Add(999, blocks_[0]);
       }},
      // One descriptor changed (a merge rewrote a landmark).
      {"a changed descriptor",
       [&](DescriptorIndex* i) {
         std::vector<cv::Mat> changed = blocks_;
         changed[3] = blocks_[3].clone();
         changed[3].at<uint8_t>(0, 5) ^= 1;
         AddBlocks(changed, 0, changed.size(), i);
       }},
      // Same descriptors, another owner (landmark slots shifted).
      {"another owner",
       [&](DescriptorIndex* i) {
         for (size_t b = 0; b < blocks_.size(); ++b) {
           i->Add(static_cast<int32_t>(b == 10 ? 7 : 100 + b), blocks_[b]);
         }
       }},
      // Another order.
      {"another order",
       [&](DescriptorIndex* i) {
         i->Add(101, blocks_[1]);
         i->Add(100, blocks_[0]);
         AddBlocks(blocks_, 2, blocks_.size(), i);
       }},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.what);
    DescriptorIndex snapshot_source(FewChecks());
    c.grow(&snapshot_source);
    ASSERT_TRUE(snapshot_source.SaveSnapshot(path_).ok());
    SnapshotLoad load;
    const std::unique_ptr<DescriptorIndex> index = Reopen(&load);
    EXPECT_FALSE(load.used) << load.message;
    EXPECT_EQ(load.covered_adds, 0);
    EXPECT_EQ(static_cast<size_t>(load.inserted_points), index->size());
    EXPECT_EQ(Answers(*index, queries_), expected);
  }
}

TEST_F(DescriptorSnapshotTest, DamagedSnapshotsAreIgnoredWithAReason) {
  SaveGrown(blocks_.size());
  const std::string whole = ReadFile();
  ASSERT_GT(whole.size(), 200u);
  const std::vector<std::tuple<int32_t, int32_t, float>> expected = GrownAnswers();
  std::vector<std::pair<std::string, std::string>> damaged;  // what, bytes
  // The header is 112 bytes.
  for (const size_t length : {size_t{0}, size_t{10}, size_t{111}, size_t{112}, size_t{113},
                              whole.size() / 2, whole.size() - 1}) {
    damaged.emplace_back("cut to " + std::to_string(length), whole.substr(0, length));
  }
  damaged.emplace_back("a stray byte after it", whole + "x");
  for (size_t offset = 0; offset < whole.size(); offset += whole.size() / 23 + 1) {
    std::string flipped = whole;
    flipped[offset] ^= 0x10;
    damaged.emplace_back("a bit flipped at " + std::to_string(offset), flipped);
  }
  damaged.emplace_back("text", "this is not a snapshot at all, just some text...");
  for (const auto& [what, bytes] : damaged) {
    SCOPED_TRACE(what);
    WriteFile(bytes);
    SnapshotLoad load;
    const std::unique_ptr<DescriptorIndex> index = Reopen(&load);
    EXPECT_FALSE(load.used);
    EXPECT_NE(load.message.find("ignored"), std::string::npos) << load.message;
    EXPECT_EQ(Answers(*index, queries_), expected);
    // The bad file is left alone (the next SaveSnapshot replaces it).
    EXPECT_EQ(ReadFile(), bytes);
  }
  // A directory where the file should be.
  std::remove(path_.c_str());
  ASSERT_EQ(mkdir(path_.c_str(), 0700), 0);
  SnapshotLoad load;
  const std::unique_ptr<DescriptorIndex> index = Reopen(&load);
  EXPECT_FALSE(load.used);
  EXPECT_EQ(Answers(*index, queries_), expected);
}

// A snapshot of another format version (version 1 held FLANN's own serialization) with an
// intact header: refused for its version, the tree grown instead.
TEST_F(DescriptorSnapshotTest, AnotherFormatVersionIsIgnoredWithAReason) {
  SaveGrown(blocks_.size());
  std::string bytes = ReadFile();
  constexpr size_t kHeaderBytes = 112;  // magic 16, four u32, five u64, layout 32, hash 8
  ASSERT_GT(bytes.size(), kHeaderBytes);
  const uint32_t version = 1;
  std::memcpy(&bytes[16], &version, 4);
  const uint64_t header_hash = XXH64(bytes.data(), kHeaderBytes - 8, 0);
  std::memcpy(&bytes[kHeaderBytes - 8], &header_hash, 8);
  WriteFile(bytes);
  SnapshotLoad load;
  const std::unique_ptr<DescriptorIndex> index = Reopen(&load);
  EXPECT_FALSE(load.used);
  EXPECT_NE(load.message.find("format version 1"), std::string::npos) << load.message;
  EXPECT_EQ(Answers(*index, queries_), GrownAnswers());
}

TEST_F(DescriptorSnapshotTest, LeftoverTemporaryFileIsOverwritten) {
  // A save killed half way leaves path.tmp behind; it is never read, and the next save reuses it.
  std::ofstream(path_ + ".tmp") << "half a snapshot";
  SaveGrown(blocks_.size());
  EXPECT_FALSE(std::ifstream(path_ + ".tmp").good());
  SnapshotLoad load;
  const std::unique_ptr<DescriptorIndex> index = Reopen(&load);
  EXPECT_TRUE(load.used) << load.message;
  EXPECT_EQ(Answers(*index, queries_), GrownAnswers());
}

TEST_F(DescriptorSnapshotTest, ASaveWhileAnotherIsWritingIsRefusedAndTouchesNothing) {
  SaveGrown(blocks_.size());
  const std::string snapshot = ReadFile();
  // Another process is writing the temporary file (it holds the lock on it).
  const std::string other_bytes = "another save's bytes";
  std::ofstream(path_ + ".tmp") << other_bytes;
  const int other = open((path_ + ".tmp").c_str(), O_RDWR);
  ASSERT_GE(other, 0);
  ASSERT_EQ(flock(other, LOCK_EX), 0);
  DescriptorIndex smaller(FewChecks());
  AddBlocks(blocks_, 0, 5, &smaller);
  const Status refused = smaller.SaveSnapshot(path_);
  EXPECT_FALSE(refused.ok());
  EXPECT_NE(refused.message().find("another process"), std::string::npos) << refused.message();
  std::ifstream temporary(path_ + ".tmp");
  EXPECT_EQ(std::string(std::istreambuf_iterator<char>(temporary), {}), other_bytes);
  EXPECT_EQ(ReadFile(), snapshot);
  close(other);
  // Once the other save is gone, saving works.
  EXPECT_TRUE(smaller.SaveSnapshot(path_).ok());
}

TEST_F(DescriptorSnapshotTest, SaveFailsCleanly) {
  DescriptorIndex empty(FewChecks());
  EXPECT_FALSE(empty.SaveSnapshot(path_).ok());

  DescriptorIndexOptions hnsw;
  hnsw.method = DescriptorSearch::kHnsw;
  DescriptorIndex graph(hnsw);
  AddBlocks(blocks_, 0, 5, &graph);
  EXPECT_FALSE(graph.SaveSnapshot(path_).ok());

  DescriptorIndex grown(FewChecks());
  AddBlocks(blocks_, 0, 5, &grown);
  const Status missing_dir = grown.SaveSnapshot(dir_ + "/no/such/dir/map.db.index");
  EXPECT_EQ(missing_dir.code(), StatusCode::kIoError);
  // Nothing was written anywhere.
  EXPECT_TRUE(std::filesystem::is_empty(dir_));
}

TEST_F(DescriptorSnapshotTest, HnswIgnoresDeferralAndSnapshots) {
  DescriptorIndexOptions hnsw;
  hnsw.method = DescriptorSearch::kHnsw;
  SaveGrown(blocks_.size());
  DescriptorIndex graph(hnsw);
  graph.DeferInsertion();
  AddBlocks(blocks_, 0, blocks_.size(), &graph);
  EXPECT_FALSE(graph.FinishDeferred(path_).used);
  DescriptorIndex grown(hnsw);
  AddBlocks(blocks_, 0, blocks_.size(), &grown);
  EXPECT_EQ(Answers(graph, queries_), Answers(grown, queries_));
}

}  // namespace
}  // namespace placerec
