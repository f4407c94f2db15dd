// Reading and writing users' files without ever leaving a half-written one behind.
#pragma once

#include <filesystem>
#include <string>
#include <string_view>

namespace cellwright {

// Why `path` cannot be read as a file, in words for an error after its path: "is a directory, not a file", "no
// such file"; empty when it is a file (or something else that opening it will judge). Every reader of a
// user's file (cell, scenario, program, URDF, decision tree, PNML, suite) says this, so that a folder given where a
// file is expected is never called missing.
std::string not_a_file(const std::filesystem::path& path);

// The whole file as bytes. Throws InputError({path}) with not_a_file's words when it is a directory or missing,
// "cannot open: <reason>" or "read failed" otherwise.
std::string read_file(const std::filesystem::path& path);

// Writes `bytes` to a temporary file beside `path`, then renames it over `path`: readers see the old file or the
// new one, never a torn one. Throws InputError naming the path (and the OS reason) when it cannot; the temporary file
// is removed on failure.
void write_file_atomically(const std::filesystem::path& path, std::string_view bytes);

// Checks, before anything runs, that `dir` can be an output directory: an existing directory we may write into, or
// one that can be created (its nearest existing ancestor is a directory we may write into). Creates nothing. Throws
// InputError({dir}) "exists and is not a directory", "cannot write into it: <reason>", "cannot be created: <ancestor>
// is not a directory" or "cannot be created in <ancestor>: <reason>".
void check_writable_dir(const std::filesystem::path& dir);

// Moves the file `from` to `to`, replacing it: a rename when both are on one file system (atomic), else a copy to a
// temporary file beside `to`, renamed over it, then `from` removed. Throws InputError naming the paths when it
// cannot; `to` is then unchanged.
void move_file(const std::filesystem::path& from, const std::filesystem::path& to);

// A new, empty file of our own in the system's temporary directory (TMPDIR, else /tmp), removed when this object
// goes. The name is `prefix`, six random characters and `suffix`. Throws InputError when it cannot be created.
class TemporaryFile {
 public:
  TemporaryFile(std::string_view prefix, std::string_view suffix);
  ~TemporaryFile();
  TemporaryFile(const TemporaryFile&) = delete;
  TemporaryFile& operator=(const TemporaryFile&) = delete;
  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
};

}  // namespace cellwright
