#include "common/recognition/descriptor_matching.h"

#include <algorithm>
#include <climits>
#include <cmath>

#if defined(__x86_64__)
#include <immintrin.h>
#endif

#include "common/features/features.h"
#include "common/util/cpu.h"
#include "common/util/logging.h"

namespace placerec {
namespace {

static_assert(kDescriptorSize % 32 == 0, "the vector loops take 32 bytes at a time");

int SquaredDistanceScalar(const uint8_t* a, const uint8_t* b) {
  int sum = 0;
  for (int i = 0; i < kDescriptorSize; ++i) {
    const int d = static_cast<int>(a[i]) - static_cast<int>(b[i]);
    sum += d * d;
  }
  return sum;
}

#if defined(__x86_64__)
// |a - b| bytewise (saturating differences both ways), widened to 16 bits, squared and summed
// in pairs by madd: exact, as the scalar loop (255^2 * 2 fits in 32 bits).
int SquaredDistanceSse2(const uint8_t* a, const uint8_t* b) {
  const __m128i zero = _mm_setzero_si128();
  __m128i sum = _mm_setzero_si128();
  for (int i = 0; i < kDescriptorSize; i += 16) {
    const __m128i va = _mm_loadu_si128(reinterpret_cast<const __m128i*>(a + i));
    const __m128i vb = _mm_loadu_si128(reinterpret_cast<const __m128i*>(b + i));
    const __m128i d = _mm_or_si128(_mm_subs_epu8(va, vb), _mm_subs_epu8(vb, va));
    const __m128i lo = _mm_unpacklo_epi8(d, zero);
    const __m128i hi = _mm_unpackhi_epi8(d, zero);
    sum = _mm_add_epi32(sum, _mm_add_epi32(_mm_madd_epi16(lo, lo), _mm_madd_epi16(hi, hi)));
  }
  sum = _mm_add_epi32(sum, _mm_shuffle_epi32(sum, _MM_SHUFFLE(1, 0, 3, 2)));
  sum = _mm_add_epi32(sum, _mm_shuffle_epi32(sum, _MM_SHUFFLE(2, 3, 0, 1)));
  return _mm_cvtsi128_si32(sum);
}

// The AVX2 form of the same: |a - b| of 32 bytes, widened, squared and added in pairs into the
// eight 32-bit lanes of `sum`; and those lanes' total.
__attribute__((target("avx2"), always_inline)) inline __m256i AddSquaredDifferences(__m256i a,
                                                                                    __m256i b,
                                                                                    __m256i sum) {
  const __m256i zero = _mm256_setzero_si256();
  const __m256i d = _mm256_or_si256(_mm256_subs_epu8(a, b), _mm256_subs_epu8(b, a));
  const __m256i lo = _mm256_unpacklo_epi8(d, zero);
  const __m256i hi = _mm256_unpackhi_epi8(d, zero);
  return _mm256_add_epi32(sum,
                          _mm256_add_epi32(_mm256_madd_epi16(lo, lo), _mm256_madd_epi16(hi, hi)));
}

__attribute__((target("avx2"), always_inline)) inline int LaneTotal(__m256i sum) {
  __m128i half = _mm_add_epi32(_mm256_castsi256_si128(sum), _mm256_extracti128_si256(sum, 1));
  half = _mm_add_epi32(half, _mm_shuffle_epi32(half, _MM_SHUFFLE(1, 0, 3, 2)));
  half = _mm_add_epi32(half, _mm_shuffle_epi32(half, _MM_SHUFFLE(2, 3, 0, 1)));
  return _mm_cvtsi128_si32(half);
}

__attribute__((target("avx2"), always_inline)) inline __m256i Load32(const uint8_t* p) {
  return _mm256_loadu_si256(reinterpret_cast<const __m256i*>(p));
}

__attribute__((target("avx2"))) int SquaredDistanceAvx2(const uint8_t* a, const uint8_t* b) {
  __m256i sum = _mm256_setzero_si256();
  for (int i = 0; i < kDescriptorSize; i += 32)
    sum = AddSquaredDifferences(Load32(a + i), Load32(b + i), sum);
  return LaneTotal(sum);
}

// SquaredDistanceAvx2 for many rows, the query held in registers.
__attribute__((target("avx2"))) void SquaredDistancesAvx2(const uint8_t* query, const uint8_t* rows,
                                                          size_t step, int n, int* out) {
  static_assert(kDescriptorSize == 128, "four 32-byte registers hold a query");
  const __m256i q[4] = {Load32(query), Load32(query + 32), Load32(query + 64), Load32(query + 96)};
  for (int r = 0; r < n; ++r) {
    const uint8_t* row = rows + r * step;
    __m256i sum = _mm256_setzero_si256();
    for (int i = 0; i < 4; ++i) sum = AddSquaredDifferences(q[i], Load32(row + 32 * i), sum);
    out[r] = LaneTotal(sum);
  }
}
#endif

// The widest implementation this processor runs, chosen once.
SquaredDistanceFunction Widest() {
  static const SquaredDistanceFunction widest = SquaredDistanceImplementations().back().second;
  return widest;
}

}  // namespace

void SquaredDistances(const uint8_t* query, const cv::Mat& rows, int* out) {
  CHECK(rows.empty() || (rows.type() == CV_8U && rows.cols == kDescriptorSize));
#if defined(__x86_64__)
  if (CpuHasAvx2()) {
    SquaredDistancesAvx2(query, rows.data, rows.step[0], rows.rows, out);
    return;
  }
#endif
  const SquaredDistanceFunction distance = Widest();
  for (int r = 0; r < rows.rows; ++r) out[r] = distance(query, rows.ptr<uint8_t>(r));
}

std::vector<std::pair<std::string, SquaredDistanceFunction>> SquaredDistanceImplementations() {
  std::vector<std::pair<std::string, SquaredDistanceFunction>> all = {
      {"scalar", &SquaredDistanceScalar}};
#if defined(__x86_64__)
  all.emplace_back("sse2", &SquaredDistanceSse2);
  if (CpuHasAvx2()) all.emplace_back("avx2", &SquaredDistanceAvx2);
#endif
  return all;
}

int SquaredDistance(const uint8_t* a, const uint8_t* b) { return Widest()(a, b); }

std::vector<DescriptorMatch> MatchRatioTest(const cv::Mat& query, const cv::Mat& train,
                                            double ratio) {
  CHECK(query.empty() || (query.type() == CV_8U && query.cols == kDescriptorSize));
  CHECK(train.empty() || (train.type() == CV_8U && train.cols == kDescriptorSize));
  std::vector<DescriptorMatch> matches;
  if (query.empty() || train.empty()) return matches;
  const double ratio_squared = ratio * ratio;
  // best[t]: index into `matches` of the match that currently owns train row t.
  std::vector<int> owner(train.rows, -1);
  std::vector<int> distances(train.rows);
  for (int q = 0; q < query.rows; ++q) {
    SquaredDistances(query.ptr<uint8_t>(q), train, distances.data());
    int best = INT_MAX;
    int second = INT_MAX;
    int best_row = -1;
    for (int t = 0; t < train.rows; ++t) {
      const int d = distances[t];
      if (d < best) {
        second = best;
        best = d;
        best_row = t;
      } else if (d < second) {
        second = d;
      }
    }
    if (second != INT_MAX && best >= ratio_squared * second) continue;
    const int current = owner[best_row];
    if (current >= 0) {
      if (matches[current].distance <= best) continue;
      matches[current] = {q, best_row, best};
      continue;
    }
    owner[best_row] = static_cast<int>(matches.size());
    matches.push_back({q, best_row, best});
  }
  return matches;
}

double AngleDifference(double a, double b) {
  double d = std::fmod(a - b, 360.0);
  if (d < -180) d += 360;
  if (d >= 180) d -= 360;
  return d;
}

std::vector<bool> ConsistentOrientation(const std::vector<double>& changes, double tolerance) {
  if (tolerance <= 0 || changes.empty()) return std::vector<bool>(changes.size(), true);
  constexpr int kBins = 36;
  std::vector<double> histogram(kBins, 0.0);
  for (const double change : changes) {
    if (!std::isfinite(change)) continue;                   // no direction: inconsistent (below)
    const double d = AngleDifference(change, 0.0) + 180.0;  // [0, 360)
    histogram[std::clamp(static_cast<int>(d / 10.0), 0, kBins - 1)] += 1.0;
  }
  int peak = 0;
  double best = -1;
  for (int b = 0; b < kBins; ++b) {
    const double v =
        histogram[(b + kBins - 1) % kBins] + 2 * histogram[b] + histogram[(b + 1) % kBins];
    if (v > best) {
      best = v;
      peak = b;
    }
  }
  const double mode = peak * 10.0 + 5.0 - 180.0;
  std::vector<bool> kept(changes.size());
  for (size_t i = 0; i < changes.size(); ++i) {
    kept[i] = std::abs(AngleDifference(changes[i], mode)) <= tolerance;
  }
  return kept;
}

}  // namespace placerec
