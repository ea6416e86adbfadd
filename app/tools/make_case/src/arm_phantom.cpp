#include "ultrasim/tools/make_case/arm_phantom.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "ultrasim/tools/make_case/random.hpp"

namespace ultrasim::tools {

namespace {

using std::numbers::pi;

// Mean grey levels before speckle. Relative echogenicities follow what B-mode images of the arm
// show: blood anechoic, fat hypoechoic, muscle mid-grey with bright perimysium, skin and vessel
// walls bright, bone cortex brightest with a shadow below.
constexpr float kLumenGrey = 3.0f;         // blood: anechoic (a little noise)
constexpr float kFatGrey = 30.0f;          // fat lobules, hypoechoic
constexpr float kFatSeptumGrey = 130.0f;   // connective septa between lobules
constexpr float kMuscleGrey = 70.0f;       // inside fascicle bundles
constexpr float kPerimysiumGrey = 200.0f;  // bright septa between bundles ("starry night")
constexpr float kFasciaGrey = 140.0f;      // deep fascia, intermuscular septum
constexpr float kSkinGrey = 150.0f;        // dermis
constexpr float kEntryGrey = 175.0f;       // gel/epidermis interface
constexpr float kVeinWallGrey = 140.0f;
constexpr float kIntimaMediaGrey = 95.0f;    // inner layer of the artery wall, less echoic
constexpr float kAdventitiaGrey = 175.0f;    // outer layer, bright
constexpr float kEpineuriumGrey = 165.0f;    // nerve sheath and interfascicular tissue
constexpr float kNerveFascicleGrey = 22.0f;  // dark round fascicles (the honeycomb)
constexpr float kBoneDiffuseGrey = 140.0f;   // cortex, diffuse part
constexpr float kBoneSpecularGrey = 200.0f;  // cortex, mirror-like part (normal incidence)

// Gentle curvature of the vessels along the limb, so a sweep along y shows change.
constexpr double kCurveLength_mm = 40.0;

double smooth_step(double edge0, double edge1, double x) {
  const double t = std::clamp((x - edge0) / (edge1 - edge0), 0.0, 1.0);
  return t * t * (3.0 - 2.0 * t);
}

// Brightness of a thin layer of half-thickness h at distance d: 1 on it, fading over 0.1 mm.
double layer(double d, double half_thickness_mm) {
  return 1.0 - smooth_step(half_thickness_mm, half_thickness_mm + 0.1, std::abs(d));
}

// Smooth value noise in [0, 1): random values on a lattice of `cell` mm (per axis), blended with
// a smooth step. Breaks septa into dashes so they look like scattered streaks, not a net.
double value_noise(std::uint64_t seed, const Eigen::Vector3d& p, const Eigen::Vector3d& cell) {
  const Eigen::Vector3d q = p.cwiseQuotient(cell);
  const Eigen::Vector3d f = q.array().floor();
  const Eigen::Vector3d t = q - f;
  const auto fade = [](double u) { return u * u * (3.0 - 2.0 * u); };
  const double wx = fade(t.x()), wy = fade(t.y()), wz = fade(t.z());
  const auto at = [&](int dx, int dy, int dz) {
    return unit_from_bits(hash64(seed, static_cast<std::int64_t>(f.x()) + dx,
                                 static_cast<std::int64_t>(f.y()) + dy,
                                 static_cast<std::int64_t>(f.z()) + dz));
  };
  const auto lerp = [](double a, double b, double w) { return a + (b - a) * w; };
  const double x00 = lerp(at(0, 0, 0), at(1, 0, 0), wx), x10 = lerp(at(0, 1, 0), at(1, 1, 0), wx);
  const double x01 = lerp(at(0, 0, 1), at(1, 0, 1), wx), x11 = lerp(at(0, 1, 1), at(1, 1, 1), wx);
  return lerp(lerp(x00, x10, wy), lerp(x01, x11, wy), wz);
}

}  // namespace

ArmPhantom::ArmPhantom(const ArmAnatomy& anatomy) : anatomy_(anatomy) {
  // Fat lobules: wide and flat (≈5 × 2.2 mm), drifting little along the limb.
  fat_lobules_ = make_grid(anatomy.seed ^ 0xfa7, -34.0, 34.0, 0.0, 14.0, 5.0, 2.2, 0.03);
  // Muscle: fascicle bundles ≈2 mm across in a transverse section, fibres slightly oblique.
  muscle_fascicles_ = make_grid(anatomy.seed ^ 0x3c1e, -34.0, 34.0, 0.0, 50.0, 3.5, 2.4, 0.03);

  // Nerve fascicles: non-overlapping discs inside the nerve, placed by rejection sampling.
  Xoshiro256 rng(anatomy.seed ^ 0x4e7e);
  const double inner = anatomy.nerve_radius_mm - 0.3;
  for (int attempt = 0;
       attempt < 2000 && static_cast<int>(nerve_fascicles_.size()) < anatomy.nerve_fascicles;
       ++attempt) {
    const double r = 0.45 + 0.3 * rng.uniform();
    const double rho = std::sqrt(rng.uniform()) * (inner - r);
    const double phi = 2.0 * pi * rng.uniform();
    const Eigen::Vector2d c(rho * std::cos(phi), rho * std::sin(phi));
    const bool overlaps = std::any_of(
        nerve_fascicles_.begin(), nerve_fascicles_.end(),
        [&](const Fascicle& f) { return (f.offset_mm - c).norm() < f.radius_mm + r + 0.15; });
    if (!overlaps) nerve_fascicles_.push_back({c, r});
  }
}

ArmPhantom::CellGrid ArmPhantom::make_grid(std::uint64_t seed, double x0, double x1, double z0,
                                           double z1, double cell_x, double cell_z, double drift) {
  CellGrid grid;
  grid.cell_x_mm = cell_x;
  grid.cell_z_mm = cell_z;
  grid.x0_mm = x0;
  grid.z0_mm = z0;
  grid.nx = static_cast<int>(std::ceil((x1 - x0) / cell_x)) + 1;
  grid.nz = static_cast<int>(std::ceil((z1 - z0) / cell_z)) + 1;
  grid.cells.reserve(static_cast<std::size_t>(grid.nx * grid.nz));
  for (int cz = 0; cz < grid.nz; ++cz) {
    for (int cx = 0; cx < grid.nx; ++cx) {
      const auto u = [&](int which) { return unit_from_bits(hash64(seed, cx, cz, which)); };
      Cell cell;
      // Jitter within the middle 80 % of the cell keeps the 3×3 neighbour search exact enough.
      cell.site_mm = {x0 + (cx + 0.1 + 0.8 * u(0)) * cell_x, z0 + (cz + 0.1 + 0.8 * u(1)) * cell_z};
      cell.drift_per_mm = {drift * (2.0 * u(2) - 1.0), 0.5 * drift * (2.0 * u(3) - 1.0)};
      cell.brightness = static_cast<float>(0.85 + 0.3 * u(4));
      grid.cells.push_back(cell);
    }
  }
  return grid;
}

ArmPhantom::CellHit ArmPhantom::nearest_cells(const CellGrid& grid, double x, double y,
                                              double z) const {
  const int cx = static_cast<int>(std::floor((x - grid.x0_mm) / grid.cell_x_mm));
  const int cz = static_cast<int>(std::floor((z - grid.z0_mm) / grid.cell_z_mm));
  // Distances in cell units, so elongated cells behave like round ones.
  const double sx = 1.0 / grid.cell_x_mm, sz = 1.0 / grid.cell_z_mm;
  double best = 1e300, second = 1e300;
  int best_i = 0, second_i = 0;
  Eigen::Vector2d best_p = Eigen::Vector2d::Zero(), second_p = Eigen::Vector2d::Zero();
  for (int dz = -1; dz <= 1; ++dz) {
    for (int dx = -1; dx <= 1; ++dx) {
      const int gx = std::clamp(cx + dx, 0, grid.nx - 1);
      const int gz = std::clamp(cz + dz, 0, grid.nz - 1);
      const int index = gz * grid.nx + gx;
      if (index == best_i && best < 1e300) continue;
      if (index == second_i && second < 1e300) continue;
      const Cell& cell = grid.cells[static_cast<std::size_t>(index)];
      const Eigen::Vector2d site = cell.site_mm + cell.drift_per_mm * y;
      const Eigen::Vector2d q((x - site.x()) * sx, (z - site.y()) * sz);
      const double d2 = q.squaredNorm();
      if (d2 < best) {
        second = best, second_i = best_i, second_p = best_p;
        best = d2, best_i = index, best_p = Eigen::Vector2d(site.x() * sx, site.y() * sz);
      } else if (d2 < second) {
        second = d2, second_i = index, second_p = Eigen::Vector2d(site.x() * sx, site.y() * sz);
      }
    }
  }
  // Distance (in mm, taking the shorter cell side) from the point to the bisector of the two sites.
  const double gap = std::max((second_p - best_p).norm(), 1e-9);
  const double edge_cells = (second - best) / (2.0 * gap);
  // The bisector's normal back in mm: the scaled-space normal n maps to (n.x·sx, n.z·sz).
  const Eigen::Vector2d n_scaled = (second_p - best_p) / gap;
  const Eigen::Vector2d n_mm = Eigen::Vector2d(n_scaled.x() * sx, n_scaled.y() * sz).normalized();
  return {edge_cells * std::min(grid.cell_x_mm, grid.cell_z_mm), best_i, second_i,
          n_mm.y() * n_mm.y()};
}

// How bright the septum between cells a and b is: some strong, some faint, some absent, so the
// network looks like scattered bright streaks rather than a regular net.
float ArmPhantom::edge_strength(std::uint64_t salt, int a, int b) const {
  const double u = unit_from_bits(hash64(anatomy_.seed ^ salt, std::min(a, b), std::max(a, b)));
  if (u < 0.35) return 1.0f;
  if (u < 0.65) return 0.4f;
  return 0.0f;
}

Eigen::Vector2d ArmPhantom::vein_centre_mm(double y) const {
  // Drifts away from the artery and rises a little along the limb.
  return {anatomy_.vein_x_mm - 1.0 * std::sin(pi * y / kCurveLength_mm),
          anatomy_.vein_z_mm + 0.6 * std::sin(pi * y / 25.0)};
}

Eigen::Vector2d ArmPhantom::vein_semi_axes_mm(double y) const {
  const double s = 1.0 + 0.06 * std::sin(pi * y / 30.0);
  return {anatomy_.vein_semi_x_mm * s, anatomy_.vein_semi_z_mm * (2.0 - s)};
}

Eigen::Vector2d ArmPhantom::artery_centre_mm(double y) const {
  const double t = y / 20.0;
  return {anatomy_.artery_x_mm + 0.8 * std::sin(pi * y / kCurveLength_mm),
          anatomy_.artery_z_mm + 0.4 * t * t};
}

Eigen::Vector2d ArmPhantom::nerve_centre_mm(double y) const {
  return {anatomy_.nerve_x_mm + 0.03 * y, anatomy_.nerve_z_mm - 0.015 * y};
}

Eigen::Vector2d ArmPhantom::bone_centre_mm() const {
  return {anatomy_.bone_x_mm, anatomy_.bone_top_z_mm + anatomy_.bone_radius_mm};
}

double ArmPhantom::fat_bottom_mm(double x, double y) const {
  return anatomy_.fat_bottom_mm + anatomy_.fat_bottom_wave_mm * (0.7 * std::sin(x / 7.0 + 0.3) +
                                                                 0.3 * std::sin(y / 9.0 + 1.1));
}

std::uint8_t ArmPhantom::label_at(const Eigen::Vector3d& p) const {
  return echo_at(p).label;
}

EchoSample ArmPhantom::echo_at(const Eigen::Vector3d& p) const {
  if (p.z() < 0.0) return {kOutside, 0.0f, 0.0f, false};
  if (p.z() < anatomy_.skin_thickness_mm) return skin_echo(p);
  if (p.z() < fat_bottom_mm(p.x(), p.y())) return fat_echo(p);
  EchoSample s;
  // Structures inside the muscle; the bone wins over everything, then the vessels.
  if (bone_echo(p, s) || artery_echo(p, s) || vein_echo(p, s) || nerve_echo(p, s)) return s;
  return muscle_echo(p);
}

EchoSample ArmPhantom::skin_echo(const Eigen::Vector3d& p) const {
  EchoSample s{kSkin, kSkinGrey, 0.0f, false};
  // The gel/epidermis interface gives a thin bright entry echo; the deep dermis is a bit darker.
  if (p.z() < 0.35) {
    s.diffuse = kEntryGrey;
    s.specular = 70.0f;
  } else {
    s.diffuse = static_cast<float>(kSkinGrey - 25.0 * (p.z() - 0.35) / anatomy_.skin_thickness_mm);
  }
  return s;
}

EchoSample ArmPhantom::fat_echo(const Eigen::Vector3d& p) const {
  EchoSample s{kFat, kFatGrey, 0.0f, false};
  const CellHit hit = nearest_cells(fat_lobules_, p.x(), p.y(), p.z());
  const float lobule = fat_lobules_.cells[static_cast<std::size_t>(hit.nearest)].brightness;
  const double dashes =
      smooth_step(0.35, 0.6, value_noise(anatomy_.seed ^ 0xda5f, p, {2.0, 8.0, 1.2}));
  const double septum = layer(hit.edge_distance, 0.12) *
                        edge_strength(0xfa75, hit.nearest, hit.second) * dashes *
                        (0.3 + 0.7 * hit.edge_facing);
  s.diffuse = static_cast<float>(kFatGrey * lobule + (kFatSeptumGrey - kFatGrey) * septum);
  // The deep fascia under the fat: a bright line on the boundary (half in fat, half in muscle).
  const double to_fascia = p.z() - fat_bottom_mm(p.x(), p.y());
  const double fascia = layer(to_fascia, 0.25);
  s.diffuse = static_cast<float>(std::max<double>(s.diffuse, kFasciaGrey * fascia));
  s.specular = static_cast<float>(55.0 * fascia);
  return s;
}

EchoSample ArmPhantom::muscle_echo(const Eigen::Vector3d& p) const {
  EchoSample s{kMuscle, kMuscleGrey, 0.0f, false};
  const CellHit hit = nearest_cells(muscle_fascicles_, p.x(), p.y(), p.z());
  const float bundle = muscle_fascicles_.cells[static_cast<std::size_t>(hit.nearest)].brightness;
  // Perimysium: bright where a septum runs and the dash noise lets it show, brightest where it
  // lies across the beam (specular-like; septa along the beam return little).
  const double dashes =
      smooth_step(0.5, 0.75, value_noise(anatomy_.seed ^ 0xda5e, p, {1.6, 6.0, 1.2}));
  const double septum = layer(hit.edge_distance, 0.12) *
                        edge_strength(0x3c15, hit.nearest, hit.second) * dashes *
                        (0.2 + 0.8 * hit.edge_facing);
  double grey = kMuscleGrey * bundle + (kPerimysiumGrey - kMuscleGrey) * septum;
  double specular = 0.0;
  // Deep fascia continued from the fat side, and an intermuscular septum separating the
  // superficial (biceps-like) from the deep (brachialis-like) muscle.
  const double deep_fascia = layer(p.z() - fat_bottom_mm(p.x(), p.y()), 0.25);
  const double septum_z = 27.5 + 3.0 * std::sin((p.x() + 5.0) / 14.0) + 0.05 * p.y();
  const double intermuscular = layer(p.z() - septum_z, 0.2);
  const double fascia = std::max(deep_fascia, intermuscular);
  grey = std::max(grey, kFasciaGrey * fascia);
  specular = 55.0 * fascia;
  s.diffuse = static_cast<float>(grey);
  s.specular = static_cast<float>(specular);
  return s;
}

bool ArmPhantom::vein_echo(const Eigen::Vector3d& p, EchoSample& out) const {
  const Eigen::Vector2d c = vein_centre_mm(p.y());
  const Eigen::Vector2d ab = vein_semi_axes_mm(p.y());
  const double dx = p.x() - c.x(), dz = p.z() - c.y();
  const double rho = std::hypot(dx / ab.x(), dz / ab.y());
  if (rho >= 1.0) return false;
  // First-order distance to the ellipse: (ρ − 1)/|∇ρ|; good enough for a 0.4 mm wall.
  const Eigen::Vector2d grad(dx / (ab.x() * ab.x()), dz / (ab.y() * ab.y()));
  const double grad_norm = rho > 1e-9 ? grad.norm() / rho : 1.0 / ab.minCoeff();
  const double depth_in = (1.0 - rho) / grad_norm;
  out = {kVein, kLumenGrey, 0.0f, true};
  if (depth_in < anatomy_.vein_wall_mm) {
    // The wall reflects most where the beam meets it square (top and bottom).
    const double nz = std::abs(grad.y()) / std::max(grad.norm(), 1e-12);
    out.diffuse = kVeinWallGrey;
    out.specular = static_cast<float>(80.0 * nz * nz);
    out.fluid = false;
  }
  return true;
}

bool ArmPhantom::artery_echo(const Eigen::Vector3d& p, EchoSample& out) const {
  const Eigen::Vector2d c = artery_centre_mm(p.y());
  const double dx = p.x() - c.x(), dz = p.z() - c.y();
  const double r = std::hypot(dx, dz);
  const double lumen = anatomy_.artery_lumen_radius_mm;
  if (r >= lumen + anatomy_.artery_wall_mm) return false;
  out = {kArtery, kLumenGrey, 0.0f, true};
  if (r >= lumen) {
    const double nz = r > 1e-9 ? std::abs(dz) / r : 0.0;
    out.diffuse = r < lumen + 0.35 ? kIntimaMediaGrey : kAdventitiaGrey;
    out.specular = static_cast<float>(35.0 * nz * nz);
    out.fluid = false;
  }
  return true;
}

bool ArmPhantom::nerve_echo(const Eigen::Vector3d& p, EchoSample& out) const {
  const Eigen::Vector2d c = nerve_centre_mm(p.y());
  const Eigen::Vector2d d(p.x() - c.x(), p.z() - c.y());
  if (d.norm() >= anatomy_.nerve_radius_mm) return false;
  out = {kNerve, kEpineuriumGrey, 0.0f, false};
  // Fascicles twist slowly along the nerve.
  const double twist = 0.012 * p.y();
  const Eigen::Vector2d q(std::cos(twist) * d.x() + std::sin(twist) * d.y(),
                          -std::sin(twist) * d.x() + std::cos(twist) * d.y());
  for (const Fascicle& f : nerve_fascicles_) {
    const double to_edge = (q - f.offset_mm).norm() - f.radius_mm;
    if (to_edge < 0.0) {
      // Dark inside, blending into the sheath over the last 0.12 mm.
      out.diffuse = static_cast<float>(kNerveFascicleGrey + (kEpineuriumGrey - kNerveFascicleGrey) *
                                                                smooth_step(-0.12, 0.0, to_edge));
      break;
    }
  }
  // The epineurium's outer surface is a bright ring.
  const double ring = layer(d.norm() - (anatomy_.nerve_radius_mm - 0.15), 0.15);
  out.specular = static_cast<float>(40.0 * ring);
  return true;
}

bool ArmPhantom::bone_echo(const Eigen::Vector3d& p, EchoSample& out) const {
  const Eigen::Vector2d c = bone_centre_mm();
  const Eigen::Vector2d d(p.x() - c.x(), p.z() - c.y());
  const double r = d.norm();
  if (r >= anatomy_.bone_radius_mm) return false;
  // Specular reflection falls off as the surface tilts away from the beam (normal · z).
  const double nz = r > 1e-9 ? -d.y() / r : 1.0;
  const double facing = std::max(nz, 0.0);
  const double strength = 0.2 + 0.8 * facing * facing;
  out = {kBone, static_cast<float>(kBoneDiffuseGrey * strength),
         static_cast<float>(kBoneSpecularGrey * strength), false};
  return true;
}

}  // namespace ultrasim::tools
