#include "ultrasim/drivers/fiducial/pose_filter.hpp"

#include <cmath>

namespace ultrasim::drivers::fiducial {

namespace {

constexpr double kPi = 3.14159265358979323846;

// The smoothing factor of a first-order low-pass at cutoff_hz sampled every dt_s.
double smoothing(double cutoff_hz, double dt_s) {
  const double tau = 1.0 / (2.0 * kPi * cutoff_hz);
  return 1.0 / (1.0 + tau / dt_s);
}

}  // namespace

Eigen::Isometry3d PoseFilter::update(const Eigen::Isometry3d& measured,
                                     hal::TimestampUs timestamp_us) {
  if (!last_ || timestamp_us <= last_us_) {
    last_ = measured;
    last_us_ = timestamp_us;
    position_speed_ = orientation_speed_ = 0.0;
    return measured;
  }
  const double dt_s = static_cast<double>(timestamp_us - last_us_) * 1e-6;
  const Eigen::Quaterniond q_last(last_->linear());
  const Eigen::Quaterniond q_new(measured.linear());
  const double moved_mm = (measured.translation() - last_->translation()).norm();
  const double turned_deg = q_last.angularDistance(q_new) * 180.0 / kPi;
  const double a_speed = smoothing(settings_.speed_cutoff_hz, dt_s);
  position_speed_ += a_speed * (moved_mm / dt_s - position_speed_);
  orientation_speed_ += a_speed * (turned_deg / dt_s - orientation_speed_);

  const double a_position =
      smoothing(settings_.min_cutoff_hz + settings_.position_beta * position_speed_, dt_s);
  const double a_orientation =
      smoothing(settings_.min_cutoff_hz + settings_.orientation_beta * orientation_speed_, dt_s);
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  out.translation() =
      last_->translation() + a_position * (measured.translation() - last_->translation());
  out.linear() = q_last.slerp(a_orientation, q_new).normalized().toRotationMatrix();
  last_ = out;
  last_us_ = timestamp_us;
  return out;
}

}  // namespace ultrasim::drivers::fiducial
