// The transfer function editor widget: see transfer_editor.h. All edits go
// through transfer_edits.h; this file only draws and reads the mouse.
#include "transfer_editor.h"

#include <imgui.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "transfer_edits.h"

namespace cinevol::viewer {
namespace {

constexpr float kPointRadius = 5;     // px
constexpr float kSelectedRadius = 7;  // px
constexpr float kHitRadius = 8;       // px: how close the mouse must be to grab a point
const ImU32 kBackground = IM_COL32(28, 28, 32, 255);
const ImU32 kFrame = IM_COL32(90, 90, 100, 255);
const ImU32 kHistogramBar = IM_COL32(85, 85, 85, 255);
const ImU32 kCurve = IM_COL32(230, 230, 230, 255);
const ImU32 kOutline = IM_COL32(20, 20, 20, 255);
const ImU32 kHighlight = IM_COL32(255, 200, 40, 255);
const ImU32 kLabel = IM_COL32(170, 170, 170, 255);

// Maps (value, opacity) to the plot area's pixels and back.
struct Canvas {
  ImVec2 min, max;       // plot area, screen pixels; opacity 1 at min.y
  float lo = 0, hi = 1;  // values at min.x and max.x

  ImVec2 ToScreen(float value, float opacity) const {
    return {min.x + (value - lo) / (hi - lo) * (max.x - min.x), max.y - opacity * (max.y - min.y)};
  }
  float ValueAt(float x) const {
    return lo + std::clamp((x - min.x) / (max.x - min.x), 0.0f, 1.0f) * (hi - lo);
  }
  float OpacityAt(float y) const { return std::clamp((max.y - y) / (max.y - min.y), 0.0f, 1.0f); }
};

// The plot for the widget's rectangle: inset so end points' circles show,
// with a strip at the bottom for the axis labels. Along x, the histogram's
// value range widened to hold every point, never empty.
Canvas MakeCanvas(const v1::TransferFunction& tf, const v1::ValueHistogram& histogram,
                  ImVec2 origin, ImVec2 size) {
  Canvas c;
  c.lo = histogram.min_value();
  c.hi = histogram.max_value();
  if (!(c.hi > c.lo) && !tf.points().empty()) c.lo = c.hi = tf.points(0).value();
  for (const auto& p : tf.points()) {
    c.lo = std::min(c.lo, p.value());
    c.hi = std::max(c.hi, p.value());
  }
  if (!(c.hi > c.lo)) {
    const float pad = std::max(1.0f, std::abs(c.lo) * 0.01f);
    c.lo -= pad;
    c.hi += pad;
  }
  const float label = ImGui::GetTextLineHeight() + 2;
  c.min = {origin.x + kSelectedRadius, origin.y + kSelectedRadius};
  c.max = {origin.x + size.x - kSelectedRadius, origin.y + size.y - label};
  return c;
}

ImU32 ToImColor(const v1::Color& c) {
  return ImGui::ColorConvertFloat4ToU32(ImVec4(c.r(), c.g(), c.b(), 1));
}

// Grey bars, log(1 + count) scaled so the fullest bin reaches opacity 1.
void DrawHistogram(ImDrawList* draw, const Canvas& canvas, const v1::ValueHistogram& histogram) {
  const int bins = histogram.counts_size();
  if (bins == 0 || !(histogram.max_value() > histogram.min_value())) return;
  const auto fullest = *std::max_element(histogram.counts().begin(), histogram.counts().end());
  if (fullest == 0) return;
  const float log_fullest = std::log1p(static_cast<float>(fullest));
  const float width = (histogram.max_value() - histogram.min_value()) / bins;
  for (int i = 0; i < bins; ++i) {
    if (histogram.counts(i) == 0) continue;
    const float bin_lo = histogram.min_value() + i * width;
    const float height = std::log1p(static_cast<float>(histogram.counts(i))) / log_fullest;
    const ImVec2 top_left = canvas.ToScreen(bin_lo, height);
    const ImVec2 bottom_right = canvas.ToScreen(bin_lo + width, 0);
    draw->AddRectFilled(top_left, {std::max(bottom_right.x, top_left.x + 1), bottom_right.y},
                        kHistogramBar);
  }
}

// The opacity polyline, held flat from the plot's left edge to the first
// point and from the last point to the right edge.
void DrawCurve(ImDrawList* draw, const Canvas& canvas, const v1::TransferFunction& tf) {
  if (tf.points().empty()) return;
  std::vector<ImVec2> line;
  line.push_back({canvas.min.x, canvas.ToScreen(canvas.lo, tf.points(0).opacity()).y});
  for (const auto& p : tf.points()) line.push_back(canvas.ToScreen(p.value(), p.opacity()));
  line.push_back({canvas.max.x, line.back().y});
  draw->AddPolyline(line.data(), static_cast<int>(line.size()), kCurve, ImDrawFlags_None, 2);
}

void DrawPoints(ImDrawList* draw, const Canvas& canvas, const v1::TransferFunction& tf,
                int selected) {
  for (int i = 0; i < tf.points_size(); ++i) {
    const auto& p = tf.points(i);
    const ImVec2 at = canvas.ToScreen(p.value(), p.opacity());
    const bool chosen = i == selected;
    const float radius = chosen ? kSelectedRadius : kPointRadius;
    draw->AddCircleFilled(at, radius, ToImColor(p.diffuse()));
    draw->AddCircle(at, radius, chosen ? kHighlight : kOutline, 0, chosen ? 2.5f : 1.5f);
  }
}

void DrawAxisLabels(ImDrawList* draw, const Canvas& canvas) {
  char text[32];
  const float y = canvas.max.y + 2;
  std::snprintf(text, sizeof text, "%.4g", canvas.lo);
  draw->AddText({canvas.min.x, y}, kLabel, text);
  std::snprintf(text, sizeof text, "%.4g", canvas.hi);
  draw->AddText({canvas.max.x - ImGui::CalcTextSize(text).x, y}, kLabel, text);
}

// When the function has no points, says which preset it stands for.
void DrawPresetNote(ImDrawList* draw, const Canvas& canvas, const v1::TransferFunction& tf) {
  if (!tf.points().empty()) return;
  const std::string note = tf.preset().empty() ? "volume's default preset; click to add points"
                                               : "preset " + tf.preset() + "; click to add points";
  draw->AddText({canvas.min.x + 4, canvas.min.y + 4}, kLabel, note.c_str());
}

// The point nearest the mouse within kHitRadius, or -1.
int PointUnderMouse(const Canvas& canvas, const v1::TransferFunction& tf, ImVec2 mouse) {
  int nearest = -1;
  float best = kHitRadius * kHitRadius;
  for (int i = 0; i < tf.points_size(); ++i) {
    const ImVec2 at = canvas.ToScreen(tf.points(i).value(), tf.points(i).opacity());
    const float dx = at.x - mouse.x, dy = at.y - mouse.y;
    if (dx * dx + dy * dy <= best) {
      best = dx * dx + dy * dy;
      nearest = i;
    }
  }
  return nearest;
}

void ShowPointTooltip(const v1::TransferFunction& tf, int index) {
  ImGui::BeginTooltip();
  ImGui::Text("value %.4g", tf.points(index).value());
  ImGui::Text("opacity %.3f", tf.points(index).opacity());
  ImGui::EndTooltip();
}

// Left press: grab the point under the mouse, or add one there and grab it.
bool OnLeftClick(const Canvas& canvas, v1::TransferFunction& tf, TransferEditorState& state,
                 int hit, ImVec2 mouse) {
  if (hit >= 0) {
    state.selected = state.dragging = hit;
    return false;
  }
  const int added = AddTransferPoint(tf, canvas.ValueAt(mouse.x), canvas.OpacityAt(mouse.y));
  if (added < 0) return false;
  state.selected = state.dragging = added;
  return true;
}

// Right press on a point: delete it, keeping the selection on the same point.
bool OnRightClick(v1::TransferFunction& tf, TransferEditorState& state, int hit) {
  if (hit < 0 || !DeleteTransferPoint(tf, hit)) return false;
  if (state.selected == hit) state.selected = -1;
  if (state.selected > hit) --state.selected;
  state.dragging = -1;
  return true;
}

// While the left button holds a point, the point follows the mouse.
bool OnDrag(const Canvas& canvas, v1::TransferFunction& tf, TransferEditorState& state,
            ImVec2 mouse) {
  const auto& p = tf.points(state.dragging);
  const float value = p.value(), opacity = p.opacity();
  MoveTransferPoint(tf, state.dragging, canvas.ValueAt(mouse.x), canvas.OpacityAt(mouse.y));
  return p.value() != value || p.opacity() != opacity;
}

// Mouse input on the canvas (the last item drawn); true when tf changed.
bool HandleMouse(const Canvas& canvas, v1::TransferFunction& tf, TransferEditorState& state) {
  const ImGuiIO& io = ImGui::GetIO();
  const bool hovered = ImGui::IsItemHovered();
  const int hit = hovered ? PointUnderMouse(canvas, tf, io.MousePos) : -1;
  bool changed = false;
  if (hovered && io.MouseClicked[ImGuiMouseButton_Left])
    changed |= OnLeftClick(canvas, tf, state, hit, io.MousePos);
  else if (hovered && io.MouseClicked[ImGuiMouseButton_Right])
    changed |= OnRightClick(tf, state, hit);
  if (!io.MouseDown[ImGuiMouseButton_Left] || !ImGui::IsItemActive()) state.dragging = -1;
  const bool moved = io.MouseDelta.x != 0 || io.MouseDelta.y != 0;
  if (state.dragging >= 0 && moved) changed |= OnDrag(canvas, tf, state, io.MousePos);
  const int tip = state.dragging >= 0 ? state.dragging : PointUnderMouse(canvas, tf, io.MousePos);
  if (tip >= 0 && (hovered || state.dragging >= 0)) ShowPointTooltip(tf, tip);
  return changed;
}

// The selected point's material; true when it changed.
bool EditSelectedPoint(v1::TransferFunction& tf, const TransferEditorState& state) {
  if (state.selected < 0) {
    ImGui::TextDisabled(
        "Click a point to edit it; click empty space to add one, right-click to delete.");
    return false;
  }
  v1::TransferFunctionPoint& p = *tf.mutable_points(state.selected);
  ImGui::Text("Point %d: value %.4g, opacity %.3f", state.selected, p.value(), p.opacity());
  bool changed = false;
  float diffuse[3] = {p.diffuse().r(), p.diffuse().g(), p.diffuse().b()};
  if (ImGui::ColorEdit3("diffuse", diffuse)) {
    p.mutable_diffuse()->set_r(diffuse[0]);
    p.mutable_diffuse()->set_g(diffuse[1]);
    p.mutable_diffuse()->set_b(diffuse[2]);
    changed = true;
  }
  // Specular is edited as one grey reflectance, as the presets define it.
  float specular = (p.specular().r() + p.specular().g() + p.specular().b()) / 3;
  if (ImGui::SliderFloat("specular", &specular, 0, 1, "%.3f", ImGuiSliderFlags_AlwaysClamp)) {
    p.mutable_specular()->set_r(specular);
    p.mutable_specular()->set_g(specular);
    p.mutable_specular()->set_b(specular);
    changed = true;
  }
  float roughness = p.roughness();
  if (ImGui::SliderFloat("roughness", &roughness, 0, 1, "%.3f", ImGuiSliderFlags_AlwaysClamp)) {
    p.set_roughness(roughness);
    changed = true;
  }
  if (changed) tf.clear_preset();
  return changed;
}

// density_scale and gradient_factor; unset fields show their default of 1.
bool EditGlobals(v1::TransferFunction& tf) {
  bool changed = false;
  float density = tf.has_density_scale() ? tf.density_scale() : 1.0f;
  if (ImGui::SliderFloat("density (per mm)", &density, 0.01f, 50.0f, "%.3g",
                         ImGuiSliderFlags_Logarithmic | ImGuiSliderFlags_AlwaysClamp)) {
    tf.set_density_scale(density);
    changed = true;
  }
  float blend = tf.has_gradient_factor() ? tf.gradient_factor() : 1.0f;
  if (ImGui::SliderFloat("surface / volume blend", &blend, 0, 5, "%.2f",
                         ImGuiSliderFlags_AlwaysClamp)) {
    tf.set_gradient_factor(blend);
    changed = true;
  }
  if (ImGui::IsItemHovered())
    ImGui::SetTooltip(
        "0: purely volumetric scattering; higher: surface shading at strong gradients");
  return changed;
}

// Forgets points that no longer exist (tf may have been replaced).
void ValidateState(const v1::TransferFunction& tf, TransferEditorState& state) {
  if (state.selected >= tf.points_size()) state.selected = -1;
  if (state.dragging >= tf.points_size()) state.dragging = -1;
}

}  // namespace

bool TransferFunctionEditor(const char* id, v1::TransferFunction& tf,
                            const v1::ValueHistogram& histogram, TransferEditorState& state,
                            float height) {
  ImGui::PushID(id);
  ValidateState(tf, state);
  const ImVec2 origin = ImGui::GetCursorScreenPos();
  const float min_height = ImGui::GetTextLineHeight() + 4 * kSelectedRadius;
  const ImVec2 size(std::max(ImGui::GetContentRegionAvail().x, 4 * kSelectedRadius),
                    std::max(height, min_height));
  ImGui::InvisibleButton("canvas", size,
                         ImGuiButtonFlags_MouseButtonLeft | ImGuiButtonFlags_MouseButtonRight);
  bool changed = HandleMouse(MakeCanvas(tf, histogram, origin, size), tf, state);
  // Drawn after the edits, whose points may have widened the value range.
  const Canvas canvas = MakeCanvas(tf, histogram, origin, size);

  ImDrawList* draw = ImGui::GetWindowDrawList();
  draw->AddRectFilled(origin, {origin.x + size.x, canvas.max.y + 1}, kBackground);
  DrawHistogram(draw, canvas, histogram);
  DrawCurve(draw, canvas, tf);
  DrawPoints(draw, canvas, tf, state.selected);
  draw->AddRect(origin, {origin.x + size.x, canvas.max.y + 1}, kFrame);
  DrawAxisLabels(draw, canvas);
  DrawPresetNote(draw, canvas, tf);

  changed |= EditSelectedPoint(tf, state);
  changed |= EditGlobals(tf);
  ImGui::PopID();
  return changed;
}

}  // namespace cinevol::viewer
