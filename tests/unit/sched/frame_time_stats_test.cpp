#include "ultrasim/sched/frame_time_stats.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <vector>

namespace ultrasim::sched {
namespace {

TEST(FrameTimeStats, EmptyStatsReadAsZero) {
  const FrameTimeStats stats(16'667);
  EXPECT_EQ(stats.count(), 0);
  EXPECT_EQ(stats.percentile_us(99), 0);
  EXPECT_EQ(stats.max_us(), 0);
  EXPECT_EQ(stats.mean_us(), 0.0);
}

TEST(FrameTimeStats, PercentilesMatchASortedReferenceToTheResolution) {
  FrameTimeStats stats(16'667, 10);
  std::mt19937 rng(3);
  std::lognormal_distribution<double> frame_us(std::log(8000.0), 0.4);
  std::vector<std::int64_t> samples;
  for (int i = 0; i < 5000; ++i) {
    samples.push_back(static_cast<std::int64_t>(frame_us(rng)));
    stats.record(samples.back());
  }
  std::sort(samples.begin(), samples.end());
  for (double p : {1.0, 50.0, 90.0, 99.0, 99.9}) {
    const auto rank = static_cast<std::size_t>(std::ceil(p / 100.0 * samples.size()));
    const std::int64_t reference = samples[rank - 1];
    EXPECT_GE(stats.percentile_us(p), reference) << p;
    EXPECT_LE(stats.percentile_us(p), reference + 10) << p;
  }
  EXPECT_EQ(stats.percentile_us(100), samples.back());
  EXPECT_EQ(stats.min_us(), samples.front());
  EXPECT_EQ(stats.deadline_misses(),
            std::count_if(samples.begin(), samples.end(), [](auto s) { return s > 16'667; }));
}

TEST(FrameTimeStats, SamplesBeyondTheHistogramStillCountExactly) {
  FrameTimeStats stats(1000, 10, 100);  // histogram covers 1 ms
  stats.record(500);
  stats.record(250'000);
  EXPECT_EQ(stats.max_us(), 250'000);
  EXPECT_EQ(stats.percentile_us(100), 250'000);
  EXPECT_EQ(stats.percentile_us(50), 510);
  EXPECT_EQ(stats.deadline_misses(), 1);
}

}  // namespace
}  // namespace ultrasim::sched
