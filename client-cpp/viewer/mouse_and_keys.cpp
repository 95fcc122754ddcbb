// Mouse and keys into edits of the shown session and the reading tools.
#include "viewer/mouse_and_keys.h"

#include <imgui.h>
#include <imgui_impl_sdl.h>

#include <cmath>
#include <utility>

#include "viewer/transfer_edits.h"

namespace cinevol::viewer {
namespace {

constexpr float kClickSlop = 3;  // logical pixels a press may move and still be a click

}  // namespace

void MouseAndKeys::Pump() {
  const ImGuiIO& io = ImGui::GetIO();
  SDL_Event e;
  while (SDL_PollEvent(&e)) {
    ImGui_ImplSDL2_ProcessEvent(&e);
    switch (e.type) {
      case SDL_QUIT:
        quit_ = true;
        break;
      case SDL_MOUSEBUTTONDOWN: {
        const float x = float(e.button.x), y = float(e.button.y);
        const int pane = screen_.PaneAt(x, y);
        if (!io.WantCaptureMouse && (screen_.frame_area().Contains(x, y) || pane >= 0)) {
          button_ = e.button.button;
          pane_ = pane;
          last_x_ = press_x_ = x;
          last_y_ = press_y_ = y;
          dragged_ = false;
        }
        break;
      }
      case SDL_MOUSEBUTTONUP:
        if (e.button.button == button_) {
          if (!dragged_) Click(button_, press_x_, press_y_);
          button_ = 0;
        }
        break;
      case SDL_WINDOWEVENT:
        if (e.window.event == SDL_WINDOWEVENT_LEAVE) sharing_.PointAt(std::nullopt);
        break;
      case SDL_MOUSEMOTION: {
        const float x = float(e.motion.x), y = float(e.motion.y);
        if (const Rect shown = screen_.ShownFrame(); shown.Contains(x, y)) {
          sharing_.PointAt(PointerShare::At{(x - shown.x) / shown.w, (y - shown.y) / shown.h});
        } else {
          sharing_.PointAt(std::nullopt);
        }
        if (!button_) break;
        const float dx = x - last_x_, dy = y - last_y_;
        dragged_ = dragged_ || std::hypot(x - press_x_, y - press_y_) > kClickSlop;
        if (pane_ < 0) {
          Drag(button_, dx, dy, SDL_GetModState());
        } else if (button_ == SDL_BUTTON_LEFT && dragged_) {
          reading_.WindowLevel(dx, dy);
        }
        last_x_ = x;
        last_y_ = y;
        break;
      }
      case SDL_MOUSEWHEEL: {
        if (io.WantCaptureMouse) break;
        int mx = 0, my = 0;
        SDL_GetMouseState(&mx, &my);
        if (const int pane = screen_.PaneAt(float(mx), float(my)); pane >= 0) {
          reading_.StepSlice(pane, float(e.wheel.y));
        } else {
          Wheel(float(e.wheel.y));
        }
        break;
      }
      case SDL_KEYDOWN:
        if (!io.WantCaptureKeyboard) Key(e.key.keysym.sym);
        break;
      default:
        break;
    }
  }
}

void MouseAndKeys::Click(int button, float x, float y) {
  if (button != SDL_BUTTON_LEFT) return;
  if (const int pane = screen_.PaneAt(x, y); pane >= 0) {
    reading_.ClickSlice(pane, x, y);
  } else {
    reading_.PickAt(x, y);
  }
}

void MouseAndKeys::Drag(int button, float dx, float dy, SDL_Keymod mods) {
  if (!link_.Drives()) return;  // a viewer watches
  ShownSession& session = link_.shown();
  ViewCamera camera = session.camera();
  if (button == SDL_BUTTON_LEFT && (mods & KMOD_CTRL)) {  // the key light: the first area light
    google::protobuf::RepeatedPtrField<v1::Light> lights = session.scene().lights();
    for (v1::Light& l : lights) {
      if (!l.has_area()) continue;
      OrbitLight(*l.mutable_area(), camera, dx * kDegreesPerPixel, dy * kDegreesPerPixel);
      session.SetLights(lights);
      break;
    }
  } else if (button == SDL_BUTTON_LEFT && (mods & KMOD_ALT)) {  // window (horizontal) and level (vertical)
    if (session.Resolving()) return;  // the points to move are the server's, not yet here
    const auto& volume = link_.volume();
    const float range = volume ? volume->max_value() - volume->min_value() : 1.0f;
    v1::TransferFunction tf = session.scene().transfer_function();
    ApplyWindowLevel(tf, -dy * range / 500.0f, std::exp(dx * 0.005f));
    session.SetTransferFunction(tf);
  } else if (button == SDL_BUTTON_MIDDLE || (button == SDL_BUTTON_LEFT && (mods & KMOD_SHIFT))) {
    Pan(camera, dx, dy, screen_.frame_area().h);
    session.SetCamera(camera);
  } else if (button == SDL_BUTTON_RIGHT) {
    Zoom(camera, DragZoomFactor(dy));
    session.SetCamera(camera);
  } else if (button == SDL_BUTTON_LEFT) {
    Orbit(camera, dx * kDegreesPerPixel, dy * kDegreesPerPixel);
    session.SetCamera(camera);
  }
}

void MouseAndKeys::Wheel(float steps) {
  if (!link_.Drives()) return;
  ViewCamera camera = link_.shown().camera();
  Zoom(camera, WheelZoomFactor(steps));
  link_.shown().SetCamera(camera);
}

bool MouseAndKeys::Key(SDL_Keycode key) {
  const SDL_Keymod mods = SDL_GetModState();
  if (key == SDLK_q && (mods & KMOD_CTRL)) {
    quit_ = true;
    return true;
  }
  if (key == SDLK_F2) {
    panels_.stats = !panels_.stats;
    return true;
  }
  if (key == SDLK_F3) {
    reading_.ToggleGrid();
    return true;
  }
  if (key == SDLK_F4) {
    reading_.identity = !reading_.identity;
    return true;
  }
  if (!link_.Drives()) return false;
  if (key == SDLK_HOME || key == SDLK_SPACE) {
    link_.shown().SetCamera(link_.home());
    return true;
  }
  if (mods & (KMOD_CTRL | KMOD_ALT)) return false;
  // Named views about the current target: the server turns them along the volume's own axes.
  static const std::pair<SDL_Keycode, v1::NamedView> kViews[] = {{SDLK_a, v1::ANTERIOR}, {SDLK_p, v1::POSTERIOR},
                                                                 {SDLK_l, v1::LEFT},     {SDLK_r, v1::RIGHT},
                                                                 {SDLK_s, v1::SUPERIOR}, {SDLK_i, v1::INFERIOR}};
  for (const auto& [k, view] : kViews) {
    if (k != key) continue;
    link_.shown().TurnTo(view);
    return true;
  }
  return false;
}

}  // namespace cinevol::viewer
