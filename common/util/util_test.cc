#include <unistd.h>

#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "common/util/csv.h"
#include "common/util/ids.h"
#include "common/util/memory.h"
#include "common/util/options.h"
#include "common/util/paths.h"
#include "common/util/stage.h"
#include "common/util/status.h"

namespace placerec {
namespace {

TEST(MemoryTest, SeesThisProcessGrow) {
  ResidentMemory before;
  ASSERT_TRUE(ReadResidentMemory(0, &before));
  EXPECT_GT(before.current_mib, 0);
  EXPECT_GE(before.peak_mib, before.current_mib);
  // 64 MiB, every page written, so that it is resident.
  std::vector<char> block(64 << 20);
  std::memset(block.data(), 1, block.size());
  ResidentMemory after;
  ASSERT_TRUE(ReadResidentMemory(getpid(), &after));
  EXPECT_GE(after.current_mib - before.current_mib, 48) << block[block.size() / 2];
  EXPECT_GE(after.peak_mib, after.current_mib);
}

TEST(MemoryTest, ReadAheadReadsAWholeFileThatFitsAndSkipsOneThatDoesNot) {
  EXPECT_GT(AvailableMemoryBytes(), 0);
  const std::string path =
      ::testing::TempDir() + "/placerec_read_ahead_" + std::to_string(getpid());
  {
    std::ofstream out(path, std::ios::binary);
    const std::string block(1 << 20, 'x');
    for (int i = 0; i < 3; ++i) out << block;
    out << "tail";
  }
  const int64_t size = (int64_t{3} << 20) + 4;
  EXPECT_EQ(ReadAhead(path, 0.5), size);
  // 3 MiB is more than a billionth of any machine's memory.
  EXPECT_EQ(ReadAhead(path, 1e-9), 0);
  std::remove(path.c_str());
  EXPECT_EQ(ReadAhead(path, 0.5), 0);
  EXPECT_EQ(ReadAhead(::testing::TempDir(), 0.5), 0);  // a folder
}

TEST(MemoryTest, NoSuchProcessLeavesTheFiguresAlone) {
  // Process ids stay below pid_max.
  std::ifstream in("/proc/sys/kernel/pid_max");
  long pid_max = 0;
  ASSERT_TRUE(in >> pid_max);
  ResidentMemory memory;
  memory.current_mib = 7;
  EXPECT_FALSE(ReadResidentMemory(static_cast<pid_t>(pid_max), &memory));
  EXPECT_EQ(memory.current_mib, 7);
  EXPECT_EQ(memory.peak_mib, 0);
}

TEST(ScopedStageTest, AnExceptionRecordsTheInnermostStageItLeft) {
  try {
    ScopedStage outer("recognize");
    { ScopedStage done("landmarks"); }
    ScopedStage inner("change");
    throw std::runtime_error("failed");
  } catch (const std::runtime_error&) {
    EXPECT_EQ(ScopedStage::TakeFailedStage(), "recognize > change");
  }
  EXPECT_EQ(ScopedStage::TakeFailedStage(), "");  // taken
  // An exception thrown between stages names the stage around it only.
  try {
    ScopedStage outer("analyze");
    { ScopedStage done("sift"); }
    throw std::runtime_error("failed");
  } catch (const std::runtime_error&) {
    EXPECT_EQ(ScopedStage::TakeFailedStage(), "analyze");
  }
}

// The server's worker: frame N fails inside a stage, frame N+1 before any stage. The second
// answer must not name the first one's stage.
TEST(ScopedStageTest, AFailureOutsideEveryStageNamesNone) {
  for (int frame = 0; frame < 2; ++frame) {
    try {
      if (frame == 1) throw std::runtime_error("before any stage");
      ScopedStage stage("analyze");
      ScopedStage inner("segmentation");
      throw std::runtime_error("failed");
    } catch (const std::runtime_error& e) {
      EXPECT_EQ(ScopedStage::TakeFailedStage(), frame == 0 ? "analyze > segmentation" : "")
          << e.what();
    }
  }
  // A record nobody took is forgotten when a stage is next entered normally.
  try {
    ScopedStage stage("decode");
    throw std::runtime_error("failed");
  } catch (const std::runtime_error&) {
  }
  { ScopedStage next("analyze"); }
  EXPECT_EQ(ScopedStage::TakeFailedStage(), "");
}

TEST(ScopedStageTest, DeepNestingKeepsTheInnermostStages) {
  const char* names[] = {"s0",  "s1",  "s2",  "s3",  "s4",  "s5",  "s6",  "s7",  "s8",  "s9",
                         "s10", "s11", "s12", "s13", "s14", "s15", "s16", "s17", "s18", "s19"};
  std::function<void(int)> nest = [&](int depth) {
    ScopedStage stage(names[depth]);
    if (depth == 19) throw std::runtime_error("deep");
    nest(depth + 1);
  };
  try {
    nest(0);
  } catch (const std::runtime_error&) {
    std::string expected;
    for (int i = 20 - ScopedStage::kMaxDepth; i < 20; ++i) {
      expected += (expected.empty() ? "" : " > ") + std::string(names[i]);
    }
    EXPECT_EQ(ScopedStage::TakeFailedStage(), expected);
  }
}

TEST(ScopedStageTest, EachThreadHasItsOwnStages) {
  try {
    ScopedStage stage("main");
    std::thread other([] {
      try {
        ScopedStage worker("worker");
        throw std::runtime_error("failed");
      } catch (const std::runtime_error&) {
        EXPECT_EQ(ScopedStage::TakeFailedStage(), "worker");
      }
    });
    other.join();
    throw std::runtime_error("failed");
  } catch (const std::runtime_error&) {
    EXPECT_EQ(ScopedStage::TakeFailedStage(), "main");
  }
}

TEST(StatusTest, OkAndErrors) {
  EXPECT_TRUE(Status::Ok().ok());
  const Status error = Status::BadImage("width 0");
  EXPECT_FALSE(error.ok());
  EXPECT_EQ(error.code(), StatusCode::kBadImage);
  EXPECT_EQ(error.ToString(), "bad image: width 0");
  StatusOr<int> value(7);
  ASSERT_TRUE(value.ok());
  EXPECT_EQ(*value, 7);
  StatusOr<int> failed(Status::NotFound("x"));
  EXPECT_FALSE(failed.ok());
  EXPECT_EQ(failed.status().code(), StatusCode::kNotFound);
}

TEST(TypedIdTest, InvalidByDefault) {
  EXPECT_FALSE(LandmarkId().IsValid());
  EXPECT_TRUE(LandmarkId(0).IsValid());
  EXPECT_EQ(PlaceId(3), PlaceId(3));
  EXPECT_NE(PlaceId(3), PlaceId::Invalid());
}

TEST(CsvTest, ReadsHeaderAndRows) {
  const std::string path = ::testing::TempDir() + "/placerec_csv_test.csv";
  {
    std::ofstream out(path);
    out << "frame,robot,image\r\n0,left,a.jpg\n1,right,b.jpg\n\n";
  }
  StatusOr<CsvTable> table = ReadCsv(path);
  ASSERT_TRUE(table.ok()) << table.status().ToString();
  ASSERT_EQ(table->rows.size(), 2u);
  EXPECT_EQ(table->Column("robot"), 1);
  EXPECT_EQ(table->Column("missing"), -1);
  EXPECT_EQ(table->rows[1][2], "b.jpg");
  std::remove(path.c_str());
}

TEST(CsvTest, RejectsRaggedRowsAndMissingFiles) {
  const std::string path = ::testing::TempDir() + "/placerec_csv_bad.csv";
  {
    std::ofstream out(path);
    out << "a,b\n1,2,3\n";
  }
  StatusOr<CsvTable> table = ReadCsv(path);
  ASSERT_FALSE(table.ok());
  EXPECT_NE(table.status().message().find(":2: expected 2 fields"), std::string::npos);
  EXPECT_EQ(ReadCsv(path + ".missing").status().code(), StatusCode::kIoError);
  std::remove(path.c_str());
}

TEST(CsvTest, ParsesNumbersStrictly) {
  long long i = 0;
  double d = 0;
  EXPECT_TRUE(ParseInt64("-42", &i));
  EXPECT_EQ(i, -42);
  EXPECT_FALSE(ParseInt64("42x", &i));
  EXPECT_FALSE(ParseInt64("", &i));
  EXPECT_TRUE(ParseDouble("0.25", &d));
  EXPECT_DOUBLE_EQ(d, 0.25);
  EXPECT_FALSE(ParseDouble("nope", &d));
}

TEST(FlagParserTest, BindsFieldsAndKeepsDefaults) {
  struct Options {
    int k = 300;
    double ratio = 0.8;
    std::string name = "x";
  } options;
  FlagParser parser("test");
  parser.Add("k", &options.k, "k");
  parser.Add("ratio", &options.ratio, "ratio");
  parser.Add("name", &options.name, "name");
  const char* argv[] = {"prog", "--k", "500"};
  bool help = false;
  ASSERT_TRUE(parser.Parse(3, argv, 1, &help).ok());
  EXPECT_FALSE(help);
  EXPECT_EQ(options.k, 500);
  EXPECT_DOUBLE_EQ(options.ratio, 0.8);
  EXPECT_NE(parser.Help().find("--ratio"), std::string::npos);
}

// An unsigned field took "-1" as 2^64 - 1 (a training manifest recorded --seed -1 as
// 18446744073709551615): negative values of unsigned flags are refused.
TEST(FlagParserTest, UnsignedFlagsRefuseNegativeValues) {
  uint64_t seed = 7;
  int offset = 0;
  FlagParser parser("test");
  parser.Add("seed", &seed, "seed");
  parser.Add("offset", &offset, "offset");
  bool help = false;
  const char* negative[] = {"prog", "--seed", "-1"};
  const Status refused = parser.Parse(3, negative, 1, &help);
  EXPECT_FALSE(refused.ok());
  EXPECT_NE(refused.message().find("--seed must not be negative"), std::string::npos)
      << refused.message();
  EXPECT_EQ(seed, 7u);
  const char* joined[] = {"prog", "--seed=-5"};
  EXPECT_FALSE(parser.Parse(2, joined, 1, &help).ok());
  const char* fine[] = {"prog", "--seed", "12", "--offset", "-3"};
  ASSERT_TRUE(parser.Parse(5, fine, 1, &help).ok());
  EXPECT_EQ(seed, 12u);
  EXPECT_EQ(offset, -3);
}

// --help shows a floating-point default as the shortest text that reads back as it.
TEST(FlagParserTest, HelpShowsShortDefaults) {
  double iou = 0.3, area = 0.004, third = 1.0 / 3.0;
  float confidence = 0.7f;
  FlagParser parser("test");
  parser.Add("iou", &iou, "iou");
  parser.Add("area", &area, "area");
  parser.Add("third", &third, "third");
  parser.Add("confidence", &confidence, "confidence");
  const std::string help = parser.Help();
  EXPECT_NE(help.find("--iou arg (=0.3)"), std::string::npos) << help;
  EXPECT_NE(help.find("--area arg (=0.004)"), std::string::npos) << help;
  EXPECT_NE(help.find("(=0.3333333333333333)"), std::string::npos) << help;
  EXPECT_NE(help.find("--confidence arg (=0.7)"), std::string::npos) << help;
  EXPECT_EQ(ShortestText(2.0), "2");
  EXPECT_EQ(ShortestText(10.0), "10");
  EXPECT_EQ(ShortestText(-1e-9), "-1e-09");
}

TEST(FlagParserTest, ReportsUnknownFlagsAndHelp) {
  int k = 1;
  FlagParser parser("test");
  parser.Add("k", &k, "k");
  const char* bad[] = {"prog", "--nope", "1"};
  bool help = false;
  const Status status = parser.Parse(3, bad, 1, &help);
  EXPECT_EQ(status.code(), StatusCode::kInvalidArgument);
  const char* with_help[] = {"prog", "--help"};
  ASSERT_TRUE(parser.Parse(2, with_help, 1, &help).ok());
  EXPECT_TRUE(help);
}

TEST(FlagParserTest, RepeatedFlagsCollectEveryOccurrence) {
  std::vector<std::string> urls;
  FlagParser parser("test");
  parser.AddRepeated("url", &urls, "url");
  const char* argv[] = {"prog", "--url", "udpm://a", "--url", "tcpq://127.0.0.1:7700"};
  bool help = false;
  ASSERT_TRUE(parser.Parse(5, argv, 1, &help).ok());
  EXPECT_EQ(urls, (std::vector<std::string>{"udpm://a", "tcpq://127.0.0.1:7700"}));
}

std::string ReadWhole(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

// Every way of moving (a hard link, and what file systems without hard links get) moves a file
// to a free name and leaves both files alone when the name is taken.
TEST(PathsTest, MoveWithoutReplacingNeverReplacesAFile) {
  for (const MoveWay way :
       {MoveWay::kHardLink, MoveWay::kRenameNoReplace, MoveWay::kReserveAndRename}) {
    const std::string dir = ::testing::TempDir() + "/placerec_move_" + std::to_string(getpid()) +
                            "_" + std::to_string(static_cast<int>(way));
    std::filesystem::remove_all(dir);
    ASSERT_TRUE(MakeDirectories(dir));
    const std::string from = dir + "/work";
    const std::string to = dir + "/map";
    std::ofstream(from) << "merged";
    ASSERT_TRUE(MoveWithoutReplacing(from, to, way).ok()) << static_cast<int>(way);
    EXPECT_FALSE(PathExists(from));
    EXPECT_EQ(ReadWhole(to), "merged");

    std::ofstream(from) << "second";
    const Status taken = MoveWithoutReplacing(from, to, way);
    EXPECT_FALSE(taken.ok());
    EXPECT_NE(taken.message().find("cannot create " + to), std::string::npos) << taken.message();
    EXPECT_EQ(ReadWhole(from), "second");
    EXPECT_EQ(ReadWhole(to), "merged");

    const Status missing = MoveWithoutReplacing(dir + "/none", dir + "/other", way);
    EXPECT_FALSE(missing.ok());
    EXPECT_FALSE(PathExists(dir + "/other"));
    // A file onto itself is a taken name.
    EXPECT_FALSE(MoveWithoutReplacing(to, to, way).ok());
    EXPECT_EQ(ReadWhole(to), "merged");
    std::filesystem::remove_all(dir);
  }
}

// A way that fails passes to the next where the failure says the file system lacks it: a folder
// cannot be hard linked (EPERM), so it is renamed; and where the rename after taking the name
// fails (a folder onto the file that holds the name), only that placeholder is removed.
TEST(PathsTest, MoveWithoutReplacingPassesOnAndCleansUp) {
  const std::string dir = ::testing::TempDir() + "/placerec_move_on_" + std::to_string(getpid());
  std::filesystem::remove_all(dir);
  ASSERT_TRUE(MakeDirectories(dir + "/folder"));
  ASSERT_TRUE(MoveWithoutReplacing(dir + "/folder", dir + "/moved", MoveWay::kHardLink).ok());
  EXPECT_TRUE(std::filesystem::is_directory(dir + "/moved"));
  EXPECT_FALSE(PathExists(dir + "/folder"));

  const Status failed =
      MoveWithoutReplacing(dir + "/moved", dir + "/file", MoveWay::kReserveAndRename);
  EXPECT_FALSE(failed.ok());
  EXPECT_NE(failed.message().find("cannot create " + dir + "/file"), std::string::npos)
      << failed.message();
  EXPECT_FALSE(PathExists(dir + "/file"));
  EXPECT_TRUE(std::filesystem::is_directory(dir + "/moved"));
  std::filesystem::remove_all(dir);
}

TEST(CommandLineTest, DropsTheDirectoryAndQuotesWhatAShellWouldSplit) {
  const char* argv[] = {"/work/build/bin/placerec-train",
                        "background",
                        "--dataset",
                        "../data/msrc_v2",
                        "--out",
                        "my models",
                        "--structured-classes",
                        "a,b",
                        "it's",
                        ""};
  EXPECT_EQ(CommandLine(10, argv),
            "placerec-train background --dataset ../data/msrc_v2 --out 'my models' "
            "--structured-classes a,b 'it'\\''s' ''");
  const char* bare[] = {"placerec-eval"};
  EXPECT_EQ(CommandLine(1, bare), "placerec-eval");
}

}  // namespace
}  // namespace placerec
