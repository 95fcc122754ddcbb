// The walls of the reader cage, raised by cinevol-reader around itself
// before it parses a byte of its input.
#pragma once

#include <cstdint>
#include <filesystem>
#include <vector>

namespace cinevol::reader {

// Resource limits, set first: no core dumps, `cpu_seconds` of CPU time
// (SIGXCPU, then SIGKILL a second later), an address space of `address_space`
// bytes that only the parent may raise (up to `address_space_max`, with
// prlimit), a scratch file of at most 16 MiB, and as many descriptors as
// the system allows a process.
void SetLimits(std::uint64_t address_space, std::uint64_t address_space_max, int cpu_seconds);

// The rest, once the inputs are in hand and placed: where the kernel has
// Landlock, file access shrinks to reading `inputs` (descriptors) and the
// work folder; then a seccomp filter allows only the system calls reading
// needs: reading and mapping memory, threads, and messages on `channel_fd`.
// No sockets, no new processes or programs, no file created, written (but
// through descriptors already open) or removed, no executable memory, no
// limit raised. A forbidden call kills the process with SIGSYS after naming
// the call on stderr. Returns whether Landlock was applied.
bool Enter(const std::vector<int>& inputs, const std::filesystem::path& work_dir, int channel_fd);

}  // namespace cinevol::reader
