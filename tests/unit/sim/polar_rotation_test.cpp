#include "../../../app/sim/src/polar_rotation.hpp"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <random>

namespace ultrasim::sim::corotational_detail {
namespace {

Eigen::Matrix3d random_rotation(std::mt19937& rng) {
  std::normal_distribution<double> normal;
  const Eigen::Quaterniond q(normal(rng), normal(rng), normal(rng), normal(rng));
  return q.normalized().toRotationMatrix();
}

// f = R diag(σ) Vᵀ with the given singular values (one negative: inverted).
Eigen::Matrix3d gradient(std::mt19937& rng, const Eigen::Vector3d& singular_values) {
  return random_rotation(rng) * singular_values.asDiagonal() * random_rotation(rng).transpose();
}

void expect_proper_rotation(const Eigen::Matrix3d& r) {
  EXPECT_LT((r.transpose() * r - Eigen::Matrix3d::Identity()).norm(), 1e-12);
  EXPECT_NEAR(r.determinant(), 1.0, 1e-12);
}

// The fast paths (Newton's iteration; for an inverted tet, its reflection flipped across the
// smallest singular direction) against the SVD: the same rotation wherever the singular values
// are apart, stretched, squeezed or turned inside out, and a proper rotation always.
TEST(PolarRotation, MatchesTheSvdForStretchedSqueezedAndInvertedGradients) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> stretch(0.3, 1.8);
  int inverted = 0;
  for (int i = 0; i < 2000; ++i) {
    Eigen::Vector3d s(stretch(rng), stretch(rng), stretch(rng));
    if (i % 2 == 1) {
      // Inverted: one singular value through zero, the smallest in size (as a tet pressed flat
      // and past it), or any of them (a tet turned inside out).
      int k = 0;
      if (i % 4 == 1)
        s.cwiseAbs().minCoeff(&k);
      else
        k = i % 3;
      s[k] = -s[k];
      ++inverted;
    }
    const Eigen::Matrix3d f = gradient(rng, s);
    const Eigen::Matrix3d fast = polar_rotation(f);
    expect_proper_rotation(fast);
    EXPECT_LT((fast - rotation_by_svd(f)).norm(), 1e-9) << "gradient " << i << ":\n" << f;
  }
  EXPECT_EQ(inverted, 1000);
}

// Where two singular values meet the flip axis is not unique (nor is the SVD's): still a proper
// rotation, and as close to f as the SVD's (tr Rᵀ f, what the rotation maximises).
TEST(PolarRotation, GivesAProperRotationWhereTheFlipAxisIsNotUnique) {
  std::mt19937 rng(11);
  for (const Eigen::Vector3d& s : {Eigen::Vector3d(1.0, -0.5, 0.5), Eigen::Vector3d(-0.7, 0.7, 1.2),
                                   Eigen::Vector3d(-1.0, 1.0, 1.0)}) {
    const Eigen::Matrix3d f = gradient(rng, s);
    const Eigen::Matrix3d fast = polar_rotation(f);
    expect_proper_rotation(fast);
    EXPECT_NEAR((fast.transpose() * f).trace(), (rotation_by_svd(f).transpose() * f).trace(), 1e-9);
  }
}

TEST(PolarRotation, ANearlyCollapsedOrNonFiniteGradientStillGivesARotation) {
  std::mt19937 rng(3);
  const Eigen::Matrix3d flat = gradient(rng, Eigen::Vector3d(1.2, 0.8, 1e-9));
  expect_proper_rotation(polar_rotation(flat));
  EXPECT_LT((polar_rotation(flat) - rotation_by_svd(flat)).norm(), 1e-9);
  Eigen::Matrix3d broken = Eigen::Matrix3d::Identity();
  broken(1, 2) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(polar_rotation(broken), Eigen::Matrix3d::Identity());
}

}  // namespace
}  // namespace ultrasim::sim::corotational_detail
