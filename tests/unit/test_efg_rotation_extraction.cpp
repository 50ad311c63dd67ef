// The rotation extraction's lanes (physics/efg/rotation_extraction.hpp) against extract_rotation
// one matrix at a time: the AVX2 kernel and the interleaved scalar lanes must give its bits.
#include "physics/efg/rotation_extraction.hpp"

#include <gtest/gtest.h>

#include <cstring>
#include <limits>
#include <random>

namespace incise::physics {
namespace {

using Quaternion = Eigen::Quaterniond;

bool same_bits(const Quaternion& a, const Quaternion& b) { return std::memcmp(a.coeffs().data(), b.coeffs().data(), 4 * sizeof(double)) == 0; }

Quaternion random_rotation(std::mt19937_64& random) {
  std::normal_distribution<double> normal;
  Quaternion q(normal(random), normal(random), normal(random), normal(random));
  return q.normalized();
}

// F = R S: a rotation times a stretch near the identity (the elements' case), with warm starts
// near R (a step's motion), far from it, exactly it, or the identity; some F inverted,
// degenerate or not finite.
void expect_lanes_match(bool vectorised) {
  set_rotation_extraction_vectorised(vectorised);
  std::mt19937_64 random(29);
  std::normal_distribution<double> normal;
  for (int sample = 0; sample < 40000; ++sample) {
    Mat3 f[rotation_lanes];
    Quaternion start[rotation_lanes];
    for (int i = 0; i < rotation_lanes; ++i) {
      const Quaternion rotation = random_rotation(random);
      const int kind = (sample + i) % 8;
      Mat3 stretch = Mat3::Identity();
      const double strain = kind == 0 ? 0.5 : kind == 1 ? 1e-9 : 1e-2;
      for (int k = 0; k < 9; ++k) stretch(k) += strain * normal(random);
      f[i] = rotation.toRotationMatrix() * stretch;
      if (kind == 2) f[i].col(0) *= -1;  // inverted
      if (kind == 3) f[i].col(2).setZero();  // degenerate
      if (kind == 4 && sample % 64 == 0) f[i](1, 1) = std::numeric_limits<double>::quiet_NaN();
      const double motion = kind == 5 ? 1.0 : kind == 6 ? 0.0 : 1e-3;
      start[i] = (Quaternion(Eigen::AngleAxisd(motion * normal(random), Vec3(normal(random), normal(random), normal(random)).normalized())) * rotation).normalized();
      if (kind == 7) start[i] = Quaternion::Identity();
    }
    for (int count = 1; count <= rotation_lanes; ++count) {
      Quaternion lanes[rotation_lanes];
      for (int i = 0; i < count; ++i) lanes[i] = start[i];
      extract_rotations(f, lanes, count);
      for (int i = 0; i < count; ++i) {
        const Quaternion one = extract_rotation(f[i], start[i]);
        ASSERT_TRUE(same_bits(lanes[i], one)) << "sample " << sample << " lane " << i << " of " << count << ": "
                                              << lanes[i].coeffs().transpose() << " vs " << one.coeffs().transpose();
      }
    }
  }
  set_rotation_extraction_vectorised(true);
}

TEST(RotationExtraction, VectorisedLanesMatchOneAtATimeBitwise) {
  if (!rotation_extraction_vectorised()) GTEST_SKIP() << "no AVX2 on this CPU";
  expect_lanes_match(true);
}

TEST(RotationExtraction, InterleavedLanesMatchOneAtATimeBitwise) { expect_lanes_match(false); }

TEST(RotationExtraction, RecoversTheRotationOfAStretch) {
  std::mt19937_64 random(3);
  for (int sample = 0; sample < 100; ++sample) {
    const Quaternion rotation = random_rotation(random);
    const Mat3 f = rotation.toRotationMatrix() * Vec3(1.1, 0.9, 1.05).asDiagonal();
    const Quaternion found = extract_rotation(f, Quaternion::Identity());
    EXPECT_NEAR(std::abs(found.dot(rotation)), 1.0, 1e-12);
  }
}

}  // namespace
}  // namespace incise::physics
