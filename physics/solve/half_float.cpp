#include "physics/solve/half_float.hpp"

#include "physics/core/cpu_features.hpp"
#include "physics/solve/block_product.hpp"

#include <bit>
#include <cmath>

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define INCISE_HALF_F16C 1
#include <immintrin.h>
#endif

namespace incise::physics {

std::uint16_t float_to_half(float value) {
  const std::uint32_t bits = std::bit_cast<std::uint32_t>(value);
  const auto sign = static_cast<std::uint16_t>((bits >> 16) & 0x8000u);
  const std::uint32_t magnitude = bits & 0x7fffffffu;
  if (magnitude > 0x7f800000u) return static_cast<std::uint16_t>(sign | 0x7e00u | ((magnitude >> 13) & 0x3ffu));  // NaN
  if (magnitude >= 0x477ff000u) return static_cast<std::uint16_t>(sign | 0x7c00u);  // >= 65520: infinity
  if (magnitude < 0x38800000u) {
    // Below 2^-14: a subnormal half, the nearest multiple of 2^-24 (exact scaling, then the
    // default rounding, to nearest even); 1024 of them is the smallest normal, encoded alike.
    const float scaled = std::bit_cast<float>(magnitude) * 16777216.0f;
    return static_cast<std::uint16_t>(sign | static_cast<std::uint16_t>(std::nearbyint(scaled)));
  }
  // Rebias the exponent (127 -> 15) and round the 23-bit mantissa to 10, ties to even (a carry
  // into the exponent is the right result).
  const std::uint32_t rebiased = magnitude - 0x38000000u;
  return static_cast<std::uint16_t>(sign | ((rebiased + 0xfffu + ((rebiased >> 13) & 1u)) >> 13));
}

float half_to_float(std::uint16_t half) {
  const std::uint32_t sign = static_cast<std::uint32_t>(half & 0x8000u) << 16;
  const std::uint32_t exponent = (half >> 10) & 0x1fu, mantissa = half & 0x3ffu;
  if (exponent == 0) {
    const float magnitude = static_cast<float>(mantissa) * (1.0f / 16777216.0f);
    return sign ? -magnitude : magnitude;
  }
  if (exponent == 31) return std::bit_cast<float>(sign | 0x7f800000u | (mantissa << 13));
  return std::bit_cast<float>(sign | ((exponent + 112u) << 23) | (mantissa << 13));
}

bool half_conversion_vectorised() {
#if defined(INCISE_HALF_F16C)
  return block_product_vectorised() && cpu_has_f16c();
#else
  return false;
#endif
}

#if defined(INCISE_HALF_F16C)
namespace {
__attribute__((target("avx,f16c"))) void f16c_floats_to_halves(const float* in, std::uint16_t* out, std::size_t count) {
  std::size_t i = 0;
  for (; i + 8 <= count; i += 8)
    _mm_storeu_si128(reinterpret_cast<__m128i*>(out + i),
                     _mm256_cvtps_ph(_mm256_loadu_ps(in + i), _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC));
  for (; i < count; ++i) out[i] = float_to_half(in[i]);
}
}  // namespace
#endif

void floats_to_halves(const float* in, std::uint16_t* out, std::size_t count) {
#if defined(INCISE_HALF_F16C)
  if (half_conversion_vectorised()) return f16c_floats_to_halves(in, out, count);
#endif
  for (std::size_t i = 0; i < count; ++i) out[i] = float_to_half(in[i]);
}

}  // namespace incise::physics
