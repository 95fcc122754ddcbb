// cinevol-reader: reads one input for the cinevol process that started it
// (io/reader_cage.h), inside the walls of readers/sandbox.h. Its socket to
// the parent is descriptor 3; stderr goes to the parent's log.
#include <signal.h>
#include <sys/mman.h>
#include <sys/prctl.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <new>
#include <string>
#include <string_view>
#include <vector>

#include "cinevol/reader/reader.pb.h"
#include "core/error.h"
#include "io/reader_channel.h"
#include "io/readers/itk_adapter.h"
#include "io/readers/reading.h"
#include "io/readers/sandbox.h"
#include "io/readers/seg_reader.h"

namespace {

using namespace cinevol;
using reader::Reply;

constexpr int kChannelFd = 3;

struct Arguments {
  pid_t parent = 0;
  std::uint64_t address_space = 0, address_space_max = 0;
  int cpu_seconds = 0;
};

Arguments Parse(int argc, char** argv) {
  Arguments a;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string_view key = argv[i];
    const unsigned long long value = std::strtoull(argv[i + 1], nullptr, 10);
    if (key == "--parent") a.parent = pid_t(value);
    if (key == "--address-space") a.address_space = value;
    if (key == "--address-space-max") a.address_space_max = value;
    if (key == "--cpu-seconds") a.cpu_seconds = int(value);
  }
  return a;
}

void Send(ReaderChannel& channel, const Reply& reply) { channel.Send(reply); }

void SendFailure(ReaderChannel& channel, reader::Failure::Kind kind, const std::string& message) {
  Reply reply;
  reply.mutable_failure()->set_kind(kind);
  reply.mutable_failure()->set_message(message);
  Send(channel, reply);
}

// The request and its inputs' descriptors, as the parent sends them.
reader::Request ReceiveRequest(ReaderChannel& channel, std::vector<UniqueFd>& inputs) {
  reader::Request request;
  std::vector<UniqueFd> none;
  channel.Receive(request, none);
  while (inputs.size() < std::size_t(request.file_names_size())) {
    reader::Batch batch;
    const std::size_t before = inputs.size();
    channel.Receive(batch, inputs);
    if (inputs.size() == before) throw std::runtime_error("a batch without descriptors");
  }
  return request;
}

// Answers the request; for voxels, waits for the memory to write them to:
// one memory a phase of a time series, each phase answered before the next.
void Serve(ReaderChannel& channel, reader::Job& job) {
  const Reply answer = job.Answer();
  Send(channel, answer);
  if (!answer.has_header() && !answer.has_image()) return;
  const int phases = answer.has_header() ? std::max<int>(1, int(answer.header().phases())) : 1;
  for (int phase = 0; phase < phases; ++phase) {
    reader::Proceed proceed;
    std::vector<UniqueFd> memory;
    channel.Receive(proceed, memory);
    if (proceed.stop() || memory.size() != 1) return;
    const off_t bytes = lseek(memory[0].get(), 0, SEEK_END);
    void* data = bytes > 0 ? mmap(nullptr, std::size_t(bytes), PROT_READ | PROT_WRITE, MAP_SHARED, memory[0].get(), 0)
                           : MAP_FAILED;
    if (data == MAP_FAILED) throw std::bad_alloc();
    job.Write(data, std::size_t(bytes), phase);
    munmap(data, std::size_t(bytes));
    Reply done;
    done.set_done(true);
    Send(channel, done);
  }
}

}  // namespace

int main(int argc, char** argv) {
  prctl(PR_SET_PDEATHSIG, SIGKILL);
  const Arguments args = Parse(argc, argv);
  if (args.parent == 0 || getppid() != args.parent) return 2;  // started by hand, or the parent is gone
  ReaderChannel channel{UniqueFd(kChannelFd)};
  try {
    reader::SetLimits(args.address_space, args.address_space_max, args.cpu_seconds);
    itk_adapter::WarmUp();  // before the request: a spare does it while it waits
    reader::WarmUpSegmentations();  // DCMTK's dictionary, which the sandbox leaves unreadable
    std::vector<UniqueFd> inputs;
    reader::Request request = ReceiveRequest(channel, inputs);
    std::vector<int> fds;
    for (const UniqueFd& fd : inputs) fds.push_back(fd.get());
    const std::string work_dir = request.work_dir();
    reader::Job job(std::move(request), std::move(inputs));
    reader::Enter(fds, work_dir, kChannelFd);
    try {
      Serve(channel, job);
    } catch (const InputError& e) {
      SendFailure(channel, reader::Failure::INPUT, e.what());
    } catch (const std::bad_alloc&) {
      SendFailure(channel, reader::Failure::MEMORY, "");
    } catch (const std::exception& e) {
      SendFailure(channel, reader::Failure::INTERNAL, e.what());
    }
  } catch (const std::exception& e) {
    // Before the walls, or the socket failed: say so on stderr, for the log.
    const std::string text = std::string("cinevol-reader: ") + e.what() + "\n";
    if (write(2, text.data(), text.size()) < 0) return 1;
    return 1;
  }
  _exit(0);  // no static destructors of the libraries: the answer is sent
}
