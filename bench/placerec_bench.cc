// placerec-bench: speed of the pipeline, measured against OpenCV's SIFT on the same frame in the
// same run (the machine is shared and noisy, so only ratios from one run mean much), and
// retrieval time against synthetic maps of 1,000 to 100,000 landmark objects, and the cost of
// signed frames (protocol 4) against a frame's processing time.
//
//   placerec-bench [--benchmark_filter=REGEX] [--benchmark_repetitions=N] ...
//
// Frames come from ../shared/data (or PLACEREC_DATA); without the data a synthetic frame is
// used and the output says so.
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <map>
#include <memory>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include <benchmark/benchmark.h>
#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "common/image/image.h"
#include "common/organization/filter_bank.h"
#include "common/organization/perceptual_organization.h"
#include "common/organization/scene_organizer.h"
#include "common/organization/textons.h"
#include "common/pipeline/frame_analyzer.h"
#include "common/pipeline/place_map.h"
#include "common/pipeline/recognizer.h"
#include "common/storage/sqlite_store.h"
#include "common/util/logging.h"
#include "common/util/memory.h"
#include "common/util/paths.h"
#include "common/util/timer.h"
#include "proto/auth/signing.h"
#include "server/authenticator.h"

namespace placerec {
namespace {

std::string DataRoot() { return DataDir("", PLACEREC_DEFAULT_DATA_DIR); }

// A synthetic textured frame for machines without the evaluation data.
cv::Mat SyntheticFrame(int width, int height, unsigned seed) {
  std::mt19937 rng(seed);
  cv::Mat frame(height, width, CV_8UC3, cv::Scalar(200, 180, 150));
  std::uniform_int_distribution<int> x(0, width - 1);
  std::uniform_int_distribution<int> y(0, height - 1);
  std::uniform_int_distribution<int> c(0, 255);
  std::uniform_int_distribution<int> r(2, 30);
  for (int i = 0; i < 400; ++i) {
    cv::circle(frame, cv::Point(x(rng), y(rng)), r(rng), cv::Scalar(c(rng), c(rng), c(rng)),
               cv::FILLED);
  }
  return frame;
}

// Gardens Point frame `index` of `walk` (day_left by default) resized to 640x480, or a
// synthetic frame.
cv::Mat Frame640(int index, bool* real, const char* walk = "day_left") {
  char path[512];
  std::snprintf(path, sizeof(path), "%s/gardens_point/%s/Image%03d.jpg", DataRoot().c_str(), walk,
                index);
  StatusOr<cv::Mat> image = ReadImageFile(path);
  *real = image.ok();
  cv::Mat frame = image.ok() ? *image : SyntheticFrame(960, 540, static_cast<unsigned>(index));
  cv::resize(frame, frame, cv::Size(640, 480), 0, 0, cv::INTER_AREA);
  return frame;
}

// Frames 100-139 of a walk: the pipeline benchmarks cycle through them like a moving robot, and
// the SIFT reference runs on the same frames, so their ratio compares like with like.
constexpr int kFirstFrame = 100;
constexpr int kWalkFrames = 40;
// The capture time of the pipeline benchmark's first frame (2026-01-01, microseconds).
constexpr int64_t kBenchStartUtime = 1767225600LL * 1000000;

struct Fixture {
  Fixture() {
    cv::setNumThreads(1);
    for (int i = 0; i < kWalkFrames; ++i) {
      bool real = false;
      walk.push_back(Frame640(kFirstFrame + i, &real));
      real_data = real_data || real;
    }
    frame = walk[20];
    previous.assign(walk.begin() + 17, walk.begin() + 20);
  }
  cv::Mat frame;                  // one frame for the single-stage benchmarks
  std::vector<cv::Mat> previous;  // the three frames before it
  std::vector<cv::Mat> walk;
  bool real_data = false;
};

Fixture& Data() {
  static Fixture fixture;
  return fixture;
}

// The reference: OpenCV SIFT alone (keypoints and descriptors, default settings) on the 640x480
// frames of the walk, in turn.
void BM_SiftReference(benchmark::State& state) {
  std::vector<cv::Mat> gray(Data().walk.size());
  for (size_t i = 0; i < gray.size(); ++i)
    cv::cvtColor(Data().walk[i], gray[i], cv::COLOR_BGR2GRAY);
  size_t i = 0;
  double keypoints = 0;
  for (auto _ : state) {
    cv::Ptr<cv::SIFT> sift = cv::SIFT::create();
    std::vector<cv::KeyPoint> found;
    cv::Mat descriptors;
    sift->detectAndCompute(gray[i++ % gray.size()], cv::noArray(), found, descriptors);
    benchmark::DoNotOptimize(descriptors.data);
    keypoints += static_cast<double>(found.size());
  }
  state.counters["keypoints"] =
      keypoints / std::max<double>(1, static_cast<double>(state.iterations()));
}
BENCHMARK(BM_SiftReference)->Unit(benchmark::kMillisecond)->Iterations(120);

void BM_StageFeatures(benchmark::State& state) {
  const RecognizerOptions options;
  for (auto _ : state) {
    Features features = ExtractFeatures(Data().frame, options.analyzer.features);
    benchmark::DoNotOptimize(features.descriptors.data);
  }
}
BENCHMARK(BM_StageFeatures)->Unit(benchmark::kMillisecond)->MinTime(2.0);

void BM_StageSegmentation(benchmark::State& state) {
  const RecognizerOptions options;
  const SuperpixelSegmenter segmenter(options.analyzer.superpixels);
  for (auto _ : state) {
    const WorkingImage working =
        MakeWorkingImage(Data().frame, options.analyzer.superpixels.working_width);
    SceneSegmentation segmentation = segmenter.Segment(working);
    benchmark::DoNotOptimize(segmentation.labels.data);
  }
}
BENCHMARK(BM_StageSegmentation)->Unit(benchmark::kMillisecond)->MinTime(2.0);

// Everything the analyzer does: SIFT, segmentation, colour invariant, objects.
void BM_StageAnalyze(benchmark::State& state) {
  const FrameAnalyzer analyzer{AnalyzerOptions()};
  for (auto _ : state) {
    FrameObservation observation = analyzer.Analyze(Data().frame);
    benchmark::DoNotOptimize(observation.objects.data());
  }
}
BENCHMARK(BM_StageAnalyze)->Unit(benchmark::kMillisecond)->MinTime(2.0);

// Landmark selection against three remembered frames.
void BM_StageLandmarks(benchmark::State& state) {
  const RecognizerOptions options;
  const FrameAnalyzer analyzer(options.analyzer);
  LandmarkSelector selector(options.landmarks);
  auto descriptors_of = [](const FrameObservation& o) {
    std::vector<cv::Mat> d;
    for (const SceneObject& object : o.objects) d.push_back(object.descriptors);
    return d;
  };
  for (const cv::Mat& frame : Data().previous)
    selector.Remember(descriptors_of(analyzer.Analyze(frame)));
  const std::vector<cv::Mat> current = descriptors_of(analyzer.Analyze(Data().frame));
  for (auto _ : state) {
    LandmarkSelection selection = selector.Select(current);
    benchmark::DoNotOptimize(selection.landmarks.data());
  }
}
BENCHMARK(BM_StageLandmarks)->Unit(benchmark::kMillisecond)->MinTime(2.0);

// The whole pipeline per frame, a robot walking the 40 frames three times: analysis, landmark
// selection, lookup in the map built so far (the second and third laps are revisits), decision,
// the change step at a matched place, and insertion into an in-memory SQLite map. Frames are
// captured one second apart, so that a lap is 40 s and the places of the lap before are past
// the recent-past gap (20 s): with every frame at time 0 no stored place was ever a candidate,
// and no lap was a revisit.
void BM_Pipeline(benchmark::State& state) {
  const RecognizerOptions options;
  StatusOr<std::unique_ptr<LandmarkStore>> store =
      OpenSqliteStore(":memory:", SqliteStoreOptions());
  StatusOr<std::unique_ptr<PlaceMap>> map = PlaceMap::Open(std::move(*store), options.index);
  Recognizer recognizer(options, map->get());
  int64_t sequence = 0;
  int loop_closures = 0;
  std::map<std::string, double> stage_ms;
  for (auto _ : state) {
    const cv::Mat& frame = Data().walk[sequence % Data().walk.size()];
    const int64_t utime = kBenchStartUtime + sequence * 1000000;
    RecognitionResult result = recognizer.Process({"bench", sequence++, utime, true}, frame);
    benchmark::DoNotOptimize(result.matches.data());
    for (const auto& [stage, ms] : result.timings) stage_ms[stage] += ms;
    loop_closures += result.loop_closure ? 1 : 0;
  }
  for (const auto& [stage, ms] : stage_ms) {
    state.counters[stage + "_ms"] =
        ms / std::max<double>(1, static_cast<double>(state.iterations()));
  }
  state.counters["map_landmarks"] = static_cast<double>((*map)->Counts().landmarks);
  state.counters["loop_closures"] = static_cast<double>(loop_closures);
}
BENCHMARK(BM_Pipeline)->Unit(benchmark::kMillisecond)->Iterations(120);

// ---- Signed frames (protocol 4, proto/README.md "Signed frames") ----

// A frame as placerec-client sends Gardens Point day_left Image120: its JPEG file's bytes, signed;
// an answer with five matches, as the server sends it.
struct SigningFixture {
  SigningFixture() {
    key.id = "robots";
    key.secret.assign(kKeyBytes, '\x5a');
    key.may_insert = key.may_query = true;
    std::ifstream in(DataRoot() + "/gardens_point/day_left/Image120.jpg", std::ios::binary);
    std::vector<uint8_t> jpeg{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
    if (jpeg.empty()) cv::imencode(".jpg", Data().frame, jpeg);
    frame.utime = 1800000000000000;
    frame.sequence = 120;
    frame.request_id = 7;
    frame.insert = true;
    frame.encoding = frame_t::ENCODING_JPEG;
    frame.width = frame.height = 0;
    frame.robot = "left";
    frame.size = static_cast<int32_t>(jpeg.size());
    frame.data = std::move(jpeg);
    SignFrame(key, 1, 1800000000000000, &frame);
    bytes = EncodeFrame(frame);
    answer.utime = 1;
    answer.robot = "left";
    answer.sequence = 120;
    answer.request_id = 7;
    answer.frame_utime = frame.utime;
    answer.insert = true;
    answer.status = result_t::STATUS_OK;
    answer.loop_closure = true;
    for (int i = 0; i < 5; ++i) {
      match_t m;
      m.utime = i;
      m.robot = "right";
      m.sequence = i;
      m.place_id = i;
      m.score = 40;
      m.matched_landmarks = 3;
      m.matched_descriptors = 60;
      m.inliers = 40;
      m.classes = {"building", "tree"};
      m.class_counts = {2, 1};
      m.num_classes = 2;
      answer.matches.push_back(m);
    }
    answer.num_matches = 5;
    answer.keypoints = 800;
    answer.objects = 14;
    answer.landmarks = 3;
    answer.stored_descriptors = 90;
    answer.place_id = 120;
    answer.map_places = answer.map_landmarks = answer.map_descriptors = 1000;
    answer.queue_ms = answer.server_ms = 100;
    for (const char* stage : {"decode", "sift", "segmentation", "objects", "landmarks", "index"}) {
      stage_time_t t;
      t.stage = stage;
      t.ms = 10;
      answer.timings.push_back(t);
    }
    answer.num_timings = static_cast<int32_t>(answer.timings.size());
    ClearAnswerSignature(&answer);
  }
  SigningKey key;
  frame_t frame;
  std::vector<uint8_t> bytes;  // the signed frame as published
  result_t answer;
};

SigningFixture& Signing() {
  static SigningFixture fixture;
  return fixture;
}

// The client's cost per send: sign the frame (HMAC over its encoding) and encode it again.
// Scene-change detection (seed §7.2.4) at a revisit, what it adds to a matched frame: robot a
// maps frames 117-120, robot b revisits frame 120 with an object pasted in; timed is the change
// step alone (load and decode the place's thumbnail, fit the homography, compare the views), for
// the ratio to SIFT on the same frame.
void BM_ChangeDetection(benchmark::State& state) {
  StatusOr<std::unique_ptr<LandmarkStore>> store =
      OpenSqliteStore(":memory:", SqliteStoreOptions());
  CHECK(store.ok());
  StatusOr<std::unique_ptr<PlaceMap>> map =
      PlaceMap::Open(std::move(*store), LandmarkIndexOptions());
  CHECK(map.ok());
  RecognizerOptions options;
  Recognizer recognizer(options, map->get());
  std::vector<cv::Mat> frames = Data().previous;
  frames.push_back(Data().frame);
  for (size_t i = 0; i < frames.size(); ++i) {
    recognizer.Process({"a", static_cast<int64_t>(i), static_cast<int64_t>(i) * 1000000, true},
                       frames[i]);
  }
  cv::Mat changed = Data().frame.clone();
  cv::rectangle(changed, cv::Rect(260, 200, 120, 100), cv::Scalar(30, 60, 200), cv::FILLED);
  const FrameObservation observation = recognizer.Analyze(changed);
  const RecognitionResult answer =
      recognizer.Recognize({"b", 0, int64_t{3600} * 1000000, false}, observation);
  if (answer.matches.empty()) {
    state.SkipWithError("the revisit matched no place");
    return;
  }
  const PlaceMatch& best = answer.matches.front();
  size_t changes = 0;
  for (auto _ : state) {
    StatusOr<std::vector<uint8_t>> jpeg = (*map)->LoadThumbnail(best.place.id);
    ChangeReference reference;
    reference.thumbnail = cv::imdecode(*jpeg, cv::IMREAD_COLOR);
    reference.image_width = best.place.image_width;
    reference.point_pairs = best.point_pairs;
    const ChangeResult found = DetectChanges(observation.thumbnail, observation.processed_size,
                                             {reference}, options.change);
    changes = found.changes.size();
    benchmark::DoNotOptimize(changes);
  }
  state.counters["changes"] = static_cast<double>(changes);
  state.counters["checked"] = answer.change.checked ? 1 : 0;
}
BENCHMARK(BM_ChangeDetection)->Unit(benchmark::kMillisecond)->MinTime(2.0);

void BM_AuthSignFrame(benchmark::State& state) {
  frame_t frame = Signing().frame;
  int64_t counter = 1;
  for (auto _ : state) {
    SignFrame(Signing().key, ++counter, 1800000000000000, &frame);
    std::vector<uint8_t> bytes = EncodeFrame(frame);
    benchmark::DoNotOptimize(bytes.data());
  }
  state.counters["frame_bytes"] = static_cast<double>(Signing().bytes.size());
}
BENCHMARK(BM_AuthSignFrame)->Unit(benchmark::kMicrosecond)->MinTime(1.0);

// The server's cost per frame: check the signature over the received bytes, and sign the answer.
void BM_AuthServerPerFrame(benchmark::State& state) {
  const SigningFixture& f = Signing();
  for (auto _ : state) {
    const bool valid = FrameSignatureValid(f.frame, f.key.secret, f.bytes.data(), f.bytes.size());
    benchmark::DoNotOptimize(valid);
    result_t answer = f.answer;
    SignAnswer(f.key, &answer);
    benchmark::DoNotOptimize(answer.signature);
  }
}
BENCHMARK(BM_AuthServerPerFrame)->Unit(benchmark::kMicrosecond)->MinTime(1.0);

// The client's cost per answer: check the server's signature.
void BM_AuthCheckAnswer(benchmark::State& state) {
  result_t answer = Signing().answer;
  SignAnswer(Signing().key, &answer);
  const std::vector<uint8_t> bytes = EncodeAnswer(answer);
  for (auto _ : state) {
    const bool valid = AnswerSignatureValid(answer, Signing().key, bytes.data(), bytes.size());
    benchmark::DoNotOptimize(valid);
  }
}
BENCHMARK(BM_AuthCheckAnswer)->Unit(benchmark::kMicrosecond)->MinTime(1.0);

// The server's replay guard per frame (Authenticator::Check on a small signed frame) while it
// remembers `range(0)` counters of one key within the window (a fleet sharing a key: 100 robots
// at 30 Hz sign 90,000 frames in 30 s).
void BM_AuthReplayGuard(benchmark::State& state) {
  const int remembered = static_cast<int>(state.range(0));
  char path[] = "/tmp/placerec_bench_keys_XXXXXX";
  const int fd = mkstemp(path);
  if (fd < 0) {
    state.SkipWithError("cannot write a keys file in /tmp");
    return;
  }
  close(fd);
  std::ofstream(path, std::ios::trunc) << "robots both " << std::string(2 * kKeyBytes, '5') << "\n";
  AuthOptions options;
  options.keys_file = path;
  const int64_t start = 1800000000000000;
  StatusOr<Authenticator> auth = Authenticator::Create(options, start);
  std::remove(path);
  if (!auth.ok()) {
    state.SkipWithError(auth.status().message().c_str());
    return;
  }
  SigningKey key;
  key.id = "robots";
  key.secret.assign(kKeyBytes, '\x55');
  frame_t frame;
  frame.utime = start;
  frame.robot = "r";
  frame.encoding = frame_t::ENCODING_JPEG;
  frame.insert = true;
  frame.data = {1, 2, 3};
  frame.size = 3;
  // Frames signed at a steady rate, `remembered` of them in the 30 s window: each frame measured
  // comes one step later and the oldest remembered one leaves the window.
  const double step_us = 30e6 / remembered;
  int64_t counter = start;
  int64_t i = 0;
  const auto next = [&] {
    const int64_t signed_at = start + static_cast<int64_t>(step_us * static_cast<double>(i++));
    SignFrame(key, ++counter, signed_at, &frame);
    return auth->Check(frame, signed_at);
  };
  for (int n = 0; n < remembered; ++n) {
    if (!next().ok) {
      state.SkipWithError("a frame of the set-up was refused");
      return;
    }
  }
  for (auto _ : state) {
    const Authenticator::Verdict verdict = next();
    benchmark::DoNotOptimize(verdict.ok);
  }
}
BENCHMARK(BM_AuthReplayGuard)->Arg(1000)->Arg(90000)->Unit(benchmark::kMicrosecond);

// ---- Retrieval against large synthetic maps ----

// PLACEREC_BENCH_POOL=wide: the descriptors of every image of the shared data (Gardens Point's
// three walks without frames 96-144, the bench frame's surroundings; the indoor loop; Stanford
// Background, MSRC and CamVid), each at most 640 px wide and in its own aspect, so that a map
// of 100,000 objects holds most of its descriptors about once, as a map of many real places
// does, instead of the same 25 frames' descriptors many times each (docs/results.md "Is the
// revisited place still found among the clutter?"). PLACEREC_BENCH_POOL_CACHE=FILE keeps them
// between runs; it is not checked against the data or the feature options: remove it when
// either changes.
bool WidePool() {
  const char* pool = std::getenv("PLACEREC_BENCH_POOL");
  return pool != nullptr && std::string(pool) == "wide";
}

cv::Mat WideDescriptorPool() {
  const RecognizerOptions options;
  cv::Mat all;
  // The cache: kPoolMagic, the row count (int32), the rows; any other file is not used.
  static constexpr char kPoolMagic[8] = {'P', 'R', 'P', 'O', 'O', 'L', '1', '\n'};
  const char* cache = std::getenv("PLACEREC_BENCH_POOL_CACHE");
  if (cache != nullptr) {
    std::error_code error;
    const uintmax_t bytes = std::filesystem::file_size(cache, error);
    std::ifstream in(cache, std::ios::binary);
    char magic[sizeof(kPoolMagic)] = {};
    int32_t rows = 0;
    if (!error && in.read(magic, sizeof(magic)) &&
        std::equal(magic, magic + sizeof(magic), kPoolMagic) &&
        in.read(reinterpret_cast<char*>(&rows), sizeof(rows)) && rows > 0 &&
        bytes == sizeof(kPoolMagic) + sizeof(rows) + uintmax_t(rows) * kDescriptorSize) {
      all.create(rows, kDescriptorSize, CV_8U);
      if (in.read(reinterpret_cast<char*>(all.data), int64_t{rows} * kDescriptorSize)) return all;
    }
    all.release();
    if (!error) std::fprintf(stderr, "wide pool: %s is no pool cache; extracting again\n", cache);
  }
  std::vector<std::string> files;
  for (const char* dir :
       {"gardens_point/day_left", "gardens_point/day_right", "gardens_point/night_right",
        "rtabmap_indoor/images", "stanford_background/images", "msrc_v2/images", "camvid/images"}) {
    std::error_code error;
    for (const auto& entry : std::filesystem::directory_iterator(DataRoot() + "/" + dir, error)) {
      const std::string name = entry.path().filename().string();
      int index = -1;
      if (std::string(dir).rfind("gardens_point", 0) == 0 &&
          std::sscanf(name.c_str(), "Image%d", &index) == 1 && index >= 96 && index <= 144) {
        continue;
      }
      files.push_back(entry.path().string());
    }
  }
  std::sort(files.begin(), files.end());
  Timer timer;
  for (size_t f = 0; f < files.size(); ++f) {
    StatusOr<cv::Mat> image = ReadImageFile(files[f]);
    if (!image.ok()) continue;
    cv::Mat frame = *image;
    if (frame.cols > 640) {
      cv::resize(frame, frame, cv::Size(640, frame.rows * 640 / frame.cols), 0, 0, cv::INTER_AREA);
    }
    all.push_back(ExtractFeatures(frame, options.analyzer.features).descriptors);
    if (f % 500 == 0) std::fprintf(stderr, "wide pool: %zu of %zu images\n", f, files.size());
  }
  std::fprintf(stderr, "wide pool: %d descriptors from %zu images in %.0f s\n", all.rows,
               files.size(), timer.ElapsedMs() / 1000);
  if (cache != nullptr && !all.empty()) {
    // Written aside and renamed, so that a run cut short leaves no partial cache.
    const std::string partial = std::string(cache) + ".partial";
    std::ofstream out(partial, std::ios::binary);
    const int32_t rows = all.rows;
    out.write(kPoolMagic, sizeof(kPoolMagic));
    out.write(reinterpret_cast<const char*>(&rows), sizeof(rows));
    out.write(reinterpret_cast<const char*>(all.data), int64_t{rows} * kDescriptorSize);
    out.close();
    std::error_code error;
    if (out) std::filesystem::rename(partial, cache, error);
    if (!out || error) std::fprintf(stderr, "wide pool: could not write %s\n", cache);
  }
  return all;
}

// Real SIFT descriptors as the pool synthetic landmarks are drawn from (with noise), so the
// index sees the structure of real descriptors rather than uniform noise: every 8th frame from
// frame 4 on, which leaves out the query frame (Fixture::frame, frame 120) but holds its
// neighbours 116 and 124, as a map holds an earlier pass's views of a place. (The pool held
// frame 120 itself until 2026-12-07, so that each query descriptor's nearest were noisy copies
// of itself.)
const cv::Mat& DescriptorPool() {
  static cv::Mat pool = [] {
    cv::Mat all;
    const RecognizerOptions options;
    if (WidePool()) {
      all = WideDescriptorPool();
      if (!all.empty()) return all;
      std::fprintf(stderr, "wide pool: no images under %s; the default pool\n", DataRoot().c_str());
    }
    for (int i = 4; i < 200; i += 8) {
      bool real = false;
      const cv::Mat frame = Frame640(i, &real);
      all.push_back(ExtractFeatures(frame, options.analyzer.features).descriptors);
    }
    return all;
  }();
  return pool;
}

// Descriptors of each synthetic landmark object (the mean stored on the Gardens Point runs).
constexpr int kSyntheticRows = 24;

struct SyntheticMap {
  std::unique_ptr<PlaceMap> map;
  MapLookup query;
  double build_seconds = 0;  // inserting every place (store and index)
  // Nearest-neighbour recall of the index against exact search, on a sample of query rows.
  double recall_at_1 = 0;  // the index's nearest is at the exact nearest's distance
  double recall_at_k = 0;  // share of the exact k nearest among the index's k (by distance)
  // The index's nearest within 5 % of the exact nearest's distance (a neighbour the ratio test
  // cannot tell from it), and the median ratio of the exact nearest's distance to the second's:
  // how close the runner-up is, which is what makes recall@1 hard.
  double recall_at_1_within_5pct = 0;
  double exact_ratio_median = 0;
  // Each stored descriptor is a noisy copy of a pool row (its source); a query descriptor's
  // nearest source is the one whose closest copy is nearest. The map holds many copies of each
  // source, all at nearly the same distance, which makes recall@1 a draw among near-ties that
  // no real map has; these two count the source instead: the index's nearest is a copy of the
  // exact nearest source, over every sampled row (recall_source) and over the rows whose
  // nearest source passes the matcher's ratio test against the second nearest source
  // (recall_distinctive; distinctive_share of the rows): the matches recognition keeps.
  std::vector<int32_t> sources;      // pool row of every stored descriptor, slot by slot
  std::vector<PlaceId> true_places;  // the bench frame's true places (InsertTruePlaces)
  double recall_source = 0;
  double recall_distinctive = 0;
  double distinctive_share = 0;
};

// Recall of the map's descriptor index against an exact scan of every stored descriptor, on
// every `step`-th query row: recall@1 counts a row when the index's nearest neighbour is at the
// exact nearest's distance (ties between equally distant descriptors are not misses); recall@k
// is the share of the exact k nearest distances found among the index's k.
void MeasureRecall(SyntheticMap* synthetic, int step) {
  const LandmarkIndex& index = synthetic->map->index();
  // Before the true places: every stored descriptor still has its synthetic source.
  CHECK_EQ(synthetic->sources.size(), index.num_landmarks() * kSyntheticRows);
  const int k = RecognizerOptions().index.matching.knn;
  cv::Mat rows;
  for (const IndexQuery& q : synthetic->query.objects) rows.push_back(q.descriptors);
  cv::Mat sample;
  for (int r = 0; r < rows.rows; r += step) sample.push_back(rows.row(r));
  NeighbourLists approximate;
  index.descriptor_index().Search(sample, k, &approximate);
  std::vector<std::vector<int>> exact(sample.rows);
  // Per sampled row: the exact nearest source, and whether it passes the ratio test against
  // the second nearest source.
  const int sources = DescriptorPool().rows;
  const double ratio = RecognizerOptions().index.matching.ratio;
  std::vector<int> nearest_source(sample.rows, -1);
  std::vector<char> distinctive(sample.rows, 0);
  cv::parallel_for_(cv::Range(0, sample.rows), [&](const cv::Range& range) {
    std::vector<int> by_source(static_cast<size_t>(sources));
    for (int r = range.start; r < range.end; ++r) {
      std::vector<int> best;  // the k smallest distances, a max-heap
      std::fill(by_source.begin(), by_source.end(), std::numeric_limits<int>::max());
      const uint8_t* q = sample.ptr<uint8_t>(r);
      for (size_t slot = 0; slot < index.num_landmarks(); ++slot) {
        const cv::Mat& d = index.landmark(static_cast<int32_t>(slot)).descriptors;
        const int32_t* source = synthetic->sources.data() + slot * kSyntheticRows;
        for (int t = 0; t < d.rows; ++t) {
          const int dist = SquaredDistance(q, d.ptr<uint8_t>(t));
          by_source[source[t]] = std::min(by_source[source[t]], dist);
          if (static_cast<int>(best.size()) < k) {
            best.push_back(dist);
            std::push_heap(best.begin(), best.end());
          } else if (dist < best.front()) {
            std::pop_heap(best.begin(), best.end());
            best.back() = dist;
            std::push_heap(best.begin(), best.end());
          }
        }
      }
      std::sort_heap(best.begin(), best.end());
      exact[r] = std::move(best);
      const auto first = std::min_element(by_source.begin(), by_source.end());
      const int d1 = *first;
      *first = std::numeric_limits<int>::max();
      const int d2 = *std::min_element(by_source.begin(), by_source.end());
      nearest_source[r] = static_cast<int>(first - by_source.begin());
      distinctive[r] = d1 < ratio * ratio * d2 ? 1 : 0;
    }
  });
  int64_t hits_1 = 0;
  int64_t hits_near = 0;
  std::vector<double> ratios;
  int64_t hits_k = 0;
  int64_t total_k = 0;
  int64_t hits_source = 0;
  int64_t hits_distinctive = 0;
  int64_t distinctive_rows = 0;
  for (int r = 0; r < sample.rows; ++r) {
    const std::vector<DescriptorIndex::Neighbour>& found = approximate[r];
    const bool source_found =
        !found.empty() &&
        synthetic->sources[static_cast<size_t>(found.front().owner) * kSyntheticRows +
                           static_cast<size_t>(found.front().row)] == nearest_source[r];
    hits_source += source_found ? 1 : 0;
    if (distinctive[r] != 0) {
      ++distinctive_rows;
      hits_distinctive += source_found ? 1 : 0;
    }
    if (!found.empty() && !exact[r].empty() &&
        static_cast<int>(found.front().distance) == exact[r].front()) {
      ++hits_1;
    }
    if (!found.empty() && !exact[r].empty() &&
        found.front().distance <= 1.05 * 1.05 * exact[r].front()) {
      ++hits_near;
    }
    if (exact[r].size() >= 2 && exact[r][1] > 0) {
      ratios.push_back(std::sqrt(static_cast<double>(exact[r][0]) / exact[r][1]));
    }
    // Multiset intersection of sorted distances.
    std::vector<int> got;
    for (const DescriptorIndex::Neighbour& n : found) got.push_back(static_cast<int>(n.distance));
    std::sort(got.begin(), got.end());
    size_t i = 0;
    size_t j = 0;
    while (i < got.size() && j < exact[r].size()) {
      if (got[i] == exact[r][j]) {
        ++hits_k;
        ++i;
        ++j;
      } else if (got[i] < exact[r][j]) {
        ++i;
      } else {
        ++j;
      }
    }
    total_k += static_cast<int64_t>(exact[r].size());
  }
  synthetic->recall_at_1 = static_cast<double>(hits_1) / std::max(1, sample.rows);
  synthetic->recall_at_k = static_cast<double>(hits_k) / std::max<int64_t>(1, total_k);
  synthetic->recall_at_1_within_5pct = static_cast<double>(hits_near) / std::max(1, sample.rows);
  synthetic->recall_source = static_cast<double>(hits_source) / std::max(1, sample.rows);
  synthetic->recall_distinctive =
      static_cast<double>(hits_distinctive) / std::max<int64_t>(1, distinctive_rows);
  synthetic->distinctive_share = static_cast<double>(distinctive_rows) / std::max(1, sample.rows);
  if (!ratios.empty()) {
    std::nth_element(ratios.begin(), ratios.begin() + ratios.size() / 2, ratios.end());
    synthetic->exact_ratio_median = ratios[ratios.size() / 2];
  }
}

// A map of `landmarks` landmark objects, 10 per place, each with `per_landmark` descriptors
// (the mean stored on the Gardens Point runs); SIFT counts log-uniform in [9, 400] and one or
// two dominant colours. The query is the real frame's objects.
RecognizerOptions BenchRecognizerOptions() {
  RecognizerOptions options;
  // PLACEREC_BENCH_DESCRIPTOR_SEARCH=hnsw|flann: the index the map's descriptors are searched
  // with (the default: the one the server uses).
  const char* method = std::getenv("PLACEREC_BENCH_DESCRIPTOR_SEARCH");
  if (method != nullptr && std::string(method) == "flann") {
    options.index.flann.method = DescriptorSearch::kFlann;
  } else if (method != nullptr && std::string(method) == "hnsw") {
    options.index.flann.method = DescriptorSearch::kHnsw;
  }
  // PLACEREC_BENCH_KNN: nearest neighbours per query descriptor (the server's --match-knn,
  // at most 1000); the recall counters always use the default.
  if (const char* knn = std::getenv("PLACEREC_BENCH_KNN")) {
    options.index.matching.knn = std::clamp(std::atoi(knn), 2, 1000);
  }
  // PLACEREC_BENCH_CHECKS: the k-d tree's leaf checks (the server's --flann-checks).
  if (const char* checks = std::getenv("PLACEREC_BENCH_CHECKS")) {
    options.index.flann.checks = std::max(1, std::atoi(checks));
  }
  // PLACEREC_BENCH_EXACT_PLACES: places matched again exactly (the server's --exact-places).
  if (const char* exact = std::getenv("PLACEREC_BENCH_EXACT_PLACES")) {
    options.index.exact_places = std::clamp(std::atoi(exact), 0, 1000);
  }
  return options;
}

// Inserts `landmarks` synthetic landmark objects into `map`, 10 per place, each with 24
// descriptors (the mean stored on the Gardens Point runs); SIFT counts log-uniform in [9, 400]
// and one or two dominant colours; one place per second of one robot's route (the shared runs'
// rate), so that the vote window (LandmarkIndexOptions::vote_window_seconds) spans a few places
// as on a real route. The same count always gives the same map.
// `sources`, when given, receives the pool row each stored descriptor was drawn from, in the
// order they are inserted (landmark slot by slot).
void FillSyntheticMap(int landmarks, PlaceMap* map, std::vector<int32_t>* sources = nullptr) {
  const int per_landmark = kSyntheticRows;
  const cv::Mat& pool = DescriptorPool();
  CHECK(!pool.empty());
  std::mt19937 rng(42);
  std::uniform_int_distribution<int> pick(0, pool.rows - 1);
  std::uniform_int_distribution<int> noise(-8, 8);
  std::uniform_real_distribution<double> log_count(std::log(9.0), std::log(400.0));
  std::uniform_real_distribution<float> hue(-1.5f, 1.5f);
  std::uniform_real_distribution<float> coordinate(0.0f, 640.0f);
  for (int place = 0; place * 10 < landmarks; ++place) {
    Place p;
    p.robot = "synthetic";
    p.sequence = place;
    p.utime = int64_t{place} * 1000000;
    std::vector<Landmark> batch;
    for (int l = 0; l < 10 && place * 10 + l < landmarks; ++l) {
      Landmark landmark;
      landmark.sift_count = static_cast<int>(std::exp(log_count(rng)));
      landmark.colour.peaks = {hue(rng)};
      if (rng() % 4 == 0) landmark.colour.peaks.push_back(hue(rng));
      landmark.descriptors.create(per_landmark, kDescriptorSize, CV_8U);
      for (int r = 0; r < per_landmark; ++r) {
        const int drawn = pick(rng);
        if (sources != nullptr) sources->push_back(drawn);
        const uint8_t* source = pool.ptr<uint8_t>(drawn);
        uint8_t* row = landmark.descriptors.ptr<uint8_t>(r);
        for (int c = 0; c < kDescriptorSize; ++c) {
          row[c] = cv::saturate_cast<uint8_t>(source[c] + noise(rng));
        }
        landmark.keypoints.emplace_back(cv::Point2f(coordinate(rng), coordinate(rng) * 0.75f),
                                        4.0f);
      }
      landmark.box = cv::Rect(0, 0, 10, 10);
      batch.push_back(std::move(landmark));
    }
    CHECK(map->Insert(&p, &batch).ok());
    if (place > 0 && place % 10000 == 0) {
      std::fprintf(stderr, "synthetic map: %d of %d landmark objects\n", place * 10, landmarks);
    }
  }
}

// The bench frame's objects as a lookup.
MapLookup BenchQuery() {
  const RecognizerOptions options;
  const FrameAnalyzer analyzer(options.analyzer);
  const FrameObservation observation = analyzer.Analyze(Data().frame);
  MapLookup query;
  query.recent.robot = "query";
  query.image_width = observation.processed_size.width;
  for (const SceneObject& object : observation.objects) {
    query.objects.push_back({object.sift_count(), object.colour, object.descriptors});
    std::vector<cv::KeyPoint> keypoints;
    for (int k : object.keypoints) keypoints.push_back(observation.features.keypoints[k]);
    query.object_keypoints.push_back(std::move(keypoints));
  }
  return query;
}

// The bench frame's true places, so that retrieval is also judged by whether it still finds
// the place a frame revisits (issue 24: speed not bought with misses): Gardens Point day_right
// frames 112-128, the other side of the path from the bench frame (day_left 120), inserted
// through the recognizer as robot "right" one second apart, as a server stores a walk. The run
// day_left_then_day_right pairs day_left 120 with day_right 118-122.
constexpr int kTrueWalkFirst = 112;
constexpr int kTrueWalkLast = 128;
constexpr int kQueryFrameIndex = kFirstFrame + 20;  // Fixture::frame
constexpr int kTrueRadius = 2;
constexpr char kTrueRobot[] = "right";  // the true places' robot, whichever walk they are from

const char* TrueWalk() {
  const char* walk = std::getenv("PLACEREC_BENCH_TRUE_WALK");
  return walk != nullptr && std::string(walk) == "day_left" ? "day_left" : "day_right";
}

// The true walk's frames kTrueWalkFirst..kTrueWalkLast, resized as the bench frame; empty
// unless every one of them can be read. PLACEREC_BENCH_TRUE_WALK=day_left takes the bench
// frame's own walk instead of day_right (InsertTruePlaces then leaves out frames 119-121: an
// easy revisit).
std::vector<cv::Mat> TrueWalkFrames() {
  std::vector<cv::Mat> frames;
  if (!Data().real_data) return frames;
  for (int i = kTrueWalkFirst; i <= kTrueWalkLast; ++i) {
    bool real = false;
    frames.push_back(Frame640(i, &real, TrueWalk()));
    if (!real) return {};
  }
  return frames;
}

// Inserts the true places into `map` and returns the ids of those within kTrueRadius of the
// bench frame; none (and nothing inserted) without the true walk's frames.
std::vector<PlaceId> InsertTruePlaces(PlaceMap* map) {
  std::vector<PlaceId> true_places;
  const std::vector<cv::Mat> frames = TrueWalkFrames();
  if (frames.empty()) return true_places;
  const char* walk = TrueWalk();
  Recognizer recognizer(BenchRecognizerOptions(), map);
  for (int i = kTrueWalkFirst; i <= kTrueWalkLast; ++i) {
    if (std::string(walk) == "day_left" && std::abs(i - kQueryFrameIndex) < 2) continue;
    const FrameRequest request{kTrueRobot, i, kBenchStartUtime + int64_t{i} * 1000000, true};
    const RecognitionResult result = recognizer.Process(request, frames[i - kTrueWalkFirst]);
    CHECK(result.status.ok()) << result.status.message();
    if (result.place.IsValid() && std::abs(i - kQueryFrameIndex) <= kTrueRadius) {
      true_places.push_back(result.place);
    }
  }
  return true_places;
}

// Where the best-ranked true place stands among a lookup's answers. It counts as answered when
// it is among the places returned (LoopDecisionOptions::max_matches) with a score above 0: the
// list may end with unverified or discarded places at score 0.
struct TruePlace {
  int rank = 0;  // 1 for the best answer; 0 when no true place is answered
  double score = 0;
};

TruePlace FindTruePlace(const std::vector<PlaceMatch>& places) {
  for (size_t i = 0; i < places.size(); ++i) {
    const PlaceMatch& match = places[i];
    if (match.place.robot == kTrueRobot &&
        std::llabs(match.place.sequence - kQueryFrameIndex) <= kTrueRadius && match.score > 0) {
      return {static_cast<int>(i) + 1, match.score};
    }
  }
  return {};
}

// The bench frame asked as a server asks it (Recognizer::Process, query only, under a robot id
// of its own): its objects and the keypoints outside them, then the loop decision. `loop`: the
// answer is a loop closure to a true place.
TruePlace ServerAnswer(PlaceMap* map, bool* loop) {
  Recognizer recognizer(BenchRecognizerOptions(), map);
  const FrameRequest request{"bench-query", 0, kBenchStartUtime + int64_t{1000} * 1000000, false};
  const RecognitionResult result = recognizer.Process(request, Data().frame);
  CHECK(result.status.ok()) << result.status.message();
  const TruePlace found = FindTruePlace(result.matches);
  *loop = result.loop_closure && found.rank == 1;
  return found;
}

// The true place's answer in a map that holds nothing else: what the synthetic objects'
// clutter is measured against.
const TruePlace& TruePlaceAlone() {
  static const TruePlace alone = [] {
    const RecognizerOptions options = BenchRecognizerOptions();
    StatusOr<std::unique_ptr<LandmarkStore>> store =
        OpenSqliteStore(":memory:", SqliteStoreOptions());
    CHECK(store.ok()) << store.status().message();
    StatusOr<std::unique_ptr<PlaceMap>> map = PlaceMap::Open(std::move(*store), options.index);
    CHECK(map.ok()) << map.status().message();
    if (InsertTruePlaces(map->get()).empty()) return TruePlace();
    return FindTruePlace((*map)->Lookup(BenchQuery(), LoopDecisionOptions()).places);
  }();
  return alone;
}

// A map of `landmarks` synthetic landmark objects in memory; the query is the real frame's
// objects.
SyntheticMap& MapOf(int landmarks) {
  static std::map<int, SyntheticMap> maps;
  auto it = maps.find(landmarks);
  if (it != maps.end()) return it->second;
  const RecognizerOptions options = BenchRecognizerOptions();
  StatusOr<std::unique_ptr<LandmarkStore>> store =
      OpenSqliteStore(":memory:", SqliteStoreOptions());
  StatusOr<std::unique_ptr<PlaceMap>> map = PlaceMap::Open(std::move(*store), options.index);
  const auto build_start = std::chrono::steady_clock::now();
  std::vector<int32_t> sources;
  FillSyntheticMap(landmarks, map->get(), &sources);
  SyntheticMap& entry = maps[landmarks];
  entry.sources = std::move(sources);
  // The index's slots are the landmarks in the order inserted, each with its kSyntheticRows
  // descriptors: what `sources` is read by.
  const LandmarkIndex& index = (*map)->index();
  CHECK_EQ(entry.sources.size(), index.num_landmarks() * kSyntheticRows);
  for (const size_t slot : {size_t{0}, index.num_landmarks() - 1}) {
    const cv::Mat& stored = index.landmark(static_cast<int32_t>(slot)).descriptors;
    const cv::Mat drawn = DescriptorPool().row(entry.sources[slot * kSyntheticRows]);
    CHECK_LE(cv::norm(stored.row(0), drawn, cv::NORM_INF), 8.0) << "slot " << slot;
  }
  entry.build_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - build_start).count();
  entry.map = std::move(*map);
  entry.query = BenchQuery();
  // PLACEREC_BENCH_RECALL_STEP: every how many query rows recall is measured on (default 6; 1
  // for every row, which the distinctive rows, few in this bench, need).
  const char* step = std::getenv("PLACEREC_BENCH_RECALL_STEP");
  MeasureRecall(&entry, step != nullptr ? std::max(1, std::atoi(step)) : 6);
  // After the recall, which reads every stored descriptor by its synthetic source.
  entry.true_places = InsertTruePlaces(entry.map.get());
  return entry;
}

// Resident memory of this process: current and peak, MiB (unchanged when it cannot be read).
void ResidentMiB(double* current, double* peak) {
  ResidentMemory memory;
  if (!ReadResidentMemory(0, &memory)) return;
  *current = memory.current_mib;
  *peak = memory.peak_mib;
}

// The places a lookup answers, one line each (id and score), best first.
std::string AnswerText(const MapLookupResult& result) {
  std::ostringstream text;
  for (const PlaceMatch& match : result.places) {
    text << match.place.id.value() << " " << match.score << "\n";
  }
  return text.str();
}

// A large map on disk (PLACEREC_BENCH_MAP_FILE, PLACEREC_BENCH_MAP_LANDMARKS landmark objects,
// default 1,000,000): the first run builds the file and keeps the bench frame's answer beside it
// (FILE.answer); every later run reopens it as the server does and reports the time to open,
// this process's memory and whether the answer is the same. A run whose reopen did not find an
// up-to-date descriptor index snapshot (FILE.index) writes one, as a server's clean shutdown
// does: the next run opens from it. So: the first run builds, the second reopens without a
// snapshot and writes it, the third reopens from it, each in a process of its own (memory).
void BM_MapReopen(benchmark::State& state) {
  const std::string path = std::getenv("PLACEREC_BENCH_MAP_FILE");
  const char* count = std::getenv("PLACEREC_BENCH_MAP_LANDMARKS");
  const int landmarks = count != nullptr ? std::atoi(count) : 1000000;
  const RecognizerOptions options = BenchRecognizerOptions();
  // The settings the file was built with head its answer file; a file built otherwise (or a
  // build cut short, which leaves no answer file) is refused rather than measured. "route 1 Hz":
  // places one second apart (FillSyntheticMap); files from before it held every place at time 0.
  const char* method = std::getenv("PLACEREC_BENCH_DESCRIPTOR_SEARCH");
  // "true places": the bench frame's true places among the synthetic ones (InsertTruePlaces),
  // so that the answer compared after reopening is not empty; "pool wide": WideDescriptorPool;
  // "knn", "checks", "exact places": PLACEREC_BENCH_KNN, PLACEREC_BENCH_CHECKS and
  // PLACEREC_BENCH_EXACT_PLACES, which change the answer.
  const bool true_walk = !TrueWalkFrames().empty();
  const std::string settings = "landmarks " + std::to_string(landmarks) + " descriptor-search " +
                               (method != nullptr ? method : "default") + " route 1 Hz" +
                               (WidePool() ? " pool wide" : "") +
                               (true_walk ? std::string(" true places ") + TrueWalk() : "") +
                               " knn " + std::to_string(options.index.matching.knn) + " checks " +
                               std::to_string(options.index.flann.checks) + " exact places " +
                               std::to_string(options.index.exact_places) + "\n";
  const bool existed = std::ifstream(path).good();
  if (existed && !std::ifstream(path + ".answer").good()) {
    state.SkipWithError((path + " has no .answer file (a build cut short?): remove it").c_str());
    return;
  }
  if (!existed) {
    SqliteStoreOptions build;
    build.synchronous_full = false;  // a throw-away file: no fsync per place
    StatusOr<std::unique_ptr<LandmarkStore>> store = OpenSqliteStore(path, build);
    CHECK(store.ok()) << store.status().message();
    StatusOr<std::unique_ptr<PlaceMap>> map = PlaceMap::Open(std::move(*store), options.index);
    CHECK(map.ok()) << map.status().message();
    FillSyntheticMap(landmarks, map->get());
    InsertTruePlaces(map->get());
    std::ofstream(path + ".answer")
        << settings << AnswerText((*map)->Lookup(BenchQuery(), LoopDecisionOptions()));
  }
  std::ifstream answer_file(path + ".answer");
  std::string built_with;
  std::getline(answer_file, built_with);
  if (built_with + "\n" != settings) {
    state.SkipWithError((path + " was built with " + built_with + ", not " + settings).c_str());
    return;
  }
  std::stringstream expected;
  expected << answer_file.rdbuf();
  const MapLookup query = BenchQuery();
  double before = 0;
  double unused = 0;
  ResidentMiB(&before, &unused);
  for (auto _ : state) {
    Timer store_timer;
    StatusOr<std::unique_ptr<LandmarkStore>> store = OpenSqliteStore(path, SqliteStoreOptions());
    CHECK(store.ok()) << store.status().message();
    // The file's checks (quick_check), before PlaceMap::Open.
    state.counters["store_open_s"] = store_timer.ElapsedMs() / 1000.0;
    StatusOr<std::unique_ptr<PlaceMap>> map = PlaceMap::Open(std::move(*store), options.index);
    CHECK(map.ok()) << map.status().message();
    const SnapshotLoad& snapshot = (*map)->snapshot_load();
    double rss = 0;
    double peak = 0;
    ResidentMiB(&rss, &peak);
    const MapCounts counts = (*map)->Counts();
    const MapLookupResult result = (*map)->Lookup(query, LoopDecisionOptions());
    const std::string answer = AnswerText(result);
    if (true_walk) state.counters["true_rank"] = FindTruePlace(result.places).rank;
    state.counters["open_s"] = (*map)->open_ms() / 1000.0;
    state.counters["rss_mib"] = rss;
    state.counters["peak_mib"] = peak;
    state.counters["map_rss_mib"] = rss - before;
    state.counters["bytes_per_landmark"] =
        (rss - before) * 1024.0 * 1024.0 / std::max<double>(1, counts.landmarks);
    state.counters["landmarks"] = static_cast<double>(counts.landmarks);
    state.counters["answer_places"] =
        static_cast<double>(std::count(answer.begin(), answer.end(), '\n'));
    state.counters["answer_same"] = answer == expected.str() ? 1 : 0;
    state.counters["built_now"] = existed ? 0 : 1;
    state.counters["snapshot_used"] = snapshot.used ? 1 : 0;
    state.counters["snapshot_load_s"] = snapshot.load_ms / 1000.0;
    state.counters["inserted_descriptors"] = static_cast<double>(snapshot.inserted_points);
    state.counters["insert_s"] = snapshot.insert_ms / 1000.0;
    state.counters["store_load_s"] =
        ((*map)->open_ms() - snapshot.load_ms - snapshot.insert_ms) / 1000.0;
    // A run that built the map leaves it without a snapshot, so that the next run measures a
    // reopen without one (and writes it) and the one after that a reopen from it.
    Timer save_timer;
    bool written = false;
    const Status saved = existed ? (*map)->SaveIndexSnapshot(&written) : Status::Ok();
    CHECK(saved.ok()) << saved.message();
    state.counters["snapshot_write_s"] = written ? save_timer.ElapsedMs() / 1000.0 : 0.0;
    std::printf("BM_MapReopen: %s\n", snapshot.message.c_str());
  }
}

void RetrievalOn(int landmarks, benchmark::State& state) {
  SyntheticMap& synthetic = MapOf(landmarks);
  const LoopDecisionOptions options;
  int descriptors = 0;
  for (const IndexQuery& q : synthetic.query.objects) descriptors += q.descriptors.rows;
  // Every stage's time is the mean over the iterations.
  IndexQueryStats sum;
  double ranking_ms = 0;
  int n = 0;
  MapLookupResult result;
  for (auto _ : state) {
    result = synthetic.map->Lookup(synthetic.query, options);
    benchmark::DoNotOptimize(result.places.data());
    sum.filter_ms += result.stats.filter_ms;
    sum.search_ms += result.stats.search_ms;
    sum.objects_ms += result.stats.objects_ms;
    sum.places_ms += result.stats.places_ms;
    sum.exact_ms += result.stats.exact_ms;
    ranking_ms += result.ranking_ms;
    ++n;
  }
  n = std::max(1, n);
  state.counters["filter_ms"] = sum.filter_ms / n;
  state.counters["search_ms"] = sum.search_ms / n;
  state.counters["objects_ms"] = sum.objects_ms / n;
  state.counters["places_ms"] = sum.places_ms / n;
  state.counters["exact_ms"] = sum.exact_ms / n;
  state.counters["ranking_ms"] = ranking_ms / n;
  const MapCounts counts = synthetic.map->Counts();
  state.counters["landmarks"] = static_cast<double>(counts.landmarks);
  state.counters["map_descriptors"] = static_cast<double>(counts.descriptors);
  state.counters["query_objects"] = static_cast<double>(synthetic.query.objects.size());
  state.counters["query_descriptors"] = descriptors;
  state.counters["recall_at_1"] = synthetic.recall_at_1;
  state.counters["recall_at_k"] = synthetic.recall_at_k;
  state.counters["recall_at_1_5pct"] = synthetic.recall_at_1_within_5pct;
  state.counters["exact_d1_d2"] = synthetic.exact_ratio_median;
  state.counters["recall_source"] = synthetic.recall_source;
  state.counters["recall_distinct"] = synthetic.recall_distinctive;
  state.counters["distinct_share"] = synthetic.distinctive_share;
  state.counters["build_s"] = synthetic.build_seconds;
  if (!synthetic.true_places.empty()) {
    const TruePlace found = FindTruePlace(result.places);
    // The true place: its rank among the answers (0: not answered), its score (a loop closure
    // from LoopDecisionOptions::min_score) and the same score with no synthetic objects; and
    // before the geometric check, how many true places are candidates with place-level
    // matches and how many matches they hold (LandmarkIndex::Query).
    const IndexResult index_result =
        synthetic.map->index().Query(synthetic.query.objects, [](PlaceId) { return true; });
    int candidates = 0;
    size_t points = 0;
    for (const PlaceId place : synthetic.true_places) {
      const auto it = index_result.place_points.find(place);
      if (it == index_result.place_points.end() || it->second.empty()) continue;
      ++candidates;
      points += it->second.size();
    }
    state.counters["true_candidates"] = candidates;
    state.counters["true_points"] = static_cast<double>(points);
    state.counters["true_rank"] = found.rank;
    state.counters["true_score"] = found.score;
    state.counters["true_loop"] = found.rank == 1 && found.score >= options.min_score ? 1 : 0;
    state.counters["true_alone"] = TruePlaceAlone().score;
    // The same through the recognizer, as a server answers the frame.
    bool server_loop = false;
    const TruePlace server = ServerAnswer(synthetic.map.get(), &server_loop);
    state.counters["server_rank"] = server.rank;
    state.counters["server_score"] = server.score;
    state.counters["server_loop"] = server_loop ? 1 : 0;
  }
}
void BM_Retrieval(benchmark::State& state) { RetrievalOn(static_cast<int>(state.range(0)), state); }
BENCHMARK(BM_Retrieval)->Arg(1000)->Arg(10000)->Arg(100000)->Unit(benchmark::kMillisecond);
// 1,000,000 landmark objects (24 million descriptors: many GB and a long build) only when
// PLACEREC_BENCH_MILLION is set (registered in main).

// ---- Perceptual Organization segmentation (seed Ch. 3), stage by stage on the frame ----

// The shipped models (models/ or PLACEREC_MODELS) and the frame's intermediate results, computed
// once so that each stage is timed on its own input. Null when the models are missing.
struct OrganizationFixture {
  OrganizationFixture() {
    StatusOr<SceneOrganizer> created =
        SceneOrganizer::Create(SceneOrganizerOptions::ForSegmentation());
    if (!created.ok()) {
      error = created.status().ToString();
      return;
    }
    organizer = std::make_unique<SceneOrganizer>(std::move(*created));
    const SceneOrganizerOptions& options = organizer->options();
    working = MakeWorkingImage(Data().frame, options.superpixels.working_width);
    features = organizer->Features(working);
    parts = organizer->ClassifiedSuperpixels(working);
    assigner = std::make_unique<TextonAssigner>(organizer->model().textons);
    map = ComputeTextonMap(features, *assigner, options.texton_stride);
    appearance = RegionAppearance(parts.labels, parts.size(), map, features, *assigner);
    boundary = organizer->BoundaryScores(parts, features);
  }
  std::string error;
  std::unique_ptr<SceneOrganizer> organizer;
  std::unique_ptr<TextonAssigner> assigner;
  WorkingImage working;
  cv::Mat features;
  TextonMap map;
  cv::Mat appearance;
  cv::Mat boundary;         // learned boundary scores on the superpixels' cracks (or empty)
  SceneSegmentation parts;  // classified superpixels
};

OrganizationFixture* Organization(benchmark::State& state) {
  static OrganizationFixture fixture;
  if (fixture.organizer == nullptr) {
    state.SkipWithError(("no background models: " + fixture.error).c_str());
    return nullptr;
  }
  return &fixture;
}

// Improved superpixels (FH plus small-region and similar-colour merges, seed §3.6) at the
// working resolution, the working image (resize, Lab) included.
void BM_OrgSuperpixels(benchmark::State& state) {
  OrganizationFixture* o = Organization(state);
  if (o == nullptr) return;
  const SuperpixelOptions& options = o->organizer->options().superpixels;
  for (auto _ : state) {
    const WorkingImage working = MakeWorkingImage(Data().frame, options.working_width);
    SceneSegmentation superpixels = ComputeSuperpixels(working, options);
    benchmark::DoNotOptimize(superpixels.labels.data);
  }
  state.counters["superpixels"] = o->parts.size();
}
BENCHMARK(BM_OrgSuperpixels)->Unit(benchmark::kMillisecond)->MinTime(2.0);

// The 17 filters plus Lab (seed §4.1.1) on the working image.
void BM_OrgFilterBank(benchmark::State& state) {
  OrganizationFixture* o = Organization(state);
  if (o == nullptr) return;
  for (auto _ : state) {
    cv::Mat features = ComputeFilterBank(o->working.lab);
    benchmark::DoNotOptimize(features.data);
  }
}
BENCHMARK(BM_OrgFilterBank)->Unit(benchmark::kMillisecond)->MinTime(2.0);

// Nearest of the 150 textons on the stride grid, then the 151-d appearance of every superpixel.
void BM_OrgTextons(benchmark::State& state) {
  OrganizationFixture* o = Organization(state);
  if (o == nullptr) return;
  const int stride = o->organizer->options().texton_stride;
  for (auto _ : state) {
    const TextonMap map = ComputeTextonMap(o->features, *o->assigner, stride);
    cv::Mat appearance =
        RegionAppearance(o->parts.labels, o->parts.size(), map, o->features, *o->assigner);
    benchmark::DoNotOptimize(appearance.data);
  }
}
BENCHMARK(BM_OrgTextons)->Unit(benchmark::kMillisecond)->MinTime(2.0);

// The five boosted classifiers on every superpixel.
void BM_OrgClassifiers(benchmark::State& state) {
  OrganizationFixture* o = Organization(state);
  if (o == nullptr) return;
  for (auto _ : state) {
    std::vector<SegmentClass> classes = o->organizer->model().classifier.Classify(
        o->appearance, o->organizer->options().background_threshold,
        o->organizer->options().one_per_class);
    benchmark::DoNotOptimize(classes.data());
  }
}
BENCHMARK(BM_OrgClassifiers)->Unit(benchmark::kMillisecond)->MinTime(2.0);

// The learned boundary classifier (boundary.h) on every pixel along a superpixel boundary, when
// the grouping model reads it.
void BM_OrgBoundary(benchmark::State& state) {
  OrganizationFixture* o = Organization(state);
  if (o == nullptr) return;
  if (o->boundary.empty()) {
    state.SkipWithError("the grouping model does not read learned boundary scores");
    return;
  }
  for (auto _ : state) {
    cv::Mat scores = o->organizer->BoundaryScores(o->parts, o->features);
    benchmark::DoNotOptimize(scores.data);
  }
  state.counters["crack_pixels"] = cv::countNonZero(CrackPixels(o->parts.labels));
}
BENCHMARK(BM_OrgBoundary)->Unit(benchmark::kMillisecond)->MinTime(2.0);

// The learned region merging of the classified superpixels (region_merging.h).
void BM_OrgLearnedMerge(benchmark::State& state) {
  OrganizationFixture* o = Organization(state);
  if (o == nullptr) return;
  int regions = 0;
  for (auto _ : state) {
    SceneSegmentation merged =
        o->organizer->MergeParts(o->parts, o->appearance, o->working.lab, o->boundary);
    regions = merged.size();
    benchmark::DoNotOptimize(merged.labels.data);
  }
  state.counters["regions"] = regions;
}
BENCHMARK(BM_OrgLearnedMerge)->Unit(benchmark::kMillisecond)->MinTime(2.0);

// Algorithm 2 (rounds of Algorithm 1) and the final merges with the seed's options on the
// classified superpixels: the grouping recognition uses (AnalyzerOptions).
void BM_OrgPerceptualOrganization(benchmark::State& state) {
  OrganizationFixture* o = Organization(state);
  if (o == nullptr) return;
  int segments = 0;
  for (auto _ : state) {
    SceneSegmentation scene =
        OrganizeScene(o->parts.labels, o->parts.classes, o->working.lab, OrganizationOptions());
    segments = scene.size();
    benchmark::DoNotOptimize(scene.labels.data);
  }
  state.counters["segments"] = segments;
}
BENCHMARK(BM_OrgPerceptualOrganization)->Unit(benchmark::kMillisecond)->MinTime(2.0);

// The whole segmentation of a 640x480 frame as `placerec-eval segment` runs it by default:
// working image, superpixels, filter bank, textons, classifiers, learned merging.
void BM_OrgWholeSegmentation(benchmark::State& state) {
  OrganizationFixture* o = Organization(state);
  if (o == nullptr) return;
  const int width = o->organizer->options().superpixels.working_width;
  for (auto _ : state) {
    const WorkingImage working = MakeWorkingImage(Data().frame, width);
    SceneSegmentation scene = o->organizer->Segment(working);
    benchmark::DoNotOptimize(scene.labels.data);
  }
}
BENCHMARK(BM_OrgWholeSegmentation)->Unit(benchmark::kMillisecond)->MinTime(2.0);

// The same as recognition runs it (AnalyzerOptions: the seed's grouping instead of the learned
// merging, the five-way background decision).
void BM_OrgWholeSegmentationSeed(benchmark::State& state) {
  OrganizationFixture* o = Organization(state);
  if (o == nullptr) return;
  SceneOrganizerOptions options = AnalyzerOptions().organization;
  options.models_dir = o->organizer->options().models_dir;
  const SceneOrganizer seed(options, std::make_shared<BackgroundModel>(o->organizer->model()));
  for (auto _ : state) {
    const WorkingImage working = MakeWorkingImage(Data().frame, options.superpixels.working_width);
    SceneSegmentation scene = seed.Segment(working);
    benchmark::DoNotOptimize(scene.labels.data);
  }
}
BENCHMARK(BM_OrgWholeSegmentationSeed)->Unit(benchmark::kMillisecond)->MinTime(2.0);

// Collects mean real time per benchmark so that ratios can be printed after the run.
class RatioReporter : public benchmark::ConsoleReporter {
 public:
  void ReportRuns(const std::vector<Run>& runs) override {
    ConsoleReporter::ReportRuns(runs);
    for (const Run& run : runs) {
      if (run.run_type != Run::RT_Iteration && run.aggregate_name != "mean") continue;
      times_[run.run_name.function_name +
             (run.run_name.args.empty() ? "" : "/" + run.run_name.args)] =
          run.GetAdjustedRealTime();
    }
  }
  std::map<std::string, double> times_;
};

}  // namespace
}  // namespace placerec

int main(int argc, char** argv) {
  placerec::InitLogging(argv[0]);
  FLAGS_minloglevel = 1;  // no INFO lines between benchmark rows
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  if (std::getenv("PLACEREC_BENCH_MILLION") != nullptr) {
    benchmark::RegisterBenchmark("BM_Retrieval/1000000", [](benchmark::State& state) {
      placerec::RetrievalOn(1000000, state);
    })->Unit(benchmark::kMillisecond);
  }
  if (std::getenv("PLACEREC_BENCH_MAP_FILE") != nullptr) {
    benchmark::RegisterBenchmark("BM_MapReopen", placerec::BM_MapReopen)
        ->Unit(benchmark::kSecond)
        ->Iterations(1);
  }
  std::printf("frames: %s\n", placerec::Data().real_data
                                  ? "Gardens Point day_left Image100-139 resized to 640x480"
                                  : "synthetic 640x480 (no ../shared/data; set PLACEREC_DATA)");
  placerec::RatioReporter reporter;
  benchmark::RunSpecifiedBenchmarks(&reporter);
  const auto& t = reporter.times_;
  const auto sift = t.find("BM_SiftReference");
  if (sift != t.end() && sift->second > 0) {
    std::printf(
        "\nRatios to OpenCV SIFT in this run (stages: frame Image120; pipeline: the same "
        "40 frames as the SIFT reference):\n");
    for (const char* name :
         {"BM_StageFeatures", "BM_StageSegmentation", "BM_StageAnalyze", "BM_StageLandmarks",
          "BM_Pipeline", "BM_ChangeDetection", "BM_OrgSuperpixels", "BM_OrgFilterBank",
          "BM_OrgTextons", "BM_OrgClassifiers", "BM_OrgBoundary", "BM_OrgLearnedMerge",
          "BM_OrgPerceptualOrganization", "BM_OrgWholeSegmentation",
          "BM_OrgWholeSegmentationSeed"}) {
      const auto it = t.find(name);
      if (it != t.end()) std::printf("  %-30s %6.2f\n", name, it->second / sift->second);
    }
  }
  const auto pipeline = t.find("BM_Pipeline");
  const auto sign = t.find("BM_AuthSignFrame");
  const auto server = t.find("BM_AuthServerPerFrame");
  const auto check = t.find("BM_AuthCheckAnswer");
  if (pipeline != t.end() && sign != t.end() && server != t.end() && check != t.end() &&
      pipeline->second > 0) {
    // Every time is in its benchmark's unit: the pipeline in ms, the signing in us.
    const double frame_us = pipeline->second * 1000;
    const double auth_us = sign->second + server->second + check->second;
    std::printf(
        "\nSigned frames: sign %.1f us + server check and answer signature %.1f us + answer "
        "check %.1f us = %.1f us per frame, %.3f %% of the pipeline's %.1f ms per frame\n",
        sign->second, server->second, check->second, auth_us, 100 * auth_us / frame_us,
        pipeline->second);
  }
  const auto r10k = t.find("BM_Retrieval/10000");
  const auto r100k = t.find("BM_Retrieval/100000");
  if (r10k != t.end() && r100k != t.end() && r10k->second > 0) {
    std::printf("\nRetrieval growth 10,000 -> 100,000 landmark objects: %.2fx\n",
                r100k->second / r10k->second);
  }
  const auto r1m = t.find("BM_Retrieval/1000000");
  if (r100k != t.end() && r1m != t.end() && r100k->second > 0) {
    std::printf("Retrieval growth 100,000 -> 1,000,000 landmark objects: %.2fx (target <= 1.5x)\n",
                r1m->second / r100k->second);
  }
  return 0;
}
