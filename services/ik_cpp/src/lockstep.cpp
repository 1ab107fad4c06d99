#include "hrc/lockstep.hpp"

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <exception>
#include <vector>

namespace hrc {
namespace {

std::vector<v2::PublishedMark> marks_of(const v2::ClockTick& tick) {
  return {tick.published().begin(), tick.published().end()};
}

std::string describe(const std::vector<v2::PublishedMark>& marks) {
  std::string out;
  for (const auto& m : marks) {
    if (!out.empty()) out += ", ";
    out += m.key() + "#" + std::to_string(m.seq()) + " from " + m.sender();
  }
  return out;
}

}  // namespace

LockstepParticipant::LockstepParticipant(Bus& bus, LockstepOptions options)
    : bus_(bus), options_(std::move(options)), inbox_(bus) {}

void LockstepParticipant::start() {
  const Keys& keys = bus_.keys();
  if (options_.ack) {
    // Acks close the barrier: no batching delay, never dropped.
    ack_pub_ = &bus_.publisher(keys.clock_ack(name()), PublisherOptions{true, true});
  }
  control_pub_ = &bus_.publisher(keys.run_control(name()), PublisherOptions{true, true});
  bus_.subscribe<v2::ClockTick>(
      keys.clock(), [this](const std::string&, const v2::ClockTick& t) { on_clock(t); });
  bus_.subscribe<v2::RunEnd>(keys.run_end(),
                             [this](const std::string&, const v2::RunEnd& e) { on_run_end(e); });
  bus_.watch_liveliness(
      [this](const std::string& service, bool alive) { on_liveliness(service, alive); });
  bus_.serve_stats();
  bus_.serve_replay();
  // Last: the token means "ready, nothing will be missed".
  bus_.declare_token();
}

void LockstepParticipant::on_clock(const v2::ClockTick& tick) {
  {
    std::unique_lock<std::mutex> lock(mutex_);
    // Fast path: nothing queued or in progress and every input of the tick is here, so compute
    // right on this zenoh thread (saves a thread hand-off per tick). Otherwise run() takes it.
    const bool inline_ok = options_.inline_ticks && running_ && !busy_ && ticks_.empty() &&
                           !end_.has_value() && inbox_.missing(marks_of(tick)).empty();
    if (!inline_ok) {
      ticks_.push_back(tick);
      lock.unlock();
      cond_.notify_all();
      return;
    }
    busy_ = true;
  }
  process(tick);
  bool queued = false;
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    busy_ = false;
    queued = !ticks_.empty() || end_.has_value();
  }
  if (queued) cond_.notify_all();  // only then has run() something to do: don't wake it idly
}

void LockstepParticipant::on_run_end(const v2::RunEnd& end) {
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    master_done_ = true;
    // e.g. after our abort: keep our reason, add the end the clock master gave
    if (end_.has_value() && !end_->run_end.has_value()) end_->run_end = end;
  }
  Outcome o;
  o.ok = end.ok();
  o.reason = end.reason();
  if (!end.ok() && !end.failed_participant().empty()) {
    o.reason += " (failed participant: " + end.failed_participant() + ")";
  }
  o.run_end = end;
  finish(std::move(o));
}

void LockstepParticipant::on_liveliness(const std::string& service, bool alive) {
  if (service != options_.clock_master) return;
  bool lost = false;
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    if (alive) {
      physics_seen_ = true;
    } else if (physics_seen_) {
      lost = true;
      master_done_ = true;
    }
  }
  if (lost) {
    Outcome o;
    o.ok = false;
    o.reason = "the clock master '" + options_.clock_master + "' disappeared";
    finish(std::move(o));
  }
}

void LockstepParticipant::finish(Outcome outcome) {
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    if (!end_.has_value()) end_ = std::move(outcome);
  }
  cond_.notify_all();
}

void LockstepParticipant::stop(const std::string& reason) {
  Outcome o;
  o.ok = false;
  o.reason = reason;
  o.stopped = true;
  finish(std::move(o));
}

std::optional<v2::ClockTick> LockstepParticipant::last_tick() const {
  const std::lock_guard<std::mutex> lock(mutex_);
  return last_tick_;
}

Outcome LockstepParticipant::run(double timeout_s) {
  std::unique_lock<std::mutex> lock(mutex_);
  running_ = true;
  const auto wait_span = std::chrono::duration_cast<std::chrono::steady_clock::duration>(
      std::chrono::duration<double>(timeout_s > 0 ? timeout_s : 0.0));
  while (true) {
    // Ticks queued before an end are still computed only while the run goes on: the end wins.
    const auto ready = [this] { return end_.has_value() || (!ticks_.empty() && !busy_); };
    if (timeout_s > 0) {
      if (!cond_.wait_for(lock, wait_span, ready)) {
        Outcome o;
        o.ok = false;
        o.reason = "no clock tick within " + std::to_string(timeout_s) + " s";
        end_ = o;
      }
    } else {
      cond_.wait(lock, ready);
    }
    if (end_.has_value()) {
      running_ = false;
      // Wait for an inline tick to finish before the caller tears the bus down.
      cond_.wait(lock, [this] { return !busy_; });
      if (aborted_) {
        // Leave after the clock master has ended the run, so its end names our abort.
        cond_.wait_for(lock, std::chrono::duration<double>(kAbortWaitS),
                       [this] { return master_done_; });
      }
      return *end_;
    }
    v2::ClockTick tick = std::move(ticks_.front());
    ticks_.pop_front();
    busy_ = true;
    lock.unlock();
    process(tick);
    lock.lock();
    busy_ = false;
  }
}

void LockstepParticipant::step_through(const v2::ClockTick& tick) {
  const uint64_t k = tick.header().tick();
  const uint32_t span = std::max<uint32_t>(1, tick.span());
  v2::ClockTick sub;  // ticks k + 1 .. of the exchange: header.tick / sim_time differ
  if (span > 1) {
    sub.set_mode(tick.mode());
    sub.set_dt(tick.dt());
    *sub.mutable_header() = tick.header();
  }
  for (uint32_t i = 0; i < span; ++i) {
    if (i > 0) {
      sub.mutable_header()->set_tick(k + i);
      // as the clock master computes it
      sub.mutable_header()->set_sim_time(static_cast<double>(k + i) * tick.dt());
    }
    const v2::ClockTick& now = i == 0 ? tick : sub;
    {
      const std::lock_guard<std::mutex> lock(mutex_);
      last_tick_ = now;
    }
    bus_.stats().tick(k + i);
    if (step_) step_(now);
  }
}

void LockstepParticipant::process(const v2::ClockTick& tick) {
  const uint64_t k = tick.header().tick();
  try {
    if (tick.mode() == v2::CLOCK_MODE_LOCKSTEP) {
      const auto missing = inbox_.wait_for(marks_of(tick), options_.input_timeout_s);
      if (!missing.empty()) {
        const std::string what = describe(missing);
        log::error("tick " + std::to_string(k) + ": inputs never arrived: " + what);
        Outcome o;
        o.reason = "tick " + std::to_string(k) + ": inputs never arrived: " + what;
        finish(std::move(o));
        return;
      }
    }
    // TickAck.compute_us starts here: every input of tick k is at hand.
    const auto t0 = std::chrono::steady_clock::now();
    // Every input of the exchange is handed over before its first tick (Jacobi): the others'
    // outputs of ticks inside this exchange are not for us yet.
    inbox_.deliver(k, options_.clock_master);
    // What the exchange publishes on a key goes out in one put, before the ack.
    bus_.begin_batch();
    try {
      step_through(tick);
    } catch (...) {
      bus_.flush_batches();  // what was published before the failure still goes out
      throw;
    }
    bus_.flush_batches();
    if (ack_pub_ != nullptr) {
      v2::TickAck ack;
      ack.set_participant(name());
      // ... and ends here, before the ack is built and published.
      const auto us = std::chrono::duration_cast<std::chrono::microseconds>(
          std::chrono::steady_clock::now() - t0);
      ack.set_compute_us(static_cast<uint32_t>(std::min<int64_t>(us.count(), UINT32_MAX)));
      for (auto& m : bus_.new_marks(ack_pub_->key())) *ack.add_published() = std::move(m);
      if (next_event_) ack.set_next_event_tick(next_event_());
      ack_pub_->put(ack, k, tick.header().sim_time());
    }
  } catch (const std::exception& e) {
    abort(tick, e.what());
  } catch (...) {
    abort(tick, "unknown exception");
  }
}

void LockstepParticipant::abort(const v2::ClockTick& tick, const std::string& error) {
  const uint64_t k = tick.header().tick();
  const std::string reason = "tick " + std::to_string(k) + " failed: " + error;
  log::error(reason);
  bool first = false;
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    first = !end_.has_value() && !aborted_;
    aborted_ = true;
  }
  // Our end before the abort goes out: the clock master's run/end, which answers it on another
  // thread, would otherwise be first to end the run and take the place of our reason.
  Outcome o;
  o.reason = reason;
  finish(std::move(o));
  if (first && control_pub_ != nullptr) {
    try {
      v2::RunControl ctl;
      ctl.set_command(v2::RunControl::COMMAND_ABORT);
      ctl.set_reason(reason);
      control_pub_->put(ctl, k, tick.header().sim_time());
    } catch (const std::exception& e) {  // the bus itself may be what failed
      log::error(std::string("could not ask the clock master to abort: ") + e.what());
    }
  }
}

}  // namespace hrc
