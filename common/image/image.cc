#include "common/image/image.h"

#include <algorithm>
#include <cmath>
#include <cstring>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "common/util/paths.h"

namespace placerec {

const char* ImageEncodingName(ImageEncoding encoding) {
  switch (encoding) {
    case ImageEncoding::kJpeg:
      return "jpeg";
    case ImageEncoding::kPng:
      return "png";
    case ImageEncoding::kRawBgr8:
      return "raw-bgr8";
    case ImageEncoding::kRawGray8:
      return "raw-gray8";
  }
  return "unknown";
}

bool DecodeOptions::Check(std::string* error) const {
  if (min_dimension < 1) {
    *error = "min_dimension must be at least 1";
    return false;
  }
  if (max_pixels < int64_t{min_dimension} * min_dimension) {
    *error = "max_pixels must hold at least a min_dimension x min_dimension image";
    return false;
  }
  if (max_dimension < min_dimension) {
    *error = "max_dimension must be at least min_dimension";
    return false;
  }
  return true;
}

namespace {

std::string SizeText(int width, int height) {
  return std::to_string(width) + "x" + std::to_string(height);
}

Status CheckDimensions(int width, int height, const DecodeOptions& options) {
  if (width < options.min_dimension || height < options.min_dimension) {
    return Status::BadImage("image size " + SizeText(width, height) + " is below the minimum of " +
                            std::to_string(options.min_dimension) + " pixels per side");
  }
  if (width > options.max_dimension || height > options.max_dimension) {
    return Status::BadImage("image size " + SizeText(width, height) + " exceeds the maximum of " +
                            std::to_string(options.max_dimension) + " pixels per side");
  }
  if (int64_t{width} * height > options.max_pixels) {
    return Status::BadImage("image size " + SizeText(width, height) + " exceeds the budget of " +
                            std::to_string(options.max_pixels) + " pixels (--max-image-pixels)");
  }
  return Status::Ok();
}

uint32_t BigEndian(const uint8_t* p, int bytes) {
  uint32_t value = 0;
  for (int i = 0; i < bytes; ++i) value = (value << 8) | p[i];
  return value;
}

// JPEG: markers from the start of image; the first start-of-frame segment (SOF0-SOF15 but DHT
// C4, JPG C8 and DAC CC) holds precision, height and width (ITU T.81, B.2.2).
Status JpegHeaderSize(const uint8_t* data, size_t size, int* width, int* height) {
  size_t i = 2;
  while (i + 4 <= size) {
    if (data[i] != 0xFF) {
      return Status::BadImage("JPEG marker expected at byte " + std::to_string(i));
    }
    const uint8_t marker = data[i + 1];
    if (marker == 0xFF) {  // fill byte
      ++i;
      continue;
    }
    if (marker == 0x01 || (marker >= 0xD0 && marker <= 0xD7)) {  // no length
      i += 2;
      continue;
    }
    if (marker == 0xD9 || marker == 0xDA) break;  // end of image, or scan data before a frame
    const size_t length = BigEndian(data + i + 2, 2);
    if (length < 2) return Status::BadImage("JPEG segment of length " + std::to_string(length));
    const bool sof =
        marker >= 0xC0 && marker <= 0xCF && marker != 0xC4 && marker != 0xC8 && marker != 0xCC;
    if (sof) {
      if (length < 7 || i + 2 + 7 > size) return Status::BadImage("JPEG frame header cut short");
      *height = static_cast<int>(BigEndian(data + i + 5, 2));
      *width = static_cast<int>(BigEndian(data + i + 7, 2));
      return Status::Ok();
    }
    i += 2 + length;
  }
  return Status::BadImage("JPEG has no frame header (SOF) before its image data");
}

// PNG: the signature, then the IHDR chunk: length 13, "IHDR", width, height (big-endian).
Status PngHeaderSize(const uint8_t* data, size_t size, int* width, int* height) {
  if (size < 24 || std::memcmp(data + 12, "IHDR", 4) != 0) {
    return Status::BadImage("PNG has no IHDR chunk after its signature");
  }
  const uint32_t w = BigEndian(data + 16, 4);
  const uint32_t h = BigEndian(data + 20, 4);
  if (w > INT32_MAX || h > INT32_MAX) {
    return Status::BadImage("PNG declares an impossible size " + std::to_string(w) + "x" +
                            std::to_string(h));
  }
  *width = static_cast<int>(w);
  *height = static_cast<int>(h);
  return Status::Ok();
}

// Whether the bytes hold the whole image: a JPEG ends with its end-of-image marker (FF D9,
// trailing zero padding allowed), a PNG with its IEND chunk.
bool EndsComplete(const uint8_t* data, size_t size, ImageEncoding encoding) {
  if (encoding == ImageEncoding::kJpeg) {
    while (size > 2 && data[size - 1] == 0x00) --size;
    return size >= 4 && data[size - 2] == 0xFF && data[size - 1] == 0xD9;
  }
  static const uint8_t kIend[8] = {'I', 'E', 'N', 'D', 0xAE, 0x42, 0x60, 0x82};
  return size >= 20 && std::memcmp(data + size - 8, kIend, 8) == 0;
}

}  // namespace

Status ReadHeaderSize(const uint8_t* data, size_t size, ImageEncoding encoding, int* width,
                      int* height) {
  if (encoding == ImageEncoding::kJpeg) return JpegHeaderSize(data, size, width, height);
  if (encoding == ImageEncoding::kPng) return PngHeaderSize(data, size, width, height);
  return Status::BadImage("only JPEG and PNG carry a header size");
}

StatusOr<cv::Mat> DecodeImage(const uint8_t* data, size_t size, ImageEncoding encoding, int width,
                              int height, const DecodeOptions& options) {
  if (data == nullptr || size == 0) return Status::BadImage("no image bytes");
  if (width < 0 || height < 0) {
    return Status::BadImage("negative image size " + SizeText(width, height));
  }
  switch (encoding) {
    case ImageEncoding::kRawBgr8:
    case ImageEncoding::kRawGray8: {
      PLACEREC_RETURN_IF_ERROR(CheckDimensions(width, height, options));
      const int channels = encoding == ImageEncoding::kRawBgr8 ? 3 : 1;
      const size_t expected = static_cast<size_t>(width) * height * channels;
      if (size != expected) {
        return Status::BadImage(std::string(ImageEncodingName(encoding)) + " image of " +
                                SizeText(width, height) + " needs " + std::to_string(expected) +
                                " bytes, got " + std::to_string(size));
      }
      cv::Mat wrapped(height, width, channels == 3 ? CV_8UC3 : CV_8UC1, const_cast<uint8_t*>(data));
      cv::Mat bgr;
      if (channels == 3) {
        bgr = wrapped.clone();
      } else {
        cv::cvtColor(wrapped, bgr, cv::COLOR_GRAY2BGR);
      }
      return bgr;
    }
    case ImageEncoding::kJpeg:
    case ImageEncoding::kPng: {
      if ((width == 0) != (height == 0)) {
        return Status::BadImage("give both width and height, or neither, for " +
                                std::string(ImageEncodingName(encoding)));
      }
      if (width > 0) PLACEREC_RETURN_IF_ERROR(CheckDimensions(width, height, options));
      const bool is_jpeg = size >= 3 && data[0] == 0xFF && data[1] == 0xD8 && data[2] == 0xFF;
      const bool is_png =
          size >= 8 && data[0] == 0x89 && data[1] == 'P' && data[2] == 'N' && data[3] == 'G';
      if (encoding == ImageEncoding::kJpeg && !is_jpeg) {
        return Status::BadImage("bytes do not start with a JPEG signature");
      }
      if (encoding == ImageEncoding::kPng && !is_png) {
        return Status::BadImage("bytes do not start with a PNG signature");
      }
      // The size the header declares, against the limits, before anything is decoded.
      int header_width = 0;
      int header_height = 0;
      const Status header = ReadHeaderSize(data, size, encoding, &header_width, &header_height);
      if (!header.ok()) {
        return Status::BadImage(std::string("cannot decode ") + ImageEncodingName(encoding) + ": " +
                                header.message());
      }
      const Status header_size = CheckDimensions(header_width, header_height, options);
      if (!header_size.ok()) {
        return Status::BadImage(std::string(ImageEncodingName(encoding)) +
                                " header: " + header_size.message());
      }
      if (width > 0 && (header_width != width || header_height != height)) {
        return Status::BadImage("declared size " + SizeText(width, height) +
                                " does not match the " + ImageEncodingName(encoding) +
                                " header's " + SizeText(header_width, header_height));
      }
      if (!EndsComplete(data, size, encoding)) {
        return Status::BadImage(std::string(ImageEncodingName(encoding)) +
                                " bytes end before the image does (truncated)");
      }
      cv::Mat bytes(1, static_cast<int>(std::min<size_t>(size, INT32_MAX)), CV_8UC1,
                    const_cast<uint8_t*>(data));
      cv::Mat bgr;
      try {
        bgr = cv::imdecode(bytes, cv::IMREAD_COLOR);
      } catch (const cv::Exception& e) {
        return Status::BadImage(std::string("cannot decode ") + ImageEncodingName(encoding) + ": " +
                                e.what());
      }
      if (bgr.empty()) {
        return Status::BadImage(std::string("cannot decode ") + ImageEncodingName(encoding) +
                                " bytes (truncated or corrupt)");
      }
      PLACEREC_RETURN_IF_ERROR(CheckDimensions(bgr.cols, bgr.rows, options));
      if (width > 0 && (bgr.cols != width || bgr.rows != height)) {
        return Status::BadImage("declared size " + SizeText(width, height) +
                                " does not match decoded size " + SizeText(bgr.cols, bgr.rows));
      }
      return bgr;
    }
  }
  return Status::BadImage("unsupported image encoding");
}

StatusOr<cv::Mat> ReadImageFile(const std::string& path) {
  if (!PathExists(path)) return Status::NotFound("no image file " + path);
  cv::Mat bgr = cv::imread(path, cv::IMREAD_COLOR);
  if (bgr.empty()) return Status::IoError("cannot read image " + path + " (not a decodable image)");
  return bgr;
}

cv::Mat DilatePoints(const std::vector<cv::Point>& points, const cv::Size& size,
                     const cv::Mat& kernel) {
  CHECK(kernel.type() == CV_8U && kernel.rows % 2 == 1 && kernel.cols % 2 == 1);
  cv::Mat mask = cv::Mat::zeros(size, CV_8U);
  // cv::dilate sets p where some kernel element k has a point at p + k - anchor: around each
  // point the kernel mirrored about its anchor.
  cv::Mat stamp;
  cv::flip(kernel != 0, stamp, -1);
  const cv::Point anchor(kernel.cols / 2, kernel.rows / 2);
  const cv::Rect image(cv::Point(0, 0), size);
  for (const cv::Point& point : points) {
    if (!image.contains(point)) continue;  // a point twice is stamped twice, to the same effect
    const cv::Rect placed(point - anchor, stamp.size());
    const cv::Rect inside = placed & image;
    cv::Mat target = mask(inside);
    cv::bitwise_or(target, stamp(inside - placed.tl()), target);
  }
  return mask;
}

cv::Mat LimitWidth(const cv::Mat& bgr, int max_width, double* scale) {
  return FitWidth(bgr, 0, max_width, scale);
}

cv::Mat ResizeToWidth(const cv::Mat& bgr, int width) {
  CHECK_GT(width, 0);
  if (bgr.cols == width) return bgr;
  const double scale = static_cast<double>(width) / bgr.cols;
  const int height = std::max(1, static_cast<int>(std::lround(bgr.rows * scale)));
  cv::Mat resized;
  cv::resize(bgr, resized, cv::Size(width, height), 0, 0,
             width < bgr.cols ? cv::INTER_AREA : cv::INTER_CUBIC);
  return resized;
}

cv::Mat FitWidth(const cv::Mat& bgr, int min_width, int max_width, double* scale) {
  *scale = 1.0;
  int width = bgr.cols;
  if (min_width > 0 && width < min_width && bgr.rows > 0) {
    // The width whose frame holds 2 x min_width^2 pixels at the frame's aspect ratio.
    const double budget = 2.0 * min_width * static_cast<double>(min_width);
    const int affordable =
        static_cast<int>(std::floor(std::sqrt(budget * bgr.cols / static_cast<double>(bgr.rows))));
    width = std::max(bgr.cols, std::min(min_width, affordable));
  }
  if (max_width > 0 && width > max_width) width = max_width;
  if (width == bgr.cols || bgr.cols == 0) return bgr;
  *scale = static_cast<double>(width) / bgr.cols;
  return ResizeToWidth(bgr, width);
}

cv::Mat ToLab(const cv::Mat& bgr) {
  CHECK_EQ(bgr.type(), CV_8UC3);
  cv::Mat bgr_float;
  bgr.convertTo(bgr_float, CV_32F, 1.0 / 255.0);
  cv::Mat lab;
  cv::cvtColor(bgr_float, lab, cv::COLOR_BGR2Lab);
  return lab;
}

cv::Mat GaussianColourModel(const cv::Mat& bgr) {
  CHECK_EQ(bgr.type(), CV_8UC3);
  // Rows of seed eq. 5.6 applied to (R, G, B); OpenCV stores B, G, R, so the columns are
  // reversed and the 1/255 scaling is folded in.
  const float s = 1.0f / 255.0f;
  const cv::Matx33f m(0.27f * s, 0.63f * s, 0.06f * s,    //
                      -0.35f * s, 0.04f * s, 0.30f * s,   //
                      0.17f * s, -0.60f * s, 0.34f * s);  //
  cv::Mat bgr_float;
  bgr.convertTo(bgr_float, CV_32F);
  cv::Mat model;
  cv::transform(bgr_float, model, m);
  return model;
}

bool ColourInvariantOptions::Check(std::string* error) const {
  if (min_intensity < 0 || min_intensity >= 1) {
    *error = "colour min_intensity must be in [0, 1)";
    return false;
  }
  if (min_denominator < 0) {
    *error = "colour min_denominator must be non-negative";
    return false;
  }
  if (max_abs_h <= 0) {
    *error = "colour max_abs_h must be positive";
    return false;
  }
  return true;
}

cv::Mat ColourInvariantH(const cv::Mat& bgr, const ColourInvariantOptions& options,
                         cv::Mat* valid) {
  const cv::Mat model = GaussianColourModel(bgr);
  cv::Mat h(bgr.size(), CV_32F);
  valid->create(bgr.size(), CV_8U);
  const float max_h = static_cast<float>(options.max_abs_h);
  for (int y = 0; y < model.rows; ++y) {
    const cv::Vec3f* in = model.ptr<cv::Vec3f>(y);
    float* out = h.ptr<float>(y);
    uint8_t* ok = valid->ptr<uint8_t>(y);
    for (int x = 0; x < model.cols; ++x) {
      const float d = in[x][0];
      const float d_l = in[x][1];
      const float d_ll = in[x][2];
      const bool usable =
          d >= options.min_intensity && std::abs(d_ll) >= options.min_denominator * d;
      ok[x] = usable ? 255 : 0;
      const float ratio = std::abs(d_ll) > 1e-9f ? d_l / d_ll : (d_l >= 0 ? max_h : -max_h);
      out[x] = std::clamp(ratio, -max_h, max_h);
    }
  }
  return h;
}

}  // namespace placerec
