// SerialDriver: what every RS-232 robot driver shares, written once on DriverCore (driver_core.hpp). The Movemaster
// EX and VAL II drivers derive from it and supply only their language: what to say at connect, how to execute one
// job (a home, a command or a position read) as an exchange of lines, and how to clear the controller's error.
//
// THE COMMUNICATION THREAD (paper section 4: one pair of threads per port). connect() opens the port (SerialPort:
// an InputError naming the port and the reason when it cannot), runs the protocol's greeting on the calling thread
// and then starts one thread, the only code that touches the port from then on. It takes the head job of the core's
// queue, marks it running, talks to the controller with no lock held, and reports the outcome by id (a job that
// stop() or disconnect() ended meanwhile is no longer there and the report is ignored). disconnect() stops and joins
// it and closes the port.
//
// PACING (the paper's rule, docs/real-robots.md): Link::send() sends nothing sooner than the previous line's wire
// time plus the controller's processing time (SerialOptions::processing_time) after that line was written.
//
// READS NEVER DELAY COMMANDS (robot_driver.hpp, POSITION READS ON A LINE). The thread takes a position read only once
// the pacing lets it go on the wire at once (it waits for the pacing window with the read still pending), and a
// pending read at the head with a command behind it is withdrawn (cancelled, "overtaken by command N") so that the
// command goes first. A read on the wire is finished: the command behind it waits at most one read. Each driver
// reports in Capabilities::read_time how long one read holds its line (read_time() below: its request and a typical
// answer at the line's rate, plus processing_time), which the runtime paces its periodic reads by.
//
// TIMING: for every job, the bytes each way, their wire time, the time spent waiting for the line (for the pacing
// and in poll()) and the rest, the host's own processing time; timing() sums them up and keeps the most recent jobs.
//
// FAILURES. A job's outcome is none (done), or a controller's error: unreachable or timeout (the job fails, the driver
// goes on), hardware, protocol, connection_lost or unknown (the driver enters fault; the message names the bytes
// received). A read that finds the line hung up is connection_lost. Nothing waits without a deadline. After a fault,
// reset() marks the controller's error to be cleared: the thread calls clear_error() before it takes the next job (the
// home() that follows); a link that dropped leaves the driver disconnected instead (connect() again).
//
// STOP. stop() and disconnect() cancel the jobs at once (DriverCore); an exchange already on the wire is finished by
// the thread (the controllers cannot be interrupted over the line: the motion in progress ends), and its outcome is
// ignored.
//
// THREADS: the owner calls the RobotDriver methods (as robot_driver.hpp says); the communication thread does the
// rest; timing() may be called from any thread.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <thread>

#include "cellwright/common/error.hpp"
#include "cellwright/drivers/driver_core.hpp"
#include "cellwright/drivers/serial/serial_port.hpp"

namespace cellwright::drivers {

struct SerialOptions {
  SerialLine line;
  SourceLocation where;  // the robot's entry in the cell file (or the command line): errors at connect name it
  // The controller's time to take a line in before the next may be sent (the paper's pacing rule).
  std::chrono::nanoseconds processing_time = std::chrono::milliseconds(20);
  // The longest wait for an answer to a line that starts no motion.
  std::chrono::nanoseconds reply_timeout = std::chrono::seconds(2);
};

// One job's exchange on the line.
struct SerialExchange {
  CommandId id = 0;
  std::string what;  // "home", "position", or describe(command)
  std::size_t bytes_sent = 0, bytes_received = 0;
  std::chrono::nanoseconds wire_sent{0};      // the time the sent bytes take on the wire
  std::chrono::nanoseconds wire_received{0};  // the same for the received bytes
  std::chrono::nanoseconds waiting{0};        // blocked: pacing, the controller, the line
  std::chrono::nanoseconds processing{0};     // the rest of the job's time: the host's own work
  std::chrono::nanoseconds elapsed{0};        // from taking the job to reporting it
};

struct SerialTiming {
  std::uint64_t jobs = 0;
  std::size_t bytes_sent = 0, bytes_received = 0;
  std::chrono::nanoseconds wire_sent{0}, wire_received{0}, waiting{0}, processing{0};
  std::deque<SerialExchange> recent;  // the most recent exchanges, oldest first (at most kRecent)
  static constexpr std::size_t kRecent = 256;
};

class SerialDriver : public DriverCore {
 public:
  // The line to the controller as the protocol code sees it: pacing, deadlines, a receive buffer, the job's counts.
  class Link {
   public:
    using Clock = SerialPort::Clock;

    // Sends `text` as it is (the protocol adds its line end), after the pacing wait. ok, or timeout / closed / error
    // with *message set.
    PortStatus send(std::string_view text, std::string* message);
    // Waits until the buffer holds a complete line (ended by CR LF, LF alone or CR alone), then removes and returns
    // it in *line, without its end. A line ended by a CR that came last: the LF that may follow it is dropped when
    // it comes (receive()), so a CR LF is one line end even when it arrives in two reads. timeout / closed / error
    // with *message set (the bytes received so far stay in buffer()).
    PortStatus read_line(Clock::time_point deadline, std::string* line, std::string* message);
    // Appends what arrives to buffer(), waiting for at least one byte (for prompts that end no line).
    PortStatus receive(Clock::time_point deadline, std::string* message);
    // Bytes received and not consumed yet.
    std::string& buffer() { return buffer_; }
    // Discards the bytes received and not read, in the buffer and in the port.
    void discard_input();
    // A deadline `after` from now.
    static Clock::time_point in(std::chrono::nanoseconds after) { return Clock::now() + after; }
    const SerialOptions& options() const { return options_; }
    // Everything received in the current job so far, for messages ("received 'ABC'"); printable, escapes the rest.
    std::string received_text() const;

   private:
    friend class SerialDriver;
    Link(SerialPort& port, const SerialOptions& options) : port_(port), options_(options) {}
    void begin(SerialExchange* exchange);
    SerialPort& port_;
    const SerialOptions& options_;
    std::string buffer_;
    bool lf_owed_ = false;            // read_line() ended a line at a CR that came last: a LF right after it is dropped
    std::string received_;            // this job's bytes, for messages
    Clock::time_point not_before_{};  // pacing: the next send waits until then
    SerialExchange* exchange_ = nullptr;  // the job being counted
  };

  // What a job came to.
  struct Outcome {
    ErrorCode error = ErrorCode::none;  // none, unreachable, timeout, hardware, protocol, connection_lost, unknown
    std::string message;
    std::optional<PositionReading> reading;  // a position job that is done: the reading (stamp set by the base)
  };

  // What the protocol code gets of a job: a copy, taken under the lock.
  struct JobCopy {
    CommandId id = 0;
    JobKind kind = JobKind::command;
    std::optional<Command> command;
  };

  ~SerialDriver() override;

  // The per-job timing so far (any thread).
  SerialTiming timing() const;
  // Why the last connect() returned connection_lost (the controller did not answer the greeting), or "".
  std::string connect_problem() const;

 protected:
  explicit SerialDriver(SerialOptions options);

  // ---- What a protocol supplies (all on the communication thread, or at connect on the owner's; no lock held) ----
  // After the port is opened: check the controller answers (and set it up: tool length, speed). Returns an Outcome:
  // none, or the error that makes connect() fail with connection_lost (its message is kept: connect_problem()).
  virtual Outcome greet(Link& link) = 0;
  // Executes one job from start to end.
  virtual Outcome execute(Link& link, const JobCopy& job) = 0;
  // After reset(): clear the controller's error (Movemaster `RS`). none, or a fatal error (the driver faults again).
  virtual Outcome clear_error(Link& link) = 0;

  // For messages: the bytes as text, non-printable ones escaped ("\r", "\x07").
  static std::string printable(std::string_view bytes);
  // Capabilities::read_time of a protocol whose position read sends `request` bytes and gets about `answer` bytes
  // back (echo and prompt included): their wire time on `options`' line plus the controller's processing_time.
  static std::chrono::nanoseconds read_time(const SerialOptions& options, std::size_t request, std::size_t answer);

 private:
  ErrorCode connect_hook() final;
  void disconnect_hook() final;
  void accept_hook(Job& job) final;
  void halt_hook() final;
  ErrorCode reset_hook() final;

  void run();
  void wake();
  void record(SerialExchange exchange);

  const SerialOptions options_;
  std::unique_ptr<SerialPort> port_;
  std::unique_ptr<Link> link_;
  std::thread thread_;
  // The thread's wake-up: taken after the core's mutex when both are held, never the other way.
  std::mutex wake_mutex_;
  std::condition_variable wake_cv_;
  std::uint64_t wake_seq_ = 0;
  bool quit_ = false;
  bool clear_pending_ = false;  // guarded by the core's mutex
  mutable std::mutex timing_mutex_;
  SerialTiming timing_;
  std::string connect_problem_;  // owner thread only
};

}  // namespace cellwright::drivers
