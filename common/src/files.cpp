#include "cellwright/common/files.hpp"

#include <stdlib.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <sstream>
#include <system_error>

#include "cellwright/common/error.hpp"

namespace cellwright {

void check_writable_dir(const std::filesystem::path& dir) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::path p = fs::absolute(dir, ec);
  if (ec || dir.empty()) throw InputError({dir.string(), 0, 0}, "not a usable output directory");
  if (fs::exists(p, ec)) {
    if (!fs::is_directory(p, ec)) throw InputError({dir.string(), 0, 0}, "exists and is not a directory");
    if (::access(p.c_str(), W_OK | X_OK) != 0) {
      throw InputError({dir.string(), 0, 0}, fmt::format("cannot write into it: {}", std::strerror(errno)));
    }
    return;
  }
  // The nearest existing ancestor must be a directory we may write into.
  fs::path parent = p.parent_path();
  while (!parent.empty() && !fs::exists(parent, ec)) {
    if (parent == parent.parent_path()) break;
    parent = parent.parent_path();
  }
  if (!fs::is_directory(parent, ec)) {
    throw InputError({dir.string(), 0, 0},
                     fmt::format("cannot be created: {} is not a directory", parent.string()));
  }
  if (::access(parent.c_str(), W_OK | X_OK) != 0) {
    throw InputError({dir.string(), 0, 0},
                     fmt::format("cannot be created in {}: {}", parent.string(), std::strerror(errno)));
  }
}

std::string not_a_file(const std::filesystem::path& path) {
  std::error_code ec;
  const std::filesystem::file_status status = std::filesystem::status(path, ec);
  if (std::filesystem::is_directory(status)) return "is a directory, not a file";
  if (status.type() == std::filesystem::file_type::not_found) return "no such file";
  return {};
}

std::string read_file(const std::filesystem::path& path) {
  if (const std::string problem = not_a_file(path); !problem.empty()) throw InputError({path.string()}, problem);
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

void move_file(const std::filesystem::path& from, const std::filesystem::path& to) {
  std::error_code ec;
  std::filesystem::rename(from, to, ec);
  if (!ec) return;
  if (ec != std::errc::cross_device_link) {
    throw InputError({to.string()}, fmt::format("cannot move {} here: {}", from.string(), ec.message()));
  }
  const std::filesystem::path tmp = to.string() + fmt::format(".tmp.{}", ::getpid());
  std::filesystem::copy_file(from, tmp, std::filesystem::copy_options::overwrite_existing, ec);
  if (!ec) std::filesystem::rename(tmp, to, ec);
  if (ec) {
    std::error_code ignored;
    std::filesystem::remove(tmp, ignored);
    throw InputError({to.string()}, fmt::format("cannot copy {} here: {}", from.string(), ec.message()));
  }
  std::filesystem::remove(from, ec);  // a leftover temporary file is not worth failing for
}

TemporaryFile::TemporaryFile(std::string_view prefix, std::string_view suffix) {
  std::error_code ec;
  std::filesystem::path dir = std::filesystem::temp_directory_path(ec);
  if (ec) dir = "/tmp";
  std::string name = (dir / fmt::format("{}XXXXXX{}", prefix, suffix)).string();
  const int fd = ::mkstemps(name.data(), static_cast<int>(suffix.size()));
  if (fd < 0) throw InputError({name}, fmt::format("cannot create a temporary file: {}", std::strerror(errno)));
  ::close(fd);
  path_ = name;
}

TemporaryFile::~TemporaryFile() {
  std::error_code ignored;
  std::filesystem::remove(path_, ignored);
}

}  // namespace cellwright
