// SelfRunningDriver: a scripted controller that runs by itself on the runtime's clock, as a real controller does,
// instead of being advanced by a plant. Before each call of its owner it catches up with the clock the runtime gave it
// (set_clock), in whole ticks of the wrapped ScriptedDriver. So a cell of such robots needs no simulation at all, and
// in lock-step the run stays deterministic (the owner calls on its turn, at a known time).
#pragma once

#include <chrono>
#include <functional>
#include <optional>
#include <utility>

#include "cellwright/drivers/scripted_driver.hpp"

namespace cellwright::testing {

class SelfRunningDriver final : public drivers::RobotDriver {
 public:
  // `inner` must outlive this driver and be used only through it; `tick` is its ScriptedDriverConfig::tick.
  SelfRunningDriver(drivers::ScriptedDriver& inner, std::chrono::nanoseconds tick) : inner_(inner), tick_(tick) {}

  const drivers::Capabilities& capabilities() const override { return inner_.capabilities(); }
  drivers::DriverState state() const override {
    catch_up();
    return inner_.state();
  }
  drivers::ErrorCode connect() override { return inner_.connect(); }
  void disconnect() override {
    catch_up();
    inner_.disconnect();
  }
  drivers::Submitted home() override {
    catch_up();
    return inner_.home();
  }
  drivers::ErrorCode activate() override {
    catch_up();
    return inner_.activate();
  }
  void stop() override {
    catch_up();
    inner_.stop();
  }
  drivers::ErrorCode reset() override {
    catch_up();
    return inner_.reset();
  }
  drivers::Submitted submit(const drivers::Command& command) override {
    catch_up();
    return inner_.submit(command);
  }
  drivers::Submitted request_position() override {
    catch_up();
    return inner_.request_position();
  }
  drivers::CommandStatus poll(drivers::CommandId id) const override {
    catch_up();
    return inner_.poll(id);
  }
  std::optional<drivers::PositionReading> last_position() const override {
    catch_up();
    return inner_.last_position();
  }
  void set_notifier(std::function<void()> notify) override { inner_.set_notifier(std::move(notify)); }
  void set_clock(Clock clock) override {
    clock_ = clock;
    inner_.set_clock(std::move(clock));
  }

  // Ticks run so far.
  std::uint64_t ticks() const { return ticks_; }

 private:
  void catch_up() const {
    if (!clock_) return;
    const auto due = static_cast<std::uint64_t>(clock_() / tick_);
    if (due > ticks_) {
      inner_.advance(due - ticks_);
      ticks_ = due;
    }
  }

  drivers::ScriptedDriver& inner_;
  std::chrono::nanoseconds tick_;
  Clock clock_;
  mutable std::uint64_t ticks_ = 0;
};

}  // namespace cellwright::testing
