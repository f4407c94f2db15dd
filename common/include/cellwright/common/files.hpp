// Reading and writing users' files without ever leaving a half-written one behind.
#pragma once

#include <filesystem>
#include <string>
#include <string_view>

namespace cellwright {

// The whole file as bytes. Throws InputError naming the path when it is missing, a directory or unreadable.
std::string read_file(const std::filesystem::path& path);

// Writes `bytes` to a temporary file beside `path`, then renames it over `path`: readers see the old file or the
// new one, never a torn one. Throws InputError naming the path (and the OS reason) when it cannot; the temporary file
// is removed on failure.
void write_file_atomically(const std::filesystem::path& path, std::string_view bytes);

}  // namespace cellwright
