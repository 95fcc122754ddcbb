// The denoisers' drivers, written once over a backend B (CpuBackend or
// CudaBackend): buffers, the sequence of per-pixel passes, and the history
// kept between frames. Instantiated in cpu_denoisers.cpp and
// cuda_denoisers.cu.
#pragma once

#include <memory>
#include <stdexcept>
#include <utility>

#include "denoise/baselines.h"
#include "denoise/cpu_passes.h"
#include "denoise/denoiser.h"
#include "denoise/wrls.h"

namespace cinevol {

// The edge guides the a-trous levels stop at (ComputeEdgeGuides), for SVGF
// and wRLS alike, in frame scratch (device/frame_scratch.h).
// They also keep the frame's first hits for the next frame's reprojection.
template <class B>
const EdgeGuide* FrameEdgeGuides(const DenoiseFrame& frame, Vec4f* kept_first_hit) {
  const std::size_t n = std::size_t(frame.width) * frame.height;
  EdgeGuide* guides = B::template FrameScratch<EdgeGuide>(Scratch::kEdgeGuides, n);
  ComputeEdgeGuides<B>(frame.first_hit, frame.camera.eye, frame.width, frame.height,
                       B::template FrameScratch<float>(Scratch::kEdgeRowHits, n), guides, kept_first_hit);
  return guides;
}

// The normals an a-trous level with this normal stop reads: null where the
// stop is off.
inline const Vec3f* NormalsFor(const DenoiseFrame& frame, float normal_stop) {
  if (!(normal_stop > 0.0f)) return nullptr;
  if (!frame.surface_normal) throw std::invalid_argument("a normal stop needs the surface normals");
  return frame.surface_normal;
}

// The a-trous levels' pair of buffers (prediction and variance), in frame
// scratch: a level reads `in` and writes `out`, then they swap.
template <class B>
struct AtrousPair {
  Vec4f* in;
  Vec4f* out;
  explicit AtrousPair(std::size_t n)
      : in(B::template FrameScratch<Vec4f>(Scratch::kEstimate, n)),
        out(B::template FrameScratch<Vec4f>(Scratch::kEstimateNext, n)) {}
  void Swap() { std::swap(in, out); }
};

// What every method shares: frame size, optional demodulation, the previous
// frame's camera and first hits for reprojection, the output, timing.
template <class B>
class DenoiserBase : public Denoiser {
 public:
  template <class T>
  using Buffer = typename B::template Buffer<T>;

  explicit DenoiserBase(const DenoiserSettings& settings) : settings_(settings) {}

  const Vec3f* Denoise(const DenoiseFrame& frame) override {
    if (frame.width <= 0 || frame.height <= 0 || !frame.radiance || !frame.first_hit) {
      throw std::invalid_argument("DenoiseFrame needs a size, radiance and first hits");
    }
    if (settings_.demodulate && !frame.albedo) throw std::invalid_argument("demodulation needs the albedo buffer");
    if (frame.width != width_ || frame.height != height_) Resize(frame.width, frame.height);
    timer_.Start();
    const Vec3f* input = frame.radiance;
    if (settings_.demodulate) {
      Vec3f* demodulated = B::template FrameScratch<Vec3f>(Scratch::kDemodulated, pixels());
      B::ForEachPixel(width_, height_, DemodulatePass{frame.radiance, frame.albedo, demodulated, width_});
      input = demodulated;
    }
    ReprojectionView rv;
    rv.first_hit = frame.first_hit;
    rv.prev_first_hit = prev_first_hit_.data();
    rv.camera = frame.camera;
    rv.prev_camera = prev_camera_;
    rv.width = width_;
    rv.height = height_;
    rv.has_history = has_history_;
    rv.still = SameScene(frame);
    rv.camera_moved = !SameProjection(frame.camera, prev_camera_);
    Run(frame, input, rv, output_.data());
    if (settings_.demodulate) B::ForEachPixel(width_, height_, RemodulatePass{frame.albedo, output_.data(), width_});
    if (!KeepsFirstHits()) prev_first_hit_.CopyFrom(frame.first_hit, pixels());
    prev_camera_ = frame.camera;
    has_history_ = true;
    timer_.Stop();
    return output_.data();
  }

  ImageRgbF Output() const override { return {width_, height_, output_.Download()}; }
  double LastMilliseconds() const override { return timer_.Milliseconds(); }

 protected:
  // One frame: read `input` (demodulated if asked), write `output`.
  virtual void Run(const DenoiseFrame& frame, const Vec3f* input, const ReprojectionView& rv, Vec3f* output) = 0;
  virtual void Allocate(std::size_t pixels) = 0;
  virtual void ResetHistory() {}
  // True for a method that copies each frame's first hits to kept_first_hit()
  // itself, once it is done with the previous ones.
  virtual bool KeepsFirstHits() const { return false; }
  Vec4f* kept_first_hit() { return prev_first_hit_.data(); }

  std::size_t pixels() const { return std::size_t(width_) * height_; }
  // True when nothing but the samples changed since the last frame.
  bool SameScene(const DenoiseFrame& frame) const { return has_history_ && !frame.changed; }

  const DenoiserSettings settings_;
  int width_ = 0, height_ = 0;
  bool has_history_ = false;

 private:
  // A new frame size: buffers of that size and no history.
  void Resize(int width, int height) {
    width_ = width;
    height_ = height;
    const std::size_t n = pixels();
    output_.Resize(n);
    prev_first_hit_.Resize(n);
    Allocate(n);
    has_history_ = false;
    ResetHistory();
  }

  Buffer<Vec3f> output_;
  Buffer<Vec4f> prev_first_hit_;
  Camera prev_camera_;  // for reprojection
  typename B::Timer timer_;
};

template <class B>
class PassThrough final : public DenoiserBase<B> {
 public:
  using DenoiserBase<B>::DenoiserBase;

 protected:
  void Run(const DenoiseFrame&, const Vec3f* input, const ReprojectionView&, Vec3f* output) override {
    B::ForEachPixel(this->width_, this->height_, CopyPass{input, output, this->width_});
  }
  void Allocate(std::size_t) override {}
};

// Progressive accumulation, reset whenever the camera or scene changes
// (Exposure Render's default; it has no settings). KNN filters the running
// mean on top of it.
template <class B>
class Accumulation : public DenoiserBase<B> {
 public:
  using DenoiserBase<B>::DenoiserBase;

 protected:
  void Run(const DenoiseFrame& frame, const Vec3f* input, const ReprojectionView&, Vec3f* output) override {
    if (!this->SameScene(frame)) {
      sum_.Zero();
      frames_ = 0;
    }
    ++frames_;
    B::ForEachPixel(this->width_, this->height_,
                    AccumulatePass{input, sum_.data(), output, this->width_, 1.0f / float(frames_)});
  }
  void Allocate(std::size_t n) override { sum_.Resize(n); }
  void ResetHistory() override { frames_ = 0; }

  int frames_ = 0;

 private:
  typename DenoiserBase<B>::template Buffer<Vec3f> sum_;
};

template <class B>
class KnnFilter final : public Accumulation<B> {
 public:
  using Accumulation<B>::Accumulation;

 protected:
  void Run(const DenoiseFrame& frame, const Vec3f* input, const ReprojectionView& rv, Vec3f* output) override {
    Accumulation<B>::Run(frame, input, rv, mean_.data());
    const KnnSettings& s = this->settings_.knn;
    const float fade = fmaxf(0.0f, 1.0f - float(this->frames_ - 1) / fmaxf(s.fade_frames, 1.0f));
    B::ForEachPixel(this->width_, this->height_, KnnPass{mean_.data(), output, this->width_, this->height_, s, fade});
  }
  void Allocate(std::size_t n) override {
    Accumulation<B>::Allocate(n);
    mean_.Resize(n);
  }

 private:
  typename DenoiserBase<B>::template Buffer<Vec3f> mean_;
};

template <class B>
class GuidedFilter final : public DenoiserBase<B> {
 public:
  using DenoiserBase<B>::DenoiserBase;

 protected:
  void Run(const DenoiseFrame& frame, const Vec3f* input, const ReprojectionView& rv, Vec3f* output) override {
    const GuidedFilterSettings& s = this->settings_.guided;
    const int w = this->width_, h = this->height_;
    std::swap(feature_, prev_feature_);
    // Measured: on a still view, identity reprojection makes this guide worse
    // (-1 dB, CThead static scenario), so the guided filter keeps reprojecting.
    ReprojectionView moving = rv;
    moving.still = false;
    B::ForEachPixel(w, h, TemporalFeaturePass{moving, input, prev_feature_.data(), feature_.data(), s.alpha});
    const GuideView guide{feature_.data(), frame.first_hit, frame.camera,
                          1.0f / fmaxf(Length(frame.camera.eye), 1e-3f)};
    B::ForEachPixel(w, h, GuidedMomentsPass{input, guide, moments_.data(), w});
    B::ForEachPixel(w, h, BoxPass<GuidedMoments>{moments_.data(), moments_tmp_.data(), w, h, s.radius, true});
    B::ForEachPixel(w, h, BoxPass<GuidedMoments>{moments_tmp_.data(), moments_.data(), w, h, s.radius, false});
    B::ForEachPixel(w, h,
                    GuidedSolvePass{moments_.data(), coefficients_.data(), w, s.epsilon_feature, s.epsilon_depth});
    B::ForEachPixel(w, h,
                    BoxPass<GuidedCoefficients>{coefficients_.data(), coefficients_tmp_.data(), w, h, s.radius, true});
    B::ForEachPixel(w, h,
                    BoxPass<GuidedCoefficients>{coefficients_tmp_.data(), coefficients_.data(), w, h, s.radius, false});
    B::ForEachPixel(w, h, GuidedOutputPass{coefficients_.data(), guide, output, w});
  }
  void Allocate(std::size_t n) override {
    feature_.Resize(n);
    prev_feature_.Resize(n);
    moments_.Resize(n);
    moments_tmp_.Resize(n);
    coefficients_.Resize(n);
    coefficients_tmp_.Resize(n);
  }

 private:
  typename DenoiserBase<B>::template Buffer<Vec3f> feature_, prev_feature_;
  typename DenoiserBase<B>::template Buffer<GuidedMoments> moments_, moments_tmp_;
  typename DenoiserBase<B>::template Buffer<GuidedCoefficients> coefficients_, coefficients_tmp_;
};

// SVGF feeds the first a-trous level's colour back as history.
struct SvgfFeedbackPass {
  const Vec4f* filtered;
  SvgfHistory* history;
  int width;
  CINEVOL_HD void operator()(int x, int y) const {
    const int i = y * width + x;
    history[i].color = Xyz(filtered[i]);
  }
};

template <class B>
class Svgf final : public DenoiserBase<B> {
 public:
  using DenoiserBase<B>::DenoiserBase;

 protected:
  void Run(const DenoiseFrame& frame, const Vec3f* input, const ReprojectionView& rv, Vec3f* output) override {
    const SvgfSettings& s = this->settings_.svgf;
    const int w = this->width_, h = this->height_;
    std::swap(history_, prev_history_);
    AtrousPair<B> pair(this->pixels());
    B::ForEachPixel(w, h, SvgfTemporalPass{rv, input, prev_history_.data(), history_.data(), s});
    B::ForEachPixel(w, h, SvgfVariancePass{history_.data(), frame.first_hit, pair.in, w, h});
    const EdgeGuide* guides = FrameEdgeGuides<B>(frame, this->kept_first_hit());
    for (int level = 0; level < s.iterations; ++level) {
      RunAtrousLevel<B>(AtrousPass{pair.in, pair.out, guides, w, h, 1 << level, s.sigma_luminance, s.sigma_depth,
                                   s.squared_luminance, nullptr, NormalsFor(frame, s.normal_stop), s.normal_stop});
      if (level == 0) B::ForEachPixel(w, h, SvgfFeedbackPass{pair.out, history_.data(), w});
      pair.Swap();
    }
    B::ForEachPixel(w, h, ColorOfPass{pair.in, output, w});
  }
  void Allocate(std::size_t n) override {
    history_.Resize(n);
    prev_history_.Resize(n);
  }
  bool KeepsFirstHits() const override { return true; }

 private:
  typename DenoiserBase<B>::template Buffer<SvgfHistory> history_, prev_history_;
};

// wRLS: the feature's history reprojected (and rescaled where the light or
// the scene changed), the temporal pass (feature and models), each pixel's
// prediction, a-trous levels guided by the variance the fit predicts, then
// the output's stabilisation.
template <class B>
class Wrls final : public DenoiserBase<B> {
 public:
  using DenoiserBase<B>::DenoiserBase;

 protected:
  void Run(const DenoiseFrame& frame, const Vec3f* input, const ReprojectionView& rv, Vec3f* output) override {
    const WrlsSettings& s = this->settings_.wrls;
    const int w = this->width_, h = this->height_;
    still_frames_ = rv.still ? still_frames_ + 1 : 0;
    std::swap(model_, prev_model_);
    const std::size_t n = this->pixels();
    AtrousPair<B> pair(n);
    Vec4f* output_history = B::template FrameScratch<Vec4f>(Scratch::kOutputHistory, n);
    int* previous_pixel = B::template FrameScratch<int>(Scratch::kPreviousPixel, n);
    // The previous feature (into pair.out) and output, reprojected: the
    // temporal pass and the stabiliser then overwrite their histories.
    B::ForEachPixel(w, h, ReprojectHistoriesPass{rv, feature_.data(), StableOutput(output), pair.out, output_history,
                                                 previous_pixel});
    const EdgeGuide* guides = FrameEdgeGuides<B>(frame, this->kept_first_hit());
    B::ForEachPixel(w, h, WrlsTemporalPass{rv, input, pair.out, previous_pixel, prev_model_.data(), feature_.data(),
                                           model_.data(), pair.in, s, still_frames_,
                                           FeatureRatioRows(input, pair.out, rv),
                                           s.young_variance_surface >= 0.0f ? guides : nullptr});
    const float* variance_scale = s.atrous_calibration_floor > 0.0f ? CalibrateStop(pair.in, guides) : nullptr;
    const Vec3f* normals = NormalGuide(frame, previous_pixel);
    for (int level = 0; level < s.atrous_iterations; ++level) {
      RunAtrousLevel<B>(AtrousPass{pair.in, pair.out, guides, w, h, 1 << level, s.atrous_sigma_luminance,
                                   s.atrous_sigma_depth, s.atrous_squared_luminance, variance_scale, normals,
                                   s.atrous_normal_stop});
      pair.Swap();
    }
    Stabilize(pair.in, output_history, rv, frame.only_moved, output);
  }

  void Allocate(std::size_t n) override {
    stable_.Resize(this->settings_.demodulate ? n : 0);
    const WrlsSettings& s = this->settings_.wrls;
    const bool guided = s.atrous_normal_stop > 0.0f && s.atrous_normal_share < 1.0f;
    normal_guide_.Resize(guided ? n : 0);
    prev_normal_guide_.Resize(guided ? n : 0);
    feature_.Resize(n);
    model_.Resize(n);
    prev_model_.Resize(n);
    calibration_bins_.Resize(kCalibrationBins);
    variance_scale_.Resize(1);
    calibrated_ = false;
  }
  void ResetHistory() override {
    still_frames_ = 0;
    calibrated_ = false;
  }
  bool KeepsFirstHits() const override { return true; }

 private:
  // The row sums the temporal pass rescales the feature's reprojected
  // history with, or null on a still view (its history is exact).
  const Vec4f* FeatureRatioRows(const Vec3f* input, const Vec4f* feature_history, const ReprojectionView& rv) {
    const WrlsSettings& s = this->settings_.wrls;
    if (rv.still) return nullptr;
    const int w = this->width_, h = this->height_;
    Vec4f* rows = RowSums();
    B::RowWindowSums(w, h, s.feature_rescale, kWindowTapStride,
                     FeatureRatioTap{input, feature_history, w, s.firefly_clamp}, rows);
    return rows;
  }

  // The estimate blended with the previous output (reprojected): recentred
  // while the view moves, accumulated while it holds still.
  void Stabilize(const Vec4f* estimate, const Vec4f* output_history, const ReprojectionView& rv, bool only_moved,
                 Vec3f* output) {
    const WrlsSettings& s = this->settings_.wrls;
    const int w = this->width_, h = this->height_;
    const int still = MinInt(still_frames_, s.stabilize_still_frames);
    const float weight = fmaxf(s.stabilize_history, 1.0f - 1.0f / float(still + 1));
    const Vec4f* offsets = nullptr;
    if (still == 0) {
      Vec4f* rows = RowSums();
      B::RowWindowSums(w, h, s.stabilize_recenter, kWindowTapStride, HistoryOffsetTap{estimate, output_history, w},
                       rows);
      offsets = rows;
    }
    B::ForEachPixel(w, h, WrlsStabilizePass{estimate, output_history, offsets, rv,
                                            only_moved && !s.stabilize_recenter_unmoved, output, StableOutput(output),
                                            w, h, weight, s.stabilize_clamp, s.stabilize_recenter});
  }

  // The frame's scale of the variance the luminance stop reads (baselines.h,
  // StopCalibrationPass), left where the levels read it (on a GPU, no wait
  // for the host).
  const float* CalibrateStop(const Vec4f* estimate, const EdgeGuide* guides) {
    const int w = this->width_;
    B::template CountInBins<kCalibrationBins>(w, CalibrationRows(this->height_), StopCalibrationBin{estimate, guides, w},
                                              calibration_bins_.data());
    const WrlsSettings& s = this->settings_.wrls;
    B::ForEachPixel(1, 1, StopCalibrationPass{calibration_bins_.data(), variance_scale_.data(),
                                              s.atrous_calibration_floor, s.atrous_calibration_fall, !calibrated_});
    calibrated_ = true;
    return variance_scale_.data();
  }

  // What the normal stop reads: null where it is off, this frame's normals,
  // or the guide they are blended into (atrous_normal_share < 1).
  const Vec3f* NormalGuide(const DenoiseFrame& frame, const int* previous_pixel) {
    const WrlsSettings& s = this->settings_.wrls;
    const Vec3f* current = NormalsFor(frame, s.atrous_normal_stop);
    if (!current || !(s.atrous_normal_share < 1.0f)) return current;
    std::swap(normal_guide_, prev_normal_guide_);
    B::ForEachPixel(this->width_, this->height_,
                    NormalGuidePass{current, prev_normal_guide_.data(), previous_pixel, normal_guide_.data(),
                                    this->width_, s.atrous_normal_share});
    return normal_guide_.data();
  }

  // The stabilised output, the next frame's history: the output itself,
  // unless demodulation remodulates that in place.
  Vec3f* StableOutput(Vec3f* output) { return this->settings_.demodulate ? stable_.data() : output; }

  // Row sums of a recentering or rescaling window, in frame scratch.
  Vec4f* RowSums() { return B::template FrameScratch<Vec4f>(Scratch::kRowSums, this->pixels()); }

  // One frame each: read (reprojected) before they are written. The frame's
  // other buffers are frame scratch (AtrousPair, FrameEdgeGuides, Run).
  typename DenoiserBase<B>::template Buffer<Vec3f> feature_;
  typename DenoiserBase<B>::template Buffer<Vec3f> stable_;  // the stabilised output, where demodulated
  // Two frames: the temporal pass reads other pixels' previous models.
  typename DenoiserBase<B>::template Buffer<StoredWrlsModel> model_, prev_model_;
  typename DenoiserBase<B>::template Buffer<unsigned> calibration_bins_;
  typename DenoiserBase<B>::template Buffer<float> variance_scale_;
  typename DenoiserBase<B>::template Buffer<Vec3f> normal_guide_, prev_normal_guide_;  // NormalGuide's
  int still_frames_ = 0;
  bool calibrated_ = false;  // variance_scale_ holds the previous frame's
};

template <class B>
std::unique_ptr<Denoiser> MakeDenoiser(const DenoiserSettings& settings) {
  std::unique_ptr<Denoiser> d;
  switch (settings.method) {
    case DenoiseMethod::kNone: d = std::make_unique<PassThrough<B>>(settings); break;
    case DenoiseMethod::kAccumulate: d = std::make_unique<Accumulation<B>>(settings); break;
    case DenoiseMethod::kKnn: d = std::make_unique<KnnFilter<B>>(settings); break;
    case DenoiseMethod::kGuidedFilter: d = std::make_unique<GuidedFilter<B>>(settings); break;
    case DenoiseMethod::kSvgf: d = std::make_unique<Svgf<B>>(settings); break;
    case DenoiseMethod::kWrls: d = std::make_unique<Wrls<B>>(settings); break;
  }
  return d;
}

}  // namespace cinevol
