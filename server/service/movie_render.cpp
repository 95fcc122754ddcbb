#include "service/movie_render.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <chrono>
#include <fstream>
#include <iterator>

#include "core/error.h"
#include "core/tone_map.h"
#include "pacs/video_capture.h"
#include "runtime/errors.h"
#include "scene/movie_path.h"

namespace cinevol::service {
namespace {

constexpr auto kProgressPeriod = std::chrono::seconds(1);

std::string ReadAll(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

std::uint64_t MicrosecondsSince(Clock::time_point start) {
  return std::uint64_t(std::chrono::duration_cast<std::chrono::microseconds>(Clock::now() - start).count());
}

}  // namespace

MovieRender::TemporaryFile::TemporaryFile(const std::string& extension) {
  static std::atomic<unsigned> count{0};
  path = std::filesystem::temp_directory_path() / fmt::format("cinevol-movie-{}-{}{}", getpid(), count++, extension);
}

MovieRender::TemporaryFile::~TemporaryFile() {
  std::error_code ignored;
  std::filesystem::remove(path, ignored);
}

void MovieRender::Start(std::shared_ptr<Session> session, Plan plan, Backend backend, TaskPool& encoder,
                        std::shared_ptr<std::atomic<bool>> cancel, Callbacks callbacks) {
  std::shared_ptr<MovieRender> movie(
      new MovieRender(std::move(session), std::move(plan), backend, encoder, std::move(cancel), std::move(callbacks)));
  v1::MovieProgress accepted;  // at once: the client knows the movie is under way before its first sample
  accepted.set_frames(std::uint32_t(movie->plan_.frames));
  accepted.set_spp(std::uint32_t(movie->plan_.spp));
  movie->callbacks_.progress(accepted);
  movie->session_->BeginStill(movie->cancel_);
  movie->Render(0);
}

MovieRender::MovieRender(std::shared_ptr<Session> session, Plan plan, Backend backend, TaskPool& encoder,
                         std::shared_ptr<std::atomic<bool>> cancel, Callbacks callbacks)
    : session_(std::move(session)),
      plan_(std::move(plan)),
      backend_(backend),
      encoder_(encoder),
      cancel_(std::move(cancel)),
      callbacks_(std::move(callbacks)) {
  VideoSettings video;
  video.width = plan_.start.render().width();
  video.height = plan_.start.render().height();
  video.fps = MovieFps(plan_.request);
  video.crf = plan_.crf;
  mp4_.emplace(mp4_file_.path, VideoContainer::kMp4, video);
  if (!plan_.request.store_to().empty()) {
    video.dicom_level = true;
    dicom_file_.emplace(".h264");
    dicom_.emplace(dicom_file_->path, VideoContainer::kAnnexB, video);
  }
}

// Frame `frame` as a still on the session's device; its radiance goes to the encoder pool, which starts the next.
void MovieRender::Render(int frame) {
  const grpc::Status status = Guarded([&] {
    if (*cancel_) throw Cancelled("the movie was cancelled");
    v1::Scene scene = MovieFrame(plan_.start, plan_.request, MovieVolumeOf(*session_->volume()), frame, plan_.frames);
    StillJob::Callbacks job;
    job.done = [self = shared_from_this(), frame](grpc::Status status, StillRadiance still) {
      if (!status.ok()) return self->Fail(std::move(status));
      const bool queued = self->encoder_.Submit(
          [self, frame, still = std::move(still)] {
            const grpc::Status encoded = Guarded([&] { self->Encode(frame, still); });
            if (!encoded.ok()) self->Fail(encoded);
          },
          self->session_->id());
      if (!queued) self->Fail(RpcError::Unavailable("the server is shutting down").status());
    };
    job.why_cancelled = [self = shared_from_this()] { return self->WhyCancelled(); };
    session_->scheduler()->Wake(std::make_shared<StillJob>(session_->volume(), session_->fused(), std::move(scene),
                                                           plan_.spp, plan_.max_chunk_spp, backend_, cancel_,
                                                           std::move(job)));
  });
  if (!status.ok()) Fail(status);
}

void MovieRender::Encode(int frame, const StillRadiance& still) {
  const Clock::time_point begin = Clock::now();
  const ImageRgb8 image = ToneMap(still.image, still.exposure);
  mp4_->Add(image.bytes);
  if (dicom_) dicom_->Add(image.bytes);
  render_us_ += still.render_us;
  encode_us_ += MicrosecondsSince(begin);
  if (std::filesystem::file_size(mp4_file_.path) > kMaxMovieMp4Bytes) {
    throw OverLimit("max-movie-bytes", fmt::format("the movie passed {} MiB at frame {} of {}; ask for fewer frames, "
                                                   "a smaller viewport or a higher crf",
                                                   kMaxMovieMp4Bytes >> 20, frame + 1, plan_.frames));
  }
  if (frame + 1 < plan_.frames) {
    if (Clock::now() - last_progress_ >= kProgressPeriod) {
      last_progress_ = Clock::now();
      v1::MovieProgress progress;
      progress.set_frames_done(std::uint32_t(frame + 1));
      progress.set_frames(std::uint32_t(plan_.frames));
      progress.set_spp(std::uint32_t(plan_.spp));
      progress.set_elapsed_us(MicrosecondsSince(start_));
      callbacks_.progress(progress);
    }
    return Render(frame + 1);
  }
  Finish();
}

void MovieRender::Finish() {
  mp4_->Finish();
  std::string dicom_stream;
  if (dicom_) {
    dicom_->Finish();
    if (std::filesystem::file_size(dicom_file_->path) > pacs::kMaxMovieBytes) {
      throw OverLimit("max-movie-bytes",
                      fmt::format("store_to: the DICOM stream is {} bytes, over the {} MiB a "
                                  "stored movie may have",
                                  std::filesystem::file_size(dicom_file_->path), pacs::kMaxMovieBytes >> 20));
    }
    dicom_stream = ReadAll(dicom_file_->path);
  }
  v1::Movie movie;
  movie.set_mp4(ReadAll(mp4_file_.path));
  movie.set_width(std::uint32_t(plan_.start.render().width()));
  movie.set_height(std::uint32_t(plan_.start.render().height()));
  movie.set_fps(std::uint32_t(MovieFps(plan_.request)));
  movie.set_frames(std::uint32_t(plan_.frames));
  movie.set_spp(std::uint32_t(plan_.spp));
  movie.set_render_us(MicrosecondsSince(start_));
  spdlog::info(
      "session {}: a movie of {} frames of {}x{} at {} spp in {:.1f} s: a frame's still {:.1f} ms, its "
      "encoding {:.1f} ms",
      session_->id(), plan_.frames, movie.width(), movie.height(), plan_.spp, movie.render_us() * 1e-6,
      render_us_ * 1e-3 / plan_.frames, encode_us_ * 1e-3 / plan_.frames);
  session_->EndStill();
  std::exchange(callbacks_.done, nullptr)(grpc::Status::OK, std::move(movie), std::move(dicom_stream));
}

void MovieRender::Fail(grpc::Status status) {
  if (!callbacks_.done) return;
  session_->EndStill();
  std::exchange(callbacks_.done, nullptr)(std::move(status), {}, {});
}

std::string MovieRender::WhyCancelled() const {
  const std::string why = session_->EndReason();
  return why.empty() ? std::string("its caller went away")
                     : fmt::format("its session '{}' ended: {}", session_->id(), why);
}

}  // namespace cinevol::service
