#pragma once

#include <Eigen/Core>
#include <Eigen/LU>
#include <cassert>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <span>
#include <stdexcept>
#include <vector>

namespace ultrasim::imaging {

// A 3D image on a regular grid, as ITK/MetaImage define it: the world position of voxel index
// (i, j, k) is origin_mm + direction · diag(spacing_mm) · (i, j, k). Voxel (i, j, k) is stored at
// i + size.x · (j + size.y · k) (x fastest), matching MetaImage's raw layout.
template <typename T>
class Volume {
 public:
  Volume() = default;
  Volume(Eigen::Vector3i size, Eigen::Vector3d spacing_mm, Eigen::Vector3d origin_mm,
         Eigen::Matrix3d direction = Eigen::Matrix3d::Identity())
      : size_(size), spacing_mm_(spacing_mm), origin_mm_(origin_mm), direction_(direction) {
    if ((size.array() <= 0).any()) throw std::invalid_argument("Volume: size must be positive");
    if (!(spacing_mm.array() > 0).all()) throw std::invalid_argument("Volume: spacing must be > 0");
    voxels_.assign(static_cast<std::size_t>(size.prod()), T{});
    update_world_to_index();
  }

  const Eigen::Vector3i& size() const { return size_; }
  const Eigen::Vector3d& spacing_mm() const { return spacing_mm_; }
  const Eigen::Vector3d& origin_mm() const { return origin_mm_; }
  const Eigen::Matrix3d& direction() const { return direction_; }
  std::size_t voxel_count() const { return voxels_.size(); }

  std::span<T> voxels() { return voxels_; }
  std::span<const T> voxels() const { return voxels_; }

  std::size_t linear_index(int i, int j, int k) const {
    return static_cast<std::size_t>(i) +
           static_cast<std::size_t>(size_.x()) *
               (static_cast<std::size_t>(j) + static_cast<std::size_t>(size_.y()) * k);
  }
  T& at(int i, int j, int k) { return voxels_[linear_index(i, j, k)]; }
  const T& at(int i, int j, int k) const { return voxels_[linear_index(i, j, k)]; }

  bool contains_index(int i, int j, int k) const {
    return i >= 0 && j >= 0 && k >= 0 && i < size_.x() && j < size_.y() && k < size_.z();
  }

  Eigen::Vector3d index_to_world(const Eigen::Vector3d& index) const {
    return origin_mm_ + direction_ * spacing_mm_.cwiseProduct(index);
  }
  Eigen::Vector3d world_to_index(const Eigen::Vector3d& world_mm) const {
    return world_to_index_ * (world_mm - origin_mm_);
  }

  // World-space bounding box of the voxel centres (exact for an axis-aligned direction).
  Eigen::Vector3d world_min_mm() const { return corner_extent(true); }
  Eigen::Vector3d world_max_mm() const { return corner_extent(false); }

  // Trilinear interpolation at a world point. Points outside the hull of voxel centres return
  // `outside`. Never allocates; safe to call from many threads at once.
  float sample_trilinear(const Eigen::Vector3d& world_mm, float outside) const {
    const Eigen::Vector3d p = world_to_index(world_mm);
    constexpr double kEdge = 1e-9;  // admit points on the last voxel centre despite rounding
    if (!(p.x() >= -kEdge && p.y() >= -kEdge && p.z() >= -kEdge && p.x() <= size_.x() - 1 + kEdge &&
          p.y() <= size_.y() - 1 + kEdge && p.z() <= size_.z() - 1 + kEdge)) {
      return outside;
    }
    const auto split = [](double v, int n, int& i0, double& f) {
      i0 = static_cast<int>(std::floor(v));
      if (i0 < 0) i0 = 0;
      if (i0 > n - 2) i0 = n > 1 ? n - 2 : 0;
      f = n > 1 ? v - i0 : 0.0;
      if (f < 0) f = 0;
      if (f > 1) f = 1;
    };
    int i, j, k;
    double fx, fy, fz;
    split(p.x(), size_.x(), i, fx);
    split(p.y(), size_.y(), j, fy);
    split(p.z(), size_.z(), k, fz);
    const int di = size_.x() > 1 ? 1 : 0;
    const int dj = size_.y() > 1 ? 1 : 0;
    const int dk = size_.z() > 1 ? 1 : 0;
    const auto v = [&](int a, int b, int c) { return static_cast<double>(at(a, b, c)); };
    const double c00 = v(i, j, k) * (1 - fx) + v(i + di, j, k) * fx;
    const double c10 = v(i, j + dj, k) * (1 - fx) + v(i + di, j + dj, k) * fx;
    const double c01 = v(i, j, k + dk) * (1 - fx) + v(i + di, j, k + dk) * fx;
    const double c11 = v(i, j + dj, k + dk) * (1 - fx) + v(i + di, j + dj, k + dk) * fx;
    const double c0 = c00 * (1 - fy) + c10 * fy;
    const double c1 = c01 * (1 - fy) + c11 * fy;
    return static_cast<float>(c0 * (1 - fz) + c1 * fz);
  }

  // Value of the voxel nearest to a world point (for label volumes), or `outside`.
  T sample_nearest(const Eigen::Vector3d& world_mm, T outside) const {
    const Eigen::Vector3d p = world_to_index(world_mm);
    const int i = static_cast<int>(std::lround(p.x()));
    const int j = static_cast<int>(std::lround(p.y()));
    const int k = static_cast<int>(std::lround(p.z()));
    return contains_index(i, j, k) ? at(i, j, k) : outside;
  }

 private:
  void update_world_to_index() {
    world_to_index_ = (direction_ * spacing_mm_.asDiagonal()).inverse();
  }
  Eigen::Vector3d corner_extent(bool min) const {
    Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e300), hi = Eigen::Vector3d::Constant(-1e300);
    for (int c = 0; c < 8; ++c) {
      const Eigen::Vector3d idx((c & 1) ? size_.x() - 1 : 0, (c & 2) ? size_.y() - 1 : 0,
                                (c & 4) ? size_.z() - 1 : 0);
      const Eigen::Vector3d w = index_to_world(idx);
      lo = lo.cwiseMin(w);
      hi = hi.cwiseMax(w);
    }
    return min ? lo : hi;
  }

  Eigen::Vector3i size_ = Eigen::Vector3i::Zero();
  Eigen::Vector3d spacing_mm_ = Eigen::Vector3d::Ones();
  Eigen::Vector3d origin_mm_ = Eigen::Vector3d::Zero();
  Eigen::Matrix3d direction_ = Eigen::Matrix3d::Identity();
  Eigen::Matrix3d world_to_index_ = Eigen::Matrix3d::Identity();
  std::vector<T> voxels_;
};

}  // namespace ultrasim::imaging
