// The preset library's tables: our own presets, 3D Slicer's volume-rendering
// presets translated into our model, and the kWindow defaults for data
// without absolute units. docs/presets-sources.md gives the raw numbers.
#include "scene/preset_library.h"

#include <algorithm>
#include <cmath>
#include <initializer_list>

namespace cinevol {
namespace {

// Colours of tissue, as in the first presets.
constexpr PresetColor kBone{0.92f, 0.88f, 0.78f}, kSkin{0.90f, 0.62f, 0.52f},
    kFat{0.95f, 0.82f, 0.6f}, kMuscle{0.78f, 0.32f, 0.28f}, kBlood{0.85f, 0.15f, 0.12f}, kGrey{0.85f, 0.8f, 0.75f};

// One merged control point of a Slicer preset: its value (HU, or an
// intensity already divided by the reference maximum), Slicer's scalar
// opacity there and its colour.
struct SlicerPoint {
  float value, opacity;
  PresetColor color;
};

// Slicer's scalar opacity `a` is the opacity of one unit distance of tissue:
// VTK's ray casters correct it per sample step to 1 - (1 - a)^(step / unit),
// and Slicer keeps VTK's default unit (ScalarOpacityUnitDistance), one world
// unit, which in Slicer is 1 mm. One unit transmits 1 - a, so the
// extinction is sigma_t = -ln(1 - a) / unit (docs/presets-sources.md).
constexpr float kSlicerUnitMm = 1.0f;
// a = 1 has no finite extinction; 0.99 stands in (4.6/mm: opaque in a voxel).
constexpr float kSlicerMaxOpacity = 0.99f;
float SlicerExtinction(float a) {
  return std::max(0.0f, -std::log(1.0f - std::min(a, kSlicerMaxOpacity)) / kSlicerUnitMm);
}

// VTK interpolates `a` linearly between points, and -ln(1 - a) is convex:
// a segment is halved until the extinction midway is within 5% of the line
// between its ends (at most 16 pieces).
constexpr float kSlicerExtinctionTolerance = 0.05f;
constexpr int kSlicerMaxHalvings = 4;

SlicerPoint Lerp(const SlicerPoint& a, const SlicerPoint& b, float t) {
  auto mix = [t](float x, float y) { return x + (y - x) * t; };
  return {mix(a.value, b.value), mix(a.opacity, b.opacity),
          {mix(a.color.r, b.color.r), mix(a.color.g, b.color.g), mix(a.color.b, b.color.b)}};
}

// The points strictly inside segment a..b that the extinction needs.
void AppendInside(const SlicerPoint& a, const SlicerPoint& b, int halvings, std::vector<SlicerPoint>& out) {
  const SlicerPoint mid = Lerp(a, b, 0.5f);
  const float exact = SlicerExtinction(mid.opacity);
  const float line = 0.5f * (SlicerExtinction(a.opacity) + SlicerExtinction(b.opacity));
  if (halvings == 0 || std::abs(line - exact) <= kSlicerExtinctionTolerance * exact) return;
  AppendInside(a, mid, halvings - 1, out);
  out.push_back(mid);
  AppendInside(mid, b, halvings - 1, out);
}

std::vector<SlicerPoint> Subdivided(std::initializer_list<SlicerPoint> points) {
  std::vector<SlicerPoint> out;
  for (auto it = points.begin(); it != points.end(); ++it) {
    if (it != points.begin()) AppendInside(*(it - 1), *it, kSlicerMaxHalvings, out);
    out.push_back(*it);
  }
  return out;
}

// Slicer's specular (0..1, Phong weight) as our reflectance at normal
// incidence, 0.1..0.3.
constexpr float SpecularFromSlicer(float specular) {
  const float s = 0.1f + 0.4f * specular;
  return s < 0.3f ? s : 0.3f;
}

// Every preset taken has shade="1" (lit surfaces): our surface/volume blend.
constexpr float kSlicerGradientFactor = 1.5f;

// A Slicer preset in our model: extinction -ln(1 - a) per mm at every point,
// written as opacity times density_scale with density_scale the largest
// extinction, one specular and roughness for all points; points of zero
// opacity get no specular, like our own presets.
PresetDefinition FromSlicer(const char* name, const char* description, const char* origin, PresetScale scale,
                            std::initializer_list<SlicerPoint> slicer, float slicer_specular, float roughness) {
  const std::vector<SlicerPoint> points = Subdivided(slicer);
  float density = 0;
  for (const SlicerPoint& p : points) density = std::max(density, SlicerExtinction(p.opacity));
  PresetDefinition preset{name, description, origin, scale, density, kSlicerGradientFactor, {}};
  const float specular = SpecularFromSlicer(slicer_specular);
  for (const SlicerPoint& p : points) {
    const float opacity = density > 0 ? SlicerExtinction(p.opacity) / density : 0.0f;
    preset.points.push_back({p.value, opacity, p.color, opacity > 0 ? specular : 0.0f, roughness});
  }
  return preset;
}

// Roughness from Slicer's specularPower: sqrt(2 / (power + 2)), clamped to
// [0.2, 0.7]. Power 1 gives 0.7, 10 gives 0.41, 40 gives 0.22.
constexpr float kRoughPower1 = 0.7f, kRoughPower10 = 0.41f, kRoughPower40 = 0.22f;

// Slicer's colour ramp shared by CT-AAA, CT-Muscle, CT-Cardiac and
// CT-Chest-Contrast-Enhanced.
constexpr PresetColor kSlicerBrown{0.549f, 0.251f, 0.149f}, kSlicerOrange{0.882f, 0.604f, 0.290f},
    kSlicerPink{1.0f, 0.937f, 0.955f}, kSlicerLavender{0.827f, 0.659f, 1.0f};

}  // namespace

const std::vector<PresetDefinition>& PresetLibrary() {
  static const std::vector<PresetDefinition> library = {
      // --- The first presets, names kept: scripts use them. ---
      {"ct-bone",
       "Bone surfaces: skull, spine, skeleton; soft tissue and contrast blood hidden",
       "cinevol, the first preset table; on a contrast CT its ramp starts above the blood pool",
       PresetScale::kHu,
       2.0f,
       2.0f,
       {{100, 0, kBone, 0, 0.5f},
        {250, 0.3f, kBone, 0.15f, 0.5f},
        {500, 1, kBone, 0.2f, 0.4f},
        {2000, 1, kBone, 0.2f, 0.4f}},
       ContrastRule::kAboveBloodPool},
      {"ct-soft-tissue",
       "Translucent skin, fat and muscle over bone",
       "cinevol, the first preset table (server/scene/presets.cpp), numbers kept",
       PresetScale::kHu,
       0.5f,
       1.5f,
       {{-300, 0, kFat, 0, 0.6f},
        {-100, 0.02f, kFat, 0.05f, 0.6f},
        {-20, 0.05f, kSkin, 0.1f, 0.5f},
        {40, 0.4f, kSkin, 0.1f, 0.5f},
        {120, 0.4f, kMuscle, 0.1f, 0.5f},
        {250, 0.8f, kBone, 0.2f, 0.4f},
        {1000, 1, kBone, 0.2f, 0.4f}}},
      // Contrast blood and bone overlap in value (bone's partial-volume rim
      // and thin bone pass through the blood pool's values). The lumen band
      // is faint (0.15/mm): a lumen millimetres deep stops a ray, a rim
      // mostly lets it through to the cortex, which stops it at once (4/mm)
      // in ivory. By value alone this halves the red on bone, no more
      // (docs/presets.md, "CT angiography").
      {"ct-vessels",
       "CT angiography: contrast-filled lumen in red, bone ivory; follows the blood pool",
       "cinevol: a band on the blood pool (reference 400 HU, edge 550) at 0.15/mm, bone at 4/mm",
       PresetScale::kHu,
       4.0f,
       1.5f,
       {{220, 0, kBlood, 0, 0.4f},
        {328, 0.0375f, kBlood, 0.3f, 0.3f},
        {550, 0.0375f, kBlood, 0.3f, 0.3f},
        {551, 0.3f, kBone, 0.2f, 0.4f},
        {650, 1, kBone, 0.2f, 0.4f},
        {2000, 1, kBone, 0.2f, 0.4f}},
       ContrastRule::kOnBloodPool},
      // Slicer's band starts at -599 HU; on 1.5-3 mm CT, where the lung's
      // boundaries are smeared, that let half the rays through a lung
      // unstopped, so it starts at -749 (docs/presets-sources.md).
      FromSlicer("ct-lung", "Lungs and airways through a translucent body: lung surfaces, vessels and bronchi",
                 "3D Slicer presets.xml 'CT-Lung' (Slicer licence, BSD-style): a band at opacity 0.15 per mm "
                 "(0.16/mm), from -749 HU rather than -599, to -400; nothing else",
                 PresetScale::kHu,
                 {{-750, 0, {0.113f, 0.113f, 1}},
                  {-749, 0.15f, {0.112f, 0.112f, 1}},
                  {-600, 0.15f, {0, 0, 1}},
                  {-530, 0.15f, {0.135f, 0.782f, 0.072f}},
                  {-460, 0.15f, {0.929f, 1, 0.109f}},
                  {-400, 0.15f, {0.889f, 0.255f, 0.024f}},
                  {-399, 0, {0.889f, 0.255f, 0.024f}}},
                 0.0f, kRoughPower1),
      {"mr-default",
       "MR of any weighting: the outer surface, softly, in grey",
       "cinevol: the first table's mr-default ramp, moved onto the automatic window",
       PresetScale::kWindow,
       1.0f,
       1.0f,
       {{0.0f, 0, kGrey, 0, 0.6f},
        {0.1f, 0.03f, kGrey, 0.05f, 0.6f},
        {0.3f, 0.25f, kGrey, 0.08f, 0.55f},
        {0.5f, 0.5f, kGrey, 0.1f, 0.5f},
        {1.0f, 0.9f, kGrey, 0.1f, 0.5f}}},

      // --- 3D Slicer's presets (presets.xml): opacity and colour points
      // merged, Slicer's opacity per mm as extinction; values in HU unless
      // kWindow. ---
      FromSlicer("ct-aaa", "Abdominal aortic aneurysm: contrast-filled aorta and bone, soft tissue hidden",
                 "3D Slicer presets.xml 'CT-AAA' (Slicer licence, BSD-style): control points merged, "
                 "points below 143.6 HU dropped",
                 PresetScale::kHu,
                 {{143.556f, 0, {0.616f, 0.357f, 0.184f}},
                  {166.222f, 0.686f, kSlicerOrange},
                  {214.389f, 0.696f, {1, 1, 1}},
                  {419.736f, 0.833f, kSlicerPink},
                  {3071, 0.804f, kSlicerLavender}},
                 0.2f, kRoughPower10),
      FromSlicer("ct-cardiac", "Heart: myocardium in tan, contrast-filled chambers and vessels in red",
                 "3D Slicer presets.xml 'CT-Cardiac' (Slicer licence, BSD-style): control points merged, "
                 "points below -77.7 HU dropped",
                 PresetScale::kHu,
                 {{-77.6875f, 0, kSlicerBrown},
                  {94.9518f, 0.286f, kSlicerOrange},
                  {179.052f, 0.554f, kSlicerPink},
                  {260.439f, 0.848f, {0.616f, 0, 0}},
                  {3071, 0.875f, kSlicerLavender}},
                 0.2f, kRoughPower10),
      FromSlicer("ct-coronary",
                 "Coronary arteries: contrast-filled vessels red to orange, calcium and bone white",
                 "3D Slicer presets.xml 'CT-Coronary-Arteries-3' (Slicer licence, BSD-style): control "
                 "points merged, points below 128.6 HU dropped",
                 PresetScale::kHu,
                 {{128.643f, 0, {0, 0, 0}},
                  {129.982f, 0.098f, {0.616f, 0, 0.016f}},
                  {173.636f, 0.670f, {0.910f, 0.455f, 0}},
                  {255.884f, 0.857f, {0.886f, 0.886f, 0.886f}},
                  {584.878f, 0.866f, {0.969f, 0.969f, 0.969f}},
                  {3661, 1, {1, 1, 1}}},
                 0.2f, kRoughPower10),
      FromSlicer("ct-chest-contrast", "Contrast-enhanced chest: heart, great vessels and bone; lungs hidden",
                 "3D Slicer presets.xml 'CT-Chest-Contrast-Enhanced' (Slicer licence, BSD-style): control "
                 "points merged, points below 67 HU dropped",
                 PresetScale::kHu,
                 {{67.0106f, 0, kSlicerBrown},
                  {251.105f, 0.446f, kSlicerOrange},
                  {439.291f, 0.625f, kSlicerPink},
                  {3071, 0.616f, kSlicerLavender}},
                 0.2f, kRoughPower10),
      FromSlicer("ct-pulmonary-arteries",
                 "Pulmonary arteries: lung vessels brown to red, soft tissue red, bone grey (crop to the "
                 "lungs)",
                 "3D Slicer presets.xml 'CT-Pulmonary-Arteries' (Slicer licence, BSD-style): control points "
                 "merged, points below -568.6 HU dropped",
                 PresetScale::kHu,
                 {{-568.625f, 0, {0, 0, 0}},
                  {-364.081f, 0.071f, {0.396f, 0.302f, 0.180f}},
                  {-244.813f, 0.402f, {0.612f, 0.353f, 0.071f}},
                  {18.2775f, 0.607f, {0.843f, 0.016f, 0.157f}},
                  {447.798f, 0.830f, {0.753f, 0.753f, 0.753f}},
                  {3592.73f, 0.839f, {1, 1, 1}}},
                 0.0f, kRoughPower1),
      FromSlicer("ct-muscle", "Muscles in brown to tan under the skin, bone white",
                 "3D Slicer presets.xml 'CT-Muscle' (Slicer licence, BSD-style): control points merged, "
                 "points below -155.4 HU dropped",
                 PresetScale::kHu,
                 {{-155.407f, 0, kSlicerBrown},
                  {217.641f, 0.676f, kSlicerOrange},
                  {419.736f, 0.833f, kSlicerPink},
                  {3071, 0.804f, kSlicerLavender}},
                 0.2f, kRoughPower10),
      // Emission-dominated: a path tracer cannot take a maximum along a ray,
      // so dense voxels glow (emission following Slicer's grey ramp,
      // -637.6..700 HU) and opacity rises steeply with density so that bone
      // and contrast outweigh the soft tissue in front of them.
      {"ct-mip",
       "Approximates a maximum-intensity projection / X-ray look: dense structures glow white",
       "3D Slicer presets.xml 'CT-MIP' (Slicer licence, BSD-style): its window -637.6..700 HU "
       "gives "
       "the emission; opacity and density_scale 0.2/mm are cinevol's, as no MIP exists here",
       PresetScale::kHu,
       0.2f,
       0.0f,
       {{-637.62f, 0, {0.05f, 0.05f, 0.05f}, 0, 0.7f, {0, 0, 0}},
        {0, 0.01f, {0.05f, 0.05f, 0.05f}, 0, 0.7f, {0.477f, 0.477f, 0.477f}},
        {300, 0.15f, {0.05f, 0.05f, 0.05f}, 0, 0.7f, {0.701f, 0.701f, 0.701f}},
        {700, 0.3f, {0.05f, 0.05f, 0.05f}, 0, 0.7f, {1, 1, 1}},
        {1500, 1, {0.05f, 0.05f, 0.05f}, 0, 0.7f, {1, 1, 1}},
        {3071, 1, {0.05f, 0.05f, 0.05f}, 0, 0.7f, {1, 1, 1}}}},
      FromSlicer("mr-angio", "MR angiography (time of flight): bright vessels orange to white",
                 "3D Slicer presets.xml 'MR-Angio' (Slicer licence, BSD-style): control points merged, "
                 "intensities divided by a reference maximum of 255, cut at 1",
                 PresetScale::kWindow,
                 {{0.5935f, 0, {0, 0, 0}},
                  {0.6207f, 0.438f, {0.749f, 0.376f, 0}},
                  {0.7455f, 0.580f, {1, 0.867f, 0.733f}},
                  {0.7877f, 0.732f, {0.937f, 0.937f, 0.937f}},
                  {1.0f, 0.732f, {0.938f, 0.938f, 0.938f}}},
                 0.0f, kRoughPower1),
      FromSlicer("mr-t2-brain",
                 "T2 brain: translucent yellow tissue, bright fluid (CSF) opaque blue to white",
                 "3D Slicer presets.xml 'MR-T2-Brain' (Slicer licence, BSD-style): control points merged, "
                 "intensities divided by a reference maximum of 641 (its last point)",
                 PresetScale::kWindow,
                 {{0.0562f, 0, {0.349f, 0.306f, 0.070f}},
                  {0.154f, 0.059f, {0.957f, 0.839f, 0.192f}},
                  {0.3406f, 0.171f, {0.592f, 0.745f, 0.427f}},
                  {0.6434f, 1, {0, 0.592f, 0.808f}},
                  {1.0f, 1, {1, 1, 1}}},
                 0.5f, kRoughPower40),
      // As ct-mip: emission follows Slicer's ramp, opacity rises steeply.
      {"mr-mip",
       "Approximates a maximum-intensity projection of MR (e.g. angiography): bright voxels glow",
       "3D Slicer presets.xml 'MR-MIP' (Slicer licence, BSD-style): its window 98.4..416.6 divided "
       "by a reference maximum of 416.6 gives the emission; opacity and density_scale 0.2/mm are "
       "cinevol's",
       PresetScale::kWindow,
       0.2f,
       0.0f,
       {{0.0f, 0, {0.05f, 0.05f, 0.05f}, 0, 0.7f, {0, 0, 0}},
        {0.236f, 0.002f, {0.05f, 0.05f, 0.05f}, 0, 0.7f, {0, 0, 0}},
        {0.5f, 0.01f, {0.05f, 0.05f, 0.05f}, 0, 0.7f, {0.346f, 0.346f, 0.346f}},
        {0.75f, 0.08f, {0.05f, 0.05f, 0.05f}, 0, 0.7f, {0.673f, 0.673f, 0.673f}},
        {1.0f, 1, {0.05f, 0.05f, 0.05f}, 0, 0.7f, {1, 1, 1}}}},

      // --- Defaults by volume kind for data without absolute units. ---
      {"ct-auto",
       "CT not in HU: translucent skin and flesh, opaque bone above 0.6 of the window",
       "cinevol; HU -450..1800 (air/tissue threshold to dense bone) mapped onto the window",
       PresetScale::kWindow,
       1.5f,
       1.5f,
       {{0.03f, 0, kFat, 0, 0.6f},
        {0.1f, 0.01f, kFat, 0.05f, 0.6f},
        {0.2f, 0.04f, kSkin, 0.1f, 0.5f},
        {0.35f, 0.06f, kMuscle, 0.1f, 0.5f},
        {0.5f, 0.3f, kBone, 0.15f, 0.45f},
        {0.6f, 0.85f, kBone, 0.2f, 0.4f},
        {1.0f, 1, kBone, 0.2f, 0.4f}}},
      // A micro-CT's subject is soft tissue with a skeleton far brighter
      // than it: the soft tissue is a faint haze (optical depth about 1
      // across 500 voxels) and the dense phase opaque. Data with no such
      // phase gets an opaque surface just above its background.
      {"auto",
       "Other data (micro-CT, industrial): a skeleton or dense phase opaque through faint soft tissue, "
       "else neutral opaque surfaces just above the background",
       "cinevol",
       PresetScale::kPhases,
       2.0f,
       2.0f,
       {{0.0f, 0, {0.75f, 0.75f, 0.73f}, 0, 0.5f},
        {0.5f, 0.0005f, {0.80f, 0.62f, 0.55f}, 0, 0.5f},
        {1.0f, 0.001f, {0.80f, 0.62f, 0.55f}, 0, 0.5f},
        {1.1f, 0.6f, {0.88f, 0.86f, 0.82f}, 0.12f, 0.5f},
        {1.4f, 0.9f, {0.9f, 0.88f, 0.85f}, 0.15f, 0.45f},
        {2.0f, 1, {0.92f, 0.92f, 0.9f}, 0.15f, 0.4f}}},
  };
  return library;
}

}  // namespace cinevol
