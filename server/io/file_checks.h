// Internal to server/io: what a volume load may open, whatever its format.
// Everything the loaders open themselves goes through here first: only
// regular files, inside the data roots where the policy says so, headers read
// with a bound; and the other files a header names (found by its format,
// io/formats/format.h) checked against the LoadPolicy before a reader sees
// anything.
#pragma once

#include <cstddef>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "io/formats/format.h"
#include "io/volume_loader.h"

namespace cinevol::file_checks {

// What messages call `path`: the policy's label when it has one.
std::string Shown(const std::filesystem::path& path, const LoadPolicy& policy);

// Whether `path`, symlinks followed, is a regular file. Looks with stat and
// never opens it: opening a FIFO for reading blocks until a writer comes.
bool IsRegularFile(const std::filesystem::path& path);

// Throws InputError "<shown>: not a regular file" unless IsRegularFile.
void RequireRegularFile(const std::filesystem::path& path, const std::string& shown);

// Opens a regular file for reading without blocking on anything else (the
// type is checked on the open descriptor, so a file swapped after
// IsRegularFile is refused too). Returns -1 if it cannot.
int OpenRegularFile(const std::filesystem::path& path);

// OpenRegularFile as a stdio stream, closed when dropped; null if it cannot.
using FileStream = std::unique_ptr<std::FILE, int (*)(std::FILE*)>;
FileStream OpenRegularStream(const std::filesystem::path& path);

// At most `limit` bytes from the start of a regular file.
std::string ReadHead(const std::filesystem::path& path, std::size_t limit, const std::string& shown);

// Whether `path` (canonical) lies in one of `roots` (canonical).
bool IsInside(const std::filesystem::path& path, const std::vector<std::filesystem::path>& roots);

// kInsideRoots: throws InputError "<shown>: outside the data roots" unless
// `path`, symlinks followed, lies inside one of the policy's roots.
void RequireInsideRoots(const std::filesystem::path& path, const LoadPolicy& policy, const std::string& shown);

// Throws InputError unless `refs` is what `policy` allows: kNone refuses any
// reference; kInsideRoots needs each file to be regular and inside the roots.
// Messages name `shown` and the field, never whether an outside file exists.
void CheckReferences(const formats::References& refs, const LoadPolicy& policy, const std::string& shown);

}  // namespace cinevol::file_checks
