#include "ultrasim/render/trainer_ui.hpp"

#include <imgui.h>
#include <imgui_impl_opengl3.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include "pointer_queue.hpp"
#include "theme.hpp"

namespace ultrasim::render {
namespace {

namespace theme = detail::theme;

ImVec4 colour(detail::Rgba8 c, float alpha = 1.0f) {
  return {c.r / 255.0f, c.g / 255.0f, c.b / 255.0f, alpha};
}

// The kiosk's colours on ImGui's widgets: dark panels, the accent for what is active.
void apply_theme(ImGuiStyle& style, float scale) {
  style.WindowRounding = 0.0f;
  style.FrameRounding = 0.0f;
  style.GrabRounding = 0.0f;
  style.WindowBorderSize = 1.0f;
  style.FrameBorderSize = 1.0f;
  style.ScaleAllSizes(scale);
  // Fingers are less precise than a mouse: hits count a little beyond each widget.
  style.TouchExtraPadding = ImVec2(2.0f * scale, 2.0f * scale);
  ImVec4* c = style.Colors;
  c[ImGuiCol_Text] = colour(theme::kTextPrimary);
  c[ImGuiCol_TextDisabled] = colour(theme::kTextSecondary);
  c[ImGuiCol_WindowBg] = colour(theme::kHeader);
  c[ImGuiCol_PopupBg] = colour(theme::kHeader, 0.98f);
  c[ImGuiCol_Border] = colour(theme::kPanelBorder);
  c[ImGuiCol_FrameBg] = colour(theme::kPanel3d);
  c[ImGuiCol_FrameBgHovered] = colour(theme::kPanelBorder);
  c[ImGuiCol_FrameBgActive] = colour(theme::kPanelBorder);
  c[ImGuiCol_TitleBg] = colour(theme::kHeader);
  c[ImGuiCol_TitleBgActive] = colour(theme::kPanel3d);
  c[ImGuiCol_Button] = colour(theme::kPanel3d);
  c[ImGuiCol_ButtonHovered] = colour(theme::kPanelBorder);
  c[ImGuiCol_ButtonActive] = colour(theme::kAccent, 0.6f);
  c[ImGuiCol_Header] = colour(theme::kPanelBorder);
  c[ImGuiCol_HeaderHovered] = colour(theme::kPanelBorder);
  c[ImGuiCol_HeaderActive] = colour(theme::kAccent, 0.6f);
  c[ImGuiCol_SliderGrab] = colour(theme::kAccent);
  c[ImGuiCol_SliderGrabActive] = colour(theme::kAccent);
  c[ImGuiCol_Tab] = colour(theme::kPanel3d);
  c[ImGuiCol_TabHovered] = colour(theme::kPanelBorder);
  c[ImGuiCol_TabActive] = colour(theme::kAccent, 0.5f);
  c[ImGuiCol_Separator] = colour(theme::kPanelBorder);
}

// A fixed strip of the screen that holds controls and draws no background of its own.
constexpr ImGuiWindowFlags kStripFlags =
    ImGuiWindowFlags_NoDecoration | ImGuiWindowFlags_NoMove | ImGuiWindowFlags_NoSavedSettings |
    ImGuiWindowFlags_NoBackground | ImGuiWindowFlags_NoBringToFrontOnFocus |
    ImGuiWindowFlags_NoFocusOnAppearing;
constexpr ImGuiWindowFlags kDialogFlags = ImGuiWindowFlags_NoCollapse |
                                          ImGuiWindowFlags_NoSavedSettings |
                                          ImGuiWindowFlags_NoResize | ImGuiWindowFlags_NoMove;

// The name a script knows a widget by: its label's ID part ("-##GAIN -" is "GAIN -").
std::string_view widget_key(std::string_view label) {
  const std::size_t hashes = label.find("##");
  return hashes == std::string_view::npos ? label : label.substr(hashes + 2);
}

std::string upper(std::string_view text) {
  std::string out(text);
  for (char& ch : out) ch = static_cast<char>(std::toupper(static_cast<unsigned char>(ch)));
  return out;
}

}  // namespace

float Calipers::distance_mm() const {
  if (points < 2) return 0.0f;
  return std::hypot(mm[1][0] - mm[0][0], mm[1][1] - mm[0][1]);
}

struct TrainerUi::Impl {
  struct WidgetRecord {
    std::string key;
    PixelRect rect;
  };

  explicit Impl(Display& d) : display(d) {
    IMGUI_CHECKVERSION();
    context = ImGui::CreateContext();
    ImGui::SetCurrentContext(context);
    ImGuiIO& io = ImGui::GetIO();
    io.IniFilename = nullptr;  // a kiosk keeps no window state between runs
    io.LogFilename = nullptr;
    // The same whole-pixel scale as the screen's layout (render::layout_screen).
    scale = static_cast<float>(std::max(1, (display.height_px() + 180) / 360));
    ImFontConfig font;
    font.SizePixels = 13.0f * scale;  // ProggyClean, drawn at a whole multiple of its pixels
    io.Fonts->AddFontDefault(&font);
    apply_theme(ImGui::GetStyle(), scale);
    ImGui_ImplOpenGL3_Init("#version 300 es");
  }
  ~Impl() {
    ImGui::SetCurrentContext(context);
    ImGui_ImplOpenGL3_Shutdown();
    ImGui::DestroyContext(context);
  }
  Impl(const Impl&) = delete;
  Impl& operator=(const Impl&) = delete;

  // Notes where the last item was, under `label`'s key, for widget_rect().
  void record(std::string_view label) {
    record(label, ImGui::GetItemRectMin(), ImGui::GetItemRectMax());
  }
  void record(std::string_view label, ImVec2 lo, ImVec2 hi) {
    const PixelRect rect{static_cast<int>(lo.x), static_cast<int>(lo.y),
                         static_cast<int>(hi.x - lo.x), static_cast<int>(hi.y - lo.y)};
    const std::string_view key = widget_key(label);
    if (recorded < widgets.size()) {
      widgets[recorded].key.assign(key);
      widgets[recorded].rect = rect;
    } else {
      widgets.push_back({std::string(key), rect});
    }
    ++recorded;
  }
  bool button(const char* label, bool highlighted = false) {
    if (highlighted) ImGui::PushStyleColor(ImGuiCol_Button, colour(theme::kAccent, 0.45f));
    const bool pressed = ImGui::Button(label);
    if (highlighted) ImGui::PopStyleColor();
    record(label);
    return pressed;
  }

  Display& display;
  ImGuiContext* context = nullptr;
  float scale = 1.0f;
  detail::PointerQueue pointer;
  std::vector<WidgetRecord> widgets;
  std::size_t recorded = 0;  // this frame's records, from the front of `widgets`
  bool pointer_over_controls = false;
  bool tgc_open = false;
  bool settings_open = false;
  bool service_open = false;
  bool caliper_mode = false;
  bool orbiting = false;  // the press started on the 3D view, not on a control
  float last_x = 0.0f, last_y = 0.0f;
  std::vector<double> edits;  // the settings dialog's values, while it is open
  std::string settings_error;
  std::vector<double> applied;  // what the last Apply handed over
};

TrainerUi::TrainerUi(Display& display) : impl_(std::make_unique<Impl>(display)) {}

TrainerUi::~TrainerUi() = default;

void TrainerUi::settings_refused(std::string_view message) {
  impl_->settings_error.assign(message);
}

void TrainerUi::settings_accepted() {
  impl_->settings_error.clear();
  impl_->settings_open = false;
}

std::optional<PixelRect> TrainerUi::widget_rect(std::string_view label) const {
  const std::string_view key = widget_key(label);
  for (std::size_t i = 0; i < impl_->recorded; ++i) {
    if (impl_->widgets[i].key == key) return impl_->widgets[i].rect;
  }
  return std::nullopt;
}

bool TrainerUi::pointer_over_controls() const {
  return impl_->pointer_over_controls;
}

TrainerActions TrainerUi::frame(const FrameInput& input, const ScreenLayout& layout,
                                const TrainerModel& model,
                                std::span<const hal::PointerEvent> events, float frame_seconds) {
  Impl& im = *impl_;
  ImGui::SetCurrentContext(im.context);
  ImGuiIO& io = ImGui::GetIO();
  io.DisplaySize =
      ImVec2(static_cast<float>(im.display.width_px()), static_cast<float>(im.display.height_px()));
  io.DeltaTime = std::isfinite(frame_seconds) && frame_seconds > 0.0f ? frame_seconds : 1.0f / 60;
  const detail::PointerState pointer = im.pointer.advance(events);
  const bool was_down = io.MouseDown[0];
  io.MousePos = ImVec2(pointer.x_px, pointer.y_px);
  io.MouseDown[0] = pointer.down;
  io.MouseWheel = pointer.wheel_notches;

  ImGui_ImplOpenGL3_NewFrame();
  ImGui::NewFrame();
  im.recorded = 0;
  im.pointer_over_controls = io.WantCaptureMouse;
  const float s = im.scale;
  TrainerActions actions;

  // Header: the case list, the method, the dialogs.
  {
    const PixelRect& h = layout.header_controls;
    ImGui::SetNextWindowPos(ImVec2(static_cast<float>(h.x_px), static_cast<float>(h.y_px)));
    ImGui::SetNextWindowSize(
        ImVec2(static_cast<float>(h.width_px), static_cast<float>(h.height_px)));
    ImGui::PushStyleVar(ImGuiStyleVar_WindowPadding, ImVec2(0.0f, 1.0f * s));
    ImGui::PushStyleVar(ImGuiStyleVar_FramePadding, ImVec2(4.0f * s, 1.0f * s));
    ImGui::Begin("##header", nullptr, kStripFlags);
    const auto list = [&](const char* label, std::span<const std::string_view> names, int current,
                          float combo_w) {
      int picked = TrainerActions::kNoChange;
      const std::string preview = current >= 0 && static_cast<std::size_t>(current) < names.size()
                                      ? upper(names[static_cast<std::size_t>(current)])
                                      : std::string("-");
      // Where the list's box goes: once open, ImGui's "last item" is inside the popup.
      const ImVec2 box = ImGui::GetCursorScreenPos();
      ImGui::SetNextItemWidth(combo_w);
      const bool open = ImGui::BeginCombo(label, preview.c_str());
      im.record(label, box, ImVec2(box.x + combo_w, box.y + ImGui::GetFrameHeight()));
      if (open) {
        for (std::size_t i = 0; i < names.size(); ++i) {
          const std::string name = upper(names[i]);
          if (ImGui::Selectable(name.c_str(), static_cast<int>(i) == current)) {
            picked = static_cast<int>(i);
          }
          im.record(name);
        }
        ImGui::EndCombo();
      }
      return picked;
    };
    actions.case_index = list("##CASE", model.case_names, model.case_index, 130.0f * s);
    ImGui::SameLine();
    actions.method_index = list("##METHOD", model.method_names, model.method_index, 100.0f * s);
    ImGui::SameLine();
    if (im.button("SETTINGS", im.settings_open)) {
      im.settings_open = !im.settings_open;
      im.edits.clear();
      for (const auto& f : model.settings) im.edits.push_back(f.value);
      im.settings_error.clear();
    }
    ImGui::SameLine();
    if (im.button("SERVICE", im.service_open)) im.service_open = !im.service_open;
    ImGui::End();
    ImGui::PopStyleVar(2);
  }

  // The scanner's controls, along the foot of the B-scan panel.
  {
    const PixelRect& c = layout.controls;
    ImGui::SetNextWindowPos(ImVec2(static_cast<float>(c.x_px), static_cast<float>(c.y_px)));
    ImGui::SetNextWindowSize(
        ImVec2(static_cast<float>(c.width_px), static_cast<float>(c.height_px)));
    ImGui::Begin("##controls", nullptr, kStripFlags);
    if (im.button("FREEZE", model.frozen)) actions.toggle_freeze = true;
    ImGui::SameLine();
    if (im.button("SAVE")) actions.save = true;
    ImGui::SameLine();
    if (im.button("CALIPER", im.caliper_mode)) {
      im.caliper_mode = !im.caliper_mode;
      calipers_ = {};
    }
    ImGui::SameLine();
    if (im.button("TGC", im.tgc_open)) im.tgc_open = !im.tgc_open;

    const auto stepper = [&](const char* name, const char* minus, const char* plus) {
      ImGui::AlignTextToFramePadding();
      ImGui::TextUnformatted(name);
      ImGui::SameLine();
      const bool down = im.button(minus);
      ImGui::SameLine();
      const bool up = im.button(plus);
      return up ? 1 : down ? -1 : 0;
    };
    if (const int step = stepper("GAIN", "-##GAIN -", "+##GAIN +"); step != 0) {
      actions.gain_db = model.gain_db + 3.0f * static_cast<float>(step);
    }
    ImGui::SameLine(0.0f, 10.0f * s);
    if (const int step = stepper("DEPTH", "-##DEPTH -", "+##DEPTH +"); step != 0) {
      actions.depth_mm = model.depth_mm + 10.0f * static_cast<float>(step);
    }
    ImGui::SameLine(0.0f, 10.0f * s);
    actions.compression_steps = stepper("PRESS", "-##PRESS -", "+##PRESS +");
    ImGui::SameLine();
    ImGui::Text("%.0f MM", static_cast<double>(model.compression_mm));
    ImGui::End();
  }

  // The 3D view's tools, bottom right of its panel.
  {
    const PixelRect& v = layout.view_3d;
    // Right of the displacement legend (bottom left).
    const float width = std::min(264.0f * s, static_cast<float>(v.width_px) - 90.0f * s);
    const float height = 24.0f * s;
    ImGui::SetNextWindowPos(ImVec2(static_cast<float>(v.x_px + v.width_px) - width,
                                   static_cast<float>(v.y_px + v.height_px) - height));
    ImGui::SetNextWindowSize(ImVec2(width, height));
    ImGui::Begin("##view", nullptr, kStripFlags);
    if (im.button("MESH", view_.show_mesh)) view_.show_mesh = !view_.show_mesh;
    ImGui::SameLine();
    if (im.button("SKIN", view_.show_skin)) view_.show_skin = !view_.show_skin;
    ImGui::SameLine();
    ImGui::AlignTextToFramePadding();
    ImGui::TextUnformatted("ZOOM");
    ImGui::SameLine();
    if (im.button("-##ZOOM -")) view_.zoom = std::max(view_.zoom / 1.25f, 0.5f);
    ImGui::SameLine();
    if (im.button("+##ZOOM +")) view_.zoom = std::min(view_.zoom * 1.25f, 4.0f);
    ImGui::SameLine();
    if (im.button("RESET VIEW")) view_ = ViewOptions{};
    ImGui::End();
  }

  // Dialogs: over the screen's middle, one at a time in front.
  const ImVec2 centre(0.5f * io.DisplaySize.x, 0.5f * io.DisplaySize.y);
  if (im.tgc_open) {
    const PixelRect& image = layout.bscan_image;
    // A fixed size: an auto-sized window is hidden its first frame while it measures itself.
    const float tgc_w = std::min(static_cast<float>(model.tgc_db.size()) * 26.0f * s + 16.0f * s,
                                 static_cast<float>(layout.bscan_panel.width_px));
    ImGui::SetNextWindowPos(
        ImVec2(static_cast<float>(image.center_x_px()), static_cast<float>(image.center_y_px())),
        ImGuiCond_Always, ImVec2(0.5f, 0.5f));
    ImGui::SetNextWindowSize(ImVec2(tgc_w, 180.0f * s));
    ImGui::Begin("TGC", nullptr, kDialogFlags);
    for (std::size_t i = 0; i < model.tgc_db.size(); ++i) {
      if (i > 0) ImGui::SameLine();
      char label[32];
      std::snprintf(label, sizeof label, "##TGC %zu", i + 1);
      float value = model.tgc_db[i];
      if (ImGui::VSliderFloat(label, ImVec2(18.0f * s, 110.0f * s), &value, -30.0f, 30.0f,
                              "%.0f")) {
        actions.tgc_slider = static_cast<int>(i);
        actions.tgc_db = std::round(value);
      }
      im.record(label);
    }
    ImGui::TextDisabled("SHALLOW ... DEEP, DB");
    if (im.button("CLOSE##TGC CLOSE")) im.tgc_open = false;
    ImGui::End();
  }

  if (im.settings_open) {
    ImGui::SetNextWindowPos(centre, ImGuiCond_Always, ImVec2(0.5f, 0.5f));
    ImGui::SetNextWindowSize(ImVec2(0.62f * io.DisplaySize.x, 0.7f * io.DisplaySize.y));
    ImGui::Begin("SETTINGS", nullptr, kDialogFlags);
    if (im.edits.size() != model.settings.size()) {
      im.edits.assign(model.settings.size(), 0.0);
      for (std::size_t i = 0; i < model.settings.size(); ++i) im.edits[i] = model.settings[i].value;
    }
    if (ImGui::BeginTabBar("##tabs")) {
      std::string_view tab_shown;
      for (std::size_t i = 0; i < model.settings.size(); ++i) {
        const std::string_view tab = model.settings[i].tab;
        if (tab == tab_shown) continue;
        tab_shown = tab;
        const std::string tab_label = std::string(tab) + "##TAB " + std::string(tab);
        const bool open = ImGui::BeginTabItem(tab_label.c_str());
        im.record(tab_label);
        if (!open) continue;
        for (std::size_t j = i; j < model.settings.size() && model.settings[j].tab == tab; ++j) {
          const SettingField& f = model.settings[j];
          const std::string name = std::string(f.table) + "." + std::string(f.key);
          ImGui::AlignTextToFramePadding();
          ImGui::TextUnformatted(name.c_str());
          ImGui::SameLine(0.62f * ImGui::GetWindowWidth());
          if (f.integer) {
            ImGui::Text("%.0f", im.edits[j]);
          } else {
            ImGui::Text("%.4g", im.edits[j]);
          }
          if (f.step > 0.0) {
            ImGui::SameLine(0.8f * ImGui::GetWindowWidth());
            const std::string minus = "-##" + name + " -";
            const std::string plus = "+##" + name + " +";
            if (im.button(minus.c_str())) im.edits[j] -= f.step;
            ImGui::SameLine();
            if (im.button(plus.c_str())) im.edits[j] += f.step;
          }
        }
        ImGui::EndTabItem();
      }
      ImGui::EndTabBar();
    }
    ImGui::Separator();
    if (!im.settings_error.empty()) {
      ImGui::PushStyleColor(ImGuiCol_Text, colour(theme::kWarning));
      ImGui::TextWrapped("%s", im.settings_error.c_str());
      ImGui::PopStyleColor();
    }
    if (im.button("APPLY")) {
      im.applied = im.edits;
      actions.settings_applied = im.applied;
    }
    ImGui::SameLine();
    if (im.button("UNDO EDITS")) {
      for (std::size_t i = 0; i < model.settings.size(); ++i) im.edits[i] = model.settings[i].value;
      im.settings_error.clear();
    }
    ImGui::SameLine();
    if (im.button("CLOSE##SETTINGS CLOSE")) im.settings_open = false;
    ImGui::End();
  }

  if (im.service_open) {
    ImGui::SetNextWindowPos(centre, ImGuiCond_Always, ImVec2(0.5f, 0.5f));
    ImGui::SetNextWindowSize(ImVec2(0.62f * io.DisplaySize.x, 0.7f * io.DisplaySize.y));
    ImGui::Begin("SERVICE", nullptr, kDialogFlags);
    if (ImGui::BeginTable("##service", 2, ImGuiTableFlags_RowBg)) {
      for (const ServiceLine& line : model.service) {
        ImGui::TableNextRow();
        ImGui::TableSetColumnIndex(0);
        ImGui::TextDisabled("%.*s", static_cast<int>(line.label.size()), line.label.data());
        ImGui::TableSetColumnIndex(1);
        if (!line.ok) ImGui::PushStyleColor(ImGuiCol_Text, colour(theme::kWarning));
        ImGui::TextUnformatted(line.value.data(), line.value.data() + line.value.size());
        if (!line.ok) ImGui::PopStyleColor();
      }
      ImGui::EndTable();
    }
    if (im.button("CLOSE##SERVICE CLOSE")) im.service_open = false;
    ImGui::End();
  }

  // The pointer on the screen itself, where no control took it: calipers on the B-scan, orbit
  // and zoom on the 3D view.
  const ImVec2 at = io.MousePos;
  const bool free = !io.WantCaptureMouse;
  const PixelRect& image = layout.bscan_image;
  const float width_mm = input.bscan.width_mm;
  const float depth_mm = input.bscan.depth_mm;
  const bool image_mm_ok = std::isfinite(width_mm) && std::isfinite(depth_mm) && width_mm > 0.0f &&
                           depth_mm > 0.0f && image.width_px > 0 && image.height_px > 0;
  const bool pressed_now = pointer.down && !was_down;
  if (free && pressed_now && im.caliper_mode && image_mm_ok &&
      image.contains(static_cast<int>(at.x), static_cast<int>(at.y))) {
    if (calipers_.points == 2) calipers_.points = 0;
    auto& point = calipers_.mm[static_cast<std::size_t>(calipers_.points)];
    point[0] =
        (at.x - static_cast<float>(image.x_px)) / static_cast<float>(image.width_px) * width_mm;
    point[1] =
        (at.y - static_cast<float>(image.y_px)) / static_cast<float>(image.height_px) * depth_mm;
    ++calipers_.points;
  }
  const PixelRect& v = layout.view_3d;
  const bool on_view = v.contains(static_cast<int>(at.x), static_cast<int>(at.y));
  if (pressed_now) im.orbiting = free && on_view;
  if (!pointer.down) im.orbiting = false;
  if (im.orbiting && !pressed_now) {
    // A drag across the panel's width turns the view half round.
    const float degrees_per_px = 180.0f / static_cast<float>(std::max(v.width_px, 1));
    view_.azimuth_offset_deg -= (at.x - im.last_x) * degrees_per_px;
    view_.elevation_offset_deg =
        std::clamp(view_.elevation_offset_deg + (at.y - im.last_y) * degrees_per_px, -60.0f, 50.0f);
  }
  if (free && on_view && pointer.wheel_notches != 0.0f) {
    view_.zoom = std::clamp(view_.zoom * std::pow(1.15f, pointer.wheel_notches), 0.5f, 4.0f);
  }
  im.last_x = at.x;
  im.last_y = at.y;

  // The calipers: crosses at the points, the line between, the distance under the image.
  if (im.caliper_mode && calipers_.points > 0 && image_mm_ok) {
    ImDrawList* draw = ImGui::GetBackgroundDrawList();
    const ImU32 mark = ImGui::GetColorU32(colour(theme::kFrozen));
    std::array<ImVec2, 2> px{};
    for (int i = 0; i < calipers_.points; ++i) {
      const auto& p = calipers_.mm[static_cast<std::size_t>(i)];
      px[static_cast<std::size_t>(i)] = ImVec2(
          static_cast<float>(image.x_px) + p[0] / width_mm * static_cast<float>(image.width_px),
          static_cast<float>(image.y_px) + p[1] / depth_mm * static_cast<float>(image.height_px));
      const ImVec2 c = px[static_cast<std::size_t>(i)];
      const float r = 5.0f * s;
      draw->AddLine(ImVec2(c.x - r, c.y), ImVec2(c.x + r, c.y), mark, s);
      draw->AddLine(ImVec2(c.x, c.y - r), ImVec2(c.x, c.y + r), mark, s);
    }
    if (calipers_.points == 2) {
      draw->AddLine(px[0], px[1], mark, 0.5f * s);
    }
    char readout[48];
    if (calipers_.points == 2) {
      std::snprintf(readout, sizeof readout, "DIST %.1f MM",
                    static_cast<double>(calipers_.distance_mm()));
    } else {
      std::snprintf(readout, sizeof readout, "DIST: TAP 2ND POINT");
    }
    const ImVec2 text_at(static_cast<float>(image.x_px) + 4.0f * s,
                         static_cast<float>(image.y_px + image.height_px) - 16.0f * s);
    const ImVec2 size = ImGui::CalcTextSize(readout);
    draw->AddRectFilled(ImVec2(text_at.x - 2.0f * s, text_at.y - 1.0f * s),
                        ImVec2(text_at.x + size.x + 2.0f * s, text_at.y + size.y + 1.0f * s),
                        IM_COL32(0, 0, 0, 200));
    draw->AddText(text_at, mark, readout);
  }

  ImGui::Render();
  ImGui_ImplOpenGL3_RenderDrawData(ImGui::GetDrawData());
  return actions;
}

}  // namespace ultrasim::render
