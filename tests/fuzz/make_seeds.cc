// Writes the fuzz targets' seed corpus (tests/fuzz/corpus/<target>/): small valid inputs that the
// fuzzer mutates, so that it starts inside the formats rather than at random bytes. A frame_t of
// each encoding, JPEG / PNG / raw images with the image target's 3-byte prefix, and a map of two
// places in 512-byte pages. `scripts/fuzz.sh --seeds` runs it; the output is committed.
#include <sqlite3.h>

#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "common/storage/sqlite_store.h"
#include "placerec/frame_t.hpp"

namespace {

void Write(const std::string& path, const std::vector<uint8_t>& bytes) {
  std::ofstream out(path, std::ios::binary);
  out.write(reinterpret_cast<const char*>(bytes.data()),
            static_cast<std::streamsize>(bytes.size()));
}

cv::Mat Picture() {
  cv::Mat image(32, 32, CV_8UC3, cv::Scalar(40, 90, 160));
  cv::circle(image, cv::Point(16, 16), 9, cv::Scalar(200, 220, 30), cv::FILLED);
  return image;
}

std::vector<uint8_t> Encode(const char* ext, const cv::Mat& image) {
  std::vector<uint8_t> bytes;
  cv::imencode(ext, image, bytes);
  return bytes;
}

std::vector<uint8_t> Frame(int8_t encoding, int width, int height, std::vector<uint8_t> data) {
  placerec::frame_t frame;
  frame.utime = 1700000000000000;
  frame.sequence = 3;
  frame.request_id = 42;
  frame.insert = true;
  frame.encoding = encoding;
  frame.width = width;
  frame.height = height;
  frame.robot = "robot-1";
  // Protocol 4: seeds are signed-looking (a key id, counter, time and signature bytes), so the
  // fuzzer starts with every length the decoder checks in place.
  frame.key_id = "robot-1";
  frame.auth_counter = 1700000000000001;
  frame.auth_utime = 1700000000000001;
  for (int i = 0; i < 32; ++i) frame.signature[i] = static_cast<uint8_t>(0x5a ^ i);
  frame.size = static_cast<int32_t>(data.size());
  frame.data = std::move(data);
  std::vector<uint8_t> bytes(static_cast<size_t>(frame.getEncodedSize()));
  frame.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
  return bytes;
}

std::vector<uint8_t> Prefixed(uint8_t encoding, uint8_t width16, uint8_t height16,
                              const std::vector<uint8_t>& data) {
  std::vector<uint8_t> bytes = {encoding, width16, height16};
  bytes.insert(bytes.end(), data.begin(), data.end());
  return bytes;
}

bool WriteMap(const std::string& path) {
  for (const char* suffix : {"", "-wal", "-shm"}) std::remove((path + suffix).c_str());
  {
    placerec::SqliteStoreOptions options;
    auto store = placerec::OpenSqliteStore(path, options);
    if (!store.ok()) return false;
    cv::RNG rng(5);
    for (int p = 0; p < 2; ++p) {
      placerec::Place place;
      place.robot = "robot-1";
      place.sequence = p;
      place.utime = 1700000000000000 + p;
      place.image_width = 320;
      placerec::Landmark landmark;
      landmark.sift_count = 3;
      landmark.box = cv::Rect(1, 2, 30, 20);
      landmark.colour.peaks = {0.25f};
      landmark.descriptors.create(2, 128, CV_8U);
      rng.fill(landmark.descriptors, cv::RNG::UNIFORM, 0, 256);
      landmark.keypoints = {cv::KeyPoint(3, 4, 5, 90), cv::KeyPoint(6, 7, 8, 180)};
      std::vector<placerec::Landmark> landmarks = {landmark};
      if (!(*store)->AddPlace(&place, &landmarks).ok()) return false;
    }
  }
  // Small pages keep the seed small (the fuzzer's inputs are bounded in size).
  sqlite3* db = nullptr;
  if (sqlite3_open(path.c_str(), &db) != SQLITE_OK) return false;
  const int rc = sqlite3_exec(db, "PRAGMA journal_mode = DELETE; PRAGMA page_size = 512; VACUUM;",
                              nullptr, nullptr, nullptr);
  sqlite3_close(db);
  return rc == SQLITE_OK;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: placerec_fuzz_seeds CORPUS_DIR\n");
    return 2;
  }
  const std::string root = argv[1];
  for (const char* target : {"frame", "image", "map"}) {
    std::filesystem::create_directories(root + "/" + target);
  }
  const cv::Mat picture = Picture();
  const std::vector<uint8_t> jpeg = Encode(".jpg", picture);
  const std::vector<uint8_t> png = Encode(".png", picture);
  cv::Mat gray;
  cv::cvtColor(picture, gray, cv::COLOR_BGR2GRAY);
  const std::vector<uint8_t> bgr(picture.data, picture.data + picture.total() * 3);
  const std::vector<uint8_t> grey(gray.data, gray.data + gray.total());
  using placerec::frame_t;
  Write(root + "/frame/jpeg", Frame(frame_t::ENCODING_JPEG, 0, 0, jpeg));
  Write(root + "/frame/png", Frame(frame_t::ENCODING_PNG, 32, 32, png));
  Write(root + "/frame/raw_gray8", Frame(frame_t::ENCODING_RAW_GRAY8, 32, 32, grey));
  Write(root + "/frame/query_no_image", Frame(frame_t::ENCODING_JPEG, 0, 0, {}));
  Write(root + "/image/jpeg", Prefixed(0, 0, 0, jpeg));
  Write(root + "/image/png", Prefixed(1, 2, 2, png));
  Write(root + "/image/raw_bgr8", Prefixed(2, 2, 2, bgr));
  Write(root + "/image/raw_gray8", Prefixed(3, 2, 2, grey));
  if (!WriteMap(root + "/map/two_places")) {
    std::fprintf(stderr, "placerec_fuzz_seeds: cannot write the map seed\n");
    return 1;
  }
  return 0;
}
