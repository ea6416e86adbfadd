// The two fast deformed slicers against the per-pixel reference (slice_deformed_reference): every
// pixel within ±1 grey level, and background on exactly the pixels where the reference has it,
// over random probe poses (both grid kinds) and random smooth deformations; planes that run
// exactly through nodes, faces and the mesh's boundary; inverted tets; rows split over threads;
// the fast slicer's AVX2 sampling against its portable sampling, bitwise; and an affine
// deformation of an affine echo, where the right answer is known.

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <iostream>
#include <numbers>
#include <random>
#include <stdexcept>
#include <thread>
#include <vector>

#include "affine_volume.hpp"
#include "ultrasim/geometry/tet_locator.hpp"
#include "ultrasim/geometry/tet_mesh.hpp"
#include "ultrasim/imaging/bscan.hpp"
#include "ultrasim/imaging/fast_slicer.hpp"
#include "ultrasim/imaging/published_slicer.hpp"

namespace ultrasim::imaging {
namespace {

// Background grey no echo can come near: volumes here hold 20..240, so a
// pixel equal to it is background for certain and the background sets can be compared exactly.
constexpr int kBackground = 3;

const Eigen::Vector3d kMeshMin(-20, -10, 0), kMeshMax(20, 10, 30);

geometry::TetMesh grid_mesh(const Eigen::Vector3i& nodes) {
  return geometry::make_grid_tet_mesh(geometry::GridSpec::spanning(kMeshMin, kMeshMax, nodes));
}

// A rough texture (hashed voxels, 20..240) so that a pixel sampled at the wrong rest position
// shows, on a volume that covers [min_mm, max_mm] at 0.5 mm.
Volume<std::uint8_t> textured_volume(const Eigen::Vector3d& min_mm, const Eigen::Vector3d& max_mm) {
  const Eigen::Vector3d spacing(0.5, 0.5, 0.5);
  const Eigen::Vector3i size =
      ((max_mm - min_mm).cwiseQuotient(spacing).array().round() + 1).cast<int>();
  Volume<std::uint8_t> v(size, spacing, min_mm);
  auto voxels = v.voxels();
  for (std::size_t i = 0; i < voxels.size(); ++i) {
    voxels[i] = static_cast<std::uint8_t>(20 + ((i * 2654435761u) >> 16) % 221);
  }
  return v;
}

using testing::affine_echo;
using testing::affine_volume;

Eigen::Matrix3d random_rotation(std::mt19937& rng) {
  std::normal_distribution<double> normal;
  std::uniform_real_distribution<double> angle(-std::numbers::pi, std::numbers::pi);
  const Eigen::Vector3d axis = Eigen::Vector3d(normal(rng), normal(rng), normal(rng)).normalized();
  return Eigen::AngleAxisd(angle(rng), axis).toRotationMatrix();
}

// A smooth deformation: a rigid motion, an indentation under a point of the skin (z = 0) fading
// with depth, and three low-frequency sine waves. Amplitudes keep the displacement gradient well
// below 1, so no tet inverts; the test checks that.
std::vector<Eigen::Vector3d> random_deformation(const geometry::TetMesh& mesh, std::mt19937& rng,
                                                bool rigid_motion) {
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  const Eigen::Matrix3d rotation =
      rigid_motion ? random_rotation(rng) : Eigen::Matrix3d::Identity();
  Eigen::Vector3d shift = Eigen::Vector3d::Zero();
  if (rigid_motion) shift = Eigen::Vector3d(unit(rng), unit(rng), unit(rng)) * 5;
  const Eigen::Vector2d dent_centre(unit(rng) * 12, unit(rng) * 6);
  const double dent_depth_mm = 2.0 + 3.0 * (unit(rng) + 1.0);
  const double dent_radius_mm = 8.0;
  std::array<Eigen::Vector3d, 3> amplitude_mm, wave_per_mm;
  std::array<double, 3> phase;
  for (int w = 0; w < 3; ++w) {
    wave_per_mm[w] = Eigen::Vector3d(unit(rng), unit(rng), unit(rng)) * 0.25;
    amplitude_mm[w] = Eigen::Vector3d(unit(rng), unit(rng), unit(rng)) * 0.4;
    phase[w] = unit(rng) * std::numbers::pi;
  }
  std::vector<Eigen::Vector3d> deformed;
  deformed.reserve(mesh.rest_positions_mm.size());
  for (const Eigen::Vector3d& p : mesh.rest_positions_mm) {
    Eigen::Vector3d u = Eigen::Vector3d::Zero();
    const double r2 = (p.head<2>() - dent_centre).squaredNorm();
    u.z() = dent_depth_mm * std::exp(-r2 / (dent_radius_mm * dent_radius_mm)) *
            (1.0 - p.z() / kMeshMax.z());
    for (int w = 0; w < 3; ++w) u += amplitude_mm[w] * std::sin(wave_per_mm[w].dot(p) + phase[w]);
    deformed.push_back(rotation * (p + u) + shift);
  }
  return deformed;
}

ProbeGeometry linear_probe() {
  ProbeGeometry probe;
  probe.width_mm = 30.0;
  probe.depth_mm = 32.0;
  return probe;
}
ProbeGeometry convex_probe() {
  ProbeGeometry probe;
  probe.kind = ProbeKind::kConvex;
  probe.radius_mm = 20.0;
  probe.depth_mm = 28.0;
  probe.fan_angle_deg = 75.0;
  return probe;
}

// Differences of one image against the reference.
struct Agreement {
  long pixels = 0;
  long differing = 0;            // |grey - reference| >= 1
  long beyond_one_level = 0;     // |grey - reference| > 1
  long background_mismatch = 0;  // background in one image only
  long inside = 0;               // non-background pixels of the reference
  void add(std::span<const std::uint8_t> reference, std::span<const std::uint8_t> image) {
    for (std::size_t i = 0; i < reference.size(); ++i) {
      ++pixels;
      const bool ref_bg = reference[i] == kBackground, bg = image[i] == kBackground;
      inside += !ref_bg;
      if (ref_bg != bg) {
        ++background_mismatch;
        continue;
      }
      const int d = std::abs(int(reference[i]) - int(image[i]));
      differing += d >= 1;
      beyond_one_level += d > 1;
    }
  }
  void expect_agrees(const char* what) const {
    std::cout << "[ agreement ] " << what << ": " << pixels << " pixels (" << inside << " inside), "
              << differing << " differ by 1 grey level, " << beyond_one_level << " by more, "
              << background_mismatch << " background mismatches\n";
    EXPECT_EQ(beyond_one_level, 0) << what;
    EXPECT_EQ(background_mismatch, 0) << what;
  }
};

// Slices one frame with all three methods and adds (b) and (c) to the tallies.
struct Frame {
  const Volume<std::uint8_t>& volume;
  const geometry::TetMesh& mesh;
  std::span<const Eigen::Vector3d> deformed;
  const geometry::TetLocator& locator;
  const ProbePose& pose;
  const BscanGrid& grid;
  BscanSettings settings;
};
// The slicers are reused from frame to frame, as the app uses them.
void compare_frame(const Frame& f, PublishedSlicer& b, FastSlicer& c, Agreement& published,
                   Agreement& fast) {
  const std::size_t n = static_cast<std::size_t>(f.grid.width_px()) * f.grid.height_px();
  std::vector<std::uint8_t> reference(n), image(n);
  slice_deformed_reference(f.volume, f.mesh, f.locator, f.pose, f.grid, f.settings, reference);
  b.prepare(f.volume, f.deformed, f.pose);
  b.slice(f.settings, image);
  published.add(reference, image);
  c.prepare(f.volume, f.deformed, f.pose);
  c.slice(f.settings, image);
  fast.add(reference, image);
}

TEST(SlicerAgreement, FastAndPublishedMatchTheReferenceOverRandomPosesAndDeformations) {
  // The volume covers most of the mesh but not all of it, so some pixels inside the mesh map
  // outside the volume and must show background there too.
  const auto volume = textured_volume({-18, -10, 0}, {20, 9, 27});
  const std::array<BscanGrid, 2> grids = {BscanGrid(linear_probe(), 61, 53),
                                          BscanGrid(convex_probe(), 67, 49)};
  const std::array<int, 6> region_counts = {1, 3, 8, 32, 64, 128};
  std::mt19937 rng(20130415);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  Agreement published, fast;
  int frames = 0;
  // The published 32×16×16 grid and a coarser one (bigger tets: longer spans per tet).
  for (const Eigen::Vector3i& nodes : {Eigen::Vector3i(16, 8, 8), Eigen::Vector3i(32, 16, 16)}) {
    const geometry::TetMesh mesh = grid_mesh(nodes);
    geometry::TetLocator locator(mesh);
    std::array<PublishedSlicer, 2> b = {PublishedSlicer(mesh, grids[0]),
                                        PublishedSlicer(mesh, grids[1])};
    std::array<FastSlicer, 2> c = {FastSlicer(mesh, grids[0]), FastSlicer(mesh, grids[1])};
    for (int d = 0; d < 6; ++d) {
      const auto deformed = random_deformation(mesh, rng, d % 2 == 1);
      locator.rebuild(deformed);
      ASSERT_EQ(locator.degenerate_tet_count(), 0) << "deformation " << d << " inverted tets";
      // Poses around where the (possibly moved) tissue is; many reach outside it.
      Eigen::Vector3d centre = Eigen::Vector3d::Zero();
      for (const auto& p : deformed) centre += p;
      centre /= static_cast<double>(deformed.size());
      for (int k = 0; k < 24; ++k) {
        ProbePose pose;
        pose.face_center_mm =
            centre + Eigen::Vector3d(unit(rng) * 14, unit(rng) * 7, unit(rng) * 12);
        pose.axes = random_rotation(rng);
        BscanSettings settings;
        settings.background_grey = kBackground;
        b[k % 2].set_region_count(region_counts[(k + d) % region_counts.size()]);
        compare_frame({volume, mesh, deformed, locator, pose, grids[k % 2], settings}, b[k % 2],
                      c[k % 2], published, fast);
        ++frames;
      }
    }
  }
  std::cout << "[ agreement ] " << frames << " frames\n";
  published.expect_agrees("published (b)");
  fast.expect_agrees("fast (c)");
  EXPECT_GT(fast.inside, fast.pixels / 5) << "the poses should see tissue";
  EXPECT_GT(fast.pixels - fast.inside, fast.pixels / 20) << "and some background";
}

TEST(SlicerAgreement, PlanesThroughNodesFacesAndTheMeshBoundaryMatchTheReference) {
  // Undeformed 9×5×7 mesh: nodes every 5 mm. With 41 columns over 41 mm, pixel centres fall on
  // every whole millimetre from -20 to 20, so columns lie on node planes and on both side faces of
  // the mesh; with the face at z = -1.5 and 1 mm rows, rows lie on z = 0 (the skin), the node
  // planes and z = 30 (the deep face). The planes y = 0 and y = -10 hold whole mesh faces (the
  // second is the mesh's boundary). The volume is exactly the mesh's box, so boundary pixels map to
  // the volume's edge. Every such pixel is inside by the reference's tolerance and must be so here.
  const geometry::TetMesh mesh = grid_mesh({9, 5, 7});
  const auto volume = textured_volume(kMeshMin, kMeshMax);
  geometry::TetLocator locator(mesh);
  ProbeGeometry probe = linear_probe();
  probe.width_mm = 41.0;
  probe.depth_mm = 33.0;
  const BscanGrid grid(probe, 41, 33);
  Agreement published, fast;
  for (const double y_mm : {0.0, -10.0, 10.0, 2.5}) {
    for (const double turn_deg : {0.0, 90.0, 180.0}) {
      ProbePose pose;
      pose.face_center_mm = {0.0, y_mm, -1.5};
      // Turning the probe about its beam keeps the plane: a plane x = const when turned by 90°.
      pose.axes = Eigen::AngleAxisd(turn_deg * std::numbers::pi / 180, Eigen::Vector3d::UnitZ())
                      .toRotationMatrix();
      if (turn_deg == 90.0) pose.face_center_mm.x() = y_mm;
      BscanSettings settings;
      settings.background_grey = kBackground;
      for (const int m : {1, 32}) {
        PublishedSlicer b(mesh, grid, m);
        FastSlicer c(mesh, grid);
        compare_frame({volume, mesh, mesh.rest_positions_mm, locator, pose, grid, settings}, b, c,
                      published, fast);
      }
    }
  }
  published.expect_agrees("published (b), planes through nodes and faces");
  fast.expect_agrees("fast (c), planes through nodes and faces");
  EXPECT_GT(fast.inside, 0);
}

TEST(SlicerAgreement, InvertedTetsAreSkippedAsTheReferenceSkipsThem) {
  const geometry::TetMesh mesh = grid_mesh({9, 5, 7});
  const auto volume = textured_volume(kMeshMin, kMeshMax);
  std::vector<Eigen::Vector3d> deformed = mesh.rest_positions_mm;
  // Drag one inner node (x = 0, y = 0, z = 15) across its neighbours: the tets around it invert,
  // leaving a hole the reference shows as background.
  const int node = geometry::GridSpec::spanning(kMeshMin, kMeshMax, {9, 5, 7}).node_index(4, 2, 3);
  deformed[node] += Eigen::Vector3d(7.0, 0.5, 6.0);
  geometry::TetLocator locator(mesh);
  locator.rebuild(deformed);
  ASSERT_GT(locator.degenerate_tet_count(), 0);
  const BscanGrid grid(linear_probe(), 71, 63);
  Agreement published, fast;
  PublishedSlicer b(mesh, grid, 8);
  FastSlicer c(mesh, grid);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  for (int k = 0; k < 12; ++k) {
    ProbePose pose;
    pose.face_center_mm = Eigen::Vector3d(unit(rng) * 3, unit(rng) * 2, 0.0);
    pose.axes =
        Eigen::AngleAxisd(unit(rng) * 0.4, Eigen::Vector3d(unit(rng), unit(rng), 0).normalized())
            .toRotationMatrix();
    BscanSettings settings;
    settings.background_grey = kBackground;
    compare_frame({volume, mesh, deformed, locator, pose, grid, settings}, b, c, published, fast);
  }
  published.expect_agrees("published (b), inverted tets");
  fast.expect_agrees("fast (c), inverted tets");
}

TEST(SlicerAgreement, ProbeBesideTheTissueShowsOnlyBackground) {
  const geometry::TetMesh mesh = grid_mesh({9, 5, 7});
  const auto volume = textured_volume(kMeshMin, kMeshMax);
  const BscanGrid grid(convex_probe(), 40, 30);
  ProbePose pose;
  pose.face_center_mm = {0.0, 40.0, 0.0};
  BscanSettings settings;
  settings.background_grey = kBackground;
  std::vector<std::uint8_t> image(40 * 30, 0);
  FastSlicer c(mesh, grid);
  c.prepare(volume, mesh.rest_positions_mm, pose);
  c.slice(settings, image);
  for (const auto px : image) EXPECT_EQ(px, kBackground);
  EXPECT_EQ(c.cut_tet_count(), 0);
  std::ranges::fill(image, 0);
  PublishedSlicer b(mesh, grid);
  b.prepare(volume, mesh.rest_positions_mm, pose);
  b.slice(settings, image);
  for (const auto px : image) EXPECT_EQ(px, kBackground);
}

// Rows split at `split` between a second thread and this one.
template <typename Slicer>
std::vector<std::uint8_t> slice_on_two_threads(const Slicer& slicer, const BscanSettings& settings,
                                               int split) {
  std::vector<std::uint8_t> image(static_cast<std::size_t>(slicer.width_px()) * slicer.height_px(),
                                  0);
  std::thread worker([&] { slicer.slice_rows(settings, 0, split, image); });
  slicer.slice_rows(settings, split, slicer.height_px(), image);
  worker.join();
  return image;
}

TEST(SlicerKernels, FastestAndPortableSamplingGiveTheSameImage) {
  // The AVX2 span kernels against the portable ones over whole images: random poses and
  // deformations, a volume that covers only part of the mesh (clamped spans, spans ending on its
  // far corner) and one that holds all of it, both grid kinds. Bitwise, not within a grey level.
  const geometry::TetMesh mesh = grid_mesh({16, 8, 8});
  const std::array<Volume<std::uint8_t>, 2> volumes = {textured_volume({-18, -10, 0}, {20, 9, 27}),
                                                       textured_volume(kMeshMin, kMeshMax)};
  const std::array<BscanGrid, 2> grids = {BscanGrid(linear_probe(), 131, 97),
                                          BscanGrid(convex_probe(), 113, 89)};
  std::mt19937 rng(5003);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  std::array<FastSlicer, 2> fastest = {FastSlicer(mesh, grids[0]), FastSlicer(mesh, grids[1])};
  std::array<FastSlicer, 2> portable = {
      FastSlicer(mesh, grids[0], FastSlicer::Sampling::kPortable),
      FastSlicer(mesh, grids[1], FastSlicer::Sampling::kPortable)};
  long inside = 0, pixels = 0;
  for (int d = 0; d < 4; ++d) {
    const auto deformed = random_deformation(mesh, rng, d % 2 == 1);
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();
    for (const auto& p : deformed) centre += p;
    centre /= static_cast<double>(deformed.size());
    for (int k = 0; k < 20; ++k) {
      ProbePose pose;
      pose.face_center_mm = centre + Eigen::Vector3d(unit(rng) * 14, unit(rng) * 7, unit(rng) * 12);
      pose.axes = random_rotation(rng);
      BscanSettings settings;
      settings.background_grey = kBackground;
      const Volume<std::uint8_t>& volume = volumes[(k / 2) % 2];
      const BscanGrid& grid = grids[k % 2];
      const std::size_t n = static_cast<std::size_t>(grid.width_px()) * grid.height_px();
      std::vector<std::uint8_t> a(n), b(n);
      fastest[k % 2].prepare(volume, deformed, pose);
      fastest[k % 2].slice(settings, a);
      portable[k % 2].prepare(volume, deformed, pose);
      portable[k % 2].slice(settings, b);
      ASSERT_EQ(a, b) << "deformation " << d << ", pose " << k;
      inside += std::ranges::count_if(a, [](std::uint8_t g) { return g != kBackground; });
      pixels += static_cast<long>(n);
    }
  }
  EXPECT_GT(inside, pixels / 5) << "the poses should see tissue";
}

TEST(SlicerTetScan, RunsPassedOverGiveTheSameImageAsEveryTetLookedAt) {
  // Runs of tets passed over on their nodes' sides against every tet looked at: random poses and
  // deformations, planes through rows of nodes (nodes on the plane, tets that only touch it), a
  // mesh in grid order (every run listed) and the same tets shuffled (no run listed). Bitwise.
  const geometry::TetMesh ordered = grid_mesh({16, 8, 8});
  geometry::TetMesh shuffled = ordered;
  std::shuffle(shuffled.tets.begin(), shuffled.tets.end(), std::mt19937(17));
  const Volume<std::uint8_t> volume = textured_volume(kMeshMin, kMeshMax);
  const BscanGrid grid(linear_probe(), 131, 97);
  std::mt19937 rng(5011);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  long inside = 0;
  for (const geometry::TetMesh* mesh :
       {&ordered, static_cast<const geometry::TetMesh*>(&shuffled)}) {
    FastSlicer by_runs(*mesh, grid);
    FastSlicer every_tet(*mesh, grid, FastSlicer::Sampling::kFastest,
                         FastSlicer::TetScan::kEveryTet);
    const std::size_t n = static_cast<std::size_t>(grid.width_px()) * grid.height_px();
    std::vector<std::uint8_t> a(n), b(n);
    BscanSettings settings;
    settings.background_grey = kBackground;
    const auto compare = [&](const std::vector<Eigen::Vector3d>& deformed, const ProbePose& pose,
                             const char* what, int k) {
      by_runs.prepare(volume, deformed, pose);
      by_runs.slice(settings, a);
      every_tet.prepare(volume, deformed, pose);
      every_tet.slice(settings, b);
      ASSERT_EQ(by_runs.cut_tet_count(), every_tet.cut_tet_count()) << what << " " << k;
      ASSERT_EQ(a, b) << what << " " << k;
      inside += std::ranges::count_if(a, [](std::uint8_t g) { return g != kBackground; });
    };
    for (int k = 0; k < 20; ++k) {
      const auto deformed = random_deformation(*mesh, rng, k % 2 == 1);
      ProbePose pose;
      pose.face_center_mm = Eigen::Vector3d(unit(rng) * 14, unit(rng) * 7, unit(rng) * 5);
      pose.axes = random_rotation(rng);
      compare(deformed, pose, "random pose", k);
    }
    // The image plane through the rest mesh's node planes x = const and y = const (the beam
    // along z): nodes on the plane, tets on both sides touching it only there.
    const double dx = (kMeshMax.x() - kMeshMin.x()) / 15, dy = (kMeshMax.y() - kMeshMin.y()) / 7;
    for (int k = 0; k < 6; ++k) {
      ProbePose pose;
      pose.face_center_mm = Eigen::Vector3d(kMeshMin.x() + (3 + 2 * k) * dx, 0.0, 0.0);
      pose.axes = Eigen::Matrix3d::Identity();  // lateral x, elevation y: the plane y = 0
      pose.face_center_mm.y() = kMeshMin.y() + (1 + k) * dy;
      compare(mesh->rest_positions_mm, pose, "plane y on nodes", k);
      pose.axes.col(0) = Eigen::Vector3d::UnitY();  // lateral y, elevation −x: the plane x = c
      pose.axes.col(1) = -Eigen::Vector3d::UnitX();
      compare(mesh->rest_positions_mm, pose, "plane x on nodes", k);
    }
  }
  EXPECT_GT(inside, 0) << "the poses should see tissue";
}

TEST(SlicerThreads, RowsSplitOverTwoThreadsGiveTheSameImageAsOneCall) {
  const geometry::TetMesh mesh = grid_mesh({16, 8, 8});
  const auto volume = textured_volume(kMeshMin, kMeshMax);
  std::mt19937 rng(99);
  const auto deformed = random_deformation(mesh, rng, false);
  for (const BscanGrid& grid :
       {BscanGrid(linear_probe(), 128, 101), BscanGrid(convex_probe(), 96, 77)}) {
    ProbePose pose;
    pose.face_center_mm = {1.0, 0.5, -1.0};
    pose.axes = Eigen::AngleAxisd(0.2, Eigen::Vector3d(1, 1, 0).normalized()).toRotationMatrix();
    BscanSettings settings;
    settings.background_grey = kBackground;
    const std::size_t n = static_cast<std::size_t>(grid.width_px()) * grid.height_px();
    FastSlicer c(mesh, grid);
    c.prepare(volume, deformed, pose);
    PublishedSlicer b(mesh, grid, 16);
    b.prepare(volume, deformed, pose);
    std::vector<std::uint8_t> whole_c(n), whole_b(n);
    c.slice(settings, whole_c);
    b.slice(settings, whole_b);
    // Splits inside a band, on a band edge, and at the ends.
    for (const int split :
         {1, 37, 3 * FastSlicer::kBandRows, grid.height_px() / 2, grid.height_px() - 1}) {
      EXPECT_EQ(slice_on_two_threads(c, settings, split), whole_c) << "split " << split;
      EXPECT_EQ(slice_on_two_threads(b, settings, split), whole_b) << "split " << split;
    }
  }
}

TEST(SlicerThreads, PreparingInPartsOnTwoThreadsGivesTheSameImage) {
  const geometry::TetMesh mesh = grid_mesh({16, 8, 8});
  const auto volume = textured_volume({-18, -10, 0}, {20, 9, 27});
  std::mt19937 rng(5);
  const auto deformed = random_deformation(mesh, rng, true);
  const BscanGrid grid(convex_probe(), 90, 70);
  ProbePose pose;
  pose.face_center_mm = deformed[deformed.size() / 2];
  pose.axes = random_rotation(rng);
  BscanSettings settings;
  settings.background_grey = kBackground;
  FastSlicer whole(mesh, grid);
  whole.prepare(volume, deformed, pose);
  std::vector<std::uint8_t> expected(90 * 70), image(90 * 70);
  whole.slice(settings, expected);
  ASSERT_GT(whole.cut_tet_count(), 0);
  FastSlicer parts(mesh, grid);
  for (const int part_count : {1, 2, 3, 7, FastSlicer::kMaxParts}) {
    parts.begin_prepare(volume, deformed, pose, part_count);
    // Odd parts on a second thread, even parts on this one.
    std::thread classify([&] {
      for (int part = 1; part < part_count; part += 2) parts.classify_nodes(part);
    });
    for (int part = 0; part < part_count; part += 2) parts.classify_nodes(part);
    classify.join();
    std::thread worker([&] {
      for (int part = 1; part < part_count; part += 2) parts.find_cuts(part);
    });
    for (int part = 0; part < part_count; part += 2) parts.find_cuts(part);
    worker.join();
    parts.end_prepare();
    EXPECT_EQ(parts.cut_tet_count(), whole.cut_tet_count()) << part_count << " parts";
    parts.slice(settings, image);
    EXPECT_EQ(image, expected) << part_count << " parts";
  }
  EXPECT_THROW(parts.begin_prepare(volume, deformed, pose, FastSlicer::kMaxParts + 1),
               std::invalid_argument);
}

TEST(SlicerReuse, SlicersFollowANewGridAndANewVolume) {
  // One pair of slicers through a change of probe and a change of case volume (which the fast
  // slicer caches per-tet facts about), against the reference each time.
  const geometry::TetMesh mesh = grid_mesh({16, 8, 8});
  std::mt19937 rng(11);
  const auto deformed = random_deformation(mesh, rng, false);
  geometry::TetLocator locator(mesh);
  locator.rebuild(deformed);
  ProbePose pose;
  pose.face_center_mm = {2.0, 1.0, 1.0};
  pose.axes = Eigen::AngleAxisd(0.3, Eigen::Vector3d(0.2, 1, 0.1).normalized()).toRotationMatrix();
  BscanSettings settings;
  settings.background_grey = kBackground;
  const BscanGrid linear(linear_probe(), 64, 60), convex(convex_probe(), 72, 50);
  // A linear probe's scan lines are a raster of their own (parallel, evenly spaced).
  const BscanGrid lines = BscanGrid::scan_lines(linear_probe(), 48, 70);
  const auto whole_volume = textured_volume(kMeshMin, kMeshMax);
  const auto part_volume = textured_volume({-10, -5, 2}, {12, 10, 20});
  PublishedSlicer b(mesh, linear);
  FastSlicer c(mesh, linear);
  Agreement published, fast;
  for (const BscanGrid* grid : {&linear, &convex, &lines, &linear}) {
    b.set_grid(*grid);
    c.set_grid(*grid);
    for (const Volume<std::uint8_t>* volume : {&whole_volume, &part_volume, &whole_volume}) {
      compare_frame({*volume, mesh, deformed, locator, pose, *grid, settings}, b, c, published,
                    fast);
    }
  }
  published.expect_agrees("published (b), new grids and volumes");
  fast.expect_agrees("fast (c), new grids and volumes");
  // A convex probe's scan lines fan out; only the reference samples those.
  const BscanGrid fan = BscanGrid::scan_lines(convex_probe(), 48, 70);
  EXPECT_THROW(c.set_grid(fan), std::invalid_argument);
  EXPECT_THROW(b.set_grid(fan), std::invalid_argument);
  EXPECT_THROW(FastSlicer(mesh, fan), std::invalid_argument);
  EXPECT_THROW(PublishedSlicer(mesh, fan), std::invalid_argument);
  EXPECT_THROW(b.set_region_count(0), std::invalid_argument);
}

TEST(SlicerThreads, SlicingRowsTouchesOnlyThoseRows) {
  const geometry::TetMesh mesh = grid_mesh({9, 5, 7});
  const auto volume = textured_volume(kMeshMin, kMeshMax);
  const BscanGrid grid(linear_probe(), 50, 40);
  ProbePose pose;
  FastSlicer c(mesh, grid);
  c.prepare(volume, mesh.rest_positions_mm, pose);
  std::vector<std::uint8_t> image(50 * 40, 77);
  c.slice_rows(BscanSettings{}, 10, 20, image);
  for (int row = 0; row < 40; ++row) {
    if (row >= 10 && row < 20) continue;
    for (int col = 0; col < 50; ++col) EXPECT_EQ(image[row * 50 + col], 77) << col << "," << row;
  }
}

TEST(SlicerAccuracy, AnAffineDeformationOfAnAffineEchoComesOutExactly) {
  // Tissue squashed by 20 % in depth towards the deep face, sheared sideways and turned: the map
  // from deformed to rest positions is one affine map, so every pixel inside is known exactly.
  const geometry::TetMesh mesh = grid_mesh({9, 5, 7});
  const auto volume = affine_volume();
  Eigen::Matrix3d a;
  a << 1.0, 0.0, 0.1, 0.0, 1.0, 0.0, 0.0, 0.0, 0.8;
  a = Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitY()).toRotationMatrix() * a;
  const Eigen::Vector3d b(1.0, 0.0, 6.0);
  std::vector<Eigen::Vector3d> deformed;
  for (const auto& x : mesh.rest_positions_mm) deformed.push_back(a * x + b);
  const Eigen::Matrix3d a_inverse = a.inverse();
  for (const ProbeGeometry& probe : {linear_probe(), convex_probe()}) {
    const BscanGrid grid(probe, 90, 70);
    BscanSettings settings;
    settings.background_grey = kBackground;
    ProbePose pose;
    pose.face_center_mm = {0.0, 1.0, 2.0};
    pose.axes = Eigen::AngleAxisd(0.25, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    std::vector<std::uint8_t> image_b(90 * 70), image_c(90 * 70);
    PublishedSlicer slicer_b(mesh, grid);
    slicer_b.prepare(volume, deformed, pose);
    slicer_b.slice(settings, image_b);
    FastSlicer slicer_c(mesh, grid);
    slicer_c.prepare(volume, deformed, pose);
    slicer_c.slice(settings, image_c);
    int inside = 0;
    for (int r = 0; r < 70; ++r) {
      for (int c = 0; c < 90; ++c) {
        const auto plane = grid.pixel_to_plane_mm(c, r);
        const std::size_t i = static_cast<std::size_t>(r) * 90 + c;
        if (!plane) {
          EXPECT_EQ(image_c[i], kBackground);
          EXPECT_EQ(image_b[i], kBackground);
          continue;
        }
        const Eigen::Vector3d rest = a_inverse * (pose.to_patient(*plane) - b);
        // Clear of the mesh's boundary by a micrometre, so rounding cannot decide.
        const Eigen::Vector3d margin = Eigen::Vector3d::Constant(1e-3);
        const bool in_mesh = ((rest - kMeshMin).array() > margin.array()).all() &&
                             ((kMeshMax - rest).array() > margin.array()).all();
        const bool out_of_mesh = ((rest - kMeshMin).array() < -margin.array()).any() ||
                                 ((kMeshMax - rest).array() < -margin.array()).any();
        if (in_mesh) {
          const double expected = affine_echo(rest);
          EXPECT_NEAR(image_c[i], expected, 0.5 + 1e-6) << c << "," << r;
          EXPECT_NEAR(image_b[i], expected, 0.5 + 1e-6) << c << "," << r;
          ++inside;
        } else if (out_of_mesh) {
          EXPECT_EQ(image_c[i], kBackground) << c << "," << r;
          EXPECT_EQ(image_b[i], kBackground) << c << "," << r;
        }
      }
    }
    EXPECT_GT(inside, 1000);
  }
}

}  // namespace
}  // namespace ultrasim::imaging
