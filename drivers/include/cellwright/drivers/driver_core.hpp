// DriverCore: the RobotDriver contract (robot_driver.hpp) written once. Every driver of this project (the MuJoCo
// SimDriver, the ScriptedDriver test double, the serial Movemaster EX and VAL II drivers) derives from it and supplies
// only what differs: how to reach its controller, what to do on stop, how to execute a job. The RobotDriver methods
// are final here, as ros2_control runs a hardware component's lifecycle once (hardware_interface/src/system.cpp) and
// lets the plugin fill on_configure/on_activate, so the contract cannot drift between drivers.
//
// WHAT THE CORE DOES
//  - The lifecycle of robot_driver.hpp (its state diagram and call table), refusing with wrong_state whatever the
//    table does not allow, and activate() while a home() is in flight.
//  - Refusals of submit(): wrong_state, then check_command() against capabilities(), then the driver's own check
//    (check_hook), then busy when capabilities().queue_depth commands are in flight.
//  - Ids 1, 2, 3, ... in acceptance order for home(), submit() and request_position(); one FIFO queue of jobs.
//    With capabilities().reads_while_moving, position requests go to a separate list of reads instead (answered at
//    the controller's next tick whatever the queue holds); they count towards queue_depth all the same.
//  - The head of the queue is running (as soon as it reaches the head, or when the controller side calls start();
//    see RunningWhen); the others are pending.
//  - When a job fails, everything queued behind it fails: with cancelled ("cancelled: command N before it failed"),
//    or with connection_lost when the link dropped. hardware, protocol, connection_lost and unknown put the driver in
//    fault (and then the pending reads fail too). A home() that completes makes the driver homed.
//  - stop() and disconnect() cancel every job ("cancelled by stop()" / "cancelled by disconnect()"); stop() takes
//    active to stopped; reset() takes fault to connected, or to disconnected (connection_lost) when the link is down.
//  - poll() answers for the kStatusRetention most recent finished jobs and every unfinished one; last_position()
//    holds the most recent reading delivered.
//  - The notifier is called after the lock is released, once per public call or Controller session in which a job
//    finished or a fault was raised.
//  - set_clock(): stamp() gives the clock's time when one is set, the driver's own time otherwise.
//  - It counts every call of the RobotDriver methods (calls()), for tests and diagnostics.
//
// WHAT A DRIVER SUPPLIES (the hooks below; each has a default that does nothing and succeeds)
//  - connect_hook()/disconnect_hook(): open and close the link (and start/stop a communication thread).
//  - check_hook(): refusals beyond check_command() (e.g. a channel this controller cannot use).
//  - accept_hook(): attach its own data to a job just accepted (a plan, a duration) and record it.
//  - halt_hook(): stop() or disconnect() cancelled everything: bring the robot to rest.
//  - reset_hook(): clear the controller's error; say whether the link is still there.
//  - Execution: on its own thread (serial), in the simulation step (SimDriver) or in a test's advance()
//    (ScriptedDriver), through a Controller session: look at the head job, start it, complete it (a position job with
//    its PositionReading), fail it with the controller's ErrorCode and message, answer reads, raise a fault.
//
// WHICH STATE ALLOWS WHAT: exactly the table of robot_driver.hpp. In addition, on the controller side, in any state:
// a Controller session may complete or fail the jobs it sees (there are none in disconnected, connected-without-
// home, or fault), and raise_fault() works in every state but disconnected (there it only fails the jobs).
//
// THREADS AND LOCKING. One mutex (the core's) guards the core's state and, by convention, the derived driver's state
// that the owner and the controller side share (a SimDriver's servo targets, a ScriptedDriver's virtual robot).
//  - The owner thread calls the RobotDriver methods, as robot_driver.hpp says.
//  - Any thread may open a Controller session (controller()): it holds the mutex for its lifetime, and on its end
//    releases it and then calls the notifier if anything finished. A serial driver's communication thread opens a
//    session to take the head job, closes it to talk to the port, and opens another to report the outcome by id (a
//    job stopped or cancelled meanwhile is then no longer there, and the report is ignored).
//  - Hooks called with the mutex held (check_hook, accept_hook, halt_hook, reset_hook) must be short and must not
//    block, open a Controller session or call the driver's public methods. connect_hook and disconnect_hook are
//    called without it, so they may block (open a port, join a thread), and may use lock() or controller().
//  - lock() gives the mutex to a derived driver's own queries and test controls (no notifier; nothing may finish).
#pragma once

#include <chrono>
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include "cellwright/drivers/robot_driver.hpp"

namespace cellwright::drivers {

class DriverCore : public RobotDriver {
 public:
  // How many times each RobotDriver method was called (refused calls included).
  struct Calls {
    int connect = 0, disconnect = 0, home = 0, activate = 0, stop = 0, reset = 0, submit = 0, request_position = 0,
        poll = 0, last_position = 0, set_notifier = 0, set_clock = 0;
  };

  // ---- RobotDriver (the owner thread): see robot_driver.hpp ----
  const Capabilities& capabilities() const final;
  DriverState state() const final;
  // Calls connect_hook() (which may throw InputError) and, if it succeeds, goes to connected.
  ErrorCode connect() final;
  void disconnect() final;
  Submitted home() final;
  ErrorCode activate() final;
  void stop() final;
  ErrorCode reset() final;
  Submitted submit(const Command& command) final;
  Submitted request_position() final;
  CommandStatus poll(CommandId id) const final;
  std::optional<PositionReading> last_position() const final;
  void set_notifier(std::function<void()> notify) final;
  void set_clock(Clock clock) final;

  // ---- Queries (any thread) ----
  Calls calls() const;

 protected:
  // When a job becomes running: at once when it reaches the head of the queue (a simulation starts it at its next
  // step anyway), or only when the controller side calls Controller::start() (a serial driver, once the controller
  // has taken it).
  enum class RunningWhen : std::uint8_t { at_head, started };

  enum class JobKind : std::uint8_t { home, command, position };

  // What a driver attaches to a job (accept_hook): derive from it; the core destroys it with the job.
  struct JobData {
    virtual ~JobData() = default;
  };

  struct Job {
    CommandId id = 0;
    JobKind kind = JobKind::command;
    std::optional<Command> command;  // set for JobKind::command
    std::unique_ptr<JobData> data;   // the driver's own, from accept_hook
    // The job's data as the driver's type T (which accept_hook attached).
    template <class T>
    T& as() const {
      return static_cast<T&>(*data);
    }
  };

  // A session on the controller side: holds the core's mutex while it lives; on destruction releases it, then calls
  // the notifier if a job finished or a fault was raised. Move-only. References to jobs stay valid until the job
  // finishes (complete/fail) or the session ends.
  class Controller {
   public:
    Controller(Controller&& other) noexcept;
    Controller& operator=(Controller&&) = delete;
    Controller(const Controller&) = delete;
    ~Controller();

    DriverState state() const;
    // The job at the head of the queue (the next to execute, or the one executing); nullptr when there is none.
    Job* head();
    // Every job in the queue, head first (e.g. to plan a motion from where the ones before it end).
    const std::deque<Job>& queued() const;
    // Position requests waiting to be answered out of the queue (reads_while_moving), oldest first.
    std::deque<Job>& reads();
    // Marks the head job running (RunningWhen::started). Returns false if `id` is not the head (it was cancelled).
    bool start(CommandId id);
    // Job `id` (the head, or a pending read) is done: a home() makes the driver homed; the next job becomes the head.
    // A position job must be completed with its reading, whose `request` is set here. Returns false (and changes
    // nothing) when `id` is neither the head nor a pending read: it was cancelled, or stop() ended it.
    bool complete(CommandId id);
    bool complete(CommandId id, PositionReading reading);
    // Job `id` failed with `error` (a controller's: unreachable, timeout, hardware, protocol, connection_lost, unknown)
    // and `message`. For the head, everything queued behind it fails (see the top); for a read, only the read. Fatal
    // errors enter fault. Returns false (and changes nothing) when `id` is neither the head nor a pending read.
    bool fail(CommandId id, ErrorCode error, std::string message);
    // The position read `id` at the head of the queue, not started, is withdrawn because a command waits behind it
    // (a read never delays a command: robot_driver.hpp, POSITION READS ON A LINE): it fails with cancelled and
    // `message`; nothing behind it is touched, and the next job becomes the head. Returns false (and changes nothing)
    // when `id` is not a position read at the head, or was started.
    bool withdraw(CommandId id, std::string message);
    // The controller reported an error or the link dropped outside any command: every job fails with `error` and
    // `message`, the driver enters fault (unless disconnected; connection_lost also marks the link down). `error`
    // is hardware, protocol, connection_lost or unknown. Always calls the notifier.
    void raise_fault(ErrorCode error, std::string message);
    // The time to stamp a reading taken now: the clock given to set_clock(), or `own` (the driver's own time).
    std::chrono::nanoseconds stamp(std::chrono::nanoseconds own) const;

   private:
    friend class DriverCore;
    explicit Controller(DriverCore& core);
    DriverCore* core_;
    std::unique_lock<std::mutex> lock_;
  };

  explicit DriverCore(RunningWhen running_when = RunningWhen::at_head);

  // Sets what the driver can do; the derived constructor calls it once, before the driver is used. Throws
  // InternalError when called twice or with queue_depth 0.
  void set_capabilities(Capabilities capabilities);

  // Opens a controller-side session (any thread; not from a hook, nor while holding lock()).
  Controller controller();
  // The core's mutex, for a derived driver's own queries and controls (any thread; not from a hook).
  std::unique_lock<std::mutex> lock() const;
  // The same without waiting: the lock owns the mutex only if it was free (from a thread that does not hold it).
  std::unique_lock<std::mutex> lock(std::try_to_lock_t) const;
  // The queue, head first, for hooks (mutex held) only: e.g. accept_hook plans a motion from where the ones before it
  // end.
  const std::deque<Job>& queued() const { return queue_; }

  // ---- Hooks ----
  // Open the link and check the controller answers (mutex NOT held; may block). Return none, or connection_lost
  // when the controller does not answer (the driver stays disconnected). Throw InputError when the configuration
  // cannot work.
  virtual ErrorCode connect_hook() { return ErrorCode::none; }
  // Close the link (mutex NOT held; may block). Called after the core has cancelled every job and entered
  // disconnected.
  virtual void disconnect_hook() {}
  // Refusals beyond check_command() (mutex held). Return a Refusal that is false to accept.
  virtual Refusal check_hook(const Command& /*command*/) { return {}; }
  // A job was accepted and has its id; it is queued (or added to the reads) right after (mutex held). Attach data,
  // plan, record.
  virtual void accept_hook(Job& /*job*/) {}
  // stop() or disconnect() has just cancelled every job: bring the robot to rest (mutex held; must not block).
  virtual void halt_hook() {}
  // reset() in fault with the link up (mutex held; must not block): clear the controller's error. Return none (the
  // driver goes to connected) or connection_lost (it goes to disconnected).
  virtual ErrorCode reset_hook() { return ErrorCode::none; }

 private:
  // All below: mutex_ held.
  Submitted accept(JobKind kind, std::optional<Command> command);
  std::size_t in_flight() const { return queue_.size() + reads_.size(); }
  void set_status(CommandId id, CommandPhase phase, ErrorCode error = ErrorCode::none, std::string message = {});
  // Fails every job (queue and reads) with `error`; returns whether there was any.
  bool fail_all(ErrorCode error, const std::string& message);
  // Fails every queued job (not the reads); returns whether there was any.
  bool fail_queue(ErrorCode error, const std::string& message);
  void head_changed();
  // Calls the notifier (after unlocking) when `changed_` is set.
  void release_and_notify(std::unique_lock<std::mutex>& lock);

  const RunningWhen running_when_;
  bool capabilities_set_ = false;
  Capabilities capabilities_;
  mutable std::mutex mutex_;
  DriverState state_ = DriverState::disconnected;
  std::string fault_cause_;  // the message of the failure that put the driver in fault (kept until the next fault)
  bool link_up_ = false;
  CommandId next_id_ = 1;
  std::deque<Job> queue_;
  std::deque<Job> reads_;
  std::map<CommandId, CommandStatus> statuses_;
  std::deque<CommandId> finished_;  // terminal ids, oldest first, for retention
  std::optional<PositionReading> last_position_;
  std::function<void()> notify_;
  Clock clock_;
  bool changed_ = false;  // a job finished or a fault was raised since the notifier was last called
  mutable Calls calls_;
};

}  // namespace cellwright::drivers
