// No request holds the server: a tiny voxel spacing is refused by name from
// every door; a slice is bounded by what a screen shows, however hostile its
// volume or slab; slices run on a pool of their own, a share of the compute,
// apart from the setup pool that CreateSession waits on; and every call has a
// server-side deadline. Each attack runs beside a witness session on a real
// server (loopback, CPU) whose stream must not stop.
#include <gtest/gtest.h>
#include <nifti/nifti1.h>

#include <atomic>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <thread>
#include <vector>

#include "server_process.h"
#include "service_test_support.h"
#include "support/test_paths.h"

namespace cinevol::testing {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

double Seconds(Clock::duration d) { return std::chrono::duration<double>(d).count(); }

// A 16^3 int16 NIfTI-1 of `spacing` mm: 8 KiB, the size of the file that
// crashed the server at 1e-10 mm.
void WriteNifti(const fs::path& path, float spacing) {
  nifti_1_header h;
  std::memset(&h, 0, sizeof h);
  h.sizeof_hdr = 348;
  h.dim[0] = 3;
  h.dim[1] = h.dim[2] = h.dim[3] = 16;
  h.datatype = DT_INT16;
  h.bitpix = 16;
  h.pixdim[1] = h.pixdim[2] = h.pixdim[3] = spacing;
  h.vox_offset = 352;
  h.scl_slope = 1.0f;
  std::memcpy(h.magic, "n+1", 4);
  std::ofstream out(path, std::ios::binary);
  out.write(reinterpret_cast<const char*>(&h), sizeof h);
  out.write("\0\0\0\0", 4);
  for (int i = 0; i < 16 * 16 * 16; ++i) {
    const std::int16_t v = std::int16_t(i % 16 < 8 ? -1000 : 40);
    out.write(reinterpret_cast<const char*>(&v), 2);
  }
}

// A 2^3 NRRD whose voxels span 0.62 x 10^4 x 10^4 mm: at one pixel a voxel
// an oblique slice of it was 260 Mpx.
void WriteSlabOfSky(const fs::path& path) {
  std::ofstream out(path, std::ios::binary);
  out << "NRRD0004\ntype: short\ndimension: 3\nsizes: 2 2 2\nspacings: 0.62 10000 10000\nencoding: raw\n"
         "endian: little\n\n";
  for (std::int16_t v : {0, 100, 200, 300, 400, 500, 600, 700}) out.write(reinterpret_cast<const char*>(&v), 2);
}

v1::SliceRequest Oblique(const std::string& session, float slab_mm, float pixel_mm = 0) {
  v1::SliceRequest r;
  r.set_session_id(session);
  r.set_axis(v1::OBLIQUE);
  r.mutable_normal()->set_x(1);
  r.mutable_normal()->set_y(1);
  r.mutable_normal()->set_z(1);
  r.mutable_row()->set_x(1);
  r.set_slab_mm(slab_mm);
  r.set_projection(v1::MAXIMUM);
  r.set_pixel_mm(pixel_mm);
  return r;
}

// A server on the phantom with two principals and a data root, and alice's
// witness session streaming.
struct Fixture {
  explicit Fixture(const ScratchDir& scratch, std::vector<std::string> flags = {}) {
    std::ofstream(scratch / "tokens") << "alice-token alice\nbob-token bob\n";
    fs::create_directories(scratch / "data");
    flags.insert(flags.end(), {"--auth-tokens", (scratch / "tokens").string(), "--data-root",
                               (scratch / "data").string(), "--max-sessions-per-principal", "32"});
    server = std::make_unique<ServerProcess>(scratch.path(), flags);
    if (!server->running()) return;
    alice = std::make_unique<Client>(server->Connect("alice-token"));
    const auto created = alice->CreateSession(SmallSession("ct-bone", 96, 64, 65536));
    witness_stream = alice->Attach(created.session_id());
    first_frame = WaitFrame(*witness_stream, [](const v1::Frame&) { return true; }).has_value();
  }
  std::unique_ptr<ServerProcess> server;
  std::unique_ptr<Client> alice;
  std::unique_ptr<SessionStream> witness_stream;
  bool first_frame = false;
};

TEST(BoundedWork, ATinySpacingIsRefusedByNameFromEveryDoor) {
  ScratchDir scratch;
  Fixture f(scratch);
  ASSERT_TRUE(f.first_frame) << f.server->Log();
  WriteNifti(scratch / "data" / "tiny.nii", 1e-10f);
  Witness witness(*f.witness_stream);
  Client bob = f.server->Connect("bob-token");
  ExpectRpcError([&] { bob.LoadVolume("tiny.nii"); }, grpc::StatusCode::INVALID_ARGUMENT,
                 "spacing x is 1e-10 mm, outside [0.0001, 10000]");
  ExpectRpcError([&] { bob.UploadVolume(scratch / "data" / "tiny.nii"); }, grpc::StatusCode::INVALID_ARGUMENT,
                 "spacing x is 1e-10 mm");
  // The smallest spacing allowed loads, and renders.
  WriteNifti(scratch / "data" / "micro.nii", 1e-4f);
  v1::CreateSessionRequest micro = SmallSession("auto");
  micro.set_volume_id(bob.LoadVolume("micro.nii").id());
  auto stream = bob.Attach(bob.CreateSession(micro).session_id());
  EXPECT_TRUE(WaitFrame(*stream, [](const v1::Frame&) { return true; })) << stream->status().error_message();
  EXPECT_LT(witness.Stop().longest_gap_s, 1.0);
  ExpectServing(bob);
}

// The 260 Mpx slice of before, and two slabs of 9,999 mm: each answered at
// most 4096 pixels a side, in seconds, in bounded memory, while another
// principal's CreateSession goes through at once and the witness streams on.
TEST(BoundedWork, HugeSlicesAndSlabsAreBoundedByTheScreen) {
  ScratchDir scratch;
  Fixture f(scratch);
  ASSERT_TRUE(f.first_frame) << f.server->Log();
  WriteSlabOfSky(scratch / "data" / "sky.nrrd");
  Client bob = f.server->Connect("bob-token");
  v1::CreateSessionRequest sky = SmallSession("auto");
  sky.set_volume_id(bob.LoadVolume("sky.nrrd").id());
  const std::string session = bob.CreateSession(sky).session_id();
  const double resident_before = f.server->ResidentMiB();
  Witness witness(*f.witness_stream);

  Clock::time_point start = Clock::now();
  const v1::SliceImage huge = bob.RenderSlice(Oblique(session, 0));
  const double huge_seconds = Seconds(Clock::now() - start);
  EXPECT_LT(huge_seconds, 30.0);
  std::printf("the 260 Mpx slice of before: %ux%u px of %.2f mm in %.2f s, +%.0f MiB\n", huge.width(), huge.height(),
              huge.row_spacing_mm(), huge_seconds, f.server->ResidentMiB() - resident_before);
  EXPECT_LE(std::max(huge.width(), huge.height()), 4096u);
  EXPECT_GT(huge.row_spacing_mm(), 0.62f) << "the pixels grew to fit the screen";
  EXPECT_EQ(huge.slab_samples(), 1u);

  std::vector<std::thread> slabs;
  std::atomic<int> slab_failures{0};
  for (int i = 0; i < 2; ++i) {
    slabs.emplace_back([&] {
      try {
        Client own = f.server->Connect("bob-token");
        const v1::SliceImage slab = own.RenderSlice(Oblique(session, 9999));
        if (std::uint64_t(slab.width()) * slab.height() * slab.slab_samples() > (std::uint64_t{1} << 27)) ++slab_failures;
      } catch (const std::exception& e) {
        ADD_FAILURE() << e.what();
      }
    });
  }
  std::this_thread::sleep_for(200ms);
  start = Clock::now();
  const auto created = f.alice->CreateSession(SmallSession());
  EXPECT_LT(Seconds(Clock::now() - start), 5.0) << "CreateSession waited behind bob's slabs";
  f.alice->CloseSession(created.session_id());
  for (std::thread& t : slabs) t.join();
  EXPECT_EQ(slab_failures.load(), 0) << "a slab took more than 2^27 samples";
  const Witness::Report seen = witness.Stop();
  EXPECT_LT(seen.longest_gap_s, 1.0) << "the witness's stream stopped";
  EXPECT_LT(f.server->ResidentMiB() - resident_before, 400.0);
}

// A call past --max-call-seconds ends with DEADLINE_EXCEEDED naming the flag,
// within a fraction of a second of its deadline, with nothing left running.
TEST(BoundedWork, EveryCallHasAServerSideDeadline) {
  ScratchDir scratch;
  Fixture f(scratch, {"--max-call-seconds", "0.2"});
  ASSERT_TRUE(f.first_frame) << f.server->Log();
  // The largest slice there is: 4096 x 4096 pixels of a 7-sample slab, a
  // second or more of one thread's time.
  const std::string session = f.alice->CreateSession(SmallSession()).session_id();
  const Clock::time_point start = Clock::now();
  ExpectRpcError([&] { f.alice->RenderSlice(Oblique(session, 80, 0.01f)); }, grpc::StatusCode::DEADLINE_EXCEEDED,
                 "--max-call-seconds");
  EXPECT_LT(Seconds(Clock::now() - start), 1.5);
  ExpectServing(*f.alice);
}

// Twelve of the heaviest slabs at once from one principal take their share of the
// compute, not the neighbour's: its frame rate holds within a fraction of a
// calm one and its stream never stops for a second.
TEST(BoundedWork, ManySlabsFromOneCallerLeaveTheNeighbourItsFrames) {
  ScratchDir scratch;
  Fixture f(scratch);
  ASSERT_TRUE(f.first_frame) << f.server->Log();
  Client bob = f.server->Connect("bob-token");
  const std::string session = bob.CreateSession(SmallSession()).session_id();
  Witness calm_witness(*f.witness_stream);
  std::this_thread::sleep_for(3s);
  const double calm = calm_witness.Stop().fps;

  std::atomic<bool> stop{false};
  std::vector<std::thread> slabs;
  for (int i = 0; i < 12; ++i) {
    slabs.emplace_back([&] {
      ClientOptions options;
      options.address = f.server->address();
      options.token = "bob-token";
      options.call_timeout = 5s;  // a slab queued behind the others gives up: the load is what matters
      Client own(options);
      for (int k = 0; k < 50 && !stop; ++k) {
        try {
          own.RenderSlice(Oblique(session, 80, 0.05f));  // 2.7 Mpx of a 49-sample slab: 2^27 samples
        } catch (const std::exception&) {
        }
      }
    });
  }
  std::this_thread::sleep_for(500ms);
  Witness loaded_witness(*f.witness_stream);
  std::this_thread::sleep_for(4s);
  const Witness::Report loaded = loaded_witness.Stop();
  stop = true;
  for (std::thread& t : slabs) t.join();
  EXPECT_GE(loaded.fps, 0.3 * calm) << "calm " << calm << " fps, beside the slabs " << loaded.fps;
  EXPECT_LT(loaded.longest_gap_s, 1.0);
}

}  // namespace
}  // namespace cinevol::testing
