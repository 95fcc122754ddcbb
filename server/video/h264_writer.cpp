// H264Writer over libavcodec (libx264), libswscale (RGB to 4:2:0) and libavformat (MP4 or raw H.264).
#include "video/h264_writer.h"

extern "C" {
#include <libavcodec/avcodec.h>
#include <libavformat/avformat.h>
#include <libavutil/opt.h>
#include <libswscale/swscale.h>
}

#include <fmt/format.h>

#include <stdexcept>

#include "core/error.h"

namespace cinevol {
namespace {

std::string AvError(int code) {
  char text[AV_ERROR_MAX_STRING_SIZE] = {};
  av_strerror(code, text, sizeof text);
  return text;
}

void Check(int code, const char* what) {
  if (code < 0) throw std::runtime_error(fmt::format("video: {}: {}", what, AvError(code)));
}

void CheckSettings(const VideoSettings& s) {
  const auto side = [](int n) { return n >= 16 && n <= 4096 && n % 2 == 0; };
  if (!side(s.width) || !side(s.height)) {
    throw InputError(fmt::format("video size {}x{}: each side even, in [16, 4096]", s.width, s.height));
  }
  if (s.fps < 1 || s.fps > 60) throw InputError(fmt::format("video rate {} frames/s: in [1, 60]", s.fps));
  if (s.crf < 0 || s.crf > 51) throw InputError(fmt::format("video quality (CRF) {}: in [0, 51]", s.crf));
  if (s.dicom_level && (s.width > 1920 || s.height > 1080 || s.fps > 30)) {
    throw InputError(
        fmt::format("a DICOM video (H.264 High Profile level 4.1) is at most 1920x1080 at 30 frames/s; "
                    "this one is {}x{} at {}",
                    s.width, s.height, s.fps));
  }
  if (s.dicom_level && s.crf == 0) {
    throw InputError("a DICOM video is H.264 High Profile, which has no lossless coding: give crf 1 or more");
  }
}

}  // namespace

struct H264Writer::Codec {
  AVFormatContext* format = nullptr;
  AVCodecContext* encoder = nullptr;
  AVStream* stream = nullptr;
  SwsContext* to_yuv = nullptr;
  AVFrame* frame = nullptr;
  AVPacket* packet = nullptr;
  bool header_written = false, finished = false;
  VideoSettings settings;

  ~Codec() {
    if (format != nullptr && !(format->oformat->flags & AVFMT_NOFILE) && format->pb != nullptr)
      avio_closep(&format->pb);
    avformat_free_context(format);
    avcodec_free_context(&encoder);
    sws_freeContext(to_yuv);
    av_frame_free(&frame);
    av_packet_free(&packet);
  }

  // Every packet the encoder has ready, into the file.
  void Drain() {
    for (;;) {
      const int got = avcodec_receive_packet(encoder, packet);
      if (got == AVERROR(EAGAIN) || got == AVERROR_EOF) return;
      Check(got, "encoding a frame");
      av_packet_rescale_ts(packet, encoder->time_base, stream->time_base);
      packet->stream_index = stream->index;
      Check(av_interleaved_write_frame(format, packet), "writing a frame");
    }
  }
};

H264Writer::H264Writer(const std::filesystem::path& path, VideoContainer container, const VideoSettings& settings)
    : codec_(std::make_unique<Codec>()) {
  CheckSettings(settings);
  av_log_set_level(AV_LOG_ERROR);  // x264's statistics are not the user's business
  Codec& c = *codec_;
  c.settings = settings;
  Check(avformat_alloc_output_context2(&c.format, nullptr, container == VideoContainer::kMp4 ? "mp4" : "h264",
                                       path.c_str()),
        "the container");
  const AVCodec* x264 = avcodec_find_encoder_by_name("libx264");
  if (x264 == nullptr) throw std::runtime_error("video: this FFmpeg has no libx264 encoder");
  c.stream = avformat_new_stream(c.format, nullptr);
  c.encoder = avcodec_alloc_context3(x264);
  c.frame = av_frame_alloc();
  c.packet = av_packet_alloc();
  if (c.stream == nullptr || c.encoder == nullptr || c.frame == nullptr || c.packet == nullptr) {
    throw std::runtime_error("video: out of memory");
  }
  c.encoder->width = settings.width;
  c.encoder->height = settings.height;
  c.encoder->time_base = {1, settings.fps};
  c.encoder->framerate = {settings.fps, 1};
  c.encoder->pix_fmt = AV_PIX_FMT_YUV420P;
  c.encoder->gop_size = settings.fps;  // a key frame a second: a player seeks within one
  c.encoder->max_b_frames = 2;
  c.encoder->color_primaries = AVCOL_PRI_BT709;
  c.encoder->color_trc = AVCOL_TRC_IEC61966_2_1;  // the stills are sRGB
  c.encoder->colorspace = AVCOL_SPC_BT709;
  c.encoder->color_range = AVCOL_RANGE_MPEG;
  if (c.format->oformat->flags & AVFMT_GLOBALHEADER) c.encoder->flags |= AV_CODEC_FLAG_GLOBAL_HEADER;
  av_opt_set(c.encoder->priv_data, "crf", std::to_string(settings.crf).c_str(), 0);
  av_opt_set(c.encoder->priv_data, "preset", "medium", 0);
  // Lossless (crf 0) needs High 4:4:4 Predictive; DICOM's transfer syntax needs High (CheckSettings).
  av_opt_set(c.encoder->priv_data, "profile", settings.crf == 0 ? "high444" : "high", 0);
  if (settings.dicom_level) av_opt_set(c.encoder->priv_data, "level", "4.1", 0);
  Check(avcodec_open2(c.encoder, x264, nullptr), "opening libx264");
  Check(avcodec_parameters_from_context(c.stream->codecpar, c.encoder), "the stream's parameters");
  c.stream->time_base = c.encoder->time_base;
  c.stream->avg_frame_rate = c.encoder->framerate;
  if (!(c.format->oformat->flags & AVFMT_NOFILE)) {
    Check(avio_open(&c.format->pb, path.c_str(), AVIO_FLAG_WRITE), "opening the file");
  }
  Check(avformat_write_header(c.format, nullptr), "the file's header");
  c.header_written = true;
  c.frame->format = AV_PIX_FMT_YUV420P;
  c.frame->width = settings.width;
  c.frame->height = settings.height;
  Check(av_frame_get_buffer(c.frame, 0), "a frame's buffer");
  c.to_yuv = sws_getContext(settings.width, settings.height, AV_PIX_FMT_RGB24, settings.width, settings.height,
                            AV_PIX_FMT_YUV420P, SWS_BICUBIC, nullptr, nullptr, nullptr);
  if (c.to_yuv == nullptr) throw std::runtime_error("video: no RGB to YUV conversion");
}

H264Writer::~H264Writer() = default;

void H264Writer::Add(const std::vector<std::uint8_t>& rgb) {
  Codec& c = *codec_;
  if (c.finished) throw std::logic_error("video: a frame after Finish");
  const std::size_t expected = std::size_t(c.settings.width) * c.settings.height * 3;
  if (rgb.size() != expected) {
    throw InputError(fmt::format("video frame {}: {} bytes, not {}x{} RGB", frames_, rgb.size(), c.settings.width,
                                 c.settings.height));
  }
  Check(av_frame_make_writable(c.frame), "a frame's buffer");
  const std::uint8_t* source[1] = {rgb.data()};
  const int source_stride[1] = {3 * c.settings.width};
  sws_scale(c.to_yuv, source, source_stride, 0, c.settings.height, c.frame->data, c.frame->linesize);
  c.frame->pts = frames_++;
  Check(avcodec_send_frame(c.encoder, c.frame), "encoding a frame");
  c.Drain();
}

void H264Writer::Finish() {
  Codec& c = *codec_;
  if (c.finished) return;
  c.finished = true;
  Check(avcodec_send_frame(c.encoder, nullptr), "flushing the encoder");
  c.Drain();
  Check(av_write_trailer(c.format), "the file's trailer");
}

}  // namespace cinevol
