#include "cellwright/common/files.hpp"

#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <sstream>
#include <system_error>

#include "cellwright/common/error.hpp"

namespace cellwright {

std::string read_file(const std::filesystem::path& path) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) throw InputError({path.string()}, "is a directory, not a file");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError({path.string()}, fmt::format("cannot open: {}", std::strerror(errno)));
  std::ostringstream s;
  s << in.rdbuf();
  if (in.bad()) throw InputError({path.string()}, "read failed");
  return std::move(s).str();
}

void write_file_atomically(const std::filesystem::path& path, std::string_view bytes) {
  // The temporary name carries the pid so that two processes writing the same file do not share a temp file.
  const std::filesystem::path tmp = path.string() + fmt::format(".tmp.{}", ::getpid());
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) throw InputError({path.string()}, fmt::format("cannot write: {}", std::strerror(errno)));
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    out.flush();
    if (!out) {
      std::error_code ignored;
      std::filesystem::remove(tmp, ignored);
      throw InputError({path.string()}, "write failed (disk full?)");
    }
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) {
    std::error_code ignored;
    std::filesystem::remove(tmp, ignored);
    throw InputError({path.string()}, fmt::format("cannot replace: {}", ec.message()));
  }
}

}  // namespace cellwright
