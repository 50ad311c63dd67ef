// Half precision (physics/solve/half_float.hpp) and the paired copy's halves (paired_blocks.hpp),
// against IEEE binary16's definition: known encodings, every half's round trip, and the F16C
// conversion against the portable one.
#include "physics/solve/block_product.hpp"
#include "physics/solve/half_float.hpp"

#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

namespace incise::physics {
namespace {

TEST(HalfFloat, KnownEncodingsRoundToNearestEven) {
  EXPECT_EQ(float_to_half(1.0f), 0x3c00);
  EXPECT_EQ(float_to_half(-2.0f), 0xc000);
  EXPECT_EQ(float_to_half(65504.0f), 0x7bff);            // the largest half
  EXPECT_EQ(float_to_half(65519.99f), 0x7bff);           // below the midpoint to infinity
  EXPECT_EQ(float_to_half(65520.0f), 0x7c00);            // the midpoint: to even, infinity
  EXPECT_EQ(float_to_half(std::ldexp(1.0f, -14)), 0x0400);  // the smallest normal
  EXPECT_EQ(float_to_half(std::ldexp(1.0f, -24)), 0x0001);  // the smallest subnormal
  EXPECT_EQ(float_to_half(std::ldexp(1.0f, -25)), 0x0000);  // its half: a tie, to even (0)
  EXPECT_EQ(float_to_half(std::ldexp(3.0f, -25)), 0x0002);  // 1.5 x 2^-24: a tie, to even (2)
  EXPECT_EQ(float_to_half(-0.0f), 0x8000);
  EXPECT_EQ(float_to_half(1.0f + std::ldexp(1.0f, -11)), 0x3c00);  // a tie above 1: to even
  EXPECT_EQ(float_to_half(1.0f + std::ldexp(3.0f, -11)), 0x3c02);  // a tie above 1 + 2^-10: to even
  EXPECT_EQ(float_to_half(INFINITY), 0x7c00);
  EXPECT_TRUE(std::isnan(half_to_float(float_to_half(NAN))));
}

TEST(HalfFloat, EveryHalfSurvivesTheRoundTrip) {
  for (std::uint32_t h = 0; h < 0x10000; ++h) {
    const auto half = static_cast<std::uint16_t>(h);
    const float value = half_to_float(half);
    if (std::isnan(value)) continue;
    ASSERT_EQ(float_to_half(value), half) << std::hex << h;
  }
  EXPECT_EQ(half_to_float(0x3555), 0.333251953125f);
  EXPECT_EQ(half_to_float(0x0001), std::ldexp(1.0f, -24));
}

// F16C's conversion against the portable one on random floats over the halves' range and
// beyond (subnormals, ties, overflow).
TEST(HalfFloat, TheVectorisedConversionHasThePortableBits) {
  std::mt19937 random(5);
  std::vector<float> values;
  std::uniform_int_distribution<std::uint32_t> mantissa(0, (1u << 23) - 1);
  for (int exponent = -30; exponent <= 17; ++exponent)
    for (int i = 0; i < 2000; ++i) {
      const float magnitude = std::ldexp(1.0f + static_cast<float>(mantissa(random)) * std::ldexp(1.0f, -23), exponent);
      values.push_back(i % 2 ? magnitude : -magnitude);
      // A tie between two halves at this exponent's spacing.
      values.push_back(std::ldexp(static_cast<float>(2 * (mantissa(random) % 2048) + 1), exponent - 11));
    }
  values.resize(values.size() - values.size() % 8 + 3);  // a tail for the scalar remainder
  std::vector<std::uint16_t> vectorised(values.size()), portable(values.size());
  set_block_product_vectorised(true);
  floats_to_halves(values.data(), vectorised.data(), values.size());
  set_block_product_vectorised(false);
  floats_to_halves(values.data(), portable.data(), values.size());
  set_block_product_vectorised(true);
  for (std::size_t i = 0; i < values.size(); ++i) ASSERT_EQ(vectorised[i], portable[i]) << values[i];
  std::printf("F16C used: %d\n", half_conversion_vectorised() ? 1 : 0);
}

}  // namespace
}  // namespace incise::physics
