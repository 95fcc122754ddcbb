// Resolves a scene (the proto model) against its loaded volume into what the
// renderer takes: transfer function (presets expanded), camera (named views
// framed), lights (environment maps read) and frame settings.
#pragma once

#include "cinevol/v1/scene.pb.h"
#include "core/camera.h"
#include "core/lights.h"
#include "core/transfer_function.h"
#include "core/volume.h"

namespace cinevol {

struct RenderSetup {
  TransferFunction transfer_function;
  LightSetup lights;
  Camera camera;
  int spp = 2;
  int max_bounces = 4;
  std::uint64_t seed = 0;
  float exposure = 0;  // stops, applied by the tone mapper
};

TransferFunction ResolveTransferFunction(const v1::TransferFunction& tf, const Volume& volume);
// Named views frame what `tf` shows of the volume.
Camera ResolveCamera(const v1::Camera& camera, const v1::RenderSettings& render, const Volume& volume,
                     const TransferFunction& tf);
LightSetup ResolveLights(const google::protobuf::RepeatedPtrField<v1::Light>& lights);

// All of the above; the scene must have passed CheckScene.
RenderSetup ResolveScene(const v1::Scene& scene, const Volume& volume);

}  // namespace cinevol
