#include "common/image/image.h"

#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

namespace placerec {
namespace {

cv::Mat Flat(int width, int height, cv::Scalar bgr) { return cv::Mat(height, width, CV_8UC3, bgr); }

TEST(DecodeTest, DefaultOptionsPass) {
  std::string error;
  EXPECT_TRUE(DecodeOptions().Check(&error)) << error;
  EXPECT_TRUE(ColourInvariantOptions().Check(&error)) << error;
  DecodeOptions bad;
  bad.max_dimension = 1;
  EXPECT_FALSE(bad.Check(&error));
  ColourInvariantOptions bad_colour;
  bad_colour.max_abs_h = 0;
  EXPECT_FALSE(bad_colour.Check(&error));
}

TEST(DecodeTest, JpegAndPngRoundTrip) {
  const cv::Mat image = Flat(64, 48, cv::Scalar(10, 200, 30));
  for (const char* ext : {".jpg", ".png"}) {
    std::vector<uint8_t> bytes;
    ASSERT_TRUE(cv::imencode(ext, image, bytes));
    const ImageEncoding encoding =
        std::string(ext) == ".jpg" ? ImageEncoding::kJpeg : ImageEncoding::kPng;
    StatusOr<cv::Mat> decoded =
        DecodeImage(bytes.data(), bytes.size(), encoding, 64, 48, DecodeOptions());
    ASSERT_TRUE(decoded.ok()) << decoded.status().ToString();
    EXPECT_EQ(decoded->cols, 64);
    EXPECT_EQ(decoded->rows, 48);
    EXPECT_EQ(decoded->type(), CV_8UC3);
    // Unknown size (0, 0) is accepted for compressed encodings.
    EXPECT_TRUE(DecodeImage(bytes.data(), bytes.size(), encoding, 0, 0, DecodeOptions()).ok());
  }
}

// A textured frame, so that its JPEG and PNG are long enough to cut in half.
std::vector<uint8_t> Encoded(const char* ext, int width = 160, int height = 120) {
  cv::Mat image(height, width, CV_8UC3);
  cv::randu(image, cv::Scalar::all(0), cv::Scalar::all(255));
  std::vector<uint8_t> bytes;
  EXPECT_TRUE(cv::imencode(ext, image, bytes));
  return bytes;
}

// Rewrites the size a JPEG's first frame header (SOF0, written by OpenCV) or a PNG's IHDR
// declares, leaving the rest of the bytes as they were.
void DeclareSize(std::vector<uint8_t>* bytes, ImageEncoding encoding, uint32_t width,
                 uint32_t height) {
  auto put = [&](size_t at, uint32_t value, int n) {
    for (int i = n - 1; i >= 0; --i, value >>= 8) (*bytes)[at + i] = value & 0xFF;
  };
  if (encoding == ImageEncoding::kPng) {
    put(16, width, 4);
    put(20, height, 4);
    return;
  }
  for (size_t i = 2; i + 9 < bytes->size(); ++i) {
    if ((*bytes)[i] == 0xFF && (*bytes)[i + 1] == 0xC0) {
      put(i + 5, height, 2);
      put(i + 7, width, 2);
      return;
    }
  }
  ADD_FAILURE() << "no SOF0 marker";
}

TEST(DecodeTest, ReadsTheHeaderSize) {
  for (const auto& [ext, encoding] :
       {std::pair{".jpg", ImageEncoding::kJpeg}, std::pair{".png", ImageEncoding::kPng}}) {
    const std::vector<uint8_t> bytes = Encoded(ext, 161, 97);
    int width = 0;
    int height = 0;
    ASSERT_TRUE(ReadHeaderSize(bytes.data(), bytes.size(), encoding, &width, &height).ok());
    EXPECT_EQ(width, 161);
    EXPECT_EQ(height, 97);
    EXPECT_FALSE(ReadHeaderSize(bytes.data(), 10, encoding, &width, &height).ok());
  }
}

// Image bombs (issue 23): a small file declaring a huge image is refused from its header, before
// decoding (the decoder would allocate width x height x 3 bytes first).
TEST(DecodeTest, RefusesImageBombsFromTheHeader) {
  for (const auto& [ext, encoding] :
       {std::pair{".jpg", ImageEncoding::kJpeg}, std::pair{".png", ImageEncoding::kPng}}) {
    for (const auto& [w, h] : {std::pair{30000u, 30000u}, std::pair{8000u, 8000u}}) {
      std::vector<uint8_t> bytes = Encoded(ext);
      DeclareSize(&bytes, encoding, w, h);
      const StatusOr<cv::Mat> r =
          DecodeImage(bytes.data(), bytes.size(), encoding, 0, 0, DecodeOptions());
      EXPECT_EQ(r.status().code(), StatusCode::kBadImage) << ext << " " << w;
      EXPECT_NE(r.status().message().find("header"), std::string::npos) << r.status().message();
    }
  }
  // 8000x8000 is within the per-side limit: the pixel budget refuses it.
  std::vector<uint8_t> bytes = Encoded(".jpg");
  DeclareSize(&bytes, ImageEncoding::kJpeg, 8000, 8000);
  const StatusOr<cv::Mat> r =
      DecodeImage(bytes.data(), bytes.size(), ImageEncoding::kJpeg, 0, 0, DecodeOptions());
  EXPECT_NE(r.status().message().find("budget"), std::string::npos) << r.status().message();
}

// A JPEG or PNG cut in half is an error, not the upper half of a frame.
TEST(DecodeTest, RefusesTruncatedImages) {
  for (const auto& [ext, encoding] :
       {std::pair{".jpg", ImageEncoding::kJpeg}, std::pair{".png", ImageEncoding::kPng}}) {
    const std::vector<uint8_t> bytes = Encoded(ext);
    const StatusOr<cv::Mat> half =
        DecodeImage(bytes.data(), bytes.size() / 2, encoding, 0, 0, DecodeOptions());
    EXPECT_EQ(half.status().code(), StatusCode::kBadImage) << ext;
    EXPECT_NE(half.status().message().find("truncated"), std::string::npos)
        << half.status().message();
    EXPECT_TRUE(DecodeImage(bytes.data(), bytes.size(), encoding, 0, 0, DecodeOptions()).ok());
  }
  // Zero padding after a JPEG's end-of-image marker is harmless.
  std::vector<uint8_t> padded = Encoded(".jpg");
  padded.resize(padded.size() + 16, 0);
  EXPECT_TRUE(
      DecodeImage(padded.data(), padded.size(), ImageEncoding::kJpeg, 0, 0, DecodeOptions()).ok());
}

TEST(DecodeTest, RejectsWhatIsWrongWithAMessage) {
  const cv::Mat image = Flat(64, 48, cv::Scalar(1, 2, 3));
  std::vector<uint8_t> jpeg;
  ASSERT_TRUE(cv::imencode(".jpg", image, jpeg));
  const DecodeOptions options;

  // Declared size does not match the JPEG.
  StatusOr<cv::Mat> r =
      DecodeImage(jpeg.data(), jpeg.size(), ImageEncoding::kJpeg, 65, 48, options);
  EXPECT_EQ(r.status().code(), StatusCode::kBadImage);
  EXPECT_NE(r.status().message().find("does not match"), std::string::npos);

  // PNG bytes claimed to be JPEG.
  std::vector<uint8_t> png;
  ASSERT_TRUE(cv::imencode(".png", image, png));
  r = DecodeImage(png.data(), png.size(), ImageEncoding::kJpeg, 0, 0, options);
  EXPECT_EQ(r.status().code(), StatusCode::kBadImage);

  // Truncated JPEG.
  r = DecodeImage(jpeg.data(), 20, ImageEncoding::kJpeg, 0, 0, options);
  EXPECT_EQ(r.status().code(), StatusCode::kBadImage);

  // Raw with the wrong byte count, zero and absurd sizes.
  std::vector<uint8_t> raw(64 * 48 * 3);
  r = DecodeImage(raw.data(), raw.size() - 1, ImageEncoding::kRawBgr8, 64, 48, options);
  EXPECT_NE(r.status().message().find("needs 9216 bytes"), std::string::npos);
  EXPECT_FALSE(DecodeImage(raw.data(), raw.size(), ImageEncoding::kRawBgr8, 0, 48, options).ok());
  EXPECT_FALSE(
      DecodeImage(raw.data(), raw.size(), ImageEncoding::kRawBgr8, 100000, 48, options).ok());
  EXPECT_FALSE(DecodeImage(nullptr, 0, ImageEncoding::kPng, 0, 0, options).ok());

  // Raw that is right decodes, gray becomes BGR.
  StatusOr<cv::Mat> ok =
      DecodeImage(raw.data(), 64 * 48, ImageEncoding::kRawGray8, 64, 48, options);
  ASSERT_TRUE(ok.ok());
  EXPECT_EQ(ok->type(), CV_8UC3);
}

TEST(ColourTest, LabOfWhiteAndBlack) {
  const cv::Mat lab_white = ToLab(Flat(2, 2, cv::Scalar(255, 255, 255)));
  EXPECT_NEAR(lab_white.at<cv::Vec3f>(0, 0)[0], 100.0f, 0.5f);
  EXPECT_NEAR(lab_white.at<cv::Vec3f>(0, 0)[1], 0.0f, 0.5f);
  const cv::Mat lab_black = ToLab(Flat(2, 2, cv::Scalar(0, 0, 0)));
  EXPECT_NEAR(lab_black.at<cv::Vec3f>(0, 0)[0], 0.0f, 0.5f);
}

TEST(ColourTest, GaussianModelFollowsEquation56) {
  // Pure red (R = 1): the first column of the matrix in eq. 5.6.
  const cv::Mat model = GaussianColourModel(Flat(1, 1, cv::Scalar(0, 0, 255)));
  const cv::Vec3f v = model.at<cv::Vec3f>(0, 0);
  EXPECT_NEAR(v[0], 0.06f, 1e-5f);
  EXPECT_NEAR(v[1], 0.30f, 1e-5f);
  EXPECT_NEAR(v[2], 0.34f, 1e-5f);
}

TEST(ColourTest, InvariantHOfKnownColours) {
  struct Case {
    cv::Scalar bgr;
    float h;
  };
  // H = D_lambda / D_lambdalambda with eq. 5.6 rows (0.3, 0.04, -0.35) and (0.34, -0.6, 0.17).
  const Case cases[] = {
      {cv::Scalar(0, 0, 255), 0.30f / 0.34f},        // red
      {cv::Scalar(0, 255, 0), 0.04f / -0.60f},       // green
      {cv::Scalar(255, 0, 0), -0.35f / 0.17f},       // blue
      {cv::Scalar(128, 128, 128), -0.01f / -0.09f},  // grey: the same for any grey level
      {cv::Scalar(200, 200, 200), -0.01f / -0.09f},
  };
  for (const Case& c : cases) {
    cv::Mat valid;
    const cv::Mat h = ColourInvariantH(Flat(3, 3, c.bgr), ColourInvariantOptions(), &valid);
    EXPECT_NEAR(h.at<float>(1, 1), c.h, 1e-4f) << c.bgr;
    EXPECT_EQ(valid.at<uint8_t>(1, 1), 255);
  }
}

TEST(ColourTest, InvariantHIgnoresIntensity) {
  // Seed §5.4.2: H does not change with illumination intensity.
  cv::Mat valid;
  const float bright =
      ColourInvariantH(Flat(1, 1, cv::Scalar(40, 120, 200)), ColourInvariantOptions(), &valid)
          .at<float>(0, 0);
  const float dim =
      ColourInvariantH(Flat(1, 1, cv::Scalar(20, 60, 100)), ColourInvariantOptions(), &valid)
          .at<float>(0, 0);
  EXPECT_NEAR(bright, dim, 0.02f);
}

TEST(ColourTest, DarkPixelsAreInvalid) {
  cv::Mat valid;
  ColourInvariantH(Flat(2, 2, cv::Scalar(2, 2, 2)), ColourInvariantOptions(), &valid);
  EXPECT_EQ(valid.at<uint8_t>(0, 0), 0);
}

TEST(ResizeTest, LimitWidthKeepsAspect) {
  double scale = 0;
  const cv::Mat small = LimitWidth(Flat(960, 540, cv::Scalar(0, 0, 0)), 640, &scale);
  EXPECT_EQ(small.cols, 640);
  EXPECT_EQ(small.rows, 360);
  EXPECT_NEAR(scale, 640.0 / 960.0, 1e-9);
  const cv::Mat same = LimitWidth(Flat(320, 240, cv::Scalar(0, 0, 0)), 640, &scale);
  EXPECT_EQ(same.cols, 320);
  EXPECT_EQ(scale, 1.0);
}

TEST(ResizeTest, FitWidthScalesUpAndDown) {
  double scale = 0;
  const cv::Mat up = FitWidth(Flat(160, 120, cv::Scalar(9, 9, 9)), 640, 0, &scale);
  EXPECT_EQ(up.cols, 640);
  EXPECT_EQ(up.rows, 480);
  EXPECT_DOUBLE_EQ(scale, 4.0);
  EXPECT_EQ(up.at<cv::Vec3b>(100, 100), cv::Vec3b(9, 9, 9));
  const cv::Mat down = FitWidth(Flat(960, 540, cv::Scalar(0, 0, 0)), 640, 800, &scale);
  EXPECT_EQ(down.cols, 800);
  EXPECT_NEAR(scale, 800.0 / 960.0, 1e-9);
  // The cap wins where the bounds disagree.
  const cv::Mat capped = FitWidth(Flat(160, 120, cv::Scalar(0, 0, 0)), 640, 320, &scale);
  EXPECT_EQ(capped.cols, 320);
  const cv::Mat kept = FitWidth(Flat(512, 384, cv::Scalar(0, 0, 0)), 400, 0, &scale);
  EXPECT_EQ(kept.cols, 512);
  EXPECT_EQ(scale, 1.0);
  // Scaling up stops at 2 x 640^2 pixels: a 16 x 8192 frame became 640 x 327,680 (209 Mpx,
  // minutes of work and tens of GB); a 1:2 portrait frame still reaches the width.
  const cv::Mat tall = FitWidth(Flat(16, 8192, cv::Scalar(0, 0, 0)), 640, 0, &scale);
  EXPECT_LE(static_cast<double>(tall.total()), 2.0 * 640 * 640);
  EXPECT_GE(tall.cols, 16);
  EXPECT_NEAR(tall.rows, 8192 * scale, 1.0);
  const cv::Mat portrait = FitWidth(Flat(200, 400, cv::Scalar(0, 0, 0)), 640, 0, &scale);
  EXPECT_EQ(portrait.cols, 640);
  EXPECT_EQ(portrait.rows, 1280);
  // Never below the frame's own width.
  const cv::Mat thread = FitWidth(Flat(16, 65536, cv::Scalar(0, 0, 0)), 640, 0, &scale);
  EXPECT_EQ(thread.cols, 16);
  EXPECT_EQ(scale, 1.0);
}

TEST(ResizeTest, ResizeToWidthKeepsAspect) {
  const cv::Mat small = ResizeToWidth(Flat(960, 540, cv::Scalar(0, 0, 0)), 160);
  EXPECT_EQ(small.cols, 160);
  EXPECT_EQ(small.rows, 90);
}

TEST(DilatePointsTest, EqualsDilatingTheMaskOfThePoints) {
  cv::RNG rng(7);
  const cv::Size size(160, 120);
  // An asymmetric kernel too: DilatePoints must mirror it as cv::dilate does.
  cv::Mat asymmetric = cv::Mat::zeros(5, 7, CV_8U);
  asymmetric.at<uint8_t>(0, 0) = asymmetric.at<uint8_t>(2, 3) = asymmetric.at<uint8_t>(4, 6) = 1;
  asymmetric.at<uint8_t>(1, 5) = 1;
  const std::vector<cv::Mat> kernels = {
      cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(97, 97)),
      cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(3, 3)),
      cv::getStructuringElement(cv::MORPH_RECT, cv::Size(9, 5)),
      cv::getStructuringElement(cv::MORPH_CROSS, cv::Size(11, 11)), asymmetric};
  for (const cv::Mat& kernel : kernels) {
    for (const int count : {0, 1, 5, 300}) {
      std::vector<cv::Point> points;
      for (int i = 0; i < count; ++i) {
        // Some outside the image, some twice.
        points.emplace_back(rng.uniform(-10, size.width + 10), rng.uniform(-10, size.height + 10));
        if (i % 7 == 0) points.push_back(points.back());
      }
      cv::Mat marked = cv::Mat::zeros(size, CV_8U);
      for (const cv::Point& p : points) {
        if (cv::Rect(cv::Point(0, 0), size).contains(p)) marked.at<uint8_t>(p) = 255;
      }
      cv::Mat expected;
      cv::dilate(marked, expected, kernel);
      const cv::Mat found = DilatePoints(points, size, kernel);
      ASSERT_EQ(found.size(), size);
      ASSERT_EQ(found.type(), CV_8U);
      EXPECT_EQ(cv::countNonZero(found != expected), 0)
          << "kernel " << kernel.cols << "x" << kernel.rows << ", " << count << " points";
    }
  }
}

}  // namespace
}  // namespace placerec
