// The cheapest real scene the pipeline and renderer tests use: a 32^3 head
// phantom at 6 mm, seen through the ct-bone preset at a few dozen pixels.
#pragma once

#include <memory>

#include "io/phantom.h"
#include "scene/presets.h"
#include "scene/scene_file.h"

namespace cinevol::testing {

inline std::shared_ptr<const Volume> SmallHead() {
  v1::Phantom p;
  p.set_kind(v1::Phantom::HEAD);
  p.set_size(32);
  p.set_spacing(6.0f);
  return std::make_shared<const Volume>(MakePhantom(p));
}

inline v1::Scene SmallScene(const Volume& volume, int width = 48, int height = 32, int spp = 2) {
  v1::Scene scene = MakePresetScene("ct-bone", volume);
  scene.mutable_render()->set_width(width);
  scene.mutable_render()->set_height(height);
  scene.mutable_render()->set_spp(spp);
  ApplyDefaults(scene);
  return scene;
}

}  // namespace cinevol::testing
