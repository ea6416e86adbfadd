#pragma once

// The anatomy of the default case: a synthetic upper arm in patient space (mm; +x lateral, +y
// along the limb, +z depth, skin at z = 0; docs/case-format.md), shaped like the published
// upper-arm/neck cases: skin, subcutaneous fat, muscle, a compressible vein beside a round
// thick-walled artery, a nerve, and the humerus deep below. Analytic, so labels are exact at any
// resolution; the echo model gives each point its mean brightness before speckle.

#include <Eigen/Core>
#include <cstdint>
#include <vector>

namespace ultrasim::tools {

// Tissue labels (docs/case-format.md).
enum Label : std::uint8_t {
  kOutside = 0,
  kSkin = 1,
  kFat = 2,
  kMuscle = 3,
  kVein = 4,    // lumen and wall
  kArtery = 5,  // lumen and wall
  kNerve = 6,
  kBone = 7,
};

// Geometry at y = 0 (vessels and nerve curve gently along y; see ArmPhantom). Millimetres.
struct ArmAnatomy {
  double skin_thickness_mm = 2.0;   // epidermis + dermis of the upper arm: 1.5–2.5 mm
  double fat_bottom_mm = 8.0;       // mean depth of the deep fascia under the fat
  double fat_bottom_wave_mm = 0.8;  // undulation of that boundary
  double vein_x_mm = -8.0;  // centre of the ovoid vein (basilic-like, just under the fascia)
  double vein_z_mm = 11.0;
  double vein_semi_x_mm = 4.0;  // lateral semi-axis (veins are wide and flat; basilic 4-8 mm)
  double vein_semi_z_mm = 2.2;  // depth semi-axis
  double vein_wall_mm = 0.4;    // thin wall
  double artery_x_mm = 6.0;     // centre of the round artery (brachial-like)
  double artery_z_mm = 19.0;
  double artery_lumen_radius_mm = 3.5;
  double artery_wall_mm = 1.2;  // thick, bright wall (intima-media + adventitia)
  double nerve_x_mm = 15.0;     // median-nerve-like honeycomb
  double nerve_z_mm = 13.0;
  double nerve_radius_mm = 2.5;
  int nerve_fascicles = 7;      // dark fascicles inside the bright epineurium
  double bone_x_mm = 1.0;       // humerus: a circle in x–z, extruded along y
  double bone_top_z_mm = 34.0;  // depth of its top surface
  double bone_radius_mm = 12.0;
  double bone_echo_mm = 1.0;        // depth of the bright cortical echo; below it, shadow
  std::uint64_t seed = 0x5eed2013;  // fixes the textures (lobules, fascicles)
};

// Mean echo of one point before speckle, in grey levels (0–255 after speckle).
struct EchoSample {
  std::uint8_t label = kOutside;
  float diffuse = 0.0f;   // incoherent scattering: becomes Rayleigh speckle of this mean
  float specular = 0.0f;  // coherent reflection from smooth interfaces: added after speckle
  bool fluid = false;     // blood in a lumen: attenuates little, so tissue below is brighter
};

// Immutable after construction; label_at/echo_at are pure, never allocate, and may be called
// from many threads at once.
class ArmPhantom {
 public:
  explicit ArmPhantom(const ArmAnatomy& anatomy = {});

  const ArmAnatomy& anatomy() const { return anatomy_; }

  // Centres (x, z) in mm of the vein, artery and nerve at position y along the limb.
  Eigen::Vector2d vein_centre_mm(double y_mm) const;
  Eigen::Vector2d vein_semi_axes_mm(double y_mm) const;
  Eigen::Vector2d artery_centre_mm(double y_mm) const;
  Eigen::Vector2d nerve_centre_mm(double y_mm) const;
  Eigen::Vector2d bone_centre_mm() const;  // same for every y
  // Depth of the fat/muscle boundary under (x, y).
  double fat_bottom_mm(double x_mm, double y_mm) const;

  // Tissue label at a point (mm). Points above the skin (z < 0) are kOutside.
  std::uint8_t label_at(const Eigen::Vector3d& p_mm) const;

  // Label plus mean echo at a point. Bone gets its surface echo throughout: the shadow beneath
  // the surface depends on the beam, so the case builder applies it along each beam line.
  EchoSample echo_at(const Eigen::Vector3d& p_mm) const;

 private:
  // A texture cell: Voronoi site (x, z) at y = 0, its drift per mm of y, and its brightness
  // factor. Fibres and lobules run roughly along the limb, so sites move slowly with y.
  struct Cell {
    Eigen::Vector2d site_mm;
    Eigen::Vector2d drift_per_mm;
    float brightness = 1.0f;
  };
  struct CellGrid {
    double cell_x_mm = 1.0, cell_z_mm = 1.0, x0_mm = 0.0, z0_mm = 0.0;
    int nx = 0, nz = 0;
    std::vector<Cell> cells;
  };
  struct Fascicle {
    Eigen::Vector2d offset_mm;  // from the nerve centre
    double radius_mm = 0.5;
  };
  // Nearest and second-nearest cell of `grid` to (x, z) at y, in a metric that stretches x by
  // 1/x_scale; returns the distance from the point to their bisector and both cell indices.
  struct CellHit {
    double edge_distance = 0.0;
    int nearest = 0;
    int second = 0;
    double edge_facing = 1.0;  // squared z part of the septum's unit normal: 1 flat, 0 vertical
  };

  static CellGrid make_grid(std::uint64_t seed, double x0, double x1, double z0, double z1,
                            double cell_x, double cell_z, double drift);
  CellHit nearest_cells(const CellGrid& grid, double x, double y, double z) const;
  float edge_strength(std::uint64_t salt, int a, int b) const;

  EchoSample skin_echo(const Eigen::Vector3d& p) const;
  EchoSample fat_echo(const Eigen::Vector3d& p) const;
  EchoSample muscle_echo(const Eigen::Vector3d& p) const;
  bool vein_echo(const Eigen::Vector3d& p, EchoSample& out) const;
  bool artery_echo(const Eigen::Vector3d& p, EchoSample& out) const;
  bool nerve_echo(const Eigen::Vector3d& p, EchoSample& out) const;
  bool bone_echo(const Eigen::Vector3d& p, EchoSample& out) const;

  ArmAnatomy anatomy_;
  CellGrid fat_lobules_;
  CellGrid muscle_fascicles_;
  std::vector<Fascicle> nerve_fascicles_;
};

}  // namespace ultrasim::tools
