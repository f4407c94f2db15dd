// A pseudo-terminal pair published at a path: what a controller emulator offers in place of a serial port, and what
// the drivers' tests talk to. The emulator (or the test) keeps the master side; a driver opens the published path
// (a symbolic link to the slave, e.g. /tmp/melfa -> /dev/pts/7) exactly as it opens /dev/ttyUSB0.
//
// The slave is put in raw mode at creation (no echo, no line editing, no translation), and the pair keeps a slave
// descriptor of its own open for its whole life, so that the master neither reads end-of-file nor loses written bytes
// while no driver has the port open, and a driver may close and open the path again (a reconnect).
//
// Errors: the constructor throws InputError naming the link and the reason (errno's text) when the pair cannot be made
// or the link cannot be written (its directory is missing, or a file that is not a symbolic link is in the way).
//
// Threads: not synchronised. One thread owns a PseudoTerminal; the master descriptor may be used by that thread with
// read()/write()/poll().
#pragma once

#include <filesystem>
#include <string>

namespace cellwright {

class PseudoTerminal {
 public:
  // Opens a new pair. With a non-empty `link`, publishes the slave's path there (replacing a symbolic link already
  // there: an emulator restarted on the same path).
  explicit PseudoTerminal(std::filesystem::path link = {});
  ~PseudoTerminal();  // closes both sides and removes the link if it still points to this pair's slave
  PseudoTerminal(const PseudoTerminal&) = delete;
  PseudoTerminal& operator=(const PseudoTerminal&) = delete;

  // The master side, non-blocking: what the emulator reads and writes.
  int master() const { return master_; }
  // The slave's device path (/dev/pts/N).
  const std::string& slave_path() const { return slave_path_; }
  // The published path, or the slave's when none was asked for: what a driver opens.
  std::string path() const { return link_.empty() ? slave_path_ : link_.string(); }

  // Hangs up: closes the master (a driver reading the slave gets end-of-file or an error, as when a cable is pulled).
  // The link is left in place. Idempotent.
  void hang_up();
  bool hung_up() const { return master_ < 0; }

 private:
  int master_ = -1;
  int slave_ = -1;  // kept open: see above
  std::string slave_path_;
  std::filesystem::path link_;
};

}  // namespace cellwright
