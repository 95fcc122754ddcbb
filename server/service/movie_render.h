// A movie (SessionService.RenderMovie): its frames rendered one after another
// as stills on the session's device (StillJob), each tone mapped and encoded
// in order on the encoder pool into an MP4 in the server's temporary folder
// (and, where it is to be stored, an H.264 stream within the level DICOM
// names); the MP4 comes back whole once the last frame is in. The session does
// not expire while its movie renders; a cancel stops it within a still's step.
#pragma once

#include <grpcpp/support/status.h>

#include <atomic>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>

#include "cinevol/v1/service.pb.h"
#include "device/device.h"
#include "runtime/session.h"
#include "runtime/task_pool.h"
#include "scene/movie_path.h"
#include "service/still_job.h"
#include "video/h264_writer.h"

namespace cinevol::service {

// The largest MP4 a movie answers with (one message): about four minutes of 1080p at visually lossless quality.
inline constexpr std::uintmax_t kMaxMovieMp4Bytes = std::uintmax_t{256} << 20;

// What a movie of `lease`'s volume is of: its first phase, its phases and their times.
inline MovieVolume MovieVolumeOf(const VolumeLease& lease) {
  return {*lease.volume(), lease.phases(), lease.phase_seconds()};
}

class MovieRender : public std::enable_shared_from_this<MovieRender> {
 public:
  // What the service checked: the request, the session's scene at the start, the frames and their samples.
  struct Plan {
    v1::MovieRequest request;
    v1::Scene start;
    int frames = 0, spp = 0, max_chunk_spp = 1, crf = 18;
  };
  struct Callbacks {
    std::function<void(const v1::MovieProgress&)> progress;  // at once, then after frames, at most every second
    // Once: the movie (and the DICOM stream where the plan's request stores it), or the error.
    std::function<void(grpc::Status, v1::Movie, std::string dicom_stream)> done;
  };

  // Opens the files (InputError for a size or rate the encoder or DICOM's level refuses, before any frame) and
  // wakes the first frame on the session's device.
  static void Start(std::shared_ptr<Session> session, Plan plan, Backend backend, TaskPool& encoder,
                    std::shared_ptr<std::atomic<bool>> cancel, Callbacks callbacks);

 private:
  MovieRender(std::shared_ptr<Session> session, Plan plan, Backend backend, TaskPool& encoder,
              std::shared_ptr<std::atomic<bool>> cancel, Callbacks callbacks);
  void Render(int frame);
  void Encode(int frame, const StillRadiance& still);
  void Finish();
  void Fail(grpc::Status status);
  std::string WhyCancelled() const;

  std::shared_ptr<Session> session_;
  Plan plan_;
  Backend backend_;
  TaskPool& encoder_;
  std::shared_ptr<std::atomic<bool>> cancel_;
  Callbacks callbacks_;
  // A file of this process's own in the temporary folder, removed with it, also when the constructor throws.
  struct TemporaryFile {
    explicit TemporaryFile(const std::string& extension);
    TemporaryFile(const TemporaryFile&) = delete;
    TemporaryFile& operator=(const TemporaryFile&) = delete;
    ~TemporaryFile();
    std::filesystem::path path;
  };

  // Declared before the writers: a writer closes its file before the file goes.
  TemporaryFile mp4_file_{".mp4"};
  std::optional<TemporaryFile> dicom_file_;
  std::optional<H264Writer> mp4_, dicom_;
  Clock::time_point start_ = Clock::now(), last_progress_ = start_;
  std::uint64_t render_us_ = 0, encode_us_ = 0;  // the frames' stills and their encoding, for the log
};

}  // namespace cinevol::service
