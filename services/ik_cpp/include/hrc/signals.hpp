// SIGINT/SIGTERM handling for the hrc C++ processes: the signals are blocked in every thread
// (construct the watcher before opening zenoh, so zenoh's threads inherit the mask) and one
// thread waits for them with sigwait and calls a handler in normal (non-signal) context.
#pragma once

#include <functional>
#include <thread>

namespace hrc {

class SignalWatcher {
 public:
  /// Blocks SIGINT and SIGTERM in the calling thread (and all threads created after).
  SignalWatcher();
  SignalWatcher(const SignalWatcher&) = delete;
  SignalWatcher& operator=(const SignalWatcher&) = delete;
  /// Stops the watching thread.
  ~SignalWatcher() { stop(); }

  /// Starts the thread; on_signal(signo) runs on it once per SIGINT/SIGTERM received.
  void start(std::function<void(int)> on_signal);
  /// Joins the thread (idempotent); after it returns on_signal is never called again. Signals
  /// stay blocked, so one arriving later is ignored.
  void stop();

 private:
  std::thread thread_;
};

}  // namespace hrc
