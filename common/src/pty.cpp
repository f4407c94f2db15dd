// PseudoTerminal (pty.hpp): posix_openpt, then the slave kept open in raw mode and published by a symbolic link.
#include "cellwright/common/pty.hpp"

#include <fcntl.h>
#include <termios.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <system_error>

#include "cellwright/common/error.hpp"

namespace cellwright {

namespace {

std::string errno_text(int e) {
  return std::strerror(e);
}

}  // namespace

PseudoTerminal::PseudoTerminal(std::filesystem::path link) : link_(std::move(link)) {
  const SourceLocation where{link_.empty() ? std::string("<pseudo-terminal>") : link_.string(), 0, 0};
  master_ = posix_openpt(O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
  if (master_ < 0) throw InputError(where, fmt::format("cannot open a pseudo-terminal: {}", errno_text(errno)));
  char name[128];
  if (grantpt(master_) != 0 || unlockpt(master_) != 0 || ptsname_r(master_, name, sizeof name) != 0) {
    const int e = errno;
    ::close(master_);
    throw InputError(where, fmt::format("cannot prepare the pseudo-terminal's slave: {}", errno_text(e)));
  }
  slave_path_ = name;
  slave_ = ::open(name, O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
  termios t{};
  if (slave_ < 0 || tcgetattr(slave_, &t) != 0) {
    const int e = errno;
    hang_up();
    if (slave_ >= 0) ::close(slave_);
    throw InputError(where, fmt::format("cannot open the pseudo-terminal's slave {}: {}", slave_path_, errno_text(e)));
  }
  cfmakeraw(&t);
  tcsetattr(slave_, TCSANOW, &t);
  if (!link_.empty()) {
    std::error_code ec;
    if (std::filesystem::is_symlink(std::filesystem::symlink_status(link_, ec))) {
      std::filesystem::remove(link_, ec);
    } else if (std::filesystem::exists(std::filesystem::symlink_status(link_, ec))) {
      hang_up();
      ::close(slave_);
      throw InputError(where, "a file that is not a symbolic link is in the way; the link is not written over it");
    }
    std::filesystem::create_symlink(slave_path_, link_, ec);
    if (ec) {
      hang_up();
      ::close(slave_);
      throw InputError(where, fmt::format("cannot publish the pseudo-terminal {} here: {}", slave_path_, ec.message()));
    }
  }
}

PseudoTerminal::~PseudoTerminal() {
  hang_up();
  if (slave_ >= 0) ::close(slave_);
  if (!link_.empty()) {
    std::error_code ec;
    if (std::filesystem::read_symlink(link_, ec) == slave_path_ && !ec) std::filesystem::remove(link_, ec);
  }
}

void PseudoTerminal::hang_up() {
  if (master_ >= 0) ::close(master_);
  master_ = -1;
}

}  // namespace cellwright
