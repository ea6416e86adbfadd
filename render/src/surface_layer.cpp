#include "surface_layer.hpp"

#include <algorithm>
#include <cmath>

namespace ultrasim::render::detail {
namespace {

bool finite_colour(const std::array<float, 4>& rgba) {
  return std::all_of(rgba.begin(), rgba.end(), [](float v) { return std::isfinite(v); });
}

}  // namespace

SurfaceLayer::Slot::Slot()
    : positions(GL_ARRAY_BUFFER), normals(GL_ARRAY_BUFFER), indices(GL_ELEMENT_ARRAY_BUFFER) {
  glGenVertexArrays(1, &vao);
  glBindVertexArray(vao);
  positions.bind();
  glEnableVertexAttribArray(0);
  glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 3 * sizeof(float), nullptr);
  normals.bind();
  glVertexAttribPointer(1, 3, GL_FLOAT, GL_FALSE, 3 * sizeof(float), nullptr);
  // The element buffer binding is part of the VAO's state.
  indices.bind();
  glBindVertexArray(0);
}

SurfaceLayer::Slot::~Slot() {
  glDeleteVertexArrays(1, &vao);
}

SurfaceLayer::SurfaceLayer() = default;
SurfaceLayer::~SurfaceLayer() = default;

void SurfaceLayer::upload(std::span<const SurfaceView> surfaces) {
  // Slots are kept across frames (their buffers keep their storage); new ones only for a frame
  // with more surfaces than any before it.
  while (slots_.size() < surfaces.size()) slots_.push_back(std::make_unique<Slot>());
  active_count_ = surfaces.size();
  opaque_count_ = 0;
  translucent_count_ = 0;

  for (std::size_t s = 0; s < surfaces.size(); ++s) {
    const SurfaceView& surface = surfaces[s];
    Slot& slot = *slots_[s];
    slot.index_count = 0;

    const std::size_t vertex_count = surface.positions_mm.size() / 3;
    const std::size_t index_count = surface.triangles.size() / 3 * 3;
    if (vertex_count == 0 || index_count == 0) continue;
    if (!std::isfinite(surface.positions_mm[0]) || !std::isfinite(surface.positions_mm[1]) ||
        !std::isfinite(surface.positions_mm[2])) {
      continue;
    }
    if (!finite_colour(surface.rgba) || surface.rgba[3] <= 0.0f) continue;

    glBindVertexArray(slot.vao);
    if (surface.triangles.data() != slot.uploaded_indices ||
        index_count != slot.uploaded_index_count || vertex_count != slot.uploaded_vertex_count) {
      // New topology: scan it once for its largest index, then only compare with the vertex
      // count each frame (an index past the last vertex would make the GPU read outside the
      // buffer).
      const auto first = surface.triangles.begin();
      slot.max_index = *std::max_element(first, first + static_cast<std::ptrdiff_t>(index_count));
      slot.indices.upload(surface.triangles.data(), index_count * sizeof(std::uint32_t));
      slot.uploaded_indices = surface.triangles.data();
      slot.uploaded_index_count = index_count;
      slot.uploaded_vertex_count = vertex_count;
    }
    if (slot.max_index >= vertex_count) {
      glBindVertexArray(0);
      continue;
    }

    slot.positions.upload(surface.positions_mm.data(), vertex_count * 3 * sizeof(float));
    slot.flat_shading = surface.normals.size() != vertex_count * 3;
    if (slot.flat_shading) {
      glDisableVertexAttribArray(1);
    } else {
      slot.normals.upload(surface.normals.data(), vertex_count * 3 * sizeof(float));
      glEnableVertexAttribArray(1);
    }
    glBindVertexArray(0);

    for (int c = 0; c < 4; ++c) slot.rgba[c] = std::clamp(surface.rgba[c], 0.0f, 1.0f);
    slot.index_count = static_cast<GLsizei>(index_count);
    slot.skin = surface.skin;
    if (slot.rgba[3] < 1.0f) {
      ++translucent_count_;
    } else {
      ++opaque_count_;
    }
  }
}

void SurfaceLayer::use(const SurfaceProgram& program, const SceneCamera& camera) const {
  glUseProgram(program.id);
  glUniformMatrix4fv(program.u_view, 1, GL_FALSE, camera.view.data());
  glUniformMatrix4fv(program.u_projection, 1, GL_FALSE, camera.projection.data());
  // Normals of flat-shaded slots come from derivatives; the attribute's constant is unused.
  glVertexAttrib3f(1, 0.0f, 0.0f, 1.0f);
}

void SurfaceLayer::draw_slot(const SurfaceProgram& program, const Slot& slot) {
  glUniform4f(program.u_colour, slot.rgba[0], slot.rgba[1], slot.rgba[2], slot.rgba[3]);
  glUniform1i(program.u_flat_shading, slot.flat_shading ? 1 : 0);
  glBindVertexArray(slot.vao);
  glDrawElements(GL_TRIANGLES, slot.index_count, GL_UNSIGNED_INT, nullptr);
}

void SurfaceLayer::draw_opaque(const SurfaceProgram& program, const SceneCamera& camera,
                               bool show_skin) const {
  if (opaque_count_ == 0) return;
  use(program, camera);
  // Culling halves what llvmpipe rasterises; the front faces hide the back ones anyway.
  glEnable(GL_CULL_FACE);
  glCullFace(GL_BACK);
  for (std::size_t s = 0; s < active_count_; ++s) {
    const Slot& slot = *slots_[s];
    if (slot.index_count > 0 && slot.rgba[3] >= 1.0f && (show_skin || !slot.skin)) {
      draw_slot(program, slot);
    }
  }
  glBindVertexArray(0);
  glDisable(GL_CULL_FACE);
}

void SurfaceLayer::draw_translucent(const SurfaceProgram& program, const SceneCamera& camera,
                                    bool show_skin) const {
  if (translucent_count_ == 0) return;
  use(program, camera);
  glEnable(GL_CULL_FACE);
  glDepthMask(GL_FALSE);
  for (std::size_t s = 0; s < active_count_; ++s) {
    const Slot& slot = *slots_[s];
    if (slot.index_count == 0 || slot.rgba[3] >= 1.0f || (slot.skin && !show_skin)) continue;
    glCullFace(GL_FRONT);
    draw_slot(program, slot);
    glCullFace(GL_BACK);
    draw_slot(program, slot);
  }
  glBindVertexArray(0);
  glDepthMask(GL_TRUE);
  glDisable(GL_CULL_FACE);
}

}  // namespace ultrasim::render::detail
