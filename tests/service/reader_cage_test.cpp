// The reader cage against a real server (issue 31): each class of file that
// once took the server down now fails its own call with a message that names
// it, while a witness session keeps streaming; a reader killed from outside or
// cancelled ends cleanly; memory is refused from the header, before any
// voxel is read; with the readers' pre-checks off, the fuzz regression inputs
// crash only their reader.
#include <gdcmAttribute.h>
#include <gdcmReader.h>
#include <gdcmWriter.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <zlib.h>

#include <cstdlib>
#include <cstring>
#include <fstream>
#include <limits>
#include <sstream>

#include "service/server_process.h"
#include "service/service_test_support.h"
#include "support/test_paths.h"

namespace cinevol::testing {
namespace {

namespace fs = std::filesystem;

// A session on the phantom that must keep answering events with frames.
class Witness {
 public:
  explicit Witness(const ServerProcess& server) : client_(server.Connect()) {
    id_ = client_.CreateSession(SmallSession()).session_id();
    stream_ = client_.Attach(id_);
  }
  // Sends an event and waits for a frame that shows it.
  bool Live() {
    const std::uint64_t seq = stream_->Send(Orbit(++step_));
    return seq > 0 && WaitFrame(*stream_, [seq](const v1::Frame& f) { return f.last_event_seq() >= seq; }, 30s);
  }

 private:
  Client client_;
  std::string id_;
  std::unique_ptr<SessionStream> stream_;
  int step_ = 0;
};

// The cinevol-reader children of `server`.
std::vector<pid_t> Readers(pid_t server) {
  std::vector<pid_t> found;
  for (const auto& entry : fs::directory_iterator("/proc")) {
    const std::string name = entry.path().filename().string();
    if (name.find_first_not_of("0123456789") != std::string::npos) continue;
    std::ifstream in(entry.path() / "stat");
    std::string stat((std::istreambuf_iterator<char>(in)), {});
    const auto close = stat.rfind(')');
    if (close == std::string::npos || stat.find("(cinevol-reader)") == std::string::npos) continue;
    std::istringstream rest(stat.substr(close + 2));
    char state;
    pid_t parent = 0;
    rest >> state >> parent;
    if (parent == server) found.push_back(pid_t(std::stoi(name)));
  }
  return found;
}

// The readers of `server` at work on a file named `file` (one of their
// descriptors leads to it); the spare reader a server keeps ready has none.
std::vector<pid_t> ReadersOf(pid_t server, const std::string& file) {
  std::vector<pid_t> found;
  for (pid_t pid : Readers(server)) {
    std::error_code ec;
    for (const auto& fd : fs::directory_iterator("/proc/" + std::to_string(pid) + "/fd", ec)) {
      const fs::path target = fs::read_symlink(fd.path(), ec);
      if (!ec && target.filename() == file) {
        found.push_back(pid);
        break;
      }
    }
  }
  return found;
}

// The server's peak resident memory so far, KiB (VmHWM).
long PeakKib(pid_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/status");
  for (std::string line; std::getline(in, line);) {
    if (line.rfind("VmHWM:", 0) == 0) return std::stol(line.substr(6));
  }
  return -1;
}

std::string NrrdHeader(const std::string& type, const std::string& sizes, const std::string& encoding = "raw") {
  return "NRRD0004\ntype: " + type + "\ndimension: 3\nsizes: " + sizes + "\nspacings: 1 1 1\nencoding: " + encoding +
         "\nendian: little\n\n";
}

void WriteFloatNrrd(const fs::path& path, const std::vector<float>& first_values) {
  std::vector<float> values(8 * 8 * 8, 100.0f);
  std::copy(first_values.begin(), first_values.end(), values.begin());
  std::ofstream out(path, std::ios::binary);
  out << NrrdHeader("float", "8 8 8");
  out.write(reinterpret_cast<const char*>(values.data()), std::streamsize(values.size() * sizeof(float)));
}

// A gzip NRRD of `bytes` zero bytes: a small file whose header declares a
// large volume.
void WriteDeclaredHugeNrrd(const fs::path& path, const std::string& type, const std::string& sizes,
                           std::uint64_t bytes) {
  std::ofstream out(path, std::ios::binary);
  out << NrrdHeader(type, sizes, "gzip");
  z_stream z{};
  deflateInit2(&z, 9, Z_DEFLATED, 15 + 16, 9, Z_DEFAULT_STRATEGY);
  std::vector<unsigned char> zeros(1 << 20, 0), buffer(1 << 20);
  for (std::uint64_t done = 0; done < bytes;) {
    const std::uint64_t n = std::min<std::uint64_t>(zeros.size(), bytes - done);
    done += n;
    z.next_in = zeros.data();
    z.avail_in = uInt(n);
    do {
      z.next_out = buffer.data();
      z.avail_out = uInt(buffer.size());
      deflate(&z, done == bytes ? Z_FINISH : Z_NO_FLUSH);
      out.write(reinterpret_cast<const char*>(buffer.data()), std::streamsize(buffer.size() - z.avail_out));
    } while (z.avail_out == 0);
  }
  deflateEnd(&z);
}

// An ASCII NRRD whose 2^24 values take teem seconds to parse.
void WriteSlowNrrd(const fs::path& path) {
  std::ofstream out(path, std::ios::binary);
  out << NrrdHeader("uchar", "256 256 256", "ascii");
  const std::string values(std::size_t(2) << 24, ' ');
  std::string text = values;
  for (std::size_t i = 0; i < text.size(); i += 2) text[i] = '7';
  out << text;
}

// A copy of a real DICOM slice, marked with another Photometric Interpretation.
void WriteMarkedSlice(const fs::path& from, const fs::path& to, const std::string& photometric) {
  gdcm::Reader reader;
  reader.SetFileName(from.c_str());
  ASSERT_TRUE(reader.Read()) << from;
  gdcm::DataSet& ds = reader.GetFile().GetDataSet();
  gdcm::Attribute<0x0028, 0x0004> pi;
  pi.SetValue(photometric);
  ds.Replace(pi.GetAsDataElement());
  gdcm::Writer writer;
  writer.CheckFileMetaInformationOff();  // the shared slices have no SOP class to rebuild it from
  writer.SetFile(reader.GetFile());
  writer.SetFileName(to.c_str());
  ASSERT_TRUE(writer.Write()) << to;
}

fs::path FirstFile(const fs::path& folder, const std::string& prefix) {
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(folder)) {
    if (e.path().filename().string().rfind(prefix, 0) == 0) files.push_back(e.path());
  }
  std::sort(files.begin(), files.end());
  return files.empty() ? fs::path() : files.front();
}

bool Alive(const ServerProcess& server) { return WaitExit(server.pid(), 0ms) == -1; }

TEST(ReaderCage, HostileFilesFailTheirOwnCallWhileAWitnessStreams) {
  ScratchDir scratch;
  const fs::path data = scratch / "data";
  fs::create_directories(data);
  ServerProcess server(scratch.path(), {"--data-root", data.string(), "--max-volume-memory-mb", "64",
                                        "--max-upload-memory-mb", "64"});
  ASSERT_TRUE(server.running()) << server.Log();
  Witness witness(server);
  ASSERT_TRUE(witness.Live());
  Client client = server.Connect();

  // A per-axis field line past 1,000 characters aborted teem (and the server).
  {
    std::ofstream out(scratch / "long.nrrd", std::ios::binary);
    out << "NRRD0004\ntype: short\ndimension: 3\nsizes: 4 4 4" << std::string(1200, ' ')
        << "\nspacings: 1 1 1\nencoding: raw\nendian: little\n\n"
        << std::string(128, '\0');
  }
  ExpectRpcError([&] { client.UploadVolume(scratch / "long.nrrd"); }, grpc::StatusCode::INVALID_ARGUMENT,
                 "upload:long.nrrd: the header's 'sizes' line has");
  EXPECT_TRUE(witness.Live());

  // Values float32 holds but the renderer cannot: refused, naming the range.
  const float max = std::numeric_limits<float>::max();
  WriteFloatNrrd(scratch / "max.nrrd", {max, -max});
  ExpectRpcError([&] { client.UploadVolume(scratch / "max.nrrd"); }, grpc::StatusCode::INVALID_ARGUMENT,
                 "values must lie within [-1e+30, 1e+30]");
  EXPECT_TRUE(witness.Live());

  // Subnormals are flushed: the volume loads and renders.
  WriteFloatNrrd(scratch / "subnormal.nrrd", {1e-40f, -1e-40f, 1e-39f});
  const v1::VolumeInfo subnormal = client.UploadVolume(scratch / "subnormal.nrrd");
  v1::CreateSessionRequest on_it = SmallSession();
  on_it.set_volume_id(subnormal.id());
  const auto created = client.CreateSession(on_it);
  auto stream = client.Attach(created.session_id());
  EXPECT_TRUE(WaitFrame(*stream, [](const v1::Frame&) { return true; }, 30s));
  EXPECT_TRUE(witness.Live());

  // A gzip upload of 260 KB declaring 2^28 voxels: refused from its header,
  // before a voxel is read (it once peaked at 8 to 35 times the limit).
  WriteDeclaredHugeNrrd(scratch / "huge.nrrd", "uchar", "1024 1024 256", std::uint64_t(1) << 28);
  const long peak_before = PeakKib(server.pid());
  ExpectRpcError([&] { client.UploadVolume(scratch / "huge.nrrd"); }, grpc::StatusCode::RESOURCE_EXHAUSTED,
                 "--max-upload-memory-mb");
  const long peak_after = PeakKib(server.pid());
  EXPECT_LT(peak_after - peak_before, 48 * 1024) << "the server's peak memory grew by " << (peak_after - peak_before)
                                                 << " KiB for a refused upload";
  EXPECT_TRUE(witness.Live());

  // A segmentation far larger than the limits, for a small volume: the same.
  WriteDeclaredHugeNrrd(data / "seg.nrrd", "uchar", "1024 1024 256", std::uint64_t(1) << 28);
  {
    std::ofstream small(data / "small.nrrd", std::ios::binary);
    small << NrrdHeader("short", "8 8 8") << std::string(8 * 8 * 8 * 2, '\0');
  }
  const v1::VolumeInfo small = client.LoadVolume("small.nrrd");
  ExpectRpcError([&] { client.LoadLabels(small.id(), "seg.nrrd"); }, grpc::StatusCode::RESOURCE_EXHAUSTED,
                 "--max-volume-memory-mb");
  EXPECT_TRUE(witness.Live());

  // DICOM slices whose Photometric Interpretation disagrees with their codec
  // (GDCM asserted or crashed on them): refused, naming the file.
  if (fs::exists(SharedData())) {
    const fs::path ct = FirstFile(SharedData() / "ct-body-totalsegmentator/example_ct_dicom", "CT");
    const fs::path mr = FirstFile(SharedData() / "mr-chest-dicom-seg3d", "IM");
    const std::vector<std::pair<fs::path, std::string>> cases = {
        {ct, "YBR_FULL"}, {ct, "YBR_RCT"}, {mr, "ARGB"}, {mr, "YBR_FULL"}, {mr, "YBR_FULL_422"}};
    for (std::size_t i = 0; i < cases.size(); ++i) {
      const fs::path folder = data / ("dicom-" + std::to_string(i));
      fs::create_directories(folder);
      WriteMarkedSlice(cases[i].first, folder / "slice.dcm", cases[i].second);
      ExpectRpcError([&] { client.LoadVolume(folder.filename().string()); }, grpc::StatusCode::INVALID_ARGUMENT,
                     "Photometric Interpretation '" + cases[i].second + "'");
      EXPECT_TRUE(witness.Live()) << cases[i].second;
    }
  }
  EXPECT_TRUE(Alive(server)) << server.Log();
  EXPECT_LE(Readers(server.pid()).size(), 1u) << "a reader outlived its load (one spare waits)";
}

TEST(ReaderCage, AReaderKilledFromOutsideFailsItsLoadCleanly) {
  ScratchDir scratch;
  const fs::path data = scratch / "data";
  fs::create_directories(data);
  WriteSlowNrrd(data / "slow.nrrd");
  ServerProcess server(scratch.path(), {"--data-root", data.string()});
  ASSERT_TRUE(server.running()) << server.Log();
  Witness witness(server);
  for (const int sig : {SIGKILL, SIGSEGV}) {
    std::thread killer([&] {
      std::vector<pid_t> readers;
      Eventually([&] { return !(readers = ReadersOf(server.pid(), "slow.nrrd")).empty(); }, 20s);
      for (pid_t pid : readers) kill(pid, sig);
    });
    Client client = server.Connect();
    ExpectRpcError([&] { client.LoadVolume("slow.nrrd"); }, grpc::StatusCode::INVALID_ARGUMENT,
                   std::string("path 'slow.nrrd': the NRRD reader stopped (SIG") + sigabbrev_np(sig) + ")");
    killer.join();
    EXPECT_TRUE(witness.Live());
  }
  EXPECT_TRUE(Alive(server)) << server.Log();
}

TEST(ReaderCage, ALoadOrUploadWhoseCallerGoesAwayKillsItsReaderWithinASecond) {
  ScratchDir scratch;
  const fs::path data = scratch / "data";
  fs::create_directories(data);
  WriteSlowNrrd(data / "slow.nrrd");
  ServerProcess server(scratch.path(), {"--data-root", data.string()});
  ASSERT_TRUE(server.running()) << server.Log();
  Client client = server.Connect();
  auto stub = v1::VolumeService::NewStub(client.channel());
  grpc::ClientContext context;
  v1::LoadVolumeRequest request;
  request.set_path("slow.nrrd");
  v1::VolumeInfo info;
  std::vector<pid_t> working;
  std::thread canceller([&] {
    Eventually([&] { return !(working = ReadersOf(server.pid(), "slow.nrrd")).empty(); }, 20s);
    context.TryCancel();
  });
  const grpc::Status status = stub->LoadVolume(&context, request, &info);
  canceller.join();
  EXPECT_EQ(status.error_code(), grpc::StatusCode::CANCELLED);
  ASSERT_FALSE(working.empty());
  EXPECT_TRUE(Eventually([&] { return kill(working[0], 0) != 0; }, 1s)) << "the reader outlived its caller";

  // The same for an upload cancelled while it loads.
  grpc::ClientContext upload_context;
  auto writer = stub->UploadVolume(&upload_context, &info);
  std::ifstream in(data / "slow.nrrd", std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), {});
  v1::UploadVolumeChunk chunk;
  chunk.mutable_header()->set_file_name("slow.nrrd");
  chunk.mutable_header()->set_size_bytes(bytes.size());
  ASSERT_TRUE(writer->Write(chunk));
  for (std::size_t at = 0; at < bytes.size(); at += 1 << 20) {
    chunk.Clear();
    chunk.set_data(bytes.substr(at, 1 << 20));
    ASSERT_TRUE(writer->Write(chunk));
  }
  writer->WritesDone();
  // The server names the uploaded file itself: the reader at work is the one that is not the spare.
  ASSERT_TRUE(Eventually([&] { return !(working = ReadersOf(server.pid(), "0.nrrd")).empty(); }, 20s));
  upload_context.TryCancel();
  EXPECT_EQ(writer->Finish().error_code(), grpc::StatusCode::CANCELLED);
  EXPECT_TRUE(Eventually([&] { return kill(working[0], 0) != 0; }, 1s)) << "the reader outlived its upload";
  ExpectServing(client);
}

TEST(ReaderCage, SigtermKillsTheReadersOfLoadsUnderWay) {
  ScratchDir scratch;
  const fs::path data = scratch / "data";
  fs::create_directories(data);
  WriteSlowNrrd(data / "slow.nrrd");
  ServerProcess server(scratch.path(), {"--data-root", data.string()});
  ASSERT_TRUE(server.running()) << server.Log();
  std::thread load([&] {
    Client client = server.Connect();
    try {
      client.LoadVolume("slow.nrrd");
    } catch (const std::exception&) {
      // UNAVAILABLE or CANCELLED: the server drains
    }
  });
  std::vector<pid_t> readers;
  ASSERT_TRUE(Eventually([&] { return !(readers = ReadersOf(server.pid(), "slow.nrrd")).empty(); }, 20s));
  kill(server.pid(), SIGTERM);
  EXPECT_TRUE(Eventually([&] { return kill(readers[0], 0) != 0; }, 1s)) << "the reader outlived the drain";
  load.join();
  server.Stop();
}

// With the readers' own pre-checks off, each input that once crashed a reader
// crashes it again, in its cage: the call fails, the server goes on.
TEST(ReaderCage, WithoutPreChecksTheFuzzRegressionsCrashOnlyTheirReader) {
  const fs::path corpus = fs::path(CINEVOL_SOURCE_DIR) / "tests/fuzz/corpus/volume";
  if (!fs::is_directory(corpus)) GTEST_SKIP() << "no fuzz corpus at " << corpus;
  ScratchDir scratch;
  const fs::path data = scratch / "data";
  fs::create_directories(data);
  setenv("CINEVOL_READER_PRECHECKS", "off", 1);
  ServerProcess server(scratch.path(), {"--data-root", data.string()});
  unsetenv("CINEVOL_READER_PRECHECKS");
  ASSERT_TRUE(server.running()) << server.Log();
  Witness witness(server);
  Client client = server.Connect();
  // tests/fuzz/fuzz_volume.cpp: the first byte picks the format, the rest is the file.
  const char* kExtensions[] = {".nii", ".nii.gz", ".nrrd", ".mha", ".vtk", ""};
  int inputs = 0, crashed = 0;
  for (const auto& entry : fs::directory_iterator(corpus)) {
    if (entry.path().filename().string().rfind("regression-", 0) != 0) continue;
    std::ifstream in(entry.path(), std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), {});
    if (bytes.empty()) continue;
    const std::string extension = kExtensions[static_cast<unsigned char>(bytes[0]) % 6];
    const std::string name = "input-" + std::to_string(inputs++);
    try {
      if (extension.empty()) {
        fs::create_directories(data / name);
        std::ofstream(data / name / "slice.dcm", std::ios::binary) << bytes.substr(1);
        client.LoadVolume(name);
      } else {
        std::ofstream(scratch / (name + extension), std::ios::binary) << bytes.substr(1);
        client.UploadVolume(scratch / (name + extension));
      }
    } catch (const RpcError& e) {  // refused, or its reader stopped: either way its own call's error
      if (std::string(e.what()).find("reader stopped (SIG") != std::string::npos) ++crashed;
    }
    EXPECT_TRUE(witness.Live()) << entry.path().filename();
  }
  EXPECT_GT(inputs, 0);
  EXPECT_GT(crashed, 0) << "none of the regression inputs crashed a reader without the pre-checks";
  EXPECT_TRUE(Alive(server)) << server.Log();
}

}  // namespace
}  // namespace cinevol::testing
