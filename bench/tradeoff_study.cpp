// The study: scenarios, references, the run of every configuration, results.
#include "tradeoff_study.h"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <map>
#include <sstream>
#include <stdexcept>

#include "core/error.h"
#include "core/tone_map.h"
#include "core/ycc.h"
#include "encode/hdr_images.h"
#include "encode/image_codecs.h"
#include "image_metrics.h"
#include "io/volume_loader.h"
#include "scene/presets.h"
#include "scene/scene_builder.h"
#include "scene/scene_file.h"

namespace cinevol::bench {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

double MsSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

// --- Scenarios ----------------------------------------------------------------

// What the renderer shows at one frame of a scenario.
struct ScenarioFrame {
  Camera camera;
  const TransferFunction* tf = nullptr;
  const LightSetup* lights = nullptr;
  int phase = 0;  // of a time series
};

struct Scenario {
  std::string name;
  int frames = 0;
  std::vector<TransferFunction> tfs;  // one, or one per frame
  std::vector<LightSetup> lights;     // one, or one per frame
  std::function<Camera(int)> camera;
  std::function<int(int)> phase = [](int) { return 0; };
  // The view holds still between frames: no camera bit, so the denoiser
  // hears of a change only where the scenario makes one (a phase switch).
  bool still_view = false;

  ScenarioFrame At(int t) const {
    return {camera(t), &tfs[std::min<std::size_t>(t, tfs.size() - 1)],
            &lights[std::min<std::size_t>(t, lights.size() - 1)], phase(t)};
  }
};

// A time series played with the view still (a beating heart): the phase
// steps every kFramesPerPhase frames and loops. At 720p on an H200 a 20-phase
// cine plays at about 430 frames/s with 30 phases a second, 14 frames a
// phase (docs/performance.md); 4 is the harder case of a slower device.
constexpr int kFramesPerPhase = 4;

// `v` turned by `degrees` about the unit `axis`.
Vec3f Rotate(Vec3f v, Vec3f axis, float degrees) {
  const float a = degrees * kPi / 180.0f, c = std::cos(a), s = std::sin(a);
  return v * c + Cross(axis, v) * s + axis * (Dot(axis, v) * (1 - c));
}

float VolumeRadius(const Volume& volume) { return 0.5f * Length(volume.extent_mm()); }

// An area key light above and beside the view, as the presets place it.
Light KeyLight(const Volume& volume) {
  const v1::Scene preset = MakePresetScene("ct-bone", volume);
  return ResolveLights(preset.lights()).lights.front();
}

EnvironmentSetup SceneEnvironment(const RenderSetup& base, const Volume& volume) {
  if (base.lights.environment.kind != Environment::Kind::kNone) return base.lights.environment;
  return ResolveLights(MakePresetScene("ct-bone", volume).lights()).environment;
}

// Several thin semi-transparent shells at values spread over the volume's range.
TransferFunction TransparentShells(const Volume& volume) {
  const float lo = volume.min_value(), range = std::max(volume.max_value() - volume.min_value(), 1e-3f);
  const Vec3f colours[] = {{0.9f, 0.5f, 0.4f}, {0.5f, 0.8f, 0.5f}, {0.5f, 0.6f, 0.95f}, {0.95f, 0.9f, 0.6f}};
  TransferFunction tf;
  tf.points.push_back({lo, 0, colours[0], {}, 0.5f, {}});
  for (int i = 0; i < 4; ++i) {
    const float centre = lo + range * (0.3f + 0.15f * i), half = 0.02f * range;
    tf.points.push_back({centre - half, 0, colours[i], {}, 0.5f, {}});
    tf.points.push_back({centre, 0.12f, colours[i], {0.05f, 0.05f, 0.05f}, 0.4f, {}});
    tf.points.push_back({centre + half, 0, colours[i], {}, 0.5f, {}});
  }
  tf.points.push_back({lo + range, 0, colours[3], {}, 0.5f, {}});
  tf.density_scale = 0.5f;
  tf.gradient_factor = 0.5f;
  return tf;
}

// The lighting an MR head was reported under (issue 38), as examples/mr-head.json
// sets it: a lateral view (from the patient's left), a directional light of
// intensity 3 and a uniform sky of 0.4; the camera orbits 1 degree a frame.
Scenario SunSky(v1::Scene scene, const Volume& volume, int frames) {
  scene.mutable_camera()->Clear();
  scene.mutable_camera()->set_view(v1::LEFT);
  scene.mutable_camera()->set_fov_y_deg(30);
  scene.clear_lights();
  v1::DirectionalLight& sun = *scene.add_lights()->mutable_directional();
  sun.mutable_direction()->set_x(0.5f);
  sun.mutable_direction()->set_y(0.6f);
  sun.mutable_direction()->set_z(-0.6f);
  sun.mutable_color()->set_r(1);
  sun.mutable_color()->set_g(0.97f);
  sun.mutable_color()->set_b(0.92f);
  sun.set_intensity(3);
  v1::EnvironmentLight& sky = *scene.add_lights()->mutable_environment();
  sky.mutable_uniform()->set_r(0.4f);
  sky.mutable_uniform()->set_g(0.4f);
  sky.mutable_uniform()->set_b(0.42f);
  sky.set_intensity(1);
  const RenderSetup lit = ResolveScene(scene, volume);
  return {"sun-sky", frames, {lit.transfer_function}, {lit.lights}, [camera = lit.camera](int t) {
            return Orbit(camera, 1.0f * t);
          }};
}

std::vector<Scenario> MakeScenarios(const v1::Scene& scene, const RenderSetup& base, const Volume& volume, int phases,
                                    float frames_scale) {
  auto frames = [&](int n) { return std::max(3, static_cast<int>(std::lround(n * frames_scale))); };
  const Camera camera = base.camera;
  const Vec3f centre = camera.eye + camera.forward * camera.focal_distance;
  std::vector<Scenario> s;

  s.push_back({"orbit", frames(30), {base.transfer_function}, {base.lights}, [camera](int t) {
                 return Orbit(camera, 1.0f * t);
               }});

  // A rectangular key light circling the volume, the scene's environment as fill.
  Scenario area{"area-light", frames(30), {base.transfer_function}, {}, [camera](int) { return camera; }};
  const Light key = KeyLight(volume);
  for (int t = 0; t < area.frames; ++t) {
    LightSetup l;
    l.environment = SceneEnvironment(base, volume);
    Light k = key;
    const float degrees = 6.0f * t;
    k.position = centre + Rotate(key.position - centre, camera.up, degrees);
    k.edge_u = Rotate(key.edge_u, camera.up, degrees);
    k.edge_v = Rotate(key.edge_v, camera.up, degrees);
    k.normal = Rotate(key.normal, camera.up, degrees);
    l.lights.push_back(k);
    area.lights.push_back(l);
  }
  s.push_back(area);

  // A point light circling in the dark.
  Scenario point{"point-light", frames(30), {base.transfer_function}, {}, [camera](int) { return camera; }};
  const float radius = 1.3f * VolumeRadius(volume);
  const Vec3f start = Normalize(camera.right * -1.0f + camera.up * 0.5f - camera.forward) * radius;
  for (int t = 0; t < point.frames; ++t) {
    LightSetup l;
    Light p;
    p.kind = LightKind::kPoint;
    p.position = centre + Rotate(start, camera.up, 6.0f * t);
    p.emitted = Vec3f{1, 0.95f, 0.9f} * (2.5f * radius * radius);  // irradiance ~2.5 at the centre
    l.lights.push_back(p);
    point.lights.push_back(l);
  }
  s.push_back(point);

  // The opacity window sweeping over 40 frames: every point moves by 10% of the range.
  Scenario tf_edit{"tf-edit", frames(40), {}, {base.lights}, [camera](int) { return camera; }};
  const float shift = 0.1f * std::max(volume.max_value() - volume.min_value(), 1e-3f);
  for (int t = 0; t < tf_edit.frames; ++t) {
    TransferFunction tf = base.transfer_function;
    const float offset = shift * (float(t) / float(std::max(tf_edit.frames - 1, 1)) - 0.5f);
    for (auto& p : tf.points) p.value += offset;
    tf_edit.tfs.push_back(tf);
  }
  s.push_back(tf_edit);

  s.push_back({"static", frames(60), {base.transfer_function}, {base.lights}, [camera](int) { return camera; }});
  s.push_back({"transparent", frames(30), {TransparentShells(volume)}, {base.lights}, [camera](int t) {
                 return Orbit(camera, 0.5f * t);
               }});
  s.push_back(SunSky(scene, volume, frames(30)));
  if (phases > 1) {
    Scenario beat{"beat", frames(40), {base.transfer_function}, {base.lights}, [camera](int) { return camera; }};
    beat.phase = [phases](int t) { return (t / kFramesPerPhase) % phases; };
    beat.still_view = true;
    s.push_back(beat);
  }
  return s;
}

// --- References -----------------------------------------------------------------

std::uint64_t Fnv1a(const std::string& text) {
  std::uint64_t h = 1469598103934665603ull;
  for (unsigned char c : text) h = (h ^ c) * 1099511628211ull;
  return h;
}

// Everything a reference frame depends on, hashed.
std::string ReferenceKey(const Dataset& d, const std::string& scene_json, const std::string& scenario, int frame,
                         int frames, int bounces, const StudyOptions& o) {
  const std::string text =
      fmt::format("{}|{}|{}|{}|{}/{}|{}x{}|{}spp|{}bounces|renderer {}|seeds per chunk, two halves", d.name, d.volume,
                  scene_json, scenario, frame, frames, o.width, o.height, o.reference_spp, bounces, kRendererVersion);
  return fmt::format("{}-{}-{:03}-{:016x}", d.name, scenario, frame, Fnv1a(text));
}

// Copies the frame's transfer function and lights into `setup` where they
// are not the previous frame's; returns the SceneChange bits that says.
unsigned ApplyFrame(const ScenarioFrame& f, RenderSetup& setup, const TransferFunction*& tf,
                    const LightSetup*& lights) {
  unsigned changes = 0;
  if (f.tf != tf) {
    setup.transfer_function = *(tf = f.tf);
    changes |= kTransferFunctionChanged;
  }
  if (f.lights != lights) {
    setup.lights = *(lights = f.lights);
    changes |= kLightsChanged;
  }
  return changes;
}

// --- One configuration over one scenario -------------------------------------------

ImageRgb8 Upsample(const ImageRgb8& image, int width, int height) {
  if (image.width == width && image.height == height) return image;
  ImageRgb8 out{width, height, std::vector<std::uint8_t>(std::size_t(width) * height * 3)};
  for (int y = 0; y < height; ++y) {
    const float sy = std::clamp((y + 0.5f) * image.height / height - 0.5f, 0.0f, float(image.height - 1));
    const int y0 = int(sy), y1 = std::min(y0 + 1, image.height - 1);
    const float fy = sy - y0;
    for (int x = 0; x < width; ++x) {
      const float sx = std::clamp((x + 0.5f) * image.width / width - 0.5f, 0.0f, float(image.width - 1));
      const int x0 = int(sx), x1 = std::min(x0 + 1, image.width - 1);
      const float fx = sx - x0;
      for (int c = 0; c < 3; ++c) {
        auto at = [&](int xx, int yy) { return float(image.bytes[(std::size_t(yy) * image.width + xx) * 3 + c]); };
        const float v =
            (at(x0, y0) * (1 - fx) + at(x1, y0) * fx) * (1 - fy) + (at(x0, y1) * (1 - fx) + at(x1, y1) * fx) * fy;
        out.bytes[(std::size_t(y) * width + x) * 3 + c] = std::uint8_t(std::lround(v));
      }
    }
  }
  return out;
}

ImageRgbF UpsampleHdr(const ImageRgbF& image, int width, int height) {
  if (image.width == width && image.height == height) return image;
  ImageRgbF out{width, height, std::vector<Vec3f>(std::size_t(width) * height)};
  for (int y = 0; y < height; ++y) {
    const int sy = std::min(image.height - 1, y * image.height / height);
    for (int x = 0; x < width; ++x) {
      out.pixels[std::size_t(y) * width + x] =
          image.pixels[std::size_t(sy) * image.width + std::min(image.width - 1, x * image.width / width)];
    }
  }
  return out;
}

// Half size (2x2 means) for the illustration images.
ImageRgb8 Half(const ImageRgb8& image) {
  const int w = std::max(1, image.width / 2), h = std::max(1, image.height / 2);
  ImageRgb8 out{w, h, std::vector<std::uint8_t>(std::size_t(w) * h * 3)};
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      for (int c = 0; c < 3; ++c) {
        int sum = 0;
        for (int dy = 0; dy < 2; ++dy) {
          for (int dx = 0; dx < 2; ++dx) {
            const int sx = std::min(2 * x + dx, image.width - 1), sy = std::min(2 * y + dy, image.height - 1);
            sum += image.bytes[(std::size_t(sy) * image.width + sx) * 3 + c];
          }
        }
        out.bytes[(std::size_t(y) * w + x) * 3 + c] = std::uint8_t((sum + 2) / 4);
      }
    }
  }
  return out;
}

struct References {
  std::vector<ImageRgbF> hdr;
  std::vector<ImageRgb8> display;
  std::vector<double> noise;  // ReferenceNoise of each frame's display
};

struct Context {
  const StudyOptions& o;
  Backend backend;                                    // resolved: every pipeline of the study on the same device
  std::vector<std::shared_ptr<const Volume>> phases;  // the volume: a time series' phases, or one
  float exposure = 0;
  const std::shared_ptr<const Volume>& PhaseVolume(int phase = 0) const { return phases[std::size_t(phase)]; }
};

// What the viewer sees of `frame`: through JPEG where `jpeg_quality` is set
// (its time in `encode_ms`), at the study's size.
ImageRgb8 Shown(const Context& ctx, const DisplayFrame& frame, int jpeg_quality, double* encode_ms) {
  ImageRgb8 shown;
  if (jpeg_quality > 0) {
    const Clock::time_point encode_start = Clock::now();
    const std::vector<std::uint8_t> jpeg = EncodeJpeg(frame.image, jpeg_quality);
    *encode_ms = MsSince(encode_start);
    shown = DecodeJpeg(jpeg);
  } else {
    shown = ToRgb(frame.image);
  }
  return Upsample(shown, ctx.o.width, ctx.o.height);
}

// Flicker on a still view, as `cinevol-bench denoise` measures it: the
// scenario's first frame held while a fresh pipeline renders it again and
// again; the mean RMS change between consecutive displayed frames after the
// first kFlickerWarmup, and between their display values before 8-bit
// rounding; and the same frames' PSNR against `reference` (the first
// frame's): what a still view costs its accuracy.
constexpr int kFlickerFrames = 16, kFlickerWarmup = 8;
void MeasureStillFlicker(const Context& ctx, const ScenarioFrame& f, RenderSetup setup, const FrameSettings& settings,
                         int jpeg_quality, const ImageRgb8& reference, RunResult& run) {
  const int width = setup.camera.width, height = setup.camera.height;  // the configuration's scale
  setup.camera = f.camera;
  setup.camera.width = width;
  setup.camera.height = height;
  setup.transfer_function = *f.tf;
  setup.lights = *f.lights;
  FramePipeline pipeline(ctx.backend, ctx.PhaseVolume(f.phase));
  pipeline.Update(setup, settings);
  double encode_ms = 0;
  const double measured = kFlickerFrames - kFlickerWarmup - 1;
  ImageRgb8 previous;
  ImageRgbF previous_radiance;
  for (int t = 0; t < kFlickerFrames; ++t) {
    const ImageRgb8 shown = Shown(ctx, pipeline.RenderFrame(), jpeg_quality, &encode_ms);
    ImageRgbF radiance = pipeline.DenoisedRadiance();
    if (t > kFlickerWarmup) {
      run.flicker += RmsDifference(shown, previous) / measured;
      run.flicker_unrounded += DisplayRmsDifference(radiance, previous_radiance) / measured;
      run.still_psnr += Psnr(shown, reference) / measured;
    }
    previous = shown;
    previous_radiance = std::move(radiance);
  }
}

RunResult RunConfig(const Context& ctx, const Scenario& scenario, const References& refs, const StudyConfig& c,
                    const fs::path& images, int image_frame) {
  RunResult run;
  run.scenario = scenario.name;
  run.config = c;
  FrameSettings settings;
  settings.denoiser.method = c.method;
  settings.denoiser.demodulate = c.demodulate;
  settings.denoiser.wrls = c.wrls;
  settings.denoiser.svgf = c.svgf;
  settings.refine = false;  // every frame as it looks while interacting
  settings.hold_codes = c.hold_codes;
  settings.phase_history = c.phase_history;
  // Without JPEG, full chroma: the displayed pixels, give or take YCbCr rounding.
  settings.chroma = c.jpeg_quality > 0 ? ChromaSubsampling::k420 : ChromaSubsampling::k444;
  FramePipeline pipeline(ctx.backend, ctx.PhaseVolume());
  RenderSetup setup;
  setup.spp = c.spp;
  setup.max_bounces = c.bounces;
  setup.seed = 7;  // every configuration of the same spp, bounces and size sees the same noise
  setup.exposure = ctx.exposure;
  const int w = std::max(1, int(std::lround(ctx.o.width * c.scale))),
            h = std::max(1, int(std::lround(ctx.o.height * c.scale)));
  const TransferFunction* tf = nullptr;
  const LightSetup* lights = nullptr;
  ImageRgb8 previous;
  for (int t = 0; t < scenario.frames; ++t) {
    const ScenarioFrame f = scenario.At(t);
    // The camera bit every frame (each frame's accumulation starts afresh),
    // but where the view holds still.
    const unsigned changes = (scenario.still_view ? 0u : unsigned(kCameraChanged)) | ApplyFrame(f, setup, tf, lights);
    setup.camera = f.camera;
    setup.camera.width = w;
    setup.camera.height = h;
    pipeline.Update(setup, settings, changes);
    pipeline.SetPhase(ctx.PhaseVolume(f.phase));
    const DisplayFrame frame = pipeline.RenderFrame();
    FrameResult fr;
    fr.frame = t;
    fr.render_ms = frame.render_ms;
    fr.denoise_ms = frame.denoise_ms;
    fr.tonemap_ms = frame.display_ms;
    const ImageRgb8 shown = Shown(ctx, frame, c.jpeg_quality, &fr.encode_ms);
    fr.psnr = Psnr(shown, refs.display[t]);
    fr.psnr_corrected = CorrectedPsnr(shown, refs.display[t], refs.noise[t]);
    fr.ssim = Ssim(shown, refs.display[t]);
    fr.rel_mse = RelativeMse(UpsampleHdr(pipeline.DenoisedRadiance(), ctx.o.width, ctx.o.height), refs.hdr[t]);
    if (t > 0) fr.temporal = TemporalError(shown, previous, refs.display[t], refs.display[t - 1]);
    if (!images.empty() && t == image_frame) WriteFile(images, EncodeJpeg(Half(shown), 92));
    previous = shown;
    run.frames.push_back(fr);
  }
  MeasureStillFlicker(ctx, scenario.At(0), setup, settings, c.jpeg_quality, refs.display[0], run);
  return run;
}

// The wRLS settings a --variant can change, by key.
const std::map<std::string, float WrlsSettings::*> kWrlsFloatKeys = {
    {"alpha", &WrlsSettings::alpha},
    {"bandwidth", &WrlsSettings::bandwidth},
    {"lambda", &WrlsSettings::lambda},
    {"initial_p", &WrlsSettings::initial_p},
    {"sigma_luminance", &WrlsSettings::atrous_sigma_luminance},
    {"sigma_depth", &WrlsSettings::atrous_sigma_depth},
    {"residual_rate", &WrlsSettings::residual_rate},
    {"drift", &WrlsSettings::drift_sigma},
    {"young", &WrlsSettings::young_variance},
    {"young_surface", &WrlsSettings::young_variance_surface},
    {"rescale_sigma", &WrlsSettings::feature_rescale_sigma},
    {"firefly", &WrlsSettings::firefly_clamp},
    {"stabilize", &WrlsSettings::stabilize_history},
    {"stabilize_clamp", &WrlsSettings::stabilize_clamp},
    {"calibrate", &WrlsSettings::atrous_calibration_floor},
    {"calibrate_fall", &WrlsSettings::atrous_calibration_fall},
    {"normal_stop", &WrlsSettings::atrous_normal_stop},
    {"normal_share", &WrlsSettings::atrous_normal_share},
};
const std::map<std::string, int WrlsSettings::*> kWrlsIntKeys = {
    {"atrous", &WrlsSettings::atrous_iterations},    {"still", &WrlsSettings::max_still_frames},
    {"recenter", &WrlsSettings::stabilize_recenter}, {"stabilize_still", &WrlsSettings::stabilize_still_frames},
    {"rescale", &WrlsSettings::feature_rescale},
};

PhaseHistory ParsePhaseHistory(const std::string& spec, const std::string& text) {
  if (text == "changed") return PhaseHistory::kChanged;
  if (text == "reset") return PhaseHistory::kReset;
  if (text == "kept") return PhaseHistory::kKept;
  throw InputError(fmt::format("--variant {}: phase_history is changed, reset or kept", spec));
}

}  // namespace

// --- Public ------------------------------------------------------------------------

StudyConfig Variant(const std::string& spec) {
  StudyConfig c;
  const auto colon = spec.find(':');
  c.variant = spec.substr(0, colon);
  if (colon == std::string::npos) return c;
  std::vector<std::pair<std::string, std::string>> items;
  std::istringstream list(spec.substr(colon + 1));
  for (std::string item; std::getline(list, item, ',');) {
    const auto eq = item.find('=');
    if (eq == std::string::npos) throw InputError(fmt::format("--variant {}: '{}' is not key=value", spec, item));
    items.emplace_back(item.substr(0, eq), item.substr(eq + 1));
    if (items.back().first == "method") c.method = ParseDenoiseMethod(items.back().second);
  }
  if (c.method != DenoiseMethod::kWrls && c.method != DenoiseMethod::kSvgf) {
    throw InputError(fmt::format("--variant {}: only wrls and svgf take variants", spec));
  }
  for (const auto& [key, text] : items) {
    if (key == "method") continue;
    if (key == "phase_history") {
      c.phase_history = ParsePhaseHistory(spec, text);
      continue;
    }
    char* end = nullptr;
    const float v = std::strtof(text.c_str(), &end);
    if (text.empty() || *end != '\0' || !std::isfinite(v)) {
      throw InputError(fmt::format("--variant {}: {}={} is not a finite number", spec, key, text));
    }
    if (key == "spp") {
      if (!(v >= 1.0f && v <= 1024.0f)) throw InputError(fmt::format("--variant {}: spp must be 1 to 1024", spec));
      c.spp = int(v);
    } else if (key == "hold") {
      if (v != 0.0f && v != 1.0f) throw InputError(fmt::format("--variant {}: hold is 0 or 1", spec));
      c.hold_codes = v != 0.0f;
    } else if (key == "squared") {
      if (v != 0.0f && v != 1.0f) throw InputError(fmt::format("--variant {}: squared is 0 or 1", spec));
      c.svgf.squared_luminance = c.wrls.atrous_squared_luminance = v != 0.0f;
    } else if (key == "recenter_unmoved") {
      if (v != 0.0f && v != 1.0f) throw InputError(fmt::format("--variant {}: recenter_unmoved is 0 or 1", spec));
      c.wrls.stabilize_recenter_unmoved = v != 0.0f;
    } else if (c.method == DenoiseMethod::kSvgf) {
      if (key == "sigma_luminance")
        c.svgf.sigma_luminance = v;
      else if (key == "sigma_depth")
        c.svgf.sigma_depth = v;
      else if (key == "normal_stop")
        c.svgf.normal_stop = v;
      else
        throw InputError(fmt::format("--variant {}: unknown SVGF key '{}'", spec, key));
    } else if (auto f = kWrlsFloatKeys.find(key); f != kWrlsFloatKeys.end()) {
      c.wrls.*(f->second) = v;
    } else if (auto n = kWrlsIntKeys.find(key); n != kWrlsIntKeys.end()) {
      // A float beyond int's range would not convert (undefined): refused.
      if (!(std::fabs(v) <= 1e6f))
        throw InputError(fmt::format("--variant {}: {}={} is out of range", spec, key, text));
      c.wrls.*(n->second) = int(v);
    } else {
      throw InputError(fmt::format("--variant {}: unknown key '{}'", spec, key));
    }
  }
  // 0 turned these stages off until the study settled them (docs/denoising.md).
  const WrlsSettings& w = c.wrls;
  if (w.feature_rescale < 1 || w.feature_rescale > 8 || w.stabilize_recenter < 1 || w.stabilize_recenter > 8 ||
      !(w.drift_sigma > 0) || w.stabilize_still_frames < 0 || w.atrous_iterations < 0 || w.atrous_iterations > 8 ||
      !(w.atrous_normal_stop >= 0 && w.atrous_normal_stop <= kMaxNormalStop) ||
      !(c.svgf.normal_stop >= 0 && c.svgf.normal_stop <= kMaxNormalStop) ||
      !(w.atrous_normal_share > 0 && w.atrous_normal_share <= 1)) {
    throw InputError(
        fmt::format("--variant {}: rescale and recenter take 1 to 8, atrous 0 to 8, drift more than 0, "
                    "stabilize_still 0 or more, normal_stop 0 to {}, normal_share above 0 to 1",
                    spec, kMaxNormalStop));
  }
  return c;
}

std::string StudyConfig::Label() const {
  std::string label = ToString(method);
  if (!variant.empty()) label += "[" + variant + "]";
  if (demodulate) label += "+demod";
  if (knob == "spp") label += fmt::format(" {}spp", spp);
  if (knob == "bounces") label += fmt::format(" {}bounces", bounces);
  if (knob == "jpeg") label += fmt::format(" jpeg{}", jpeg_quality);
  if (knob == "scale") label += fmt::format(" x{}", scale);
  return label;
}

std::vector<StudyConfig> StudyConfigs(bool quick) {
  std::vector<StudyConfig> configs;
  const DenoiseMethod all[] = {DenoiseMethod::kNone,         DenoiseMethod::kAccumulate, DenoiseMethod::kKnn,
                               DenoiseMethod::kGuidedFilter, DenoiseMethod::kSvgf,       DenoiseMethod::kWrls};
  for (DenoiseMethod m : all) {
    if (quick && m != DenoiseMethod::kNone && m != DenoiseMethod::kSvgf && m != DenoiseMethod::kWrls) continue;
    for (bool demodulate : {false, true}) {
      if (demodulate && (quick || m == DenoiseMethod::kNone)) continue;
      StudyConfig c;
      c.method = m;
      c.demodulate = demodulate;
      configs.push_back(c);
    }
  }
  auto sweep = [&](const std::string& knob, const std::vector<float>& values, auto set) {
    for (float v : values) {
      StudyConfig c;
      c.knob = knob;
      set(c, v);
      configs.push_back(c);
    }
  };
  sweep("spp", quick ? std::vector<float>{1, 4} : std::vector<float>{1, 4, 8},
        [](StudyConfig& c, float v) { c.spp = int(v); });
  // With 4 (the baseline's): the sweep is measured against longer paths.
  if (!quick) sweep("bounces", {1, 2, 4, 8}, [](StudyConfig& c, float v) { c.bounces = int(v); });
  sweep("jpeg", quick ? std::vector<float>{75} : std::vector<float>{50, 75, 90},
        [](StudyConfig& c, float v) { c.jpeg_quality = int(v); });
  sweep("scale", quick ? std::vector<float>{0.5f} : std::vector<float>{0.125f, 0.25f, 0.375f, 0.5f, 0.75f},
        [](StudyConfig& c, float v) { c.scale = v; });
  return configs;
}

std::vector<std::string> ScenarioNames() {
  return {"orbit", "area-light", "point-light", "tf-edit", "static", "transparent", "sun-sky", "beat"};
}

double RunResult::Mean(double FrameResult::*field) const {
  double sum = 0;
  int n = 0;
  for (const FrameResult& f : frames) {
    if (field == &FrameResult::temporal && f.frame == 0) continue;
    sum += f.*field;
    ++n;
  }
  return n ? sum / n : NAN;
}

double RunResult::MeanMs() const {
  return Mean(&FrameResult::render_ms) + Mean(&FrameResult::denoise_ms) + Mean(&FrameResult::tonemap_ms) +
         Mean(&FrameResult::encode_ms);
}

namespace {

std::string Slug(std::string s) {
  for (char& c : s) {
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '-' && c != '.') c = '_';
  }
  return s;
}

// Whether two frames show the same: camera, transfer function, lights and
// phase. Since the references share their seeds, such frames' references
// are one image.
bool SameView(const ScenarioFrame& a, const ScenarioFrame& b) {
  const Camera &p = a.camera, &q = b.camera;
  return a.tf == b.tf && a.lights == b.lights && a.phase == b.phase && p.eye == q.eye && p.forward == q.forward &&
         p.right == q.right && p.up == q.up && p.tan_half_fov_y == q.tan_half_fov_y && p.lens_radius == q.lens_radius &&
         p.focal_distance == q.focal_distance;
}

// Frame t's reference, as its two halves: from the cache, else rendered and
// cached (one EXR a half).
ReferenceHalves LoadReference(const Context& ctx, const Dataset& d, const std::string& scene_json, const Scenario& s,
                              int t, const ScenarioFrame& f, int bounces) {
  const std::string key = ReferenceKey(d, scene_json, s.name, t, s.frames, bounces, ctx.o);
  const fs::path path_a = ctx.o.cache / (key + "-a.exr"), path_b = ctx.o.cache / (key + "-b.exr");
  ReferenceHalves halves = ReferenceHalves::Split(ctx.o.reference_spp);
  if (fs::exists(path_a) && (halves.b_spp == 0 || fs::exists(path_b))) {
    // A cached half of another size (a cache edited or written by other
    // code) would be compared pixel by pixel with frames it does not match.
    auto cached = [&](const fs::path& path) {
      ImageRgbF image = ReadExr(path);
      if (image.width != ctx.o.width || image.height != ctx.o.height) {
        throw InputError(fmt::format("cached reference {} is {}x{}, not the study's {}x{}: remove it", path.string(),
                                     image.width, image.height, ctx.o.width, ctx.o.height));
      }
      return image;
    };
    halves.a = cached(path_a);
    if (halves.b_spp > 0) halves.b = cached(path_b);
    return halves;
  }
  RenderSetup view;
  view.camera = f.camera;
  view.camera.width = ctx.o.width;
  view.camera.height = ctx.o.height;
  view.transfer_function = *f.tf;
  view.lights = *f.lights;
  halves = RenderReferenceHalves(ctx.backend, ctx.PhaseVolume(f.phase), view, ctx.o.reference_spp, bounces);
  WriteExr(path_a, halves.a);
  if (halves.b_spp > 0) WriteExr(path_b, halves.b);
  return halves;
}

References LoadReferences(const Context& ctx, const Dataset& d, const std::string& scene_json, const Scenario& s,
                          int bounces) {
  References refs;
  fs::create_directories(ctx.o.cache);
  ScenarioFrame previous;
  for (int t = 0; t < s.frames; ++t) {
    const ScenarioFrame f = s.At(t);
    if (t > 0 && SameView(f, previous)) {
      refs.hdr.push_back(refs.hdr.back());
      refs.display.push_back(refs.display.back());
      refs.noise.push_back(refs.noise.back());
    } else {
      const ReferenceHalves halves = LoadReference(ctx, d, scene_json, s, t, f, bounces);
      refs.hdr.push_back(halves.Mean());
      refs.display.push_back(ToneMap(refs.hdr.back(), ctx.exposure));
      refs.noise.push_back(ReferenceNoise(halves.a, halves.b, halves.a_spp, halves.b_spp, ctx.exposure));
    }
    previous = f;
  }
  return refs;
}

void WriteCsv(const fs::path& path, const std::vector<RunResult>& results) {
  std::ofstream out(path);
  out << "dataset,scenario,knob,config,method,demodulate,spp,bounces,jpeg_quality,scale,frame,psnr,ssim,rel_mse,"
         "temporal,render_ms,denoise_ms,tonemap_ms,encode_ms,psnr_corrected\n";
  for (const RunResult& r : results) {
    const StudyConfig& c = r.config;
    for (const FrameResult& f : r.frames) {
      out << fmt::format(
          "{},{},{},{},{},{},{},{},{},{},{},{:.4f},{:.5f},{:.6g},{:.6f},{:.4f},{:.4f},{:.4f},{:.4f},{:.4f}\n",
          r.dataset, r.scenario, c.knob, c.Label(), ToString(c.method), c.demodulate ? 1 : 0, c.spp, c.bounces,
          c.jpeg_quality, c.scale, f.frame, f.psnr, f.ssim, f.rel_mse, f.temporal, f.render_ms, f.denoise_ms,
          f.tonemap_ms, f.encode_ms, f.psnr_corrected);
    }
  }
}

void WriteJson(const fs::path& path, const StudyOptions& o, const std::string& device,
               const std::vector<RunResult>& results) {
  std::ofstream out(path);
  out << fmt::format(
      "{{\"command\": \"{}\", \"device\": \"{}\", \"width\": {}, \"height\": {}, \"reference_spp\": {}, "
      "\"reference_bounces\": {},\n \"runs\": [",
      o.command_line, device, o.width, o.height, o.reference_spp, o.reference_bounces);
  for (std::size_t i = 0; i < results.size(); ++i) {
    const RunResult& r = results[i];
    const StudyConfig& c = r.config;
    out << fmt::format(
        "{}\n  {{\"dataset\": \"{}\", \"scenario\": \"{}\", \"knob\": \"{}\", \"config\": \"{}\", \"method\": \"{}\", "
        "\"demodulate\": {}, \"spp\": {}, \"bounces\": {}, \"jpeg_quality\": {}, \"scale\": {}, \"frames\": {}, "
        "\"psnr\": {:.4f}, \"psnr_corrected\": {:.4f}, \"ssim\": {:.5f}, \"rel_mse\": {:.6g}, \"temporal\": {:.6f}, "
        "\"flicker\": {:.6f}, \"flicker_unrounded\": {:.6f}, \"still_psnr\": {:.4f}, \"ms\": {{\"render\": {:.4f}, "
        "\"denoise\": {:.4f}, \"tonemap\": {:.4f}, \"encode\": {:.4f}, \"total\": {:.4f}}}}}",
        i ? "," : "", r.dataset, r.scenario, c.knob, c.Label(), ToString(c.method), c.demodulate ? "true" : "false",
        c.spp, c.bounces, c.jpeg_quality, c.scale, r.frames.size(), r.Mean(&FrameResult::psnr),
        r.Mean(&FrameResult::psnr_corrected), r.Mean(&FrameResult::ssim), r.Mean(&FrameResult::rel_mse),
        r.Mean(&FrameResult::temporal), r.flicker, r.flicker_unrounded, r.still_psnr, r.Mean(&FrameResult::render_ms),
        r.Mean(&FrameResult::denoise_ms), r.Mean(&FrameResult::tonemap_ms), r.Mean(&FrameResult::encode_ms),
        r.MeanMs());
  }
  out << "]}\n";
}

}  // namespace

Camera Orbit(const Camera& c, float degrees) {
  const Vec3f target = c.eye + c.forward * c.focal_distance;
  Camera out = LookAt(target + Rotate(c.eye - target, c.up, degrees), target, c.up,
                      2.0f * std::atan(c.tan_half_fov_y) * 180.0f / kPi, c.width, c.height);
  out.lens_radius = c.lens_radius;
  return out;
}

ReferenceHalves ReferenceHalves::Split(int spp) {
  ReferenceHalves halves;
  halves.b_spp = spp / 2;
  halves.a_spp = spp - halves.b_spp;
  return halves;
}

ImageRgbF ReferenceHalves::Mean() const {
  if (b_spp == 0) return a;
  if (b.pixels.size() != a.pixels.size()) throw std::invalid_argument("reference halves differ in size");
  ImageRgbF mean = a;
  const float wa = float(a_spp) / float(a_spp + b_spp), wb = 1.0f - wa;
  for (std::size_t i = 0; i < mean.pixels.size(); ++i) mean.pixels[i] = a.pixels[i] * wa + b.pixels[i] * wb;
  return mean;
}

ReferenceHalves RenderReferenceHalves(Backend backend, std::shared_ptr<const Volume> volume, RenderSetup view, int spp,
                                      int bounces) {
  FrameSettings settings;
  settings.denoiser.method = DenoiseMethod::kNone;
  view.max_bounces = bounces;
  int chunk = 0;
  // `samples` in chunks of 64, each chunk its own seed, in one accumulation:
  // only the first update says what changed. The seeds do not depend on the
  // frame: the temporal error subtracts consecutive references, whose own
  // noise would otherwise be most of it on a still view (a still output
  // scored 93% of the denoisers' error at 320x180, against 64-spp
  // references). The second half's chunks take the next seeds.
  auto half = [&](int samples) {
    FramePipeline pipeline(backend, volume);  // its frames count the chunks from 0
    for (int done = 0, first = chunk; done < samples; done += 64, ++chunk) {
      view.seed = 1000003ull + chunk;
      pipeline.Update(view, settings, chunk == first ? kEverythingChanged : 0u);
      pipeline.Accumulate(std::min(64, samples - done));
    }
    return pipeline.AccumulatedRadiance();
  };
  ReferenceHalves halves = ReferenceHalves::Split(spp);
  halves.a = half(halves.a_spp);
  if (halves.b_spp > 0) halves.b = half(halves.b_spp);
  return halves;
}

ImageRgbF RenderReference(Backend backend, std::shared_ptr<const Volume> volume, RenderSetup view, int spp,
                          int bounces) {
  return RenderReferenceHalves(backend, std::move(volume), view, spp, bounces).Mean();
}

std::vector<RunResult> RunStudy(const StudyOptions& o) {
  Context ctx{o, Resolve(ParseBackend(o.backend), "study"), {}};
  std::string device;
  if (!CudaAvailable(&device) || ctx.backend != Backend::kCuda) device = "cpu";
  std::vector<RunResult> results;
  for (const Dataset& d : o.datasets) {
    // "preset:NAME" (NAME may be "default"): the scene a session gets for
    // that preset, lights and framing included, as a new user would see it.
    const bool preset = d.scene.rfind("preset:", 0) == 0;
    v1::Scene scene = preset ? v1::Scene{} : LoadSceneFile(d.scene);
    if (!d.volume.empty()) *scene.mutable_volume() = ParseVolumeSpec(d.volume);
    if (preset) {
      const Volume loaded = std::move(LoadVolumeSeries(scene.volume()).phases.front());
      const std::string name = d.scene.substr(7);
      const auto source = scene.volume();
      scene = MakePresetScene(name == "default" ? DefaultPreset(loaded) : name, loaded);
      *scene.mutable_volume() = source;
      ApplyDefaults(scene);
    }
    scene.mutable_render()->set_width(o.width);
    scene.mutable_render()->set_height(o.height);
    const std::string scene_json = SceneToJson(scene);
    VolumeSeries series = LoadVolumeSeries(scene.volume());
    ctx.phases.clear();
    for (Volume& phase : series.phases) ctx.phases.push_back(std::make_shared<const Volume>(std::move(phase)));
    const Volume& volume = *ctx.PhaseVolume();
    const RenderSetup setup = ResolveScene(scene, volume);
    ctx.exposure = setup.exposure;
    for (const Scenario& s : MakeScenarios(scene, setup, volume, int(ctx.phases.size()), o.frames_scale)) {
      if (!o.scenarios.empty() && std::find(o.scenarios.begin(), o.scenarios.end(), s.name) == o.scenarios.end()) {
        continue;
      }
      std::map<int, References> by_bounces;  // rendered or read when a configuration first needs them
      auto references = [&](int bounces) -> const References& {
        auto it = by_bounces.find(bounces);
        if (it != by_bounces.end()) return it->second;
        const Clock::time_point start = Clock::now();
        it = by_bounces.emplace(bounces, LoadReferences(ctx, d, scene_json, s, bounces)).first;
        std::fprintf(stderr, "%s/%s: %d frames, references at %d bounces in %.1f s\n", d.name.c_str(), s.name.c_str(),
                     s.frames, bounces, MsSince(start) / 1000);
        return it->second;
      };
      const int image_frame = s.frames / 2;
      fs::path images;
      if (!o.out.empty()) {
        images = o.out / "images" / d.name / s.name;
        fs::create_directories(images);
        const References& baseline = references(StudyConfig{}.bounces);
        WriteFile(images / "reference.jpg", EncodeJpeg(Half(baseline.display[image_frame]), 92));
      }
      for (const StudyConfig& c : o.configs) {
        const fs::path image =
            images.empty() || c.knob != "denoiser" ? fs::path() : images / (Slug(c.Label()) + ".jpg");
        // Each configuration against the converged image of what it renders;
        // the bounces sweep against the long paths it leaves out.
        const int bounces = c.knob == "bounces" ? o.reference_bounces : c.bounces;
        RunResult run = RunConfig(ctx, s, references(bounces), c, image, image_frame);
        run.dataset = d.name;
        std::fprintf(stderr,
                     "  %-22s PSNR %6.2f (%6.2f)  SSIM %.4f  temporal %.4f  flicker %.4f (%.4f; %.2f dB)  %7.2f ms\n",
                     c.Label().c_str(), run.Mean(&FrameResult::psnr), run.Mean(&FrameResult::psnr_corrected),
                     run.Mean(&FrameResult::ssim), run.Mean(&FrameResult::temporal), run.flicker, run.flicker_unrounded,
                     run.still_psnr, run.MeanMs());
        results.push_back(std::move(run));
      }
    }
  }
  if (!o.out.empty()) {
    fs::create_directories(o.out);
    WriteCsv(o.out / "tradeoff.csv", results);
    WriteJson(o.out / "tradeoff.json", o, device, results);
    std::ofstream(o.out / "tradeoff.md") << SummaryTable(results);
  }
  return results;
}

std::string SummaryTable(const std::vector<RunResult>& results) {
  std::string t;
  std::string current;
  for (const RunResult& r : results) {
    const std::string heading = r.dataset + " / " + r.scenario;
    if (heading != current) {
      current = heading;
      t += fmt::format(
          "\n#### {} ({} frames)\n\n| configuration | PSNR dB (corrected) | SSIM | relMSE | temporal error | "
          "still view: flicker; before rounding; PSNR dB | ms (render + denoise + tone map + encode) |\n"
          "|---|---|---|---|---|---|---|\n",
          heading, r.frames.size());
    }
    t += fmt::format(
        "| {} | {:.2f} ({:.2f}) | {:.4f} | {:.4g} | {:.4f} | {:.4f}; {:.4f}; {:.2f} | "
        "{:.2f} ({:.2f} + {:.2f} + {:.2f} + {:.2f}) |\n",
        r.config.Label(), r.Mean(&FrameResult::psnr), r.Mean(&FrameResult::psnr_corrected), r.Mean(&FrameResult::ssim),
        r.Mean(&FrameResult::rel_mse), r.Mean(&FrameResult::temporal), r.flicker, r.flicker_unrounded, r.still_psnr,
        r.MeanMs(), r.Mean(&FrameResult::render_ms), r.Mean(&FrameResult::denoise_ms), r.Mean(&FrameResult::tonemap_ms),
        r.Mean(&FrameResult::encode_ms));
  }
  return t;
}

}  // namespace cinevol::bench
