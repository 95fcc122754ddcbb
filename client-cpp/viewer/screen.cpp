// The window, its layout and the textures drawn into it.
#include "viewer/screen.h"

#include <fmt/format.h>
#include <imgui.h>
#include <imgui_impl_sdl.h>
#include <imgui_impl_sdlrenderer.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>

#include "core/error.h"
#include "image_files.h"

namespace cinevol::viewer {
namespace {

constexpr float kPanelWidth = 330;  // logical pixels

double Ms(std::chrono::steady_clock::duration d) { return std::chrono::duration<double, std::milli>(d).count(); }

SDL_Rect ToPixels(const Rect& r, float scale) {
  return {int(std::lround(r.x * scale)), int(std::lround(r.y * scale)), int(std::lround(r.w * scale)),
          int(std::lround(r.h * scale))};
}

// Replaces `texture` with one of the image's size where it differs, and fills it.
void Fill(SDL_Renderer* renderer, SDL_Texture*& texture, const RgbImage& image) {
  int w = 0, h = 0;
  if (texture) SDL_QueryTexture(texture, nullptr, nullptr, &w, &h);
  if (!texture || w != image.width || h != image.height) {
    if (texture) SDL_DestroyTexture(texture);
    texture = SDL_CreateTexture(renderer, SDL_PIXELFORMAT_RGB24, SDL_TEXTUREACCESS_STREAMING, image.width, image.height);
  }
  if (texture) SDL_UpdateTexture(texture, nullptr, image.rgb.data(), image.width * 3);
}

}  // namespace

Rect Fit(const Rect& area, float w, float h) {
  if (w <= 0 || h <= 0) return {};
  const float s = std::min(area.w / w, area.h / h);
  return {area.x + (area.w - w * s) / 2, area.y + (area.h - h * s) / 2, w * s, h * s};
}

void Screen::OpenDisplay() {
  if (SDL_Init(SDL_INIT_VIDEO) != 0) throw InputError(fmt::format("cannot open a window: {}", SDL_GetError()));
  // Without a display SDL falls back to drivers that draw nowhere: the
  // window would run unseen for ever. Only a user who asks for one gets it.
  const std::string driver = SDL_GetCurrentVideoDriver() ? SDL_GetCurrentVideoDriver() : "";
  const bool windowless = driver == "offscreen" || driver == "dummy" || driver == "evdev";
  if (windowless && !std::getenv("SDL_VIDEODRIVER")) {
    throw InputError(
        "no display to open a window on (DISPLAY and WAYLAND_DISPLAY are not set): run it in a desktop session or "
        "over ssh -X; for a script without a screen, use xvfb-run (or SDL_VIDEODRIVER=offscreen)");
  }
}

Screen::Screen(int width, int height) {
  window_ = SDL_CreateWindow("cinevol-viewer", SDL_WINDOWPOS_CENTERED, SDL_WINDOWPOS_CENTERED, width, height,
                             SDL_WINDOW_RESIZABLE | SDL_WINDOW_ALLOW_HIGHDPI);
  if (!window_) throw InputError(fmt::format("cannot open a window: {}", SDL_GetError()));
  renderer_ = SDL_CreateRenderer(window_, -1, SDL_RENDERER_ACCELERATED);
  if (!renderer_) renderer_ = SDL_CreateRenderer(window_, -1, SDL_RENDERER_SOFTWARE);
  if (!renderer_) throw InputError(fmt::format("cannot draw in the window: {}", SDL_GetError()));
  ImGui::CreateContext();
  ImGui::GetIO().IniFilename = nullptr;  // the layout is the program's, not a file's
  ImGui::StyleColorsDark();
  ImGui_ImplSDL2_InitForSDLRenderer(window_);
  ImGui_ImplSDLRenderer_Init(renderer_);
  Layout(false);
}

Screen::~Screen() {
  ImGui_ImplSDLRenderer_Shutdown();
  ImGui_ImplSDL2_Shutdown();
  ImGui::DestroyContext();
  if (texture_) SDL_DestroyTexture(texture_);
  for (SDL_Texture* t : pane_textures_) {
    if (t) SDL_DestroyTexture(t);
  }
  if (renderer_) SDL_DestroyRenderer(renderer_);
  if (window_) SDL_DestroyWindow(window_);
  SDL_Quit();
}

void Screen::Layout(bool grid) {
  grid_ = grid;
  int w = 0, h = 0, pw = 0, ph = 0;
  SDL_GetWindowSize(window_, &w, &h);
  SDL_GetRendererOutputSize(renderer_, &pw, &ph);
  pixel_scale_ = w > 0 ? float(pw) / float(w) : 1.0f;
  const float panel = std::min(kPanelWidth, float(w) * 0.5f);
  panel_ = {0, 0, panel, float(h)};
  frame_ = {panel, 0, float(w) - panel, float(h)};
  if (!grid) return;
  // 2x2: the 3D view top left, axial top right, coronal and sagittal below.
  const float hw = frame_.w / 2, hh = frame_.h / 2;
  frame_ = {panel, 0, hw, hh};
  panes_[0] = {panel + hw, 0, hw, hh};
  panes_[1] = {panel, hh, hw, hh};
  panes_[2] = {panel + hw, hh, hw, hh};
}

int Screen::PaneAt(float x, float y) const {
  if (!grid_) return -1;
  for (int pane = 0; pane < kPanes; ++pane) {
    if (panes_[pane].Contains(x, y)) return pane;
  }
  return -1;
}

int Screen::Pixels(float logical) const { return std::max(16, int(std::lround(logical * pixel_scale_))); }

void Screen::BeginTurn() {
  ImGui_ImplSDLRenderer_NewFrame();
  ImGui_ImplSDL2_NewFrame();
  ImGui::NewFrame();
}

void Screen::EndTurn(bool grid, const std::array<Rect, kPanes>& slices_shown) {
  ImGui::Render();
  SDL_SetRenderDrawColor(renderer_, 24, 26, 30, 255);
  SDL_RenderClear(renderer_);
  DrawFrame();
  for (int pane = 0; grid && pane < kPanes; ++pane) {
    if (!pane_textures_[pane] || slices_shown[pane].w <= 0) continue;
    const SDL_Rect dst = ToPixels(slices_shown[pane], pixel_scale_);
    SDL_RenderCopy(renderer_, pane_textures_[pane], nullptr, &dst);
  }
  ImGui_ImplSDLRenderer_RenderDrawData(ImGui::GetDrawData());
}

double Screen::UploadFrame(const RgbImage& image, int shown_width, int shown_height) {
  const auto start = std::chrono::steady_clock::now();
  Fill(renderer_, texture_, image);
  // A frame that rendered smaller comes at that size: drawn stretched, filtered.
  if (texture_) SDL_SetTextureScaleMode(texture_, SDL_ScaleModeLinear);
  frame_w_ = shown_width > 0 ? shown_width : image.width;
  frame_h_ = shown_height > 0 ? shown_height : image.height;
  return Ms(std::chrono::steady_clock::now() - start);
}

Rect Screen::ShownFrame() const {
  if (!texture_) return {};
  return Fit(frame_, float(frame_w_), float(frame_h_));
}

void Screen::DrawFrame() {
  // The frame fitted into its area, its aspect ratio kept (it matches once a resize has settled).
  if (!texture_) return;
  const SDL_Rect dst = ToPixels(ShownFrame(), pixel_scale_);
  SDL_RenderCopy(renderer_, texture_, nullptr, &dst);
}

void Screen::UploadSlice(int pane, const RgbImage& image) { Fill(renderer_, pane_textures_[pane], image); }

bool Screen::WriteScreenshot(const std::string& path) {
  RgbImage image;
  WindowSize(image.width, image.height);
  image.rgb.resize(std::size_t(image.width) * image.height * 3);
  if (SDL_RenderReadPixels(renderer_, nullptr, SDL_PIXELFORMAT_RGB24, image.rgb.data(), image.width * 3) != 0) {
    std::fprintf(stderr, "cinevol-viewer: cannot read the window: %s\n", SDL_GetError());
    return false;
  }
  WritePngFile(path, image);
  return true;
}

std::string Screen::RendererName() const {
  SDL_RendererInfo info;
  return SDL_GetRendererInfo(renderer_, &info) == 0 ? info.name : "?";
}

}  // namespace cinevol::viewer
