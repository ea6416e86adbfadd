#include "ultrasim/tools/marker_mesh.hpp"

#include <apriltag/apriltag.h>
#include <apriltag/tag36h11.h>

#include <algorithm>
#include <cmath>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

namespace ultrasim::tools {

namespace {

constexpr std::uint8_t kCard = 232;  // printed white, a little short of the sensor's white
constexpr std::uint8_t kInk = 24;    // printed black

}  // namespace

render::TexturedMesh marker_body_mesh(const hal::MarkerBody& body,
                                      const std::vector<std::vector<Eigen::Vector3d>>& faces,
                                      int tile_px) {
  apriltag_family_t* family = tag36h11_create();
  const int columns = 4;
  const int rows = static_cast<int>((faces.size() + columns - 1) / columns);
  render::TexturedMesh mesh;
  mesh.texture_width_px = columns * tile_px;
  mesh.texture_height_px = rows * tile_px;
  mesh.texture_grey.assign(static_cast<std::size_t>(mesh.texture_width_px) * mesh.texture_height_px,
                           kCard);
  for (std::size_t f = 0; f < faces.size(); ++f) {
    const hal::BodyMarker& marker = body.markers[f];
    const auto& c = marker.corners_mm;
    const Eigen::Vector3d centre = (c[0] + c[1] + c[2] + c[3]) / 4.0;
    const Eigen::Vector3d right = (c[1] - c[0]).normalized();
    const Eigen::Vector3d up = (c[3] - c[0]).normalized();
    const double side_mm = (c[1] - c[0]).norm();
    double half = 0.0;  // the tile's half-width on the face, mm
    for (const auto& p : faces[f]) {
      half = std::max({half, std::abs((p - centre).dot(right)), std::abs((p - centre).dot(up))});
    }
    half *= 1.02;
    const int tile_x = static_cast<int>(f % columns) * tile_px;
    const int tile_y = static_cast<int>(f / columns) * tile_px;

    image_u8_t* tag = apriltag_to_image(family, static_cast<std::uint32_t>(marker.id));
    // The body's markers are the black-bordered square, inside the image's white outer ring.
    const int cells = tag->width - 2;
    constexpr int kSub = 4;  // supersampling per texel and axis
    for (int j = 0; j < tile_px; ++j) {
      for (int i = 0; i < tile_px; ++i) {
        int black = 0;
        for (int sj = 0; sj < kSub; ++sj) {
          for (int si = 0; si < kSub; ++si) {
            const double x = ((i + (si + 0.5) / kSub) / tile_px * 2.0 - 1.0) * half;
            const double y = (1.0 - (j + (sj + 0.5) / kSub) / tile_px * 2.0) * half;
            const double s = x / side_mm + 0.5, t = -y / side_mm + 0.5;
            if (s < 0.0 || s >= 1.0 || t < 0.0 || t >= 1.0) continue;  // white ring and card
            const int col = 1 + static_cast<int>(s * cells), row = 1 + static_cast<int>(t * cells);
            if (tag->buf[row * tag->stride + col] < 128) ++black;
          }
        }
        const double ink = static_cast<double>(black) / (kSub * kSub);
        mesh.texture_grey[static_cast<std::size_t>(tile_y + j) * mesh.texture_width_px + tile_x +
                          i] = static_cast<std::uint8_t>(std::lround(kCard + ink * (kInk - kCard)));
      }
    }
    image_u8_destroy(tag);

    const auto base = static_cast<std::uint32_t>(mesh.positions_mm.size());
    for (const auto& p : faces[f]) {
      const double x = (p - centre).dot(right), y = (p - centre).dot(up);
      const double u = (tile_x + (x / half + 1.0) / 2.0 * tile_px) / mesh.texture_width_px;
      const double v = (tile_y + (1.0 - y / half) / 2.0 * tile_px) / mesh.texture_height_px;
      mesh.positions_mm.push_back(p.cast<float>());
      mesh.normals.push_back(marker.outward_normal.cast<float>());
      mesh.texcoords.emplace_back(static_cast<float>(u), static_cast<float>(v));
    }
    for (std::uint32_t k = 1; k + 1 < faces[f].size(); ++k) {
      mesh.triangles.insert(mesh.triangles.end(), {base, base + k, base + k + 1});
    }
  }
  tag36h11_destroy(family);
  return mesh;
}

hal::CameraFrame camera_frame(const render::RgbaImage& view, double blur_sigma_px,
                              double noise_sigma, std::uint64_t seed) {
  cv::Mat grey(view.height, view.width, CV_32F);
  for (int y = 0; y < view.height; ++y) {
    for (int x = 0; x < view.width; ++x) {
      grey.at<float>(y, x) = view.at(x, y)[0];  // red = grey
    }
  }
  if (blur_sigma_px > 0.0) cv::GaussianBlur(grey, grey, cv::Size(0, 0), blur_sigma_px);
  if (noise_sigma > 0.0) {
    cv::Mat noise(grey.size(), CV_32F);
    cv::RNG rng(seed);
    rng.fill(noise, cv::RNG::NORMAL, 0.0, noise_sigma);
    grey += noise;
  }
  hal::CameraFrame frame;
  frame.width = view.width;
  frame.height = view.height;
  frame.grey.resize(static_cast<std::size_t>(frame.width) * frame.height);
  for (int y = 0; y < frame.height; ++y) {
    for (int x = 0; x < frame.width; ++x) {
      frame.grey[static_cast<std::size_t>(y) * frame.width + x] =
          cv::saturate_cast<std::uint8_t>(grey.at<float>(y, x));
    }
  }
  return frame;
}

}  // namespace ultrasim::tools
