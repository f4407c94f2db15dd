#include "cellwright/emulate/cell_io_emulator.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <charconv>
#include <chrono>
#include <cmath>
#include <utility>

namespace cellwright::emulate {

namespace {

double steady_seconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

}  // namespace

InputChange parse_input_change(std::string_view text, const SourceLocation& where) {
  const auto fail = [&](const std::string& problem) {
    return InputError(where, fmt::format("'{}': {} (write AT:INPUT=VALUE, e.g. 2.5:0=1: photo-eye 0 on at 2.5 s)",
                                         text, problem));
  };
  const std::size_t colon = text.find(':');
  const std::size_t eq = text.find('=');
  if (colon == std::string_view::npos || eq == std::string_view::npos || eq < colon) {
    throw fail("not of the form AT:INPUT=VALUE");
  }
  InputChange c;
  const std::string_view at = text.substr(0, colon);
  const auto [end, ec] = std::from_chars(at.data(), at.data() + at.size(), c.at);
  if (at.empty() || ec != std::errc() || end != at.data() + at.size() || !std::isfinite(c.at) || c.at < 0) {
    throw fail(fmt::format("the time '{}' is not a number of seconds >= 0", at));
  }
  const std::string_view input = text.substr(colon + 1, eq - colon - 1);
  if (input != "0" && input != "1") throw fail(fmt::format("the input '{}' is not 0 or 1 (the photo-eyes)", input));
  c.input = input == "1" ? 1 : 0;
  const std::string_view value = text.substr(eq + 1);
  if (value != "0" && value != "1") throw fail(fmt::format("the value '{}' is not 0 or 1", value));
  c.value = value == "1";
  return c;
}

CellIoEmulator::CellIoEmulator(CellIoEmulatorOptions options, const SourceLocation& where)
    : options_(std::move(options)), image_(kCoils, kInputs, "emulated cell I/O") {
  if (!std::isfinite(options_.process_time) || options_.process_time < 0) {
    throw InputError(where, fmt::format("the process time must be a number of seconds >= 0, got {}",
                                        options_.process_time));
  }
  if (!std::isfinite(options_.take_out_after)) {
    throw InputError(where, fmt::format("the take-out time must be a number of seconds, got {}",
                                        options_.take_out_after));
  }
  for (const InputChange& c : options_.script) {
    if (c.input > 1 || !std::isfinite(c.at) || c.at < 0) {
      throw InputError(where, fmt::format("a scripted change of input {} at {} s: only inputs 0 and 1 (the "
                                          "photo-eyes), at a time >= 0",
                                          c.input, c.at));
    }
  }
  std::stable_sort(options_.script.begin(), options_.script.end(),
                   [](const InputChange& a, const InputChange& b) { return a.at < b.at; });
  if (!options_.clock) epoch_ = steady_seconds();
}

double CellIoEmulator::now() const { return options_.clock ? options_.clock() : steady_seconds() - epoch_; }

void CellIoEmulator::update(double t) {
  for (; next_change_ < options_.script.size() && options_.script[next_change_].at <= t; ++next_change_) {
    image_.set_input(options_.script[next_change_].input, options_.script[next_change_].value);
  }
  if (mill_ == Mill::busy && t >= since_ + options_.process_time) {
    mill_ = Mill::done;
    since_ += options_.process_time;
  }
  if (mill_ == Mill::done && options_.take_out_after >= 0 && t >= since_ + options_.take_out_after) {
    mill_ = Mill::idle;
    since_ += options_.take_out_after;
  }
  image_.set_input(kMillBusy, mill_ == Mill::busy);
  image_.set_input(kMillDone, mill_ == Mill::done);
}

std::string CellIoEmulator::describe() const { return image_.describe(); }
drivers::IoResult CellIoEmulator::connect() { return image_.connect(); }
void CellIoEmulator::close() { image_.close(); }
bool CellIoEmulator::is_open() const { return image_.is_open(); }

drivers::IoResult CellIoEmulator::write_coil(std::uint16_t address, bool value) {
  std::lock_guard lock(mu_);
  const bool rising = address == kMillStart && value && !image_.coil(kMillStart);
  drivers::IoResult r = image_.write_coil(address, value);
  if (!r.ok()) return r;
  const double t = now();
  update(t);
  if (rising && mill_ == Mill::idle) {
    mill_ = Mill::busy;
    since_ = t;
    ++cycles_;
    update(t);  // a process time of 0: done at once
  }
  return r;
}

drivers::IoResult CellIoEmulator::read_coils(std::uint16_t first, std::uint16_t count, std::vector<bool>& values) {
  return image_.read_coils(first, count, values);
}

drivers::IoResult CellIoEmulator::read_inputs(std::uint16_t first, std::uint16_t count, std::vector<bool>& values) {
  std::lock_guard lock(mu_);
  update(now());
  return image_.read_inputs(first, count, values);
}

void CellIoEmulator::set_input(std::uint16_t address, bool value) {
  std::lock_guard lock(mu_);
  CW_CHECK(address < 2, "CellIoEmulator: set_input({}) is for the photo-eyes, inputs 0 and 1", address);
  update(now());
  image_.set_input(address, value);
}

void CellIoEmulator::take_out() {
  std::lock_guard lock(mu_);
  update(now());
  if (mill_ == Mill::done) mill_ = Mill::idle;
  update(now());
}

bool CellIoEmulator::coil(std::uint16_t address) const { return image_.coil(address); }

int CellIoEmulator::cycles() const {
  std::lock_guard lock(mu_);
  return cycles_;
}

}  // namespace cellwright::emulate
