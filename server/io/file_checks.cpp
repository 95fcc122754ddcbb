// What a volume load may open, whatever its format.
#include "io/file_checks.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>

#include <fmt/format.h>

#include "core/error.h"

namespace fs = std::filesystem;

namespace cinevol::file_checks {

std::string Shown(const fs::path& path, const LoadPolicy& policy) {
  return policy.label.empty() ? path.string() : policy.label;
}

bool IsRegularFile(const fs::path& path) {
  std::error_code ec;
  return fs::is_regular_file(fs::status(path, ec));
}

void RequireRegularFile(const fs::path& path, const std::string& shown) {
  if (!IsRegularFile(path)) throw InputError(fmt::format("{}: not a regular file", shown));
}

int OpenRegularFile(const fs::path& path) {
  if (!IsRegularFile(path)) return -1;  // opening a device can have effects of its own
  const int fd = open(path.c_str(), O_RDONLY | O_NONBLOCK | O_NOCTTY | O_CLOEXEC);
  struct stat st;
  if (fd >= 0 && (fstat(fd, &st) != 0 || !S_ISREG(st.st_mode))) {
    close(fd);
    return -1;
  }
  return fd;
}

FileStream OpenRegularStream(const fs::path& path) {
  const int fd = OpenRegularFile(path);
  std::FILE* f = fd < 0 ? nullptr : fdopen(fd, "rb");
  if (!f && fd >= 0) close(fd);
  return {f, &std::fclose};
}

std::string ReadHead(const fs::path& path, std::size_t limit, const std::string& shown) {
  const int fd = OpenRegularFile(path);
  if (fd < 0) throw InputError(fmt::format("{}: not a regular file that can be read", shown));
  std::string text(limit, '\0');
  std::size_t got = 0;
  for (ssize_t n; got < limit && (n = read(fd, text.data() + got, limit - got)) > 0;) got += std::size_t(n);
  close(fd);
  text.resize(got);
  return text;
}

bool IsInside(const fs::path& path, const std::vector<fs::path>& roots) {
  return std::any_of(roots.begin(), roots.end(), [&](const fs::path& given) {
    std::error_code ec;
    const fs::path root = fs::weakly_canonical(given, ec);  // in case a caller's is not
    return !ec && !root.empty() &&
           std::mismatch(root.begin(), root.end(), path.begin(), path.end()).first == root.end();
  });
}

void RequireInsideRoots(const fs::path& path, const LoadPolicy& policy, const std::string& shown) {
  if (policy.references != LoadPolicy::References::kInsideRoots) return;
  std::error_code ec;
  const fs::path real = fs::canonical(path, ec);
  if (ec || !IsInside(real, policy.roots)) throw InputError(fmt::format("{}: outside the data roots", shown));
}

void CheckReferences(const formats::References& refs, const LoadPolicy& policy, const std::string& shown) {
  using R = LoadPolicy::References;
  if (refs.field.empty()) {
    if (!refs.problem.empty() && policy.references != R::kAnywhere) {
      throw InputError(fmt::format("{}: {}", shown, refs.problem));
    }
    return;
  }
  if (policy.references == R::kNone) {
    throw InputError(fmt::format("{}: the header names another file ('{}'); uploads must be self-contained",
                                 shown, refs.field));
  }
  if (policy.references == R::kAnywhere) {
    // The operator's own files may name any file, but only a regular one: a
    // FIFO blocks the reader, a device never ends. A missing one ITK reports.
    for (const fs::path& file : refs.files) {
      std::error_code ec;
      if (fs::exists(fs::status(file, ec)) && !IsRegularFile(file)) {
        throw InputError(fmt::format("{}: the header's '{}' names something other than a regular file", shown,
                                     refs.field));
      }
    }
    return;
  }
  if (!refs.problem.empty()) {
    throw InputError(fmt::format("{}: the header's '{}' cannot be checked: {}", shown, refs.field, refs.problem));
  }
  for (const fs::path& file : refs.files) {
    // One message for missing, outside and irregular files: it must not
    // tell whether a file outside the roots exists.
    std::error_code ec;
    const fs::path real = fs::canonical(file, ec);
    if (ec || !IsInside(real, policy.roots) || !IsRegularFile(real)) {
      throw InputError(fmt::format(
          "{}: the header's '{}' names a file that is not a regular file inside the data roots", shown,
          refs.field));
    }
  }
}

}  // namespace cinevol::file_checks
