#pragma once

#include <Eigen/Core>
#include <span>
#include <vector>

#include "ultrasim/geometry/surface_embedding.hpp"
#include "ultrasim/geometry/triangle_mesh.hpp"
#include "ultrasim/render/frame_input.hpp"
#include "ultrasim/sim/skin_surface.hpp"

namespace ultrasim::kiosk {

struct TissueCase;

// The body part's skin in the 3D view: a sim::SkinSurface over the case's tissue and around it,
// its nodes over the tissue embedded in the rest tet mesh (so they follow the tissue's
// deformation) and the rest struck by the probe; drawn translucent, so the trainee looks under
// it at the vessels.
class DeformableSkin {
 public:
  // The skin lies on the tissue's top (its smallest z). Allocates; at case load.
  DeformableSkin(const TissueCase& tissue, const sim::SkinSettings& settings = {});

  // One frame: the tissue's deformed nodes, the probe (null: none), the frame's time. Never
  // allocates.
  void step(std::span<const Eigen::Vector3d> deformed_nodes_mm, const sim::ProbeCollider* probe,
            double dt_s);

  // The skin for render::FrameInput::surfaces, valid until the next step().
  const render::SurfaceView& view() const { return view_; }
  const sim::SkinSurface& surface() const { return skin_; }

 private:
  void refresh_view();

  sim::SkinSurface skin_;
  geometry::SurfaceEmbedding embedding_;
  std::vector<Eigen::Vector3d> driven_;
  std::vector<geometry::Triangle> triangles_;
  std::vector<Eigen::Vector3d> normals_;
  std::vector<float> positions_f_, normals_f_;
  std::vector<std::uint32_t> indices_;
  render::SurfaceView view_;
};

}  // namespace ultrasim::kiosk
