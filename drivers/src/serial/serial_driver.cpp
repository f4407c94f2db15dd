// SerialDriver (serial_driver.hpp): the port, the communication thread, pacing and timing shared by the serial
// drivers.
#include "cellwright/drivers/serial/serial_driver.hpp"

#include <fmt/format.h>

#include <cstdio>
#include <cstdlib>
#include <utility>

namespace cellwright::drivers {

namespace {

using SteadyClock = SerialPort::Clock;

bool fatal(ErrorCode e) {
  return e == ErrorCode::hardware || e == ErrorCode::protocol || e == ErrorCode::connection_lost ||
         e == ErrorCode::unknown;
}

}  // namespace

// ---- Link ---------------------------------------------------------------------------------------------------------

void SerialDriver::Link::begin(SerialExchange* exchange) {
  exchange_ = exchange;
  received_.clear();
}

PortStatus SerialDriver::Link::send(std::string_view text, std::string* message) {
  const auto now = Clock::now();
  if (now < not_before_) {
    std::this_thread::sleep_until(not_before_);  // the paper's pacing rule, not a race
    if (exchange_ != nullptr) exchange_->waiting += Clock::now() - now;
  }
  const auto waited = port_.waited();
  const PortStatus s = port_.write(text, in(options_.reply_timeout), message);
  const auto written = Clock::now();
  if (exchange_ != nullptr) {
    exchange_->waiting += port_.waited() - waited;
    exchange_->bytes_sent += text.size();
    exchange_->wire_sent += options_.line.wire_time(text.size());
  }
  not_before_ = written + options_.line.wire_time(text.size()) + options_.processing_time;
  return s;
}

PortStatus SerialDriver::Link::receive(Clock::time_point deadline, std::string* message) {
  const std::size_t before = buffer_.size();
  const auto waited = port_.waited();
  const PortStatus s = port_.read_some(&buffer_, deadline, message);
  const std::size_t got = buffer_.size() - before;
  received_.append(buffer_, before, got);
  if (lf_owed_ && !buffer_.empty()) {
    lf_owed_ = false;
    if (buffer_.front() == '\n') buffer_.erase(0, 1);  // the LF of a CR LF whose CR ended a line
  }
  if (exchange_ != nullptr) {
    exchange_->waiting += port_.waited() - waited;
    exchange_->bytes_received += got;
    exchange_->wire_received += options_.line.wire_time(got);
  }
  return s;
}

PortStatus SerialDriver::Link::read_line(Clock::time_point deadline, std::string* line, std::string* message) {
  for (;;) {
    const std::size_t end = buffer_.find_first_of("\r\n");
    if (end != std::string::npos) {
      line->assign(buffer_, 0, end);
      std::size_t taken = end + 1;
      if (buffer_[end] == '\r') {
        if (taken == buffer_.size()) {
          lf_owed_ = true;  // a LF may still come: receive() drops it
        } else if (buffer_[taken] == '\n') {
          ++taken;
        }
      }
      buffer_.erase(0, taken);
      return PortStatus::ok;
    }
    const PortStatus s = receive(deadline, message);
    if (s != PortStatus::ok) return s;
  }
}

void SerialDriver::Link::discard_input() {
  buffer_.clear();
  lf_owed_ = false;
  port_.discard_input();
}

std::string SerialDriver::Link::received_text() const {
  return printable(received_);
}

std::string SerialDriver::printable(std::string_view bytes) {
  std::string out;
  for (const char ch : bytes) {
    const auto c = static_cast<unsigned char>(ch);
    if (c == '\r') {
      out += "\\r";
    } else if (c == '\n') {
      out += "\\n";
    } else if (c == '\\') {
      out += "\\\\";
    } else if (c >= 0x20 && c < 0x7f) {
      out += ch;
    } else {
      out += fmt::format("\\x{:02x}", c);
    }
  }
  return out;
}

std::chrono::nanoseconds SerialDriver::read_time(const SerialOptions& options, std::size_t request,
                                                 std::size_t answer) {
  return options.line.wire_time(request + answer) + options.processing_time;
}

// ---- SerialDriver -------------------------------------------------------------------------------------------------

SerialDriver::SerialDriver(SerialOptions options) : DriverCore(RunningWhen::started), options_(std::move(options)) {}

SerialDriver::~SerialDriver() {
  // The derived driver's greet/execute are gone by now: the thread must not outlive them. Derived destructors call
  // disconnect(); this catches a driver destroyed without it.
  if (thread_.joinable()) {
    std::fprintf(stderr, "internal error: a serial driver on %s was destroyed with its thread running\n",
                 options_.line.port.c_str());
    std::abort();
  }
}

SerialTiming SerialDriver::timing() const {
  std::lock_guard lock(timing_mutex_);
  return timing_;
}

std::string SerialDriver::connect_problem() const {
  return connect_problem_;
}

ErrorCode SerialDriver::connect_hook() {
  disconnect_hook();  // a link that dropped (reset() left the driver disconnected): the old thread and port go first
  connect_problem_.clear();
  port_ = std::make_unique<SerialPort>(options_.line, options_.where);  // throws InputError naming the port
  link_.reset(new Link(*port_, options_));
  SerialExchange greeting;
  greeting.what = "connect";
  link_->begin(&greeting);
  const Outcome o = greet(*link_);
  link_->begin(nullptr);
  if (o.error != ErrorCode::none) {
    connect_problem_ = fmt::format("the controller on {} did not answer as expected: {}: {}", options_.line.port,
                                   to_string(o.error), o.message);
    link_.reset();
    port_.reset();
    return ErrorCode::connection_lost;
  }
  {
    std::lock_guard lock(wake_mutex_);
    quit_ = false;
  }
  thread_ = std::thread([this] { run(); });
  return ErrorCode::none;
}

void SerialDriver::disconnect_hook() {
  if (thread_.joinable()) {
    {
      std::lock_guard lock(wake_mutex_);
      quit_ = true;
    }
    wake_cv_.notify_all();
    port_->interrupt();
    thread_.join();
  }
  link_.reset();
  port_.reset();
}

void SerialDriver::accept_hook(Job& /*job*/) {
  wake();
}

void SerialDriver::halt_hook() {
  wake();
}

ErrorCode SerialDriver::reset_hook() {
  clear_pending_ = true;
  wake();
  return ErrorCode::none;
}

void SerialDriver::wake() {
  {
    std::lock_guard lock(wake_mutex_);
    ++wake_seq_;
  }
  wake_cv_.notify_all();
}

void SerialDriver::record(SerialExchange exchange) {
  std::lock_guard lock(timing_mutex_);
  ++timing_.jobs;
  timing_.bytes_sent += exchange.bytes_sent;
  timing_.bytes_received += exchange.bytes_received;
  timing_.wire_sent += exchange.wire_sent;
  timing_.wire_received += exchange.wire_received;
  timing_.waiting += exchange.waiting;
  timing_.processing += exchange.processing;
  timing_.recent.push_back(std::move(exchange));
  while (timing_.recent.size() > SerialTiming::kRecent) timing_.recent.pop_front();
}

void SerialDriver::run() {
  CommandId last_taken = 0;
  for (;;) {
    std::uint64_t seen = 0;
    {
      std::lock_guard lock(wake_mutex_);
      if (quit_) return;
      seen = wake_seq_;
    }
    bool clear = false;
    std::optional<JobCopy> job;
    std::optional<SteadyClock::time_point> read_due;  // a read waits for the pacing window before it is taken
    {
      Controller c = controller();
      if (clear_pending_) {
        clear = true;
        clear_pending_ = false;
      } else {
        Job* head = c.head();
        // A read not yet on the wire never delays a command queued behind it (serial_driver.hpp).
        while (head != nullptr && head->kind == JobKind::position && head->id > last_taken && c.queued().size() > 1 &&
               c.queued()[1].kind != JobKind::position) {
          const CommandId overtaken = head->id;
          c.withdraw(overtaken, fmt::format("cancelled: overtaken by command {} (a position read never delays a "
                                            "command; it was not on the wire yet)",
                                            c.queued()[1].id));
          head = c.head();
        }
        if (head != nullptr && head->id > last_taken) {
          if (head->kind == JobKind::position && SteadyClock::now() < link_->not_before_) {
            read_due = link_->not_before_;
          } else {
            job = JobCopy{head->id, head->kind, head->command};
            last_taken = head->id;
            c.start(head->id);
          }
        }
      }
    }
    if (clear) {
      const Outcome o = clear_error(*link_);
      if (fatal(o.error)) controller().raise_fault(o.error, o.message);
      continue;
    }
    if (job) {
      SerialExchange exchange;
      exchange.id = job->id;
      exchange.what = job->kind == JobKind::home       ? std::string("home")
                      : job->kind == JobKind::position ? std::string("position")
                                                       : describe(*job->command);
      const auto start = SteadyClock::now();
      link_->begin(&exchange);
      Outcome o = execute(*link_, *job);
      link_->begin(nullptr);
      // Recorded before the outcome is reported, so that timing() includes every job poll() says has ended.
      exchange.elapsed = SteadyClock::now() - start;
      exchange.processing = exchange.elapsed - exchange.waiting;
      record(std::move(exchange));
      {
        Controller c = controller();
        if (o.error == ErrorCode::none && job->kind == JobKind::position) {
          CW_CHECK(o.reading.has_value(), "a serial driver's position job {} ended without a reading", job->id);
          PositionReading reading = std::move(*o.reading);
          reading.stamp = c.stamp(std::chrono::duration_cast<std::chrono::nanoseconds>(
              std::chrono::steady_clock::now().time_since_epoch()));
          c.complete(job->id, std::move(reading));
        } else if (o.error == ErrorCode::none) {
          c.complete(job->id);
        } else {
          c.fail(job->id, o.error, std::move(o.message));
        }
      }
      continue;
    }
    std::unique_lock lock(wake_mutex_);
    if (read_due) {
      wake_cv_.wait_until(lock, *read_due, [&] { return quit_ || wake_seq_ != seen; });
    } else {
      wake_cv_.wait(lock, [&] { return quit_ || wake_seq_ != seen; });
    }
  }
}

}  // namespace cellwright::drivers
