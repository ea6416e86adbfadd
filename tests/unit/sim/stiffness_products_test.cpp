// The PCG FEM's products with its stiffness, against Eigen's sparse product: the node-block form
// its CG iterates with, and the product with a vector that is zero but where the constraints
// hold it.

#include <gtest/gtest.h>

#include <array>
#include <random>
#include <stdexcept>

#include "../../../app/sim/src/sparse_products.hpp"
#include "block_fixture.hpp"
#include "ultrasim/sim/linear_fem.hpp"
#include "ultrasim/sim/node_block_matrix.hpp"

namespace ultrasim::sim {
namespace {

Eigen::SparseMatrix<double, Eigen::RowMajor> two_material_stiffness() {
  const testing::Block b = testing::make_block({9, 5, 5}, [](const Eigen::Vector3d& x) {
    return x.z() < 10.0 ? Material{1, "fat", 10.0, 0.45} : Material{2, "muscle", 30.0, 0.45};
  });
  return LinearFem(b.mesh, b.materials, b.fixed, FemSettings{}).stiffness();
}

// Every band run in any order, then the spills: Eigen's product of the whole symmetric matrix
// (plus a diagonal), the same to the last bit in every order; only the upper blocks stored.
TEST(NodeBlockMatrix, MatchesEigensProductWhateverOrderTheBandsRunIn) {
  const Eigen::SparseMatrix<double, Eigen::RowMajor> k = two_material_stiffness();
  const detail::NodeBlockMatrix blocks(k, 4);
  ASSERT_EQ(blocks.block_rows(), k.rows() / 3);
  const auto nodes = static_cast<int>(k.rows() / 3);
  // 9 entries a block: the upper triangle and the diagonal blocks, about half of K.
  EXPECT_LT(9 * blocks.stored_blocks(), 0.6 * static_cast<double>(k.nonZeros()) + 9 * nodes);
  std::mt19937 random(3);
  std::uniform_real_distribution<double> value(-1.0, 1.0);
  const auto random_vector = [&] {
    return Eigen::VectorXd(Eigen::VectorXd::NullaryExpr(k.rows(), [&] { return value(random); }));
  };
  const Eigen::VectorXd x = random_vector();
  const Eigen::VectorXd d = random_vector();
  for (const Eigen::VectorXd* diagonal : {static_cast<const Eigen::VectorXd*>(nullptr), &d}) {
    Eigen::VectorXd expected = k * x;
    if (diagonal != nullptr) expected += diagonal->cwiseProduct(x);
    const double tolerance = 1e-13 * expected.cwiseAbs().maxCoeff();
    Eigen::VectorXd first;
    for (const std::array<int, 4>& order : {std::array{0, 1, 2, 3}, std::array{3, 1, 0, 2}}) {
      Eigen::VectorXd y = Eigen::VectorXd::Constant(k.rows(), 99.0);  // stale values
      std::vector<Eigen::VectorXd> spills(blocks.bands());
      for (int band : order) blocks.times_band(band, x, diagonal, y, spills[band]);
      blocks.add_spills(spills, y);
      EXPECT_LE((y - expected).cwiseAbs().maxCoeff(), tolerance);
      if (first.size() == 0) first = y;
      EXPECT_EQ(y, first) << "the same sum whatever the order";
    }
  }
}

TEST(NodeBlockMatrix, RejectsAMatrixNotMadeOfNodeBlocks) {
  using Matrix = Eigen::SparseMatrix<double, Eigen::RowMajor>;
  EXPECT_THROW(detail::NodeBlockMatrix(Matrix(7, 7), 4), std::invalid_argument);
  EXPECT_THROW(detail::NodeBlockMatrix(Matrix(6, 9), 4), std::invalid_argument);
  EXPECT_THROW(detail::NodeBlockMatrix(Matrix(6, 6), 0), std::invalid_argument);
}

TEST(SymmetricTimesSparseVector, MatchesTheFullProductOnAFemStiffness) {
  const Eigen::SparseMatrix<double, Eigen::RowMajor> k = two_material_stiffness();
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
