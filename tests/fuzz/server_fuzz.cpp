// cinevol-server-fuzz: a real cinevol-server fed mutated volume files, with a
// witness session that must keep streaming throughout. The server runs on a
// free loopback port with a small data root and low memory limits; inputs
// are the fuzz corpora (tests/fuzz/corpus/volume and /dicom, their
// regression inputs included) as they are, then mutations of them: byte-level
// for every format, element-level for DICOM (dicom_model.h). NIfTI, NRRD,
// MetaImage and VTK go in as uploads; DICOM as a series of 1 to 3 slices
// placed in the data root and loaded with LoadVolume. What loads is unloaded.
//
// It reports the inputs tried, their outcomes (loaded; refused, by status
// code; the reader stopped, by signal or limit), the server's deaths (each
// one a bug: the server is started again and the input kept) and the
// witness's frames before, during and after. tests/fuzz/server-fuzz.sh runs
// it; docs/security.md has the figures.
//
//   cinevol-server-fuzz --server build/cinevol-server --corpus tests/fuzz/corpus --out DIR
//                       [--inputs N] [--seconds S] [--seed N] [--prechecks on|off] [--replay-only]
#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <optional>
#include <regex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "client.h"
#include "dicom_model.h"

extern char** environ;

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;
using namespace std::chrono_literals;

namespace {

using cinevol::fuzz::Random;

struct Options {
  std::string server;
  fs::path corpus = "tests/fuzz/corpus";
  fs::path out;
  std::uint64_t inputs = 1000;  // mutated inputs, after the corpus as it is
  double seconds = 600;         // for the whole run
  std::uint64_t seed = 1;
  bool prechecks_off = false;
  bool replay_only = false;
};

[[noreturn]] void Usage(const std::string& problem) {
  std::cerr << "cinevol-server-fuzz: " << problem
            << "\nusage: cinevol-server-fuzz --server PATH --out DIR [--corpus DIR] [--inputs N] [--seconds S]"
               " [--seed N] [--prechecks on|off] [--replay-only]\n";
  std::exit(2);
}

Options Parse(int argc, char** argv) {
  Options o;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) Usage(a + " needs a value");
      return argv[++i];
    };
    if (a == "--server") o.server = value();
    else if (a == "--corpus") o.corpus = value();
    else if (a == "--out") o.out = value();
    else if (a == "--inputs") o.inputs = std::stoull(value());
    else if (a == "--seconds") o.seconds = std::stod(value());
    else if (a == "--seed") o.seed = std::stoull(value());
    else if (a == "--prechecks") o.prechecks_off = value() == "off";
    else if (a == "--replay-only") o.replay_only = true;
    else Usage("unknown argument " + a);
  }
  if (o.server.empty() || o.out.empty()) Usage("--server and --out are needed");
  return o;
}

std::string ReadFile(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

void WriteFile(const fs::path& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary) << bytes;
}

// ---- the server

class Server {
 public:
  Server(const Options& options, const fs::path& data_root, int generation) {
    const fs::path port_file = options.out / "port";
    fs::remove(port_file);
    log_ = options.out / ("server-" + std::to_string(generation) + ".log");
    std::vector<std::string> args{options.server,
                                  "--listen", "127.0.0.1:0",
                                  "--port-file", port_file.string(),
                                  "--backend", "cpu",
                                  "--data-root", data_root.string(),
                                  "--volume", "phantom:head?size=32",
                                  "--encode-threads", "1",
                                  "--max-volume-memory-mb", "64",
                                  "--max-upload-memory-mb", "64",
                                  "--max-upload-mb", "16"};
    std::vector<char*> argv;
    for (std::string& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, 1, log_.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_adddup2(&actions, 1, 2);
    if (posix_spawn(&pid_, argv[0], &actions, nullptr, argv.data(), environ) != 0) pid_ = -1;
    posix_spawn_file_actions_destroy(&actions);
    for (const auto end = Clock::now() + 60s; pid_ > 0 && port_ == 0 && Clock::now() < end;) {
      std::ifstream(port_file) >> port_;
      if (port_ == 0) std::this_thread::sleep_for(50ms);
      if (!Alive()) return;
    }
  }
  ~Server() { Stop(); }

  bool running() const { return pid_ > 0 && port_ > 0; }
  std::string address() const { return "127.0.0.1:" + std::to_string(port_); }
  pid_t pid() const { return pid_; }

  // Whether it still runs; once it has ended, how (`ended()`).
  bool Alive() {
    if (pid_ <= 0) return false;
    int status = 0;
    if (waitpid(pid_, &status, WNOHANG) == pid_) {
      pid_ = -1;
      ended_ = WIFSIGNALED(status) ? std::string("signal ") + sigabbrev_np(WTERMSIG(status))
                                   : "exit " + std::to_string(WEXITSTATUS(status));
      return false;
    }
    return true;
  }
  const std::string& ended() const { return ended_; }

  void Stop() {
    if (pid_ <= 0) return;
    kill(pid_, SIGTERM);
    for (const auto end = Clock::now() + 15s; Clock::now() < end;) {
      if (waitpid(pid_, nullptr, WNOHANG) == pid_) {
        pid_ = -1;
        return;
      }
      std::this_thread::sleep_for(20ms);
    }
    kill(pid_, SIGKILL);
    waitpid(pid_, nullptr, 0);
    pid_ = -1;
  }

 private:
  pid_t pid_ = -1;
  int port_ = 0;
  std::string ended_;
  fs::path log_;
};

// ---- the witness: a session that must keep streaming

class Witness {
 public:
  explicit Witness(cinevol::Client& client) {
    cinevol::v1::CreateSessionRequest r;
    r.set_volume_id("phantom:head?size=32");
    r.mutable_viewport()->set_width(48);
    r.mutable_viewport()->set_height(32);
    r.set_preset("ct-bone");
    r.mutable_stream()->set_target_spp(2);
    session_ = client.CreateSession(r).session_id();
    cinevol::StreamOptions options;
    options.failover = false;
    options.on_message = [this](const cinevol::v1::ServerMessage& m) {
      if (m.has_frame()) frames_.fetch_add(1);
    };
    stream_ = client.Attach(session_, options);
    // A camera that keeps moving keeps frames coming.
    mover_ = std::thread([this] {
      for (int step = 0; !stop_.load(); ++step) {
        cinevol::v1::SessionEvent e;
        cinevol::v1::Camera* c = e.mutable_camera();
        c->mutable_eye()->set_x(float(200 * std::sin(step * 0.05)));
        c->mutable_eye()->set_y(float(-200 * std::cos(step * 0.05)));
        c->mutable_target();
        c->mutable_up()->set_z(1);
        stream_->Send(e);
        std::this_thread::sleep_for(250ms);
      }
    });
  }
  ~Witness() {
    stop_ = true;
    mover_.join();
    stream_->Cancel();
  }

  std::uint64_t frames() const { return frames_.load(); }
  bool open() const { return !stream_->ended(); }
  std::string status() const { return stream_->ended() ? stream_->status().error_message() : "open"; }

  // Waits up to `timeout` for frames past `count`.
  bool FramesPast(std::uint64_t count, std::chrono::milliseconds timeout) const {
    for (const auto end = Clock::now() + timeout; Clock::now() < end;) {
      if (frames_.load() > count) return true;
      std::this_thread::sleep_for(50ms);
    }
    return frames_.load() > count;
  }

 private:
  std::string session_;
  std::unique_ptr<cinevol::SessionStream> stream_;
  std::atomic<std::uint64_t> frames_{0};
  std::atomic<bool> stop_{false};
  std::thread mover_;
};

// ---- inputs

constexpr const char* kExtensions[] = {".nii", ".nii.gz", ".nrrd", ".mha", ".vtk", ""};  // fuzz_volume's format byte

struct Seed {
  std::string name;
  std::string bytes;  // a volume file (without fuzz_volume's format byte) or a DICOM file
  std::string extension;  // "" for DICOM
};

struct Input {
  std::string origin;                // the seed's name, and how it was changed
  std::string extension;             // "" for a DICOM series
  std::vector<std::string> files;    // one upload, or the series' slices
};

std::vector<Seed> ReadSeeds(const fs::path& corpus) {
  std::vector<Seed> seeds;
  std::vector<fs::path> files;
  for (const char* folder : {"volume", "dicom"}) {
    for (const auto& entry : fs::directory_iterator(corpus / folder)) files.push_back(entry.path());
  }
  std::sort(files.begin(), files.end());
  for (const fs::path& f : files) {
    const std::string bytes = ReadFile(f);
    const std::string name = f.parent_path().filename().string() + "/" + f.filename().string();
    if (f.parent_path().filename() == "dicom") {
      seeds.push_back({name, bytes, ""});
    } else if (!bytes.empty()) {
      seeds.push_back({name, bytes.substr(1), kExtensions[std::uint8_t(bytes[0]) % std::size(kExtensions)]});
    }
  }
  return seeds;
}

// A DICOM file as a series: as many slices as its preamble asks for.
std::vector<std::string> SeriesOf(const std::string& bytes) {
  const auto* data = reinterpret_cast<const std::uint8_t*>(bytes.data());
  if (std::optional<cinevol::fuzz::DicomFile> file = cinevol::fuzz::ParseDicom(data, bytes.size())) {
    const int count = cinevol::fuzz::SliceCount(*file);
    if (count > 1) return cinevol::fuzz::Slices(*file, count);
  }
  return {bytes};
}

Input AsIs(const Seed& seed) {
  return {seed.name, seed.extension, seed.extension.empty() ? SeriesOf(seed.bytes) : std::vector{seed.bytes}};
}

// A mutation of a seed: one to four rounds, DICOM by elements (and bytes), the others by bytes.
Input Mutated(const Seed& seed, Random& random) {
  constexpr std::size_t kMaxBytes = 1 << 20;
  const cinevol::fuzz::ByteMutator bytes = cinevol::fuzz::PlainByteMutator(random);
  std::string data = seed.bytes;
  const std::size_t rounds = 1 + random.Below(4);
  for (std::size_t r = 0; r < rounds; ++r) {
    if (seed.extension.empty()) {
      data = cinevol::fuzz::MutateDicomBytes(reinterpret_cast<const std::uint8_t*>(data.data()), data.size(),
                                             kMaxBytes, random, bytes);
    } else {
      data = cinevol::fuzz::MutateString(data, bytes, std::min(kMaxBytes, data.size() + 256));
    }
  }
  Input in{seed.name + " mutated x" + std::to_string(rounds), seed.extension, {}};
  in.files = seed.extension.empty() ? SeriesOf(data) : std::vector{data};
  return in;
}

// ---- outcomes

// "loaded", "refused INVALID_ARGUMENT", "reader stopped (SIGSEGV)", "reader: cpu", ...
std::string Classify(const cinevol::RpcError& e) {
  const std::string what = e.what();
  static const std::regex kSignal(R"(reader stopped \((SIG[A-Z0-9]+|signal [0-9]+)\))");
  std::smatch m;
  if (std::regex_search(what, m, kSignal)) return "reader stopped by " + m[1].str();
  if (what.find("stopped by its sandbox") != std::string::npos) return "reader stopped by its sandbox (SIGSYS)";
  if (what.find("ran out of memory") != std::string::npos) return "reader out of memory";
  if (what.find("of CPU time") != std::string::npos) return "reader out of CPU time";
  if (what.find("took longer than") != std::string::npos) return "reader out of time";
  if (what.find("without an answer") != std::string::npos || what.find("out of turn") != std::string::npos ||
      what.find("does not hold together") != std::string::npos || what.find("impossible") != std::string::npos) {
    return "reader broke the protocol";
  }
  return "refused " + cinevol::StatusCodeName(e.code());
}

bool ReaderStopped(const std::string& outcome) { return outcome.rfind("reader ", 0) == 0; }

struct Tally {
  std::uint64_t inputs = 0, replayed = 0, mutated = 0, uploads = 0, series = 0, slices = 0;
  std::map<std::string, std::uint64_t> outcomes;
  std::map<std::string, std::uint64_t> regression_outcomes;  // the committed regression inputs, replayed
  std::uint64_t deaths = 0;
  std::vector<std::string> death_notes;
  std::uint64_t slot_waits = 0;  // seconds an input waited for an earlier load to end
  std::uint64_t kept = 0;
};

// ---- the run

class Run {
 public:
  explicit Run(const Options& options) : o_(options), random_(options.seed) {
    fs::create_directories(o_.out / "kept");
    data_root_ = o_.out / "data";
    fs::remove_all(data_root_);
    fs::create_directories(data_root_);
    uploads_ = o_.out / "uploads";
    fs::create_directories(uploads_);
    if (o_.prechecks_off) setenv("CINEVOL_READER_PRECHECKS", "off", 1);
  }

  int Main() {
    const auto start = Clock::now();
    const auto end = start + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(o_.seconds));
    if (!Start()) return 1;
    const std::vector<Seed> seeds = ReadSeeds(o_.corpus);
    Connect();
    const std::uint64_t before = FramesIn(5s);  // the witness's pace with nothing else to do
    const std::uint64_t frames_before = Frames();
    const auto inputs_start = Clock::now();
    for (const Seed& seed : seeds) {
      if (Clock::now() > end) break;
      const std::string outcome = Feed(AsIs(seed));
      ++tally_.replayed;
      if (seed.name.find("/regression-") != std::string::npos) {
        tally_.regression_outcomes[seed.name + ": " + outcome]++;
      }
    }
    for (std::uint64_t i = 0; !o_.replay_only && i < o_.inputs && Clock::now() < end; ++i) {
      Feed(Mutated(seeds[random_.Below(seeds.size())], random_));
      ++tally_.mutated;
      if (tally_.inputs % 500 == 0) Progress(start);
    }
    const std::uint64_t during = Frames() - frames_before;
    const double during_s = std::chrono::duration<double>(Clock::now() - inputs_start).count();
    const std::uint64_t after = FramesIn(5s);
    const bool open = witness_->open();
    const bool ok = tally_.deaths == 0 && after > 0 && open;
    Report(start, before, during, during_s, after, ok);
    witness_.reset();
    client_.reset();
    server_->Stop();
    return ok ? 0 : 1;
  }

 private:
  bool Start() {
    server_ = std::make_unique<Server>(o_, data_root_, ++generation_);
    if (!server_->running()) {
      std::cerr << "cinevol-server did not start; see " << (o_.out / "server-1.log") << "\n";
      return false;
    }
    return true;
  }

  void Connect() {
    cinevol::ClientOptions options;
    options.address = server_->address();
    options.call_timeout = 330s;  // past the reader's own limit (300 s)
    client_ = std::make_unique<cinevol::Client>(options);
    witness_ = std::make_unique<Witness>(*client_);
    if (!witness_->FramesPast(0, 60s)) std::cerr << "the witness got no first frame\n";
  }

  // Feeds one input; returns its outcome.
  std::string Feed(const Input& in) {
    ++tally_.inputs;
    std::string outcome;
    std::string volume_id;
    const std::uint64_t n = tally_.inputs;
    fs::path placed;
    try {
      if (in.extension.empty()) {
        ++tally_.series;
        tally_.slices += in.files.size();
        placed = data_root_ / ("series-" + std::to_string(n));
        fs::create_directories(placed);
        for (std::size_t i = 0; i < in.files.size(); ++i) {
          WriteFile(placed / ("slice" + std::to_string(i) + ".dcm"), in.files[i]);
        }
        volume_id = WithSlot([&] { return client_->LoadVolume(placed.filename().string()).id(); });
      } else {
        ++tally_.uploads;
        placed = uploads_ / ("fuzz-" + std::to_string(n) + in.extension);
        WriteFile(placed, in.files[0]);
        volume_id = WithSlot([&] { return client_->UploadVolume(placed).id(); });
      }
      outcome = "loaded";
    } catch (const cinevol::RpcError& e) {
      outcome = Classify(e);
      last_message_ = e.what();
    } catch (const std::exception& e) {
      outcome = std::string("client error");
      last_message_ = e.what();
    }
    if (!volume_id.empty()) {
      try {
        client_->UnloadVolume(volume_id);
      } catch (const std::exception& e) {
        std::cerr << "unload " << volume_id << ": " << e.what() << "\n";
      }
    }
    tally_.outcomes[outcome]++;
    if (ReaderStopped(outcome)) Keep(in, outcome);
    if (!server_->Alive()) Died(in, outcome);
    std::error_code ec;
    fs::remove_all(placed, ec);
    return outcome;
  }

  // `call`, again while the server still runs an earlier load of ours (a
  // load whose call ended before it did: --max-uploads-per-principal).
  template <class Call>
  std::string WithSlot(const Call& call) {
    for (const auto give_up = Clock::now() + 330s;;) {
      try {
        return call();
      } catch (const cinevol::RpcError& e) {
        if (e.code() != grpc::StatusCode::RESOURCE_EXHAUSTED ||
            std::string(e.what()).find("max-uploads-per-principal") == std::string::npos || Clock::now() > give_up) {
          throw;
        }
        ++tally_.slot_waits;
        std::this_thread::sleep_for(1s);
      }
    }
  }

  // The inputs that stopped a reader, the first few of each kind.
  void Keep(const Input& in, const std::string& outcome) {
    if (kept_[outcome]++ >= 5) return;
    ++tally_.kept;
    std::string tag = outcome.substr(outcome.rfind(' ') + 1);
    tag.erase(std::remove_if(tag.begin(), tag.end(), [](char c) { return !std::isalnum(std::uint8_t(c)); }),
              tag.end());
    const fs::path dir = o_.out / "kept" / (tag + "-" + std::to_string(tally_.inputs));
    fs::create_directories(dir);
    for (std::size_t i = 0; i < in.files.size(); ++i) {
      WriteFile(dir / ((in.extension.empty() ? "slice" + std::to_string(i) + ".dcm" : "input" + in.extension)),
                in.files[i]);
    }
    std::ofstream(dir / "what.txt") << in.origin << "\n" << outcome << "\n" << last_message_ << "\n";
  }

  void Died(const Input& in, const std::string& outcome) {
    ++tally_.deaths;
    const std::string note = "input " + std::to_string(tally_.inputs) + " (" + in.origin + ", " + outcome +
                             "): the server ended, " + server_->ended();
    tally_.death_notes.push_back(note);
    std::cerr << "SERVER DIED: " << note << "\n";
    const fs::path dir = o_.out / "kept" / ("server-death-" + std::to_string(tally_.inputs));
    fs::create_directories(dir);
    for (std::size_t i = 0; i < in.files.size(); ++i)
      WriteFile(dir / ("file" + std::to_string(i) + in.extension), in.files[i]);
    frames_of_dead_witnesses_ += witness_ ? witness_->frames() : 0;
    witness_.reset();
    client_.reset();
    if (Start()) Connect();
  }

  // Frames the witness gets in the next `window`.
  std::uint64_t FramesIn(std::chrono::milliseconds window) {
    const std::uint64_t start = witness_->frames();
    std::this_thread::sleep_for(window);
    return witness_->frames() - start;
  }

  // The witnesses' frames: this one's and those of witnesses lost with a server.
  std::uint64_t Frames() const { return frames_of_dead_witnesses_ + witness_->frames(); }

  void Progress(Clock::time_point start) {
    const double s = std::chrono::duration<double>(Clock::now() - start).count();
    std::cerr << tally_.inputs << " inputs in " << int(s) << " s; deaths " << tally_.deaths << "; witness frames "
              << Frames() << "\n";
  }

  void Report(Clock::time_point start, std::uint64_t before, std::uint64_t during, double during_s,
              std::uint64_t after, bool ok) {
    const double s = std::chrono::duration<double>(Clock::now() - start).count();
    std::ostringstream r;
    r << "cinevol-server-fuzz: seed " << o_.seed << ", pre-checks " << (o_.prechecks_off ? "off" : "on") << ", "
      << int(s) << " s\n";
    r << "inputs: " << tally_.inputs << " (" << tally_.replayed << " corpus files as they are, " << tally_.mutated
      << " mutated; " << tally_.uploads << " uploads, " << tally_.series << " DICOM series of " << tally_.slices
      << " slices)\n";
    if (tally_.slot_waits > 0) {
      r << "waited " << tally_.slot_waits << " s in all for earlier loads whose calls had ended (a call ends "
        << "CANCELLED after --upload-idle-seconds while its load goes on)\n";
    }
    r << "outcomes:\n";
    for (const auto& [outcome, count] : tally_.outcomes) r << "  " << outcome << ": " << count << "\n";
    r << "committed regression inputs:\n";
    for (const auto& [line, count] : tally_.regression_outcomes) r << "  " << line << "\n";
    r << "server deaths: " << tally_.deaths << "\n";
    for (const std::string& note : tally_.death_notes) r << "  " << note << "\n";
    char pace[160];
    std::snprintf(pace, sizeof pace,
                  "%llu in the 5 s before the inputs, %llu during them (%.0f s, %.1f/s), %llu in the 5 s after",
                  (unsigned long long)before, (unsigned long long)during, during_s, during / std::max(during_s, 1e-3),
                  (unsigned long long)after);
    r << "witness frames: " << pace << "; stream " << (witness_->open() ? "open" : "ended: " + witness_->status())
      << "\n";
    r << "inputs kept (readers stopped, deaths): " << tally_.kept << " under " << (o_.out / "kept").string() << "\n";
    r << (ok ? "PASS" : "FAIL") << "\n";
    std::cout << r.str();
    std::ofstream(o_.out / "report.txt") << r.str();
  }

  Options o_;
  Random random_;
  fs::path data_root_, uploads_;
  int generation_ = 0;
  std::unique_ptr<Server> server_;
  std::unique_ptr<cinevol::Client> client_;
  std::unique_ptr<Witness> witness_;
  Tally tally_;
  std::map<std::string, std::uint64_t> kept_;
  std::string last_message_;
  std::uint64_t frames_of_dead_witnesses_ = 0;
};

}  // namespace

int main(int argc, char** argv) {
  signal(SIGPIPE, SIG_IGN);
  const Options options = Parse(argc, argv);
  fs::create_directories(options.out);
  return Run(options).Main();
}
