// libFuzzer target: the image decoder with the server's limits (common/image/image.h). The first
// byte picks the encoding (JPEG, PNG, raw BGR8, raw gray8), the next two the declared width and
// height in 16-pixel steps (0: none); the rest are the image bytes. Limits are small so that the
// fuzzer explores headers rather than big images: no decode may allocate past them. scripts/fuzz.sh
// runs it.
#include <cstddef>
#include <cstdint>

#include <opencv2/core.hpp>

#include "common/image/image.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace placerec;
  if (size < 3) return 0;
  const auto encoding = static_cast<ImageEncoding>(data[0] % 4);
  const int width = data[1] * 16;
  const int height = data[2] * 16;
  DecodeOptions options;
  options.max_dimension = 2048;
  options.max_pixels = 1 << 20;
  StatusOr<cv::Mat> image = DecodeImage(data + 3, size - 3, encoding, width, height, options);
  if (image.ok() && (image->cols > options.max_dimension || image->rows > options.max_dimension ||
                     static_cast<int64_t>(image->cols) * image->rows > options.max_pixels)) {
    __builtin_trap();  // a decoded image beyond the limits
  }
  int header_width = 0;
  int header_height = 0;
  (void)ReadHeaderSize(data + 3, size - 3, encoding, &header_width, &header_height);
  return 0;
}
