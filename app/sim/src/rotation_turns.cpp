// The portable turn kernel (rotation_turns.hpp): one tet at a time, in the order the AVX2
// kernel keeps lane by lane.

#include "rotation_turns.hpp"

#include <cmath>

namespace ultrasim::sim::corotational_detail {

namespace {

void portable_turns(const TurnInputs& in, std::span<const int> tets, double* turns) {
  const auto* rest = reinterpret_cast<const double*>(in.rest_mm);
  for (const int t : tets) {
    const geometry::Tet& tet = in.tets[t];
    const double* g = in.shape_gradients[t].data();  // column-major: g[3 a + j], node a's
    const double* r = in.rotations[t].data();        // column-major: r[3 col + row]
    double x[4][3];
    for (int a = 0; a < 4; ++a) {
      for (int i = 0; i < 3; ++i) {
        x[a][i] = rest[3 * tet[a] + i] + in.u_mm[3 * tet[a] + i];
      }
    }
    // F(i, j) = Σ_b (x_b − x_0)_i g_b,j over b = 1..3, summed in b's order.
    double f[3][3];
    for (int i = 0; i < 3; ++i) {
      const double e1 = x[1][i] - x[0][i], e2 = x[2][i] - x[0][i], e3 = x[3][i] - x[0][i];
      for (int j = 0; j < 3; ++j) f[i][j] = e1 * g[3 + j] + e2 * g[6 + j] + e3 * g[9 + j];
    }
    // S = rᵀ F: S(i, j) = Σ_k r(k, i) F(k, j).
    double s[3][3];
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) {
        s[i][j] = r[3 * i] * f[0][j] + r[3 * i + 1] * f[1][j] + r[3 * i + 2] * f[2][j];
      }
    }
    const double d0 = s[0][0], d1 = s[1][1], d2 = s[2][2];
    const double m01 = 0.5 * (s[0][1] + s[1][0]), m02 = 0.5 * (s[0][2] + s[2][0]),
                 m12 = 0.5 * (s[1][2] + s[2][1]);
    const double minor2 = d0 * d1 - m01 * m01;
    const double det_symmetric =
        d0 * (d1 * d2 - m12 * m12) - m01 * (m01 * d2 - m12 * m02) + m02 * (m01 * m12 - d1 * m02);
    const double det_f = f[0][0] * (f[1][1] * f[2][2] - f[1][2] * f[2][1]) -
                         f[0][1] * (f[1][0] * f[2][2] - f[1][2] * f[2][0]) +
                         f[0][2] * (f[1][0] * f[2][1] - f[1][1] * f[2][0]);
    const bool lost = !(d0 > kCollapsedStretch) || !(d1 > kCollapsedStretch) ||
                      !(d2 > kCollapsedStretch) || !(minor2 > 0.0) || !(det_symmetric > 0.0) ||
                      !(det_f > 0.0);
    const double t0 = (s[2][1] - s[1][2]) / (d1 + d2), t1 = (s[0][2] - s[2][0]) / (d0 + d2),
                 t2 = (s[1][0] - s[0][1]) / (d0 + d1);
    const double turn = std::sqrt(t0 * t0 + t1 * t1 + t2 * t2);
    turns[t] = lost ? std::numeric_limits<double>::infinity() : turn;
  }
}

}  // namespace

TurnKernel portable_turn_kernel() {
  return &portable_turns;
}

}  // namespace ultrasim::sim::corotational_detail
