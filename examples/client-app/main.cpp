// cinevol-client-app SERVER OUT_DIR: the client library in a program of your
// own. Opens a session on the server's first volume, turns the camera, waits
// for the refined frame, saves it, takes a PNG still and closes the session.
#include <cinevol/client.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: %s SERVER OUT_DIR\n", argv[0]);
    return 2;
  }
  const std::filesystem::path out = argv[2];
  std::filesystem::create_directories(out);
  try {
    cinevol::ClientOptions options;
    options.address = argv[1];
    cinevol::Client client(options);
    const auto volumes = client.ListVolumes();
    if (volumes.empty()) throw std::runtime_error("the server holds no volume");

    cinevol::v1::CreateSessionRequest request;
    request.set_volume_id(volumes.front().id());
    request.mutable_viewport()->set_width(160);
    request.mutable_viewport()->set_height(120);
    request.set_preset("ct-bone");
    request.mutable_stream()->set_target_spp(32);
    const auto session = client.CreateSession(request);
    std::printf("session %s on %s, volume %s\n", session.session_id().c_str(), session.device().c_str(),
                volumes.front().id().c_str());

    auto stream = client.Attach(session.session_id());
    cinevol::v1::SessionEvent turn;
    turn.mutable_camera()->set_view(cinevol::v1::LEFT);
    const std::uint64_t seq = stream->Send(turn);
    int frames = 0;
    while (auto message = stream->Next(std::chrono::seconds(30))) {
      if (!message->has_frame()) continue;
      ++frames;
      const cinevol::v1::Frame& frame = message->frame();
      if (frame.last_event_seq() < seq || !frame.final()) continue;
      std::ofstream(out / "refined.jpg", std::ios::binary) << frame.jpeg();
      const cinevol::RgbImage pixels = cinevol::DecodeFrame(frame);
      std::printf("%d frames; refined frame %dx%d at %u spp -> %s\n", frames, pixels.width, pixels.height,
                  frame.accumulated_spp(), (out / "refined.jpg").c_str());
      break;
    }

    cinevol::v1::SnapshotRequest still;
    still.set_session_id(session.session_id());
    still.set_spp(16);
    std::ofstream(out / "still.png", std::ios::binary) << client.Snapshot(still).image();
    client.CloseSession(session.session_id());
    std::printf("still -> %s\n", (out / "still.png").c_str());
    return frames > 0 ? 0 : 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "cinevol-client-app: %s\n", e.what());
    return 1;
  }
}
