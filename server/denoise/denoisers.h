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

// The edge guides the a-trous levels stop at (ComputeEdgeGuides), with
// their scratch: a frame's worth, for SVGF and wRLS alike. They also keep
// the frame's first hits for the next frame's reprojection.
template <class B>
class EdgeGuides {
 public:
  void Resize(std::size_t n) {
    guides_.Resize(n);
    row_hits_.Resize(n);
  }
  const EdgeGuide* Compute(const DenoiseFrame& frame, Vec4f* kept_first_hit) {
    ComputeEdgeGuides<B>(frame.first_hit, frame.camera.eye, frame.width, frame.height, row_hits_.data(),
                         guides_.data(), kept_first_hit);
    return guides_.data();
  }

 private:
  typename B::template Buffer<EdgeGuide> guides_;
  typename B::template Buffer<float> row_hits_;
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
      demodulated_.Resize(pixels());  // only demodulating denoisers pay for it
      B::ForEachPixel(width_, height_, DemodulatePass{frame.radiance, frame.albedo, demodulated_.data(), width_});
      input = demodulated_.data();
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

  Buffer<Vec3f> output_, demodulated_;
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
    B::ForEachPixel(w, h, SvgfTemporalPass{rv, input, prev_history_.data(), history_.data(), s});
    B::ForEachPixel(w, h, SvgfVariancePass{history_.data(), frame.first_hit, a_.data(), w, h});
    const EdgeGuide* guides = guides_.Compute(frame, this->kept_first_hit());
    for (int level = 0; level < s.iterations; ++level) {
      RunAtrousLevel<B>(AtrousPass{a_.data(), b_.data(), guides, w, h,
                                   1 << level, s.sigma_luminance, s.sigma_depth});
      if (level == 0) B::ForEachPixel(w, h, SvgfFeedbackPass{b_.data(), history_.data(), w});
      std::swap(a_, b_);
    }
    B::ForEachPixel(w, h, ColorOfPass{a_.data(), output, w});
  }
  void Allocate(std::size_t n) override {
    history_.Resize(n);
    prev_history_.Resize(n);
    a_.Resize(n);
    b_.Resize(n);
    guides_.Resize(n);
  }
  bool KeepsFirstHits() const override { return true; }

 private:
  typename DenoiserBase<B>::template Buffer<SvgfHistory> history_, prev_history_;
  typename DenoiserBase<B>::template Buffer<Vec4f> a_, b_;
  EdgeGuides<B> guides_;
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
    // The previous feature and output, reprojected: the temporal pass and the
    // stabiliser then overwrite them.
    B::ForEachPixel(w, h, ReprojectHistoriesPass{rv, feature_.data(), stable_.data(), b_.data(), stable_history_.data(),
                                                 previous_pixel_.data()});
    B::ForEachPixel(w, h, WrlsTemporalPass{rv, input, b_.data(), previous_pixel_.data(), prev_model_.data(),
                                           feature_.data(), model_.data(), a_.data(), s, still_frames_,
                                           FeatureRatioRows(input, rv)});
    const EdgeGuide* guides = guides_.Compute(frame, this->kept_first_hit());
    for (int level = 0; level < s.atrous_iterations; ++level) {
      RunAtrousLevel<B>(AtrousPass{a_.data(), b_.data(), guides, w, h,
                                   1 << level, s.atrous_sigma_luminance, s.atrous_sigma_depth});
      std::swap(a_, b_);
    }
    Stabilize(output);
  }

  void Allocate(std::size_t n) override {
    stable_.Resize(n);
    stable_history_.Resize(n);
    feature_.Resize(n);
    previous_pixel_.Resize(n);
    model_.Resize(n);
    prev_model_.Resize(n);
    a_.Resize(n);
    b_.Resize(n);
    offset_rows_.Resize(n);
    guides_.Resize(n);
  }
  void ResetHistory() override { still_frames_ = 0; }
  bool KeepsFirstHits() const override { return true; }

 private:
  // The row sums the temporal pass rescales the feature's history (in b_)
  // with, or null on a still view (its history is exact).
  const Vec4f* FeatureRatioRows(const Vec3f* input, const ReprojectionView& rv) {
    const WrlsSettings& s = this->settings_.wrls;
    if (rv.still) return nullptr;
    const int w = this->width_, h = this->height_;
    B::RowWindowSums(w, h, s.feature_rescale, kWindowTapStride, FeatureRatioTap{input, b_.data(), w, s.firefly_clamp},
                     offset_rows_.data());
    return offset_rows_.data();
  }

  // The estimate in a_ blended with the previous output: recentred while
  // the view moves, accumulated while it holds still.
  void Stabilize(Vec3f* output) {
    const WrlsSettings& s = this->settings_.wrls;
    const int w = this->width_, h = this->height_;
    const int still = MinInt(still_frames_, s.stabilize_still_frames);
    const float weight = fmaxf(s.stabilize_history, 1.0f - 1.0f / float(still + 1));
    const Vec4f* offsets = nullptr;
    if (still == 0) {
      B::RowWindowSums(w, h, s.stabilize_recenter, kWindowTapStride,
                       HistoryOffsetTap{a_.data(), stable_history_.data(), w}, offset_rows_.data());
      offsets = offset_rows_.data();
    }
    B::ForEachPixel(w, h, WrlsStabilizePass{a_.data(), stable_history_.data(), offsets, output, stable_.data(), w, h,
                                            weight, s.stabilize_clamp, s.stabilize_recenter});
  }

  // One frame each: read (reprojected) before they are written.
  typename DenoiserBase<B>::template Buffer<Vec3f> feature_;
  typename DenoiserBase<B>::template Buffer<Vec3f> stable_;  // the stabilised output
  typename DenoiserBase<B>::template Buffer<Vec4f> stable_history_;  // the previous one, reprojected
  typename DenoiserBase<B>::template Buffer<int> previous_pixel_;  // ReprojectHistoriesPass
  // Two frames: the temporal pass reads other pixels' previous models.
  typename DenoiserBase<B>::template Buffer<StoredWrlsModel> model_, prev_model_;
  typename DenoiserBase<B>::template Buffer<Vec4f> a_, b_;  // prediction and its variance, per a-trous level
  typename DenoiserBase<B>::template Buffer<Vec4f> offset_rows_;  // row sums of a recentering or rescaling window
  EdgeGuides<B> guides_;
  int still_frames_ = 0;
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
