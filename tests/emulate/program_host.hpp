// ProgramHost: a host on an emulated controller's published line, through the project's SerialPort, that loads a
// robot program and runs it as docs/real-robots.md ("Robot programs") says: Movemaster lines then `RN` and `ER`;
// VAL II lines each answered by the prompt, then `EXECUTE name`. For the emulators' program tests and the proof that
// generated programs run.
//
// Threads: one test thread.
#pragma once

#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>

#include "cellwright/drivers/serial/serial_port.hpp"

namespace cellwright::emulate::testing {

class ProgramHost {
 public:
  using Clock = drivers::SerialPort::Clock;

  explicit ProgramHost(const std::filesystem::path& link) : port_(line(link), {"test host", 0, 0}) {}

  // Sends `text` followed by `end`.
  void send(std::string_view text, std::string_view end) {
    std::string message;
    const drivers::PortStatus s = port_.write(std::string(text) + std::string(end), Clock::now() + kWrite, &message);
    EXPECT_EQ(s, drivers::PortStatus::ok) << "writing '" << text << "': " << message;
  }

  // The next line received (without its end), or nullopt when none comes within `timeout`.
  std::optional<std::string> line(std::chrono::nanoseconds timeout) {
    const auto deadline = Clock::now() + timeout;
    for (;;) {
      const std::size_t lf = buffer_.find('\n');
      if (lf != std::string::npos) {
        std::string l = buffer_.substr(0, lf);
        buffer_.erase(0, lf + 1);
        if (!l.empty() && l.back() == '\r') l.pop_back();
        return l;
      }
      if (!fill(deadline)) return std::nullopt;
    }
  }

  // Everything up to the VAL II prompt (a `.` at the start of a line, nothing after it), without the prompt; nullopt
  // when it does not come within `timeout`.
  std::optional<std::string> until_prompt(std::chrono::nanoseconds timeout) {
    const auto deadline = Clock::now() + timeout;
    for (;;) {
      if (buffer_ == "." || buffer_.ends_with("\n.")) {
        std::string out = buffer_.substr(0, buffer_.size() - 1);
        buffer_.clear();
        return out;
      }
      if (!fill(deadline)) return std::nullopt;
    }
  }

  // Movemaster: sends the program lines, then ER; true when the controller answered 0 (every line stored).
  bool load_movemaster(const std::vector<std::string>& lines) {
    for (const std::string& l : lines) send(l, "\r\n");
    send("ER", "\r\n");
    const std::optional<std::string> er = line(kAnswer);
    EXPECT_EQ(er.value_or("(nothing)"), "0") << "after loading the program";
    return er == "0";
  }
  // Movemaster: RN then ER; the ER's answer (it comes when the program has ended), or nullopt after `timeout`.
  std::optional<std::string> run_movemaster(std::chrono::nanoseconds timeout) {
    send("RN", "\r\n");
    send("ER", "\r\n");
    return line(timeout);
  }

  // VAL II: asks WHERE and reads prompts until its answer, so that what came before (the first prompt, which the port
  // may have discarded when it opened) is behind. True when it came.
  bool sync_val2() {
    send("WHERE", "\r");
    while (const std::optional<std::string> printed = until_prompt(kAnswer)) {
      if (printed->find("X/JT1") != std::string::npos) return true;
    }
    return false;
  }

  // VAL II (its first prompt taken): sends each line and waits for its prompt; returns what the monitor printed.
  std::string load_val2(const std::vector<std::string>& lines) {
    std::string printed;
    for (const std::string& l : lines) {
      send(l, "\r");
      printed += until_prompt(kAnswer).value_or("(no prompt after " + l + ")");
    }
    return printed;
  }
  // VAL II: EXECUTE name; what the monitor printed before its prompt, or nullopt after `timeout`.
  std::optional<std::string> execute_val2(const std::string& name, std::chrono::nanoseconds timeout) {
    send("EXECUTE " + name, "\r");
    return until_prompt(timeout);
  }

 private:
  static constexpr std::chrono::seconds kWrite{5};
  static constexpr std::chrono::seconds kAnswer{10};

  static drivers::SerialLine line(const std::filesystem::path& link) {
    drivers::SerialLine l;
    l.port = link.string();
    return l;
  }

  bool fill(Clock::time_point deadline) {
    std::string message;
    return port_.read_some(&buffer_, deadline, &message) == drivers::PortStatus::ok;
  }

  drivers::SerialPort port_;
  std::string buffer_;
};

}  // namespace cellwright::emulate::testing
