// The participant side of the tick protocol (docs/ARCHITECTURE.md; twin of Python
// hrc.bus.lockstep.LockstepParticipant).
//
// On ClockTick k: (lockstep mode) wait until every message the clock says was published before k
// has arrived, hand the inputs to the service through the Inbox, call the step, then publish
// TickAck on clock/ack/<name> (header.tick = k, compute_us, published marks). run() returns when
// run/end arrives (ok -> exit code 0, else 1), when the clock master's liveliness token
// alive/physics disappears after having been seen, or when stop() is called.
// A step (or input handler) that throws ends the run at once: the participant publishes a
// run/control ABORT naming the tick and the error, waits (at most kAbortWaitS) for the clock
// master's run/end, which names this participant, and run() returns a failed outcome.
#pragma once

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <mutex>
#include <optional>
#include <string>

#include "hrc/inbox.hpp"
#include "hrc/typed_bus.hpp"

namespace hrc {

/// How a participant's run ended.
struct Outcome {
  bool ok = false;
  std::string reason;
  std::optional<v2::RunEnd> run_end;  // the clock master's run/end, when it came
  bool stopped = false;               // set when stop() ended it (e.g. a signal)
  int exit_code() const { return ok ? 0 : 1; }
};

/// After an abort, how long run() waits for the clock master's run/end before returning.
inline constexpr double kAbortWaitS = 2.0;

struct LockstepOptions {
  bool ack = true;                // false: observer (follows the clock, never acks)
  double input_timeout_s = 10.0;  // lockstep: how long a tick may wait for its inputs
  std::string clock_master = "physics";
  // Compute a tick right on the zenoh thread that delivered it when nothing is missing (saves a
  // thread hand-off). Off with zenoh's low-latency transport: a put from a zenoh runtime thread
  // makes tokio hand that thread's work to another one (block_in_place), which costs more.
  bool inline_ticks = true;
};

class LockstepParticipant {
 public:
  using Step = std::function<void(const v2::ClockTick&)>;

  explicit LockstepParticipant(Bus& bus, LockstepOptions options = {});
  /// Closes the bus: its subscriptions call into this object (and its Inbox), so none may
  /// outlive it.
  ~LockstepParticipant() { bus_.close(); }
  LockstepParticipant(const LockstepParticipant&) = delete;
  LockstepParticipant& operator=(const LockstepParticipant&) = delete;

  /// Registers a typed input (delivered in deterministic order before the step of each tick).
  template <class M>
  void input(const std::string& key_expr, Bus::Handler<M> handler,
             Bus::Validator<M> validate = {}) {
    inbox_.add<M>(key_expr, std::move(handler), std::move(validate));
  }
  /// The step of each tick; it publishes the tick's outputs through the Bus.
  void on_tick(Step step) { step_ = std::move(step); }

  /// Asked after the steps of an exchange: the earliest tick at which the service, holding its
  /// inputs, may make a change others react to; 0 if none is known (TickAck.next_event_tick,
  /// docs/ARCHITECTURE.md "Exchange step").
  void on_next_event(std::function<uint64_t()> next_event) { next_event_ = std::move(next_event); }

  /// Subscribes to clock and run/end, watches liveliness, serves stats, then declares
  /// alive/<name>: call after every input and subscription of the service exists.
  void start();
  /// Processes ticks until the run ends. timeout_s > 0: give up when no tick came for that long.
  Outcome run(double timeout_s = 0.0);
  /// Ends run() (thread-safe, callable from a signal-watching thread).
  void stop(const std::string& reason);

  Inbox& inbox() { return inbox_; }
  const std::string& name() const { return bus_.sender(); }
  /// Last tick processed (empty before the first).
  std::optional<v2::ClockTick> last_tick() const;

 private:
  void on_clock(const v2::ClockTick& tick);
  void on_run_end(const v2::RunEnd& end);
  void on_liveliness(const std::string& service, bool alive);
  void finish(Outcome outcome);
  /// Computes one tick; called with busy_ set by exactly one thread at a time.
  void process(const v2::ClockTick& tick);
  /// The step of every tick of the exchange `tick` opens (k .. k + span - 1).
  void step_through(const v2::ClockTick& tick);
  /// The tick failed: asks the clock master to abort the run, naming the error.
  void abort(const v2::ClockTick& tick, const std::string& error);

  Bus& bus_;
  LockstepOptions options_;
  Inbox inbox_;
  Step step_;
  std::function<uint64_t()> next_event_;
  TypedPublisher* ack_pub_ = nullptr;
  TypedPublisher* control_pub_ = nullptr;

  mutable std::mutex mutex_;
  std::condition_variable cond_;
  std::deque<v2::ClockTick> ticks_;
  bool running_ = false;
  bool busy_ = false;  // a tick is being computed (on run()'s thread or inline on a zenoh thread)
  bool physics_seen_ = false;
  bool aborted_ = false;      // our own tick failed and we asked the clock master to abort
  bool master_done_ = false;  // run/end came, or the clock master is gone
  std::optional<Outcome> end_;
  std::optional<v2::ClockTick> last_tick_;
};

}  // namespace hrc
