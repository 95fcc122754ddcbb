// Bad requests against a real server: each gets the right status code and a
// message naming the field or id, and the server keeps serving others.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <functional>
#include <limits>
#include <numeric>

#include "server_process.h"
#include "service_test_support.h"
#include "support/test_paths.h"

namespace cinevol::testing {
namespace {

using namespace std::chrono_literals;

TEST(ServiceErrors, BadSessionRequestsNameTheField) {
  ScratchDir scratch;
  ServerProcess server(scratch.path());
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = server.Connect();

  v1::CreateSessionRequest r = SmallSession();
  r.set_volume_id("no-such-volume");
  ExpectRpcError([&] { client.CreateSession(r); }, grpc::StatusCode::NOT_FOUND, "no-such-volume");

  r = SmallSession("ct-bone", 0, 0);
  ExpectRpcError([&] { client.CreateSession(r); }, grpc::StatusCode::INVALID_ARGUMENT, "viewport.width");
  r = SmallSession("ct-bone", 100000, 100000);
  ExpectRpcError([&] { client.CreateSession(r); }, grpc::StatusCode::INVALID_ARGUMENT, "viewport.width");
  r = SmallSession("ct-bone", 8192, 8192);  // within a side's range, over --max-pixels
  ExpectRpcError([&] { client.CreateSession(r); }, grpc::StatusCode::INVALID_ARGUMENT, "--max-pixels");
  r = SmallSession();
  r.clear_viewport();
  ExpectRpcError([&] { client.CreateSession(r); }, grpc::StatusCode::INVALID_ARGUMENT, "viewport");

  r = SmallSession("no-such-preset");
  ExpectRpcError([&] { client.CreateSession(r); }, grpc::StatusCode::INVALID_ARGUMENT, "preset");

  r = SmallSession();
  r.mutable_stream()->set_denoiser(static_cast<v1::Denoiser>(42));
  ExpectRpcError([&] { client.CreateSession(r); }, grpc::StatusCode::INVALID_ARGUMENT, "stream.denoiser");
  r = SmallSession();
  r.mutable_stream()->set_jpeg_quality(0);
  ExpectRpcError([&] { client.CreateSession(r); }, grpc::StatusCode::INVALID_ARGUMENT, "stream.jpeg_quality");
  for (const float budget : {-1.0f, NAN, 1e9f}) {
    r = SmallSession();
    r.mutable_stream()->set_interactive_frame_ms(budget);
    ExpectRpcError([&] { client.CreateSession(r); }, grpc::StatusCode::INVALID_ARGUMENT, "stream.interactive_frame_ms");
  }
  for (const float target : {-0.01f, NAN, 2.0f}) {
    r = SmallSession();
    r.mutable_stream()->set_error_target(target);
    ExpectRpcError([&] { client.CreateSession(r); }, grpc::StatusCode::INVALID_ARGUMENT, "stream.error_target");
  }
  r = SmallSession();
  r.mutable_stream()->set_final_format(static_cast<v1::FinalFormat>(7));
  ExpectRpcError([&] { client.CreateSession(r); }, grpc::StatusCode::INVALID_ARGUMENT, "stream.final_format");
  r = SmallSession();
  r.mutable_stream()->set_target_spp(0);
  ExpectRpcError([&] { client.CreateSession(r); }, grpc::StatusCode::INVALID_ARGUMENT, "stream.target_spp");

  // A scene with a NaN camera, a negative spp (as a uint32 it wraps) and an unknown view.
  r = SmallSession();
  v1::Scene* scene = r.mutable_scene();
  scene->mutable_transfer_function()->set_preset("ct-bone");
  scene->mutable_camera()->mutable_eye()->set_x(NAN);
  scene->mutable_camera()->mutable_target()->set_y(1);
  ExpectRpcError([&] { client.CreateSession(r); }, grpc::StatusCode::INVALID_ARGUMENT, "camera.eye.x");
  scene->mutable_camera()->mutable_eye()->set_x(-500);
  scene->mutable_render()->set_spp(static_cast<std::uint32_t>(-1));
  ExpectRpcError([&] { client.CreateSession(r); }, grpc::StatusCode::INVALID_ARGUMENT, "render.spp");
  scene->mutable_render()->set_spp(1000);
  ExpectRpcError([&] { client.CreateSession(r); }, grpc::StatusCode::INVALID_ARGUMENT, "render.spp");
  scene->mutable_render()->set_spp(2);
  scene->mutable_camera()->set_view(static_cast<v1::NamedView>(77));
  ExpectRpcError([&] { client.CreateSession(r); }, grpc::StatusCode::INVALID_ARGUMENT, "camera.view");
  // Values at the extremes (docs/rendering.md): refused, naming the field.
  scene->mutable_camera()->set_view(v1::NAMED_VIEW_UNSPECIFIED);
  scene->mutable_transfer_function()->set_density_scale(std::numeric_limits<float>::max());
  ExpectRpcError([&] { client.CreateSession(r); }, grpc::StatusCode::INVALID_ARGUMENT, "transferFunction.densityScale");
  scene->mutable_transfer_function()->clear_density_scale();
  scene->add_lights()->mutable_point()->set_intensity(std::numeric_limits<float>::max());
  ExpectRpcError([&] { client.CreateSession(r); }, grpc::StatusCode::INVALID_ARGUMENT, "lights[0].point.intensity");
  scene->clear_lights();
  scene->mutable_camera()->mutable_eye()->set_x(1e30f);
  ExpectRpcError([&] { client.CreateSession(r); }, grpc::StatusCode::INVALID_ARGUMENT, "camera.eye.x");

  // Unknown ids.
  ExpectRpcError([&] { client.CloseSession("s999"); }, grpc::StatusCode::NOT_FOUND, "s999");
  v1::SnapshotRequest still;
  still.set_session_id("s999");
  ExpectRpcError([&] { client.Snapshot(still); }, grpc::StatusCode::NOT_FOUND, "s999");
  auto stream = client.Attach("s999");
  EXPECT_TRUE(Eventually([&] { return stream->ended(); }, 10s));
  EXPECT_EQ(stream->status().error_code(), grpc::StatusCode::NOT_FOUND);
  ExpectRpcError([&] { client.DescribeVolume("nope"); }, grpc::StatusCode::NOT_FOUND, "nope");

  // A snapshot asking for too many samples.
  const auto created = client.CreateSession(SmallSession());
  still.set_session_id(created.session_id());
  still.set_spp(1 << 20);
  ExpectRpcError([&] { client.Snapshot(still); }, grpc::StatusCode::INVALID_ARGUMENT, "spp");

  ExpectServing(client);
}

TEST(ServiceErrors, ABadEventEndsOnlyItsSession) {
  ScratchDir scratch;
  ServerProcess server(scratch.path());
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = server.Connect();
  const auto good = client.CreateSession(SmallSession());
  auto good_stream = client.Attach(good.session_id());
  ASSERT_TRUE(WaitFinal(*good_stream));

  const auto bad = client.CreateSession(SmallSession());
  auto bad_stream = client.Attach(bad.session_id());
  ASSERT_TRUE(WaitFrame(*bad_stream, [](const v1::Frame&) { return true; }));
  v1::SessionEvent nan_camera;
  nan_camera.mutable_camera()->mutable_eye()->set_x(NAN);
  nan_camera.mutable_camera()->mutable_target()->set_x(1);
  bad_stream->Send(nan_camera);
  EXPECT_TRUE(Eventually([&] { return bad_stream->ended(); }, 10s));
  EXPECT_EQ(bad_stream->status().error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(bad_stream->status().error_message().find("camera.eye.x"), std::string::npos)
      << bad_stream->status().error_message();
  EXPECT_FALSE(FindSessionStatus(client, bad.session_id())) << "the failed session is gone";

  // The neighbour carries on.
  v1::SessionEvent move;
  move.mutable_camera()->set_view(v1::RIGHT);
  const std::uint64_t seq = good_stream->Send(move);
  EXPECT_TRUE(WaitFinal(*good_stream, seq));

  // Other bad events: a resize out of range, an unknown enum, a render event
  // that resizes, a clip plane without a normal.
  for (int kind = 0; kind < 4; ++kind) {
    const auto s = client.CreateSession(SmallSession());
    auto stream = client.Attach(s.session_id());
    v1::SessionEvent e;
    std::string field;
    if (kind == 0) {
      e.mutable_resize()->set_width(100000);
      e.mutable_resize()->set_height(64);
      field = "resize.width";
    } else if (kind == 1) {
      e.mutable_stream()->set_chroma(static_cast<v1::ChromaSubsampling>(9));
      field = "stream.chroma";
    } else if (kind == 2) {
      e.mutable_render()->set_width(10);
      field = "render.width";
    } else {
      e.mutable_clipping()->add_planes();
      field = "clipping.planes[0].normal";
    }
    stream->Send(e);
    EXPECT_TRUE(Eventually([&] { return stream->ended(); }, 10s)) << field;
    EXPECT_EQ(stream->status().error_code(), grpc::StatusCode::INVALID_ARGUMENT) << field;
    EXPECT_NE(stream->status().error_message().find(field), std::string::npos) << stream->status().error_message();
  }
  ExpectServing(client);
}

TEST(ServiceErrors, VolumesLoadOnlyFromTheDataRoots) {
  ScratchDir scratch;
  const auto root = scratch / "data";
  std::filesystem::create_directories(root / "sub");
  WriteSmallNrrd(root / "sub" / "small.nrrd");
  WriteSmallNrrd(scratch / "outside.nrrd");
  std::filesystem::create_directory_symlink(scratch.path(), root / "escape");
  ServerProcess server(scratch.path(), {"--data-root", root.string()});
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = server.Connect();

  ExpectRpcError([&] { client.LoadVolume("/etc/passwd"); }, grpc::StatusCode::PERMISSION_DENIED, "outside");
  ExpectRpcError([&] { client.LoadVolume("../outside.nrrd"); }, grpc::StatusCode::PERMISSION_DENIED, "outside");
  ExpectRpcError([&] { client.LoadVolume("sub/../../outside.nrrd"); }, grpc::StatusCode::PERMISSION_DENIED,
                 "outside");
  ExpectRpcError([&] { client.LoadVolume("escape/outside.nrrd"); }, grpc::StatusCode::PERMISSION_DENIED, "symlink");
  ExpectRpcError([&] { client.LoadVolume("sub/missing.nrrd"); }, grpc::StatusCode::NOT_FOUND, "does not exist");
  ExpectRpcError([&] { client.LoadVolume(""); }, grpc::StatusCode::INVALID_ARGUMENT, "path");

  const v1::VolumeInfo small = client.LoadVolume("sub/small.nrrd");
  EXPECT_EQ(small.id(), "small");
  EXPECT_EQ(small.dims().x(), 16u);
  EXPECT_EQ(client.LoadVolume((root / "sub" / "small.nrrd").string()).id(), "small") << "loaded once";
  EXPECT_EQ(client.ListVolumes().size(), 2u);

  // In use: not unloadable; after the session closes, it is.
  v1::CreateSessionRequest r = SmallSession();
  r.set_volume_id(small.id());
  const auto created = client.CreateSession(r);
  EXPECT_EQ(client.DescribeVolume(small.id()).sessions(), 1u);
  ExpectRpcError([&] { client.UnloadVolume(small.id()); }, grpc::StatusCode::FAILED_PRECONDITION, "in use");
  client.CloseSession(created.session_id());
  EXPECT_TRUE(Eventually([&] { return client.DescribeVolume(small.id()).sessions() == 0; }, 10s));
  client.UnloadVolume(small.id());
  ExpectRpcError([&] { client.DescribeVolume(small.id()); }, grpc::StatusCode::NOT_FOUND, "small");

  // Environment maps are server files too.
  r = SmallSession();
  v1::Scene* scene = r.mutable_scene();
  scene->mutable_transfer_function()->set_preset("ct-bone");
  scene->add_lights()->mutable_environment()->set_map("/etc/passwd");
  scene->mutable_lights(0)->mutable_environment()->set_intensity(1);
  ExpectRpcError([&] { client.CreateSession(r); }, grpc::StatusCode::PERMISSION_DENIED, "lights[0].environment.map");
  ExpectServing(client);
}

TEST(ServiceErrors, UploadsAreCheckedLikeFiles) {
  ScratchDir scratch;
  ServerProcess server(scratch.path(), {"--max-upload-mb", "1"});
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = server.Connect();

  WriteSmallNrrd(scratch / "upload.nrrd");
  const v1::VolumeInfo uploaded = client.UploadVolume(scratch / "upload.nrrd", {}, 1000);
  EXPECT_EQ(uploaded.id(), "upload");
  EXPECT_EQ(uploaded.source(), "upload:upload.nrrd");
  EXPECT_EQ(uploaded.dims().z(), 16u);
  v1::CreateSessionRequest r = SmallSession();
  r.set_volume_id(uploaded.id());
  const auto created = client.CreateSession(r);
  auto stream = client.Attach(created.session_id());
  EXPECT_TRUE(WaitFinal(*stream)) << "an uploaded volume renders";

  {
    std::ofstream(scratch / "garbage.nii") << "this is not a NIfTI file";
  }
  ExpectRpcError([&] { client.UploadVolume(scratch / "garbage.nii"); }, grpc::StatusCode::INVALID_ARGUMENT,
                 "garbage.nii");
  std::filesystem::copy_file(scratch / "upload.nrrd", scratch / "upload.png");
  ExpectRpcError([&] { client.UploadVolume(scratch / "upload.png"); }, grpc::StatusCode::INVALID_ARGUMENT,
                 "header.file_name");
  {
    std::ofstream big(scratch / "big.nrrd", std::ios::binary);
    big << std::string(2 << 20, 'x');
  }
  ExpectRpcError([&] { client.UploadVolume(scratch / "big.nrrd"); }, grpc::StatusCode::RESOURCE_EXHAUSTED,
                 "--max-upload-mb");
  ExpectServing(client);
}

// An 8^3 float NRRD whose voxel i holds value(i).
void WriteFloatNrrd(const std::filesystem::path& path, const std::function<float(int)>& value) {
  std::ofstream out(path, std::ios::binary);
  out << "NRRD0004\ntype: float\ndimension: 3\nsizes: 8 8 8\nspacings: 1 1 1\nencoding: raw\nendian: little\n\n";
  for (int i = 0; i < 8 * 8 * 8; ++i) {
    const float v = value(i);
    out.write(reinterpret_cast<const char*>(&v), sizeof v);
  }
}

// Volumes at the extremes of what Volume takes render; past them they are
// refused naming the range. A constant volume of 1e30 and one of 0 and the
// smallest normal floats (subnormals flushed) used to end the server at
// their first frame: their transfer table's range collapsed or overflowed
// to an infinite scale, and the majorants indexed with NaN.
TEST(ServiceErrors, VolumesAtTheExtremesRenderOrAreRefused) {
  ScratchDir scratch;
  ServerProcess server(scratch.path());
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = server.Connect();
  const float tiny = std::numeric_limits<float>::min();
  WriteFloatNrrd(scratch / "constant.nrrd", [](int) { return 1e30f; });
  WriteFloatNrrd(scratch / "narrow.nrrd", [&](int i) { return i % 3 == 0 ? 1e-40f : float(i % 3) * tiny; });
  WriteFloatNrrd(scratch / "widest.nrrd", [](int i) { return i % 2 ? 1e30f : -1e30f; });
  for (const char* name : {"constant.nrrd", "narrow.nrrd", "widest.nrrd"}) {
    const v1::VolumeInfo v = client.UploadVolume(scratch / name);
    v1::CreateSessionRequest r = SmallSession();
    r.clear_preset();  // the default preset, on the histogram's window
    r.set_volume_id(v.id());
    const auto created = client.CreateSession(r);
    auto stream = client.Attach(created.session_id());
    EXPECT_TRUE(WaitFrame(*stream, [](const v1::Frame&) { return true; }, 30s)) << name;
    client.CloseSession(created.session_id());
  }
  WriteFloatNrrd(scratch / "floatmax.nrrd", [](int i) { return i == 7 ? std::numeric_limits<float>::max() : 0.0f; });
  ExpectRpcError([&] { client.UploadVolume(scratch / "floatmax.nrrd"); }, grpc::StatusCode::INVALID_ARGUMENT,
                 "[-1e+30, 1e+30]");
  ExpectServing(client);
}

TEST(ServiceErrors, RealDataUploadsAndRenders) {
  CINEVOL_REQUIRE_SHARED_DATA();
  ScratchDir scratch;
  ServerProcess server(scratch.path());
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = server.Connect();
  const v1::VolumeInfo mr = client.UploadVolume(SharedData() / "mr-head-seg3d-nifti" / "MR.nii.gz");
  EXPECT_EQ(mr.id(), "MR");
  EXPECT_GT(mr.dims().x(), 100u);
  // A NIfTI file says no modality: the histogram does not look like CT.
  EXPECT_EQ(mr.kind(), v1::OTHER) << mr.kind_reason();
  EXPECT_EQ(mr.default_preset(), "auto");
  ASSERT_EQ(mr.histogram().counts_size(), 256);
  EXPECT_EQ(std::accumulate(mr.histogram().counts().begin(), mr.histogram().counts().end(), std::uint64_t{0}),
            std::uint64_t{mr.dims().x()} * mr.dims().y() * mr.dims().z());
  EXPECT_EQ(client.DescribeVolume(mr.id()).histogram().counts_size(), 256);
  for (const v1::VolumeInfo& v : client.ListVolumes()) EXPECT_EQ(v.histogram().counts_size(), 0) << v.id();
  // A session that names neither a scene nor a preset gets the default.
  v1::CreateSessionRequest r = SmallSession();
  r.clear_preset();
  r.set_volume_id(mr.id());
  const auto created = client.CreateSession(r);
  EXPECT_EQ(created.scene().transfer_function().preset(), "auto");
  auto stream = client.Attach(created.session_id());
  const auto frame = WaitFinal(*stream);
  ASSERT_TRUE(frame);
  EXPECT_GT(MeanLevel(Decode(*frame)), 1.0);
}

}  // namespace
}  // namespace cinevol::testing
