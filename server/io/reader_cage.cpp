// The parent's side of the reader cage: start cinevol-reader, hand it the
// inputs, watch it, and turn its answer (or its end) into a result or an
// error. Nothing here parses the input's bytes.
#include "io/reader_cage.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <linux/landlock.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <spdlog/spdlog.h>
#include <sys/mman.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <sys/syscall.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <optional>
#include <thread>

#include "cinevol/reader/reader.pb.h"
#include "core/error.h"
#include "core/log_safe.h"
#include "io/file_checks.h"
#include "io/label_volume.h"
#include "io/reader_channel.h"
#include "io/suv.h"
#include "scene/volume_kind.h"

extern char** environ;

namespace fs = std::filesystem;

namespace cinevol::reader_cage {
namespace {

using Clock = std::chrono::steady_clock;
using reader::Reply;
using reader::Request;

// The most a child's stderr is kept for the log.
constexpr std::size_t kMaxStderrBytes = 64 << 10;
// An image (environment map) the cage reads: 8192 x 8192 pixels at most.
constexpr std::uint64_t kMaxImagePixels = std::uint64_t{1} << 26;
// The address space a child may be granted at most beyond its header's.
constexpr std::uint64_t kMaxVoxelAddressSpace = std::uint64_t{48} << 30;

std::mutex observer_mu;
OutcomeObserver& Observer() {
  static OutcomeObserver observer;
  return observer;
}

void Report(std::string_view outcome) {
  std::lock_guard lock(observer_mu);
  if (Observer()) Observer()(outcome);
}

std::string SignalName(int sig) {
  const char* abbrev = sigabbrev_np(sig);
  return abbrev ? fmt::format("SIG{}", abbrev) : fmt::format("signal {}", sig);
}

std::string Mib(std::uint64_t bytes) { return fmt::format("{} MiB", (bytes + (1 << 20) - 1) >> 20); }

// A private folder for one child's links, removed with everything in it.
class WorkDir {
 public:
  WorkDir() {
    std::string pattern = (fs::temp_directory_path() / "cinevol-reader-XXXXXX").string();
    if (!mkdtemp(pattern.data())) throw std::runtime_error("cannot make a folder for the reader");
    path_ = pattern;
  }
  ~WorkDir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

// A cinevol-reader started and waiting for its request: the process, its
// socket and its stderr, and the limits it was started with.
struct Started {
  pid_t pid = -1;
  UniqueFd socket, stderr_pipe;
  ReaderLimits limits;
};

// Kills and reaps a started child that will not be used.
void Discard(Started& child) {
  if (child.pid > 0) {
    kill(child.pid, SIGKILL);
    waitpid(child.pid, nullptr, 0);
    child.pid = -1;
  }
}

Started StartReader(const ReaderLimits& limits) {
  Started child;
  child.limits = limits;
  int sockets[2], err[2];
  if (socketpair(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0, sockets) != 0) {
    throw ResourceExhausted(fmt::format("cannot start a reader ({})", std::strerror(errno)));
  }
  child.socket.Reset(sockets[0]);
  UniqueFd child_end(sockets[1]);
  if (pipe2(err, O_CLOEXEC) != 0)
    throw ResourceExhausted(fmt::format("cannot start a reader ({})", std::strerror(errno)));
  child.stderr_pipe.Reset(err[0]);
  UniqueFd stderr_write(err[1]);
  fcntl(child.stderr_pipe.get(), F_SETFL, O_NONBLOCK);

  const std::string program = ReaderPath().string();
  const std::uint64_t max_space = limits.header_address_space + kMaxVoxelAddressSpace;
  std::vector<std::string> args{program,
                                "--parent",
                                std::to_string(getpid()),
                                "--address-space",
                                std::to_string(limits.header_address_space),
                                "--address-space-max",
                                std::to_string(max_space),
                                "--cpu-seconds",
                                std::to_string(int(std::ceil(limits.cpu_seconds)))};
  // One malloc arena (the address-space limit counts each arena's reservation);
  // large blocks from the heap, kept when freed: a reader allocates a buffer
  // per slice, and fresh mappings for each would fault in every page again.
  std::vector<std::string> env{"MALLOC_ARENA_MAX=1", "MALLOC_MMAP_THRESHOLD_=67108864",
                               "MALLOC_TRIM_THRESHOLD_=1073741824"};
  if (const char* path = std::getenv("LD_LIBRARY_PATH")) env.push_back(std::string("LD_LIBRARY_PATH=") + path);
  std::vector<char*> argv, envp;
  for (std::string& a : args) argv.push_back(a.data());
  for (std::string& e : env) envp.push_back(e.data());
  argv.push_back(nullptr);
  envp.push_back(nullptr);

  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 0, "/dev/null", O_RDONLY, 0);
  posix_spawn_file_actions_addopen(&actions, 1, "/dev/null", O_WRONLY, 0);
  posix_spawn_file_actions_adddup2(&actions, stderr_write.get(), 2);
  posix_spawn_file_actions_adddup2(&actions, child_end.get(), 3);
  posix_spawn_file_actions_addclosefrom_np(&actions, 4);
  posix_spawnattr_t attributes;
  posix_spawnattr_init(&attributes);
  sigset_t none, all;
  sigemptyset(&none);
  sigfillset(&all);
  posix_spawnattr_setsigmask(&attributes, &none);
  posix_spawnattr_setsigdefault(&attributes, &all);
  posix_spawnattr_setflags(&attributes, POSIX_SPAWN_SETSIGMASK | POSIX_SPAWN_SETSIGDEF);
  const int error = posix_spawn(&child.pid, program.c_str(), &actions, &attributes, argv.data(), envp.data());
  posix_spawn_file_actions_destroy(&actions);
  posix_spawnattr_destroy(&attributes);
  if (error != 0) {
    child.pid = -1;
    throw ResourceExhausted(fmt::format("cannot start {} ({})", program, std::strerror(error)));
  }
  return child;
}

bool SameLimits(const ReaderLimits& a, const ReaderLimits& b) {
  return a.header_address_space == b.header_address_space && a.cpu_seconds == b.cpu_seconds;
}

// One reader started ahead of need: exec and the readers' libraries take tens
// of milliseconds to start (ITK's and GDCM's static tables), which a load then
// does not wait for. The spare has read nothing and raised no walls yet: it
// waits for its request.
class Spare {
 public:
  static Spare& Get() {
    static Spare* spare = new Spare;  // never destroyed: its child dies with this process
    return *spare;
  }

  void Keep() { keep_ = true; }

  Started Take(const ReaderLimits& limits) {
    if (!keep_) return StartReader(limits);
    std::optional<Started> ready;
    {
      std::lock_guard lock(mu_);
      ready.swap(spare_);
    }
    int status = 0;
    if (ready && (!SameLimits(ready->limits, limits) || waitpid(ready->pid, &status, WNOHANG) != 0)) {
      Discard(*ready);
      ready.reset();
    }
    return ready ? std::move(*ready) : StartReader(limits);
  }

  // Starts the next spare, if none waits: once a load has ended, so that its
  // start-up does not compete with the load for the processor.
  void Replenish(const ReaderLimits& limits) {
    if (!keep_) return;
    {
      std::lock_guard lock(mu_);
      if (spare_) return;
    }
    try {
      Started next = StartReader(limits);
      std::lock_guard lock(mu_);
      if (!spare_) {
        spare_ = std::move(next);
      } else {
        Discard(next);
      }
    } catch (const std::exception&) {
      // none ahead this time; the next load starts its own
    }
  }

 private:
  std::atomic<bool> keep_{false};
  std::mutex mu_;
  std::optional<Started> spare_;
};

// One cinevol-reader child, from its start to its end.
class ReaderProcess {
 public:
  ReaderProcess(Request request, const std::vector<Input>& inputs, const LoadPolicy& policy)
      : shown_(request.shown()),
        limits_(policy.reader),
        cancel_(policy.cancel),
        deadline_(Clock::now() +
                  std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(limits_.wall_seconds))) {
    request.set_work_dir(work_dir_.path().string());
    const char* skip = std::getenv("CINEVOL_READER_PRECHECKS");
    request.set_skip_prechecks(skip && std::string_view(skip) == "off");
    for (const Input& in : inputs) request.add_file_names(in.name);
    reader_ = ReaderName(request.kind(), inputs.empty() ? "" : inputs[0].name);
    try {
      Started child = Spare::Get().Take(limits_);
      pid_ = child.pid;
      channel_ = ReaderChannel(std::move(child.socket));
      stderr_ = std::move(child.stderr_pipe);
      try {
        channel_.Send(request);
        SendInputs(inputs);
      } catch (const ChannelError&) {
        Ended();
      }
    } catch (...) {
      End();  // no destructor runs for an object whose constructor threw
      throw;
    }
  }

  ~ReaderProcess() { End(); }

  ReaderProcess(const ReaderProcess&) = delete;
  ReaderProcess& operator=(const ReaderProcess&) = delete;

  // The child's next answer; its failure or its end as the load's error.
  Reply Receive() {
    Reply reply;
    std::vector<UniqueFd> fds;  // a child sends none: dropped
    try {
      channel_.Receive(reply, fds, [this] { Wait(); });
    } catch (const ChannelError&) {
      Ended();
    }
    if (reply.has_failure()) Fail(reply.failure());
    return reply;
  }

  // Lets the child write `bytes` into `memory`, with the address space for it.
  // The memory for the voxels (or a time series' phase of `all_bytes` in all),
  // three times: a multi-frame file is decoded whole, its encoded and its
  // decoded frames beside the memory written.
  void Proceed(int memory, std::uint64_t bytes, std::uint64_t all_bytes = 0) {
    rlimit limit{};
    if (prlimit(pid_, RLIMIT_AS, nullptr, &limit) == 0) {
      const std::uint64_t wanted =
          limits_.header_address_space + 3 * std::max(bytes, all_bytes) + (std::uint64_t{64} << 20);
      limit.rlim_cur = std::min<rlim_t>(rlim_t(wanted), limit.rlim_max);
      prlimit(pid_, RLIMIT_AS, &limit, nullptr);
    }
    reader::Proceed proceed;
    try {
      channel_.Send(proceed, {memory});
    } catch (const ChannelError&) {
      Ended();  // the child died after its header
    }
  }

  // Waits for `done` (a phase of a time series written, more to come).
  void AwaitDone() {
    const Reply reply = Receive();
    if (reply.reply_case() != Reply::kDone) Violation("answered out of turn");
  }

  // Waits for `done`, then for the child's clean exit.
  void Finish() {
    AwaitDone();
    for (const auto end = Clock::now() + std::chrono::seconds(2); Clock::now() < end;) {
      int status = 0;
      if (waitpid(pid_, &status, WNOHANG) == pid_) {
        pid_ = -1;
        if (WIFEXITED(status) && WEXITSTATUS(status) == 0) {
          outcome_ = "ok";
          return;
        }
        Classify(status);
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
    Violation("did not end after its answer");
  }

  // The child's answer that ends a request (a list, a table).
  void Answered() { outcome_ = "ok"; }

  [[noreturn]] void Violation(const std::string& what) {
    outcome_ = "protocol";
    throw InputError(fmt::format("{}: the {} reader {}", shown_, reader_, what));
  }

  const std::string& shown() const { return shown_; }

 private:
  // The inputs' descriptors, opened here (regular files only), a batch at a
  // time so the parent never holds many.
  void SendInputs(const std::vector<Input>& inputs) {
    for (std::size_t at = 0; at < inputs.size(); at += ReaderChannel::kMaxFds) {
      std::vector<UniqueFd> open;
      std::vector<int> fds;
      for (std::size_t i = at; i < std::min(inputs.size(), at + ReaderChannel::kMaxFds); ++i) {
        open.emplace_back(file_checks::OpenRegularFile(inputs[i].path));
        if (!open.back()) {
          throw InputError(fmt::format("{}: {} is not a regular file that can be read", shown_,
                                       inputs[i].name.empty() ? std::string("it") : "'" + inputs[i].name + "'"));
        }
        fds.push_back(open.back().get());
      }
      channel_.Send(reader::Batch(), fds);
    }
  }

  // Kills the child if it still runs, logs what it said and counts how it ended.
  void End() {
    if (pid_ > 0) {
      kill(pid_, SIGKILL);
      waitpid(pid_, nullptr, 0);
      pid_ = -1;
    }
    DrainStderr();
    for (std::size_t at = 0, end; at < stderr_text_.size(); at = end + 1) {
      end = std::min(stderr_text_.find('\n', at), stderr_text_.size());
      if (end > at) spdlog::debug("reader for {}: {}", LogSafe(shown_), LogSafe(stderr_text_.substr(at, end - at)));
    }
    stderr_text_.clear();
    if (outcome_ != "reported") Report(outcome_.empty() ? "refused" : outcome_);
    outcome_ = "reported";
    Spare::Get().Replenish(limits_);
  }

  // Returns once the socket has something to read; keeps the child's stderr
  // flowing; stops the load when it is cancelled or out of time.
  void Wait() {
    for (;;) {
      if (cancel_ && cancel_->load()) {
        outcome_ = "cancelled";
        throw Cancelled(fmt::format("{}: the load was cancelled", shown_));
      }
      if (Clock::now() > deadline_) {
        outcome_ = "timeout";
        throw ResourceExhausted(fmt::format("{}: the {} reader took longer than {:g} s (--reader-seconds)", shown_,
                                            reader_, limits_.wall_seconds));
      }
      pollfd fds[2] = {{channel_.fd(), POLLIN, 0}, {stderr_.get(), POLLIN, 0}};
      const int n = poll(fds, stderr_ ? 2 : 1, 100);
      if (n > 0 && fds[1].revents) DrainStderr();
      if (n > 0 && fds[0].revents) return;
    }
  }

  void DrainStderr() {
    if (!stderr_) return;
    char buffer[4096];
    for (ssize_t n; (n = read(stderr_.get(), buffer, sizeof buffer)) != 0;) {
      if (n < 0) {
        if (errno == EINTR) continue;
        if (errno != EAGAIN) stderr_.Reset();
        return;
      }
      stderr_text_.append(
          buffer,
          std::min<std::size_t>(std::size_t(n), kMaxStderrBytes - std::min(kMaxStderrBytes, stderr_text_.size())));
    }
    stderr_.Reset();  // end of file: the child has gone
  }

  // The socket closed: the child ended (or is ending); say how.
  [[noreturn]] void Ended() {
    int status = 0;
    for (const auto end = Clock::now() + std::chrono::seconds(1); Clock::now() < end;) {
      if (waitpid(pid_, &status, WNOHANG) == pid_) {
        pid_ = -1;
        Classify(status);
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
    Violation("closed its socket without an answer");
  }

  [[noreturn]] void Classify(int status) {
    if (WIFSIGNALED(status)) {
      const int sig = WTERMSIG(status);
      if (sig == SIGXCPU) {
        outcome_ = "cpu";
        throw ResourceExhausted(fmt::format("{}: the {} reader used up its {:g} s of CPU time (--reader-cpu-seconds)",
                                            shown_, reader_, limits_.cpu_seconds));
      }
      if (sig == SIGSYS) {
        outcome_ = "sandbox";
        throw InputError(
            fmt::format("{}: the {} reader was stopped by its sandbox (a forbidden system call)", shown_, reader_));
      }
      outcome_ = "crashed";
      throw InputError(fmt::format("{}: the {} reader stopped ({})", shown_, reader_, SignalName(sig)));
    }
    Violation(fmt::format("ended without an answer (exit code {})", WIFEXITED(status) ? WEXITSTATUS(status) : -1));
  }

  [[noreturn]] void Fail(const reader::Failure& failure) {
    const std::string message = ValidUtf8(failure.message().substr(0, 4096));
    switch (failure.kind()) {
      case reader::Failure::MEMORY:
        outcome_ = "memory";
        throw ResourceExhausted(fmt::format("{}: the {} reader ran out of memory ({})", shown_, reader_,
                                            message.empty() ? "its limit" : message));
      case reader::Failure::INPUT:
        outcome_ = "refused";
        throw InputError(message);
      default:
        outcome_ = "refused";
        throw InputError(fmt::format("{}: the {} reader failed: {}", shown_, reader_, message));
    }
  }

  std::string shown_;
  ReaderLimits limits_;
  const std::atomic<bool>* cancel_;
  Clock::time_point deadline_;
  WorkDir work_dir_;
  pid_t pid_ = -1;
  UniqueFd stderr_;
  ReaderChannel channel_{UniqueFd()};
  std::string stderr_text_;
  std::string reader_;   // "NRRD", ... for messages
  std::string outcome_;  // for the metrics, once known
};

// Shared memory of `bytes` that cannot grow or shrink: what the child writes
// the voxels to.
UniqueFd SealedMemory(std::uint64_t bytes, const std::string& shown) {
  UniqueFd fd(memfd_create("cinevol-voxels", MFD_CLOEXEC | MFD_ALLOW_SEALING));
  if (!fd || ftruncate(fd.get(), off_t(bytes)) != 0 ||
      fcntl(fd.get(), F_ADD_SEALS, F_SEAL_SHRINK | F_SEAL_GROW | F_SEAL_SEAL) != 0) {
    throw ResourceExhausted(
        fmt::format("{}: cannot make {} of shared memory ({})", shown, Mib(bytes), std::strerror(errno)));
  }
  return fd;
}

// The shared memory as a block of this process's, given back when dropped.
MemoryBlock MapMemory(UniqueFd fd, std::uint64_t bytes, const std::string& shown) {
  void* data = mmap(nullptr, bytes, PROT_READ | PROT_WRITE, MAP_SHARED | MAP_POPULATE, fd.get(), 0);
  if (data == MAP_FAILED) throw ResourceExhausted(fmt::format("{}: cannot map {} of voxels", shown, Mib(bytes)));
  return {data, bytes, MemoryBlock::Pages::kOwn, [](void* p, std::size_t size) { munmap(p, size); }};
}

bool AllFinite(const google::protobuf::RepeatedField<double>& values, int count) {
  if (values.size() != count) return false;
  for (double v : values) {
    if (!std::isfinite(v)) return false;
  }
  return true;
}

// A DICOM UID: 1 to 64 digits and dots, no empty component; anything else
// from a file counts as none.
bool IsUid(std::string_view uid) {
  if (uid.empty() || uid.size() > 64 || uid.front() == '.' || uid.back() == '.') return false;
  for (std::size_t i = 0; i < uid.size(); ++i) {
    if (uid[i] == '.' ? uid[i + 1] == '.' : !(uid[i] >= '0' && uid[i] <= '9')) return false;
  }
  return true;
}

// DICOM allows 64 characters a field (3 x 64 for a name); more is a
// violation of the protocol, not a long name.
bool IdentityFits(const reader::Identity& id) {
  constexpr std::size_t kMaxBytes = 4 * 3 * 64;  // UTF-8 bytes of 3 x 64 characters
  for (const std::string* field :
       {&id.patient_name(), &id.patient_id(), &id.study_date(), &id.study_description(), &id.series_description()}) {
    if (field->size() > kMaxBytes) return false;
  }
  return true;
}

// The fields as a client may be shown them: UTF-8 (other bytes escaped), no
// control characters (a corner of a view holds one line each).
PatientIdentity IdentityOf(const reader::Identity& id) {
  const auto shown = [](const std::string& field) { return ValidUtf8(LogSafe(field, field.size())); };
  return {shown(id.patient_name()), shown(id.patient_id()), shown(id.study_date()), shown(id.study_description()),
          shown(id.series_description())};
}

// The header as the parent can trust it, or a protocol violation.
struct CheckedHeader {
  Vec3i dims;
  Vec3f spacing;
  VoxelType type;
  VolumeMetadata meta;
  std::uint64_t voxels = 0;  // a phase's
  int phases = 1;
  std::vector<double> seconds;
};

CheckedHeader Check(const reader::Header& h, ReaderProcess& child, const LoadPolicy& policy) {
  CheckedHeader c;
  const auto type = VoxelTypeNamed(h.voxel_type());
  const bool sane = h.dims_size() == 3 && AllFinite(h.spacing_mm(), 3) && AllFinite(h.origin_mm(), 3) &&
                    AllFinite(h.direction(), 9) && type && h.modality().size() <= 64 && h.value_unit().size() <= 64 &&
                    h.original_type().size() <= 256 && h.notes_size() <= 8 && IdentityFits(h.identity()) &&
                    (h.stored_window_size() == 0 || h.stored_window_size() == 2);
  if (!sane) child.Violation("sent a header that does not hold together");
  c.type = *type;
  for (int a = 0; a < 3; ++a) {
    if (h.dims(a) < 1 || h.dims(a) > std::uint32_t(kMaxVoxelsPerAxis)) child.Violation("sent impossible dimensions");
    c.dims[a] = int(h.dims(a));
    c.spacing[a] = float(h.spacing_mm(a));
  }
  CheckVolumeGeometry(c.dims, c.spacing, child.shown());
  c.voxels = std::uint64_t(c.dims.x) * std::uint64_t(c.dims.y) * std::uint64_t(c.dims.z);
  c.phases = std::max<int>(1, int(std::min<std::uint32_t>(h.phases(), kMaxPhases + 1u)));
  if (c.phases > kMaxPhases) child.Violation(fmt::format("announced more than {} phases", kMaxPhases));
  CheckVoxelLimit(c.dims, std::uint64_t(c.phases), policy.max_voxels, child.shown());  // before any is read
  if (h.phase_seconds_size() > 0) {
    // Times from the first, rising: anything else from a file is no time axis.
    bool rising = h.phase_seconds_size() == c.phases && AllFinite(h.phase_seconds(), c.phases);
    for (int k = 1; rising && k < c.phases; ++k) rising = h.phase_seconds(k) > h.phase_seconds(k - 1);
    if (!rising) child.Violation("sent phase times that are not one rising time a phase");
    c.seconds.assign(h.phase_seconds().begin(), h.phase_seconds().end());
    for (double& t : c.seconds) t -= h.phase_seconds(0);
  }
  c.meta.source = child.shown();
  c.meta.modality = ValidUtf8(h.modality());
  c.meta.value_unit = ValidUtf8(h.value_unit());
  c.meta.original_type = ValidUtf8(h.original_type());
  for (int i = 0; i < 3; ++i) c.meta.origin_mm[i] = h.origin_mm(i);
  for (int i = 0; i < 9; ++i) c.meta.direction[i] = h.direction(i);
  for (const std::string& note : h.notes()) c.meta.notes.push_back(ValidUtf8(LogSafe(note, 512)));
  c.meta.identity = IdentityOf(h.identity());
  if (h.stored_window_size() == 2 && AllFinite(h.stored_window(), 2) && h.stored_window(1) >= 1) {
    c.meta.stored_window = VoiWindow{h.stored_window(0), h.stored_window(1)};
  }
  if (IsUid(h.frame_of_reference_uid())) c.meta.frame_of_reference_uid = h.frame_of_reference_uid();
  if (h.has_pet()) {  // the child's reading of the file: checked, computed here
    const SuvbwFactor suv = SuvbwFactorOf(h.pet());
    c.meta.suv_factor = suv.factor;
    c.meta.suv_refused = suv.refused;
  }
  return c;
}

// A CT whose file did not say its unit (NIfTI, NRRD, VTK have no field for
// it) but whose values are judged HU (air near -1000, bone above 300) reads
// in HU everywhere, as a DICOM CT does: the slices' default window, picks,
// lists. A time series is judged by its first phase, and all its phases alike.
void TakeHuWhereJudged(std::vector<Volume>& phases) {
  if (!phases.front().metadata().value_unit.empty()) return;
  const VolumeKindJudgement kind = JudgeVolumeKind(phases.front());
  if (kind.kind != v1::CT_HU) return;
  for (Volume& volume : phases) volume.SetValueUnit("HU", "values taken as HU: " + kind.reason);
}

// The volume (or time series) a child announced with `reply`: every phase
// reserved, then each read into its own sealed memory and built.
VolumeSeries ReceiveSeries(ReaderProcess& child, const Reply& reply, const LoadPolicy& policy) {
  if (reply.reply_case() != Reply::kHeader) child.Violation("answered out of turn");
  CheckedHeader h = Check(reply.header(), child, policy);
  if (policy.reserve) policy.reserve(Volume::BytesToLoad(h.type, h.voxels) * std::uint64_t(h.phases));
  const std::uint64_t bytes = h.voxels * BytesPerVoxel(h.type);
  std::vector<UniqueFd> memories;
  for (int k = 0; k < h.phases; ++k) {
    memories.push_back(SealedMemory(bytes, child.shown()));
    child.Proceed(memories.back().get(), bytes, bytes * std::uint64_t(h.phases));
    if (k + 1 < h.phases) child.AwaitDone();
  }
  child.Finish();
  // The child is gone: nobody else can change the memory now.
  VolumeSeries series;
  series.seconds = std::move(h.seconds);
  for (UniqueFd& memory : memories) {
    series.phases.emplace_back(h.dims, h.spacing, h.type, MapMemory(std::move(memory), bytes, child.shown()), h.meta);
  }
  TakeHuWhereJudged(series.phases);
  return series;
}

std::string Relative(const fs::path& file, const fs::path& folder) {
  const fs::path relative = file.lexically_relative(folder);
  return relative.empty() ? file.filename().string() : relative.string();
}

}  // namespace

void ObserveOutcomes(OutcomeObserver observer) {
  std::lock_guard lock(observer_mu);
  Observer() = std::move(observer);
}

void KeepSpareReader() { Spare::Get().Keep(); }

bool KernelHasLandlock() {
  return syscall(SYS_landlock_create_ruleset, nullptr, 0, LANDLOCK_CREATE_RULESET_VERSION) >= 1;
}

std::string ReaderName(int request_kind, const std::string& file_name) {
  switch (request_kind) {
    case Request::DICOM_SERIES:
    case Request::DICOM_LIST:
      return "DICOM";
    case Request::LABEL_TABLE:
      return "label table";
    case Request::DICOM_SEG:
      return "DICOM SEG";
    case Request::EXR_IMAGE:
      return "OpenEXR";
    default:
      break;
  }
  const formats::Format format = formats::FormatOfName(file_name);
  // Any other name is NRRD's: teem reads any file that starts with its magic.
  return formats::ReaderName(format == formats::Format::kUnknown ? formats::Format::kNrrd : format);
}

fs::path ReaderPath() {
  if (const char* path = std::getenv("CINEVOL_READER")) return path;
  std::error_code ec;
  const fs::path self = fs::read_symlink("/proc/self/exe", ec);
  for (const fs::path& dir : {self.parent_path(), self.parent_path().parent_path()}) {
    const fs::path candidate = dir / "cinevol-reader";
    if (!ec && access(candidate.c_str(), X_OK) == 0) return candidate;
  }
  throw std::runtime_error(
      fmt::format("cinevol-reader, which reads every file, is not beside {}: install it there", self.string()));
}

VolumeSeries ReadVolumeFile(const fs::path& file, const formats::References& refs, const LoadPolicy& policy) {
  Request request;
  request.set_kind(Request::VOLUME);
  request.set_shown(file_checks::Shown(file, policy));
  request.set_max_voxels(policy.max_voxels);
  std::vector<Input> inputs{{file, file.filename().string()}};
  for (const fs::path& named : refs.files) inputs.push_back({named, Relative(named, file.parent_path())});
  ReaderProcess child(request, inputs, policy);
  return ReceiveSeries(child, child.Receive(), policy);
}

VolumeSeries ReadDicomSeries(const std::vector<Input>& files, const std::string& series_uid, const LoadPolicy& policy) {
  Request request;
  request.set_kind(Request::DICOM_SERIES);
  request.set_shown(policy.label);
  request.set_series_uid(series_uid);
  request.set_max_voxels(policy.max_voxels);
  request.set_resample_uneven(policy.resample_uneven);
  ReaderProcess child(request, files, policy);
  return ReceiveSeries(child, child.Receive(), policy);
}

std::vector<DicomSeriesInfo> ListDicomSeries(const std::vector<Input>& files, const LoadPolicy& policy) {
  Request request;
  request.set_kind(Request::DICOM_LIST);
  request.set_shown(policy.label);
  ReaderProcess child(request, files, policy);
  const Reply reply = child.Receive();
  if (reply.reply_case() != Reply::kSeriesList) child.Violation("answered out of turn");
  child.Answered();
  std::vector<DicomSeriesInfo> out;
  for (const reader::Series& s : reply.series_list().series()) {
    out.push_back({ValidUtf8(s.uid()), ValidUtf8(s.description()), ValidUtf8(s.modality()), ValidUtf8(s.size()),
                   std::size_t(s.file_count())});
  }
  return out;
}

SegmentationRead ReadSegmentation(const std::vector<Input>& files, const Volume& image, const LoadPolicy& policy) {
  Request request;
  request.set_kind(Request::DICOM_SEG);
  request.set_shown(policy.label);
  request.set_max_voxels(policy.max_voxels);
  reader::Grid& grid = *request.mutable_target();
  const VolumeMetadata& meta = image.metadata();
  for (int a = 0; a < 3; ++a) {
    grid.add_dims(std::uint32_t(image.dims()[a]));
    grid.add_spacing_mm(image.spacing_mm()[a]);
    grid.add_origin_mm(meta.origin_mm[a]);
  }
  grid.mutable_direction()->Add(meta.direction.begin(), meta.direction.end());
  ReaderProcess child(request, files, policy);
  const Reply reply = child.Receive();
  if (reply.reply_case() != Reply::kHeader || !reply.header().has_segmentation())
    child.Violation("answered out of turn");
  const reader::Header& h = reply.header();
  const reader::Segmentation& seg = h.segmentation();
  bool sane = h.dims_size() == 3 && h.voxel_type() == "uint16" && h.notes_size() <= 8 &&
              (seg.type() == "BINARY" || seg.type() == "FRACTIONAL") && seg.segments_size() >= 1 &&
              seg.segments_size() <= 1024 && seg.frames_outside() < seg.frames() &&
              h.frame_of_reference_uid().size() <= 64;
  for (int a = 0; sane && a < 3; ++a) sane = h.dims(a) == std::uint32_t(image.dims()[a]);
  SegmentationRead out;
  std::vector<bool> is_segment(65536, false);
  for (int i = 0; sane && i < seg.segments_size(); ++i) {
    const reader::Segment& s = seg.segments(i);
    sane = s.number() >= 1 && s.number() <= 65535 && !is_segment[s.number()] && s.label().size() <= 1024 &&
           (s.cielab_size() == 0 || s.cielab_size() == 3);
    for (int k = 0; sane && k < s.cielab_size(); ++k) sane = s.cielab(k) <= 65535;
    if (!sane) break;
    is_segment[s.number()] = true;
    SegmentationRead::Segment& mine = out.segments.emplace_back();
    mine.number = int(s.number());
    mine.label = ValidUtf8(LogSafe(s.label(), 256));
    mine.has_cielab = s.cielab_size() == 3;
    for (int k = 0; k < s.cielab_size(); ++k) mine.cielab[k] = std::uint16_t(s.cielab(k));
  }
  if (!sane) child.Violation("sent a segmentation header that does not hold together");
  std::sort(out.segments.begin(), out.segments.end(), [](const auto& a, const auto& b) { return a.number < b.number; });
  out.type = seg.type();
  out.frames = seg.frames();
  out.frames_outside = seg.frames_outside();
  for (const std::string& note : h.notes()) out.notes.push_back(ValidUtf8(LogSafe(note, 512)));
  if (IsUid(h.frame_of_reference_uid())) out.frame_of_reference_uid = h.frame_of_reference_uid();
  const std::string& volume_frame = meta.frame_of_reference_uid;
  if (!volume_frame.empty() && out.frame_of_reference_uid != volume_frame) {
    throw InputError(fmt::format(
        "{}: its frame of reference ({}) is not the volume's ({}): it segments another "
        "acquisition's patient space",
        child.shown(), out.frame_of_reference_uid.empty() ? "none" : out.frame_of_reference_uid, volume_frame));
  }
  const std::uint64_t bytes = image.voxel_count() * sizeof(std::uint16_t);
  if (policy.reserve) policy.reserve(2 * bytes);
  UniqueFd memory = SealedMemory(bytes, child.shown());
  child.Proceed(memory.get(), bytes);
  child.Finish();
  const MemoryBlock block = MapMemory(std::move(memory), bytes, child.shown());
  const auto* labels = static_cast<const std::uint16_t*>(block.data());
  out.labels.assign(labels, labels + image.voxel_count());
  for (std::uint16_t label : out.labels) {
    if (label != 0 && !is_segment[label]) {
      throw InputError(
          fmt::format("{}: the DICOM SEG reader wrote label {}, which is no segment", child.shown(), label));
    }
  }
  return out;
}

std::map<int, std::string> ReadLabelTable(const fs::path& file, const std::string& shown, const LoadPolicy& policy) {
  Request request;
  request.set_kind(Request::LABEL_TABLE);
  request.set_shown(shown);
  ReaderProcess child(request, {{file, file.filename().string()}}, policy);
  const Reply reply = child.Receive();
  if (reply.reply_case() != Reply::kLabelTable) child.Violation("answered out of turn");
  child.Answered();
  std::map<int, std::string> names;
  for (const auto& [value, name] : reply.label_table().names()) {
    if (value < 0 || value > 65535 || name.empty() || name.size() > 1024) child.Violation("sent an impossible label");
    names[value] = ValidUtf8(name);
  }
  return names;
}

std::map<int, std::string> ReadLabelTableText(const std::string& text, const std::string& shown) {
  if (text.size() > kMaxLabelTableBytes) {
    throw InputError(fmt::format("{}: a label table may have at most {} bytes", shown, kMaxLabelTableBytes));
  }
  if (text.empty()) return {};
  UniqueFd memory(memfd_create("cinevol-label-table", MFD_CLOEXEC));
  if (!memory || write(memory.get(), text.data(), text.size()) != ssize_t(text.size())) {
    throw ResourceExhausted(fmt::format("{}: cannot hold the table for its reader", shown));
  }
  return ReadLabelTable(fmt::format("/proc/self/fd/{}", memory.get()), shown, {});
}

ImageRgbF ReadExrImage(const fs::path& file, const std::string& shown, const LoadPolicy& policy) {
  Request request;
  request.set_kind(Request::EXR_IMAGE);
  request.set_shown(shown);
  ReaderProcess child(request, {{file, file.filename().string()}}, policy);
  const Reply reply = child.Receive();
  if (reply.reply_case() != Reply::kImage) child.Violation("answered out of turn");
  const std::uint64_t pixels = std::uint64_t(reply.image().width()) * reply.image().height();
  if (pixels == 0 || pixels > kMaxImagePixels) {
    throw InputError(fmt::format("{}: a {}x{} image; environment maps may have up to {} pixels", shown,
                                 reply.image().width(), reply.image().height(), kMaxImagePixels));
  }
  const std::uint64_t bytes = pixels * sizeof(Vec3f);
  UniqueFd memory = SealedMemory(bytes, shown);
  child.Proceed(memory.get(), bytes);
  child.Finish();
  const MemoryBlock block = MapMemory(std::move(memory), bytes, shown);
  ImageRgbF image;
  image.width = int(reply.image().width());
  image.height = int(reply.image().height());
  const Vec3f* p = static_cast<const Vec3f*>(block.data());
  image.pixels.assign(p, p + pixels);  // as the file holds them: ResolveLights makes them radiance
  return image;
}

ImageRgbF ReadEnvironmentMap(const std::string& path, const std::atomic<bool>* cancel) {
  LoadPolicy policy;
  policy.cancel = cancel;
  return ReadExrImage(path, "environment map '" + fs::path(path).filename().string() + "'", policy);
}

}  // namespace cinevol::reader_cage
