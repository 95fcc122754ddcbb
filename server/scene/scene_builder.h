// Resolves a scene (the proto model) against its loaded volume into what the
// renderer takes: transfer function (presets expanded), camera (named views
// framed), lights (environment maps read) and frame settings.
#pragma once

#include <array>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "cinevol/v1/scene.pb.h"
#include "core/camera.h"
#include "core/clip_region.h"
#include "core/fused_view.h"
#include "core/image.h"
#include "core/labels.h"
#include "core/lights.h"
#include "core/transfer_function.h"
#include "core/volume.h"
#include "core/volume_view.h"

namespace cinevol {

struct RenderSetup {
  TransferFunction transfer_function;
  LightSetup lights;
  Camera camera;
  int spp = 2;
  int max_bounces = 4;
  std::uint64_t seed = 0;
  float exposure = 0;  // stops, applied by the tone mapper
  ClipRegion clip;     // what the crop box and clip planes keep
  Reconstruction reconstruction = Reconstruction::kTrilinear;
  LabelSetup labels;  // how the segmentation's labels show, where there is one
  // A second volume (Scene.fusion) and how it shows; null: none. Resolved by
  // ResolveFusion where the caller holds one: a scene names it by id.
  std::shared_ptr<const Volume> fused_volume;
  FusionSetup fusion;
};

// A named view in world space: the direction from the volume to the eye
// and the screen's up.
struct ViewDirections {
  Vec3f to_eye, up;
};
// `direction` is the volume's direction cosines (VolumeMetadata::direction).
using DirectionCosines = std::array<double, 9>;
ViewDirections NamedViewDirections(v1::NamedView view, const DirectionCosines& direction);

// A patient (LPS) direction in world space, through the direction cosines.
Vec3f PatientToWorld(const DirectionCosines& direction, Vec3f lps);

// The crop box and clip planes (patient LPS mm) as half-spaces in world mm.
ClipRegion ResolveClipping(const v1::Clipping& clipping, const Volume& volume);

// Per block of Volume::kBlockSize^3 voxels (Volume::block_counts, x fastest),
// whether it holds a label `setup` shows. One pass over the labels: callers
// keep it while the label styles stay (FramePipeline does).
std::vector<bool> BlocksWithVisibleLabels(const Volume& volume, const LabelVolume& labels, const LabelSetup& setup);

// What a scene leaves in view beyond its transfer function: the clipping
// and, where the volume has a segmentation, the blocks holding labels it shows.
struct InView {
  ClipRegion clip;
  const std::vector<bool>* label_blocks = nullptr;  // BlocksWithVisibleLabels; null: no segmentation
};

// The corners of the blocks of voxels (Volume::block_ranges) that `tf` makes
// visible (able to take 5% of the light crossing them), the clipping does not
// cut away whole and, with labels, that hold a visible label; the volume's
// corners when it shows nothing.
std::vector<Vec3f> VisibleCorners(const Volume& volume, const TransferFunction& tf, const InView& in_view = InView());

// Where a named view looks at and how far back its eye sits so that
// `points`, centred, fill 80% of the viewport's shorter side (perspective
// included).
struct Framing {
  Vec3f target;
  float distance = 0;
};
Framing FrameView(const std::vector<Vec3f>& points, const ViewDirections& view, float fov_y_deg, float aspect);

// With neither points nor a preset, the volume's default preset.
TransferFunction ResolveTransferFunction(const v1::TransferFunction& tf, const Volume& volume);
// A named view with eye and target set turns about the target at their
// distance; without, it frames what `tf` shows of the volume and `in_view`
// keeps (FrameView).
Camera ResolveCamera(const v1::Camera& camera, const v1::RenderSettings& render, const Volume& volume,
                     const TransferFunction& tf, const InView& in_view = InView());
// Unspecified is trilinear: tricubic costs 2.2 to 3.3 times the frame time
// (docs/rendering.md, "Reconstruction"), which interactive frames cannot pay.
Reconstruction ResolveReconstruction(v1::Reconstruction reconstruction);
// Label styles, their own transfer functions resolved against the volume.
LabelSetup ResolveLabels(const v1::Labels& labels, const Volume& volume);

// Scene.fusion against the scene's volume and the second volume it names
// (checked: session_state.h): its transfer function in the second volume's
// own values (SUVbw divided out with `suv`), the map from the render frame
// into its volume-centred frame through both volumes' patient coordinates,
// and the factor its values are shown with.
FusionSetup ResolveFusion(const v1::Fusion& fusion, const Volume& volume, const Volume& fused);
// An environment map's texels (linear RGB) from its path: the scene model
// opens no file itself; io/reader_cage.h's ReadEnvironmentMap reads one
// through the reader cage.
using EnvironmentMapReader = std::function<ImageRgbF(const std::string& path)>;
// An environment map needs `read_map` (InputError without one).
LightSetup ResolveLights(const google::protobuf::RepeatedPtrField<v1::Light>& lights,
                         const EnvironmentMapReader& read_map = {});

// All of the above; the scene must have passed CheckScene. `labels`: the
// volume's segmentation, where it has one.
RenderSetup ResolveScene(const v1::Scene& scene, const Volume& volume, const LabelVolume* labels = nullptr,
                         const EnvironmentMapReader& read_map = {});

}  // namespace cinevol
