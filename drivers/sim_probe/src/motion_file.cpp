#include "ultrasim/drivers/sim_probe/motion_file.hpp"

#include <charconv>
#include <cmath>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace ultrasim::drivers::sim_probe {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr const char* kFields[] = {"time_s", "x_mm", "y_mm", "z_mm", "rx_deg", "ry_deg", "rz_deg"};

std::vector<std::string_view> words(std::string_view line) {
  std::vector<std::string_view> out;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t' || line[i] == '\r')) ++i;
    const std::size_t start = i;
    while (i < line.size() && line[i] != ' ' && line[i] != '\t' && line[i] != '\r') ++i;
    if (i > start) out.push_back(line.substr(start, i - start));
  }
  return out;
}

}  // namespace

std::vector<Keyframe> parse_motion(std::string_view text, const std::string& source) {
  std::vector<Keyframe> keyframes;
  int number = 0;
  double last_time_s = -1.0;
  std::size_t begin = 0;
  while (begin <= text.size()) {
    const std::size_t end = std::min(text.find('\n', begin), text.size());
    std::string_view line = text.substr(begin, end - begin);
    begin = end + 1;
    ++number;
    if (const auto hash = line.find('#'); hash != std::string_view::npos)
      line = line.substr(0, hash);
    const auto fields = words(line);
    if (fields.empty()) continue;
    const std::string where = source + ":" + std::to_string(number) + ": ";
    if (fields.size() < 7) {
      throw std::invalid_argument(where + kFields[fields.size()] +
                                  ": missing (a keyframe is time_s x_mm y_mm z_mm rx_deg ry_deg "
                                  "rz_deg [marker])");
    }
    if (fields.size() > 8) {
      throw std::invalid_argument(where + "marker: one word, found " +
                                  std::to_string(fields.size() - 7));
    }
    double v[7];
    for (int i = 0; i < 7; ++i) {
      const auto f = fields[static_cast<std::size_t>(i)];
      const auto [ptr, ec] = std::from_chars(f.data(), f.data() + f.size(), v[i]);
      if (ec != std::errc() || ptr != f.data() + f.size()) {
        throw std::invalid_argument(where + kFields[i] + ": not a number: '" + std::string(f) +
                                    "'");
      }
      if (!std::isfinite(v[i])) throw std::invalid_argument(where + kFields[i] + ": not finite");
    }
    if (v[0] < 0.0 || v[0] <= last_time_s) {
      throw std::invalid_argument(where + "time_s: must be >= 0 and increase (previous " +
                                  std::to_string(last_time_s) + ")");
    }
    last_time_s = v[0];
    Keyframe k;
    k.time_us = static_cast<hal::TimestampUs>(std::llround(v[0] * 1e6));
    k.position_mm = {v[1], v[2], v[3]};
    const Eigen::Vector3d rotation(v[4], v[5], v[6]);
    const double degrees = rotation.norm();
    if (degrees > 0.0) {
      k.orientation = Eigen::AngleAxisd(degrees * kPi / 180.0, rotation / degrees);
    }
    if (fields.size() == 8) k.marker = std::string(fields[7]);
    keyframes.push_back(std::move(k));
  }
  if (keyframes.empty()) throw std::invalid_argument(source + ": no keyframe");
  return keyframes;
}

std::vector<Keyframe> read_motion_file(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::invalid_argument(path.string() + ": cannot read the motion file");
  std::ostringstream text;
  text << in.rdbuf();
  return parse_motion(text.str(), path.string());
}

}  // namespace ultrasim::drivers::sim_probe
