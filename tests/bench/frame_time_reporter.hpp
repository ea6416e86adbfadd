#pragma once

// A benchmark reporter for summaries printed after the runs: the console output as usual, and
// every benchmark's wall time per iteration (ms) kept by run name, so that a program can print
// its medians as ratios within one run (docs/benchmarks.md).

#include <benchmark/benchmark.h>

#include <map>
#include <string>
#include <vector>

#include "median.hpp"

namespace ultrasim::bench {

class FrameTimeReporter : public benchmark::ConsoleReporter {
 public:
  void ReportRuns(const std::vector<Run>& runs) override {
    ConsoleReporter::ReportRuns(runs);
    for (const Run& run : runs) {
      if (run.run_type != Run::RT_Iteration || run.error_occurred || run.iterations == 0) continue;
      times_ms_[run.run_name.str()].push_back(1e3 * run.real_accumulated_time / run.iterations);
    }
  }

 protected:
  // The median over the repetitions of the run with this full name; 0 when it did not run.
  double median_ms(const std::string& name) const {
    const auto it = times_ms_.find(name);
    return it == times_ms_.end() ? 0.0 : median(it->second);
  }
  // The same for the first run whose name starts with `prefix` (names end in options such as
  // "/iterations:60").
  double median_ms_by_prefix(const std::string& prefix) const {
    for (const auto& [name, times] : times_ms_) {
      if (name.starts_with(prefix)) return median(times);
    }
    return 0.0;
  }

 private:
  std::map<std::string, std::vector<double>> times_ms_;
};

}  // namespace ultrasim::bench
