#include "ultrasim/tracking/marker_body.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace ultrasim::tracking {
namespace {

constexpr double kEdgeMm = 40.0;

// The folded net is a regular dodecahedron: 20 corners, each shared by three faces, all at the
// circumradius e·√3·φ/2; face centres at the inradius; opposite faces parallel.
TEST(FoldedNet, ClosesIntoARegularDodecahedron) {
  const auto faces = dodecahedron_faces(kEdgeMm);
  ASSERT_EQ(faces.size(), 12u);
  const double phi = (1.0 + std::sqrt(5.0)) / 2.0;
  const double circumradius = kEdgeMm * std::sqrt(3.0) * phi / 2.0;
  const double inradius = kEdgeMm * phi * phi / (2.0 * std::sqrt(3.0 - phi));
  std::vector<Eigen::Vector3d> corners;
  std::vector<int> shared;
  for (const auto& face : faces) {
    ASSERT_EQ(face.size(), 5u);
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();
    for (const auto& c : face) {
      EXPECT_NEAR(c.norm(), circumradius, 1e-9);
      centre += c / 5.0;
      bool found = false;
      for (std::size_t i = 0; i < corners.size(); ++i) {
        if ((corners[i] - c).norm() < 1e-9) {
          ++shared[i];
          found = true;
        }
      }
      if (!found) {
        corners.push_back(c);
        shared.push_back(1);
      }
    }
    EXPECT_NEAR(centre.norm(), inradius, 1e-9);
    // Counter-clockwise seen from outside.
    const Eigen::Vector3d normal = (face[1] - face[0]).cross(face[2] - face[0]);
    EXPECT_GT(normal.dot(centre), 0.0);
  }
  ASSERT_EQ(corners.size(), 20u);
  for (int s : shared) EXPECT_EQ(s, 3);
}

// Markers sit in their faces' planes, centred, facing out, and read unmirrored from outside:
// bottom-left → bottom-right × bottom-left → top-left points out of the body. Same for the cube.
void expect_markers_on_faces(const hal::MarkerBody& body,
                             const std::vector<std::vector<Eigen::Vector3d>>& faces,
                             double detected_side_mm) {
  ASSERT_EQ(body.markers.size(), faces.size());
  for (std::size_t i = 0; i < faces.size(); ++i) {
    const auto& m = body.markers[i];
    EXPECT_EQ(m.id, static_cast<int>(i));
    Eigen::Vector3d face_centre = Eigen::Vector3d::Zero();
    for (const auto& c : faces[i]) face_centre += c / static_cast<double>(faces[i].size());
    Eigen::Vector3d marker_centre = Eigen::Vector3d::Zero();
    for (const auto& c : m.corners_mm) {
      marker_centre += c / 4.0;
      EXPECT_NEAR((c - face_centre).dot(m.outward_normal), 0.0, 1e-9);
    }
    EXPECT_LT((marker_centre - face_centre).norm(), 1e-9);
    EXPECT_NEAR(m.outward_normal.dot(face_centre.normalized()), 1.0, 1e-9);
    const Eigen::Vector3d right = m.corners_mm[1] - m.corners_mm[0];
    const Eigen::Vector3d up = m.corners_mm[3] - m.corners_mm[0];
    EXPECT_NEAR(right.norm(), detected_side_mm, 1e-9);
    EXPECT_NEAR(up.norm(), detected_side_mm, 1e-9);
    EXPECT_NEAR(right.cross(up).normalized().dot(m.outward_normal), 1.0, 1e-9);
  }
}

TEST(MarkerBody, DodecahedronMarkersLieOnTheFoldedFaces) {
  const double printed = largest_marker_side_mm(kEdgeMm);
  const auto body = dodecahedron_marker_body(kEdgeMm, printed);
  EXPECT_EQ(body.family, "tag36h11");
  expect_markers_on_faces(body, dodecahedron_faces(kEdgeMm), 0.8 * printed);
}

TEST(MarkerBody, CubeMarkersLieOnItsFaces) {
  const auto body = cube_marker_body(50.0, 45.0);
  expect_markers_on_faces(body, cube_faces(50.0), 36.0);
}

// The marker's top on the page is the face's "up" on the folded solid: the net face's corners
// 0–1 edge, where the printed tag's top row points, is the edge its top-left → top-right
// corners run along.
TEST(MarkerBody, PrintedTopPointsAtTheNetFacesUpEdge) {
  const auto net = make_dodecahedron_net(kEdgeMm);
  const auto placed = fold_dodecahedron_net(net);
  const auto body = dodecahedron_marker_body(kEdgeMm, largest_marker_side_mm(kEdgeMm));
  for (std::size_t f = 0; f < 12; ++f) {
    const auto& corners = net.faces[f].corners_mm;
    const Eigen::Vector2d mid = (corners[0] + corners[1]) / 2;
    const Eigen::Vector3d edge_mid = placed[f] * Eigen::Vector3d(mid.x(), mid.y(), 0.0);
    const auto& m = body.markers[f];
    const Eigen::Vector3d centre = (m.corners_mm[0] + m.corners_mm[2]) / 2;
    const Eigen::Vector3d up = (m.corners_mm[3] - m.corners_mm[0]).normalized();
    EXPECT_NEAR(up.dot((edge_mid - centre).normalized()), 1.0, 1e-9) << "face " << f;
  }
}

// The largest printed square (white ring included) stays inside its pentagon, touching it within
// the 2 % margin: its corners are at most 0.98 inradii out along every edge normal.
TEST(MarkerBody, LargestMarkerFitsThePentagon) {
  const auto faces = dodecahedron_faces(kEdgeMm);
  const auto body = dodecahedron_marker_body(kEdgeMm, largest_marker_side_mm(kEdgeMm));
  const double inradius = pentagon_inradius_mm(kEdgeMm);
  double reach = 0.0;
  for (std::size_t f = 0; f < faces.size(); ++f) {
    const auto& m = body.markers[f];
    const Eigen::Vector3d centre = (m.corners_mm[0] + m.corners_mm[2]) / 2;
    for (const auto& corner : m.corners_mm) {
      const Eigen::Vector3d printed = centre + (corner - centre) / kTag36h11BorderFraction;
      for (std::size_t k = 0; k < 5; ++k) {
        const Eigen::Vector3d a = faces[f][k], b = faces[f][(k + 1) % 5];
        const Eigen::Vector3d inward = m.outward_normal.cross(b - a).normalized();
        const Eigen::Vector3d midpoint = (a + b) / 2;
        reach = std::max(reach, (centre - printed).dot(inward) / (centre - midpoint).dot(inward));
      }
    }
  }
  EXPECT_NEAR(reach, 0.98, 1e-6);
  EXPECT_GT(largest_marker_side_mm(kEdgeMm), 0.9 * std::sqrt(2.0) * inradius);
}

TEST(MarkerBody, RefusesMarkersThatDoNotFit) {
  EXPECT_THROW(dodecahedron_marker_body(0.0, 10.0), std::invalid_argument);
  EXPECT_THROW(cube_marker_body(20.0, -1.0), std::invalid_argument);
}

}  // namespace
}  // namespace ultrasim::tracking
