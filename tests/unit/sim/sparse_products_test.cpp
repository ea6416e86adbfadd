// The PCG FEM's product with a vector that is zero but where the constraints hold it, against
// Eigen's full sparse product.

#include "../../../app/sim/src/sparse_products.hpp"

#include <gtest/gtest.h>

#include <random>

#include "block_fixture.hpp"
#include "ultrasim/sim/linear_fem.hpp"

namespace ultrasim::sim {
namespace {

TEST(SymmetricTimesSparseVector, MatchesTheFullProductOnAFemStiffness) {
  const testing::Block b = testing::make_block({9, 5, 5}, [](const Eigen::Vector3d& x) {
    return x.z() < 10.0 ? Material{1, "fat", 10.0, 0.45} : Material{2, "muscle", 30.0, 0.45};
  });
  const LinearFem fem(b.mesh, b.materials, b.fixed, FemSettings{});
  const Eigen::SparseMatrix<double, Eigen::RowMajor>& k = fem.stiffness();
  // The fast path reads rows for columns: the assembled stiffness is symmetric to rounding.
  const Eigen::SparseMatrix<double> asymmetry =
      Eigen::SparseMatrix<double>(k) - Eigen::SparseMatrix<double>(k.transpose());
  EXPECT_LT(asymmetry.norm(), 1e-12 * k.norm());

  std::mt19937 random(7);
  std::uniform_real_distribution<double> value(-2.0, 2.0);
  std::uniform_int_distribution<Eigen::Index> entry(0, k.rows() - 1);
  const Eigen::VectorXd diagonal =
      Eigen::VectorXd::NullaryExpr(k.rows(), [&] { return value(random); });
  for (int nonzeros : {0, 1, 12, 60}) {
    Eigen::VectorXd p = Eigen::VectorXd::Zero(k.rows());
    for (int i = 0; i < nonzeros; ++i) p[entry(random)] = value(random);
    for (const Eigen::VectorXd* d : {static_cast<const Eigen::VectorXd*>(nullptr), &diagonal}) {
      Eigen::VectorXd expected = k * p;
      if (d != nullptr) expected += d->cwiseProduct(p);
      Eigen::VectorXd out = Eigen::VectorXd::Constant(3, 99.0);  // wrong size, stale values
      detail::symmetric_times_sparse_vector(k, d, p, out);
      ASSERT_EQ(out.size(), k.rows());
      EXPECT_LE((out - expected).cwiseAbs().maxCoeff(),
                1e-12 * (1.0 + expected.cwiseAbs().maxCoeff()))
          << nonzeros << " nonzeros, diagonal " << (d != nullptr);
    }
  }
}

}  // namespace
}  // namespace ultrasim::sim
