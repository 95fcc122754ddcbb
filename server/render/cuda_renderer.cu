// CudaRenderer: uploads SceneData's tables, takes the GPU's shared copies of
// the voxels and the majorants, and launches RenderKernel<F> over the image,
// two threads a pixel where it has two samples or more, else one.
#include <array>
#include <cstdint>
#include <utility>

#include "device/cuda_buffer.h"
#include "render/cuda_renderer.h"
#include "render/integrator.h"

namespace cinevol {

using cuda::DeviceBuffer;

namespace {

// 64 threads a block. Blocks per SM the register allocation must allow: 16
// caps the integrator at 64 registers (50% occupancy). With the 32-bit random
// generator and the voxel buffer's code out of line it is the fastest on an
// H100 against 10 (96 registers, 31%), 12 (80) and 20 (48): CThead 1.21 ms
// against 1.41 at 10 before those changes (H100). With two lanes a pixel it
// still beats 12, 14 (72) and 20 under 128 sessions and at 4K, though it
// spills more than 72 or 80 (H200; docs/performance.md, "Register caps").
constexpr int kBlockThreads = 64;
constexpr int kMinBlocksPerSm = 16;

// Threads a pixel: with two samples or more, two lanes share a pixel's
// samples, so a warp covers a 4x4 tile of pixels rather than 8x4 and its
// camera rays stay closer together (their voxels and their paths' first
// steps), and a frame has twice the threads to end its tail with. A block is
// two warps' tiles, one above the other. On an H200 (CThead, 2 spp) that took
// 128 sessions at 640x360 7% further and one 720p session 13%, and, once the
// lanes met only after their samples, one 3840x2160 session 1.7% over a
// thread a pixel (docs/performance.md, "Two threads a pixel", "The lanes meet
// once").
int LanesPerPixel(int spp) { return spp >= 2 ? 2 : 1; }
CINEVOL_HD dim3 BlockPixels(int lanes) { return dim3(8 / lanes, 8); }

// The samples lane `source_lane` of the warp added up.
__device__ PixelSamples ShuffleFrom(const PixelSamples& p, int source_lane) {
  constexpr unsigned kWarp = 0xffffffffu;
  const auto from = [&](float v) { return __shfl_sync(kWarp, v, source_lane); };
  PixelSamples o;
  o.sum = {from(p.sum.x), from(p.sum.y), from(p.sum.z)};
  o.albedo = {from(p.albedo.x), from(p.albedo.y), from(p.albedo.z)};
  o.first_hit = {from(p.first_hit.x), from(p.first_hit.y), from(p.first_hit.z), from(p.first_hit.w)};
  o.nearest = from(p.nearest);
  return o;
}

// __grid_constant__: the integrator takes the scene by reference, which would
// otherwise copy the whole parameter block into local memory per thread.
// With two lanes a pixel, lane 0 traces the even samples and lane 1 the odd,
// and lane 0 adds lane 1's sums to its own: at 1 or 2 spp the sums one thread
// makes (RenderPixel), beyond that the same to rounding. The lanes meet once,
// after their samples (every thread of the warp reaches the shuffle, inside
// the image or not): a shuffle after each sample, with the loop around it,
// spilled nearly twice the registers and rendered 4K frames 3% slower
// (docs/performance.md).
template <unsigned kFeatures>
__global__ void __launch_bounds__(kBlockThreads, kMinBlocksPerSm)
    RenderKernel(const __grid_constant__ RenderScene scene, const FrameTargets targets, int lanes) {
  const dim3 tile = BlockPixels(lanes);
  const int lane = int(threadIdx.x) % lanes, p = int(threadIdx.x) / lanes;
  const int x = int(blockIdx.x * tile.x) + p % int(tile.x);
  const int y = int(blockIdx.y * tile.y) + p / int(tile.x);
  const bool inside = x < scene.camera.width && y < scene.camera.height;
  PixelSamples samples;
  if (inside) {
    for (int k = lane; k < scene.spp; k += lanes) samples.Add(TracePixelSample<kFeatures>(scene, x, y, k), scene.camera.eye);
  }
  if (lanes == 2) samples.Merge(ShuffleFrom(samples, int(threadIdx.x % 32u) ^ 1));
  if (inside && lane == 0) {
    const int pixel = y * scene.camera.width + x;
    samples.Write(targets, pixel, scene.spp);
    if (targets.surface_normal) targets.surface_normal[pixel] = SurfaceNormalAt<kFeatures>(scene, samples.first_hit);
  }
}

using Kernel = void (*)(const RenderScene, const FrameTargets, int);

template <unsigned... kVariant>
std::array<Kernel, sizeof...(kVariant)> MakeKernels(std::integer_sequence<unsigned, kVariant...>) {
  return {&RenderKernel<VariantFeatures(kVariant)>...};
}

}  // namespace

// A transfer table on the device: what a TransferView points to.
struct DeviceTable {
  DeviceBuffer<float> sigma_t;
  DeviceBuffer<Vec4f> diffuse_opacity, specular_roughness, emission;

  void Upload(const TransferTable& t, cudaStream_t stream) {
    sigma_t.Upload(t.sigma_t, stream);
    diffuse_opacity.Upload(t.diffuse_opacity, stream);
    specular_roughness.Upload(t.specular_roughness, stream);
    emission.Upload(t.emission, stream);
    CINEVOL_CUDA_CHECK(cudaStreamSynchronize(stream));
  }
  void PointTo(TransferView& view) const {
    view.sigma_t = sigma_t.data();
    view.diffuse_opacity = diffuse_opacity.data();
    view.specular_roughness = specular_roughness.data();
    view.emission = emission.data();
  }
};

// All work goes to the calling thread's default stream (cudaStreamPerThread),
// where the CUDA denoiser of the same session follows it in order.
struct CudaRenderer::Device {
  cudaStream_t stream = cudaStreamPerThread;
  cudaEvent_t start = nullptr, stop = nullptr;
  DeviceTable table, fused_table;  // the first volume's (and its labels'), the second volume's
  DeviceBuffer<float> env_weight, env_marginal, env_conditional, fused_majorants;
  DeviceBuffer<Vec4f> env_texels;
  DeviceBuffer<Light> lights;
  DeviceBuffer<LabelMaterial> label_materials;
  DeviceBuffer<Vec3f> accumulated;
  // The last frame's outputs, in its frame scratch (device/frame_scratch.h):
  // valid while the frame's set is, within FramePipeline's frame.
  Vec3f* radiance = nullptr;
  Vec3f* albedo = nullptr;
  Vec4f* first_hit = nullptr;
  Vec3f* surface_normal = nullptr;  // where the frame asked for it

  Device() {
    CINEVOL_CUDA_CHECK(cudaEventCreate(&start));
    CINEVOL_CUDA_CHECK(cudaEventCreate(&stop));
  }
  ~Device() {
    cudaStreamSynchronize(stream);
    cudaEventDestroy(start);
    cudaEventDestroy(stop);
  }
};

CudaRenderer::CudaRenderer(const RendererOptions& options)
    : brick_size_(options.brick_size), use_texture_(options.volume_texture), device_(std::make_unique<Device>()) {}
CudaRenderer::~CudaRenderer() = default;

void CudaRenderer::SetVolume(std::shared_ptr<const Volume> volume) {
  int gpu = 0;
  CINEVOL_CUDA_CHECK(cudaGetDevice(&gpu));
  volume_ = VolumeCache::Get().Acquire(volume, brick_size_, gpu, use_texture_);
  data_.SetVolume(volume_->prepared_ptr());
  AcquireMajorants();
}

void CudaRenderer::SetTransferFunction(const TransferFunction& tf) {
  data_.SetTransferFunction(tf);
  UploadTables();
}

void CudaRenderer::SetReconstruction(Reconstruction r) {
  data_.SetReconstruction(r);
  UploadTables();
}

void CudaRenderer::SetLabels(std::shared_ptr<const LabelVolume> labels, const LabelSetup& setup) {
  int gpu = 0;
  CINEVOL_CUDA_CHECK(cudaGetDevice(&gpu));
  // Labels that change nothing are neither uploaded nor looked up (a CT's table while it shows).
  const bool used = labels && setup.ChangesAnything(*labels);
  data_.SetLabels(used ? VolumeCache::Get().AcquireLabels(labels, data_.volume().brick_size(), gpu) : nullptr, setup);
  Device& d = *device_;
  d.label_materials.Upload(data_.label_materials(), d.stream);
  UploadTables();
}

void CudaRenderer::SetFusion(std::shared_ptr<const Volume> fused, const FusionSetup& setup) {
  int gpu = 0;
  CINEVOL_CUDA_CHECK(cudaGetDevice(&gpu));
  // Its bricks' ranges bound its extinction over each of the first volume's bricks (SceneData).
  fused_ = fused ? VolumeCache::Get().Acquire(fused, kAutoBrickSize, gpu, use_texture_) : nullptr;
  data_.SetFusion(fused_ ? fused_->prepared_ptr() : nullptr, setup);
  device_->fused_table.Upload(data_.fused_table(), device_->stream);
  AcquireMajorants();
}

void CudaRenderer::UploadTables() {
  device_->table.Upload(data_.table(), device_->stream);
  AcquireMajorants();
}

void CudaRenderer::AcquireMajorants() {
  int gpu = 0;
  CINEVOL_CUDA_CHECK(cudaGetDevice(&gpu));
  const auto& shared = data_.shared_majorants();
  majorants_ = shared && !shared->empty() ? VolumeCache::Get().AcquireMajorantsOnGpu(shared, gpu) : nullptr;
  // With a second volume, this renderer's own bounds of both (SceneData::fused_majorants).
  Device& d = *device_;
  d.fused_majorants.Upload(data_.fused_majorants(), d.stream);
  CINEVOL_CUDA_CHECK(cudaStreamSynchronize(d.stream));
}

void CudaRenderer::SetLights(const LightSetup& lights) {
  data_.SetLights(lights);
  Device& d = *device_;
  d.lights.Upload(data_.lights(), d.stream);
  const EnvironmentDistribution& env = data_.environment_distribution();
  d.env_texels.Upload(env.texels, d.stream);
  d.env_weight.Upload(env.weight, d.stream);
  d.env_marginal.Upload(env.marginal_cdf, d.stream);
  d.env_conditional.Upload(env.conditional_cdf, d.stream);
  CINEVOL_CUDA_CHECK(cudaStreamSynchronize(d.stream));
}

void CudaRenderer::Render(const FrameRequest& request) {
  if (!data_.has_volume()) throw std::logic_error("CudaRenderer::Render before SetVolume");
  Device& d = *device_;
  const int w = request.camera.width, h = request.camera.height;
  const std::size_t pixels = std::size_t(w) * h;
  if (w != width_ || h != height_) {
    width_ = w;
    height_ = h;
    d.accumulated.Resize(pixels);
    ResetAccumulation();
  }
  d.radiance = cuda::DeviceScratch<Vec3f>(Scratch::kRadiance, pixels);
  d.albedo = cuda::DeviceScratch<Vec3f>(Scratch::kAlbedo, pixels);
  d.first_hit = cuda::DeviceScratch<Vec4f>(Scratch::kFirstHit, pixels);
  d.surface_normal = request.surface_normals ? cuda::DeviceScratch<Vec3f>(Scratch::kSurfaceNormal, pixels) : nullptr;
  RenderScene scene = data_.HostView();
  scene.volume.voxels = volume_->voxels();
  if (use_texture_) scene.volume.texture = volume_->texture();
  scene.majorants.majorant = data_.fused_majorants().empty() ? majorants_.get() : d.fused_majorants.data();
  if (scene.labels.voxels) scene.labels = {data_.labels()->voxels(), d.label_materials.data()};
  d.table.PointTo(scene.transfer);
  if (scene.fused.present()) {
    scene.fused.volume.voxels = fused_->voxels();
    scene.fused.volume.texture = use_texture_ ? fused_->texture() : 0;
    d.fused_table.PointTo(scene.fused.transfer);
  }
  scene.lights = d.lights.data();
  scene.environment.map.texels = d.env_texels.data();
  scene.environment.map.weight = d.env_weight.data();
  scene.environment.map.marginal_cdf = d.env_marginal.data();
  scene.environment.map.conditional_cdf = d.env_conditional.data();
  last_features_ = ApplyRequest(request, scene);

  static const auto kKernels = MakeKernels(std::make_integer_sequence<unsigned, kIntegratorVariants>());
  // A volume no texture holds takes an integrator with every feature
  // (ReadsTexturesOnly), which specialises less and draws the same image.
  const bool textures = scene.volume.texture != 0 && (!scene.fused.present() || scene.fused.volume.texture != 0);
  const Kernel kernel = kKernels[VariantOf(textures ? last_features_ : last_features_ | kAllFeatures)];
  const int lanes = LanesPerPixel(request.spp);
  const dim3 tile = BlockPixels(lanes);
  const dim3 grid((w + tile.x - 1) / tile.x, (h + tile.y - 1) / tile.y);
  CINEVOL_CUDA_CHECK(cudaEventRecord(d.start, d.stream));
  kernel<<<grid, kBlockThreads, 0, d.stream>>>(scene, Targets(), lanes);
  CINEVOL_CUDA_CHECK_LAUNCH();
  CINEVOL_CUDA_CHECK(cudaEventRecord(d.stop, d.stream));
  ++accumulated_frames_;
  accumulated_samples_ += request.spp;
}

void CudaRenderer::ResetAccumulation() {
  accumulated_frames_ = 0;
  accumulated_samples_ = 0;
}

double CudaRenderer::LastFrameMilliseconds() const {
  CINEVOL_CUDA_CHECK(cudaEventSynchronize(device_->stop));
  float ms = 0;
  CINEVOL_CUDA_CHECK(cudaEventElapsedTime(&ms, device_->start, device_->stop));
  return ms;
}

ImageRgbF CudaRenderer::Radiance() const { return {width_, height_, Download(device_->radiance)}; }

ImageRgbF CudaRenderer::AccumulatedMean() const {
  if (accumulated_samples_ == 0) return {width_, height_, std::vector<Vec3f>(std::size_t(width_) * height_)};
  ImageRgbF image{width_, height_, device_->accumulated.Download(device_->stream)};
  const float inv = float(1.0 / double(accumulated_samples_));
  for (Vec3f& p : image.pixels) p *= inv;
  return image;
}

std::vector<Vec4f> CudaRenderer::FirstHits() const { return Download(device_->first_hit); }

ImageRgbF CudaRenderer::Albedo() const { return {width_, height_, Download(device_->albedo)}; }

std::vector<Vec3f> CudaRenderer::SurfaceNormals() const { return Download(device_->surface_normal); }

FrameTargets CudaRenderer::Targets() const {
  return {device_->radiance, device_->first_hit,      device_->accumulated.data(),
          device_->albedo,   device_->surface_normal, accumulated_frames_ == 0};
}

template <class T>
std::vector<T> CudaRenderer::Download(const T* frame_scratch) const {
  if (!frame_scratch) return {};
  return cuda::Download(frame_scratch, std::size_t(width_) * height_, device_->stream);
}

}  // namespace cinevol
