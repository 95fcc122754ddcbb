// Layout and panes: the SDL window and renderer, Dear ImGui on them, where
// the panel, the 3D view and the 2x2 layout's slice panes lie, the textures
// the frames and slices are drawn from, and screenshots of the window.
#pragma once

#include <SDL.h>

#include <array>
#include <string>

#include "client.h"

namespace cinevol::viewer {

// A rectangle in logical (ImGui) pixels.
struct Rect {
  float x = 0, y = 0, w = 0, h = 0;
  bool Contains(float px, float py) const { return px >= x && py >= y && px < x + w && py < y + h; }
};

// `w` x `h` (any units) fitted into `area`, centred, its aspect ratio kept; empty for an empty size.
Rect Fit(const Rect& area, float w, float h);

class Screen {
 public:
  static constexpr int kPanes = 3;  // axial, coronal, sagittal, in the 2x2 layout's order

  // Opens SDL's video; throws InputError (exit 2) where there is no display
  // to open a window on. Call before anything slow, such as a local server.
  static void OpenDisplay();
  Screen(int width, int height);  // the window, its renderer, Dear ImGui
  ~Screen();
  Screen(const Screen&) = delete;
  Screen& operator=(const Screen&) = delete;

  // Where things go this turn: the panel on the left, the 3D view beside it,
  // or (grid) the 3D view top left and the slices in the other quadrants.
  void Layout(bool grid);
  Rect panel_area() const { return panel_; }
  Rect frame_area() const { return frame_; }
  Rect pane_area(int pane) const { return panes_[pane]; }
  // The pane under a point, or -1 (only in the grid).
  int PaneAt(float x, float y) const;
  // A length of the window in its pixels (at least 16): the session's viewport for the frame area.
  int Pixels(float logical) const;

  // Starts a turn's drawing (ImGui's frame), and ends it: the frames, the
  // slices and the panels drawn, in that order, not yet presented.
  void BeginTurn();
  void EndTurn(bool grid, const std::array<Rect, kPanes>& slices_shown);
  void Present() { SDL_RenderPresent(renderer_); }

  // The newest frame onto its texture, to be shown at `shown_width` x
  // `shown_height` (the frame's width and height: a frame that rendered
  // smaller is stretched); returns the milliseconds it took.
  double UploadFrame(const RgbImage& image, int shown_width, int shown_height);
  bool has_frame() const { return texture_ != nullptr; }
  int frame_width() const { return frame_w_; }  // the session's viewport, whatever size it is drawn at
  int frame_height() const { return frame_h_; }
  // Where the frame is drawn (empty before one).
  Rect ShownFrame() const;
  // A pane's slice onto its texture.
  void UploadSlice(int pane, const RgbImage& image);

  // The window as drawn this turn into a PNG; false (and stderr says why) when it cannot be read.
  bool WriteScreenshot(const std::string& path);
  float pixel_scale() const { return pixel_scale_; }
  void Resize(int width, int height) { SDL_SetWindowSize(window_, width, height); }
  void WindowSize(int& width, int& height) const { SDL_GetRendererOutputSize(renderer_, &width, &height); }
  std::string RendererName() const;

 private:
  void DrawFrame();

  SDL_Window* window_ = nullptr;
  SDL_Renderer* renderer_ = nullptr;
  SDL_Texture* texture_ = nullptr;
  int frame_w_ = 0, frame_h_ = 0;
  std::array<SDL_Texture*, kPanes> pane_textures_{};
  float pixel_scale_ = 1;
  bool grid_ = false;
  Rect panel_, frame_;
  std::array<Rect, kPanes> panes_{};
};

}  // namespace cinevol::viewer
