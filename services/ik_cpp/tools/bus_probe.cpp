// hrc-bus-probe: a small bus peer for integration tests and the bus benchmark (see --help).
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <csignal>
#include <cstdint>
#include <iostream>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <google/protobuf/descriptor.h>
#include <google/protobuf/message.h>

#include "hrc/cli.hpp"
#include "hrc/log.hpp"
#include "hrc/signals.hpp"
#include "hrc/typed_bus.hpp"

namespace {

using hrc::cli::UsageError;

constexpr const char* kUsage =
    "usage:\n"
    "  hrc-bus-probe echo --in KEY --out KEY [--type TYPE] [--count N] [--timeout-s S] [--name "
    "NAME] [bus options]\n"
    "  hrc-bus-probe publish --key KEY --type RobotState --count N [--interval-ms MS] [--wait-s "
    "S]\n"
    "                        [--linger-ms MS] [--name NAME] [bus options]\n"
    "\n"
    "KEY is relative to hrc/<session>/ (e.g. bench/ping) unless it starts with 'hrc/'.\n"
    "Both modes declare the liveliness token hrc/<session>/alive/<NAME> (default NAME bus_probe)\n"
    "after their subscriptions and print 'ready' on stdout (flushed). Every put carries NAME as\n"
    "the attachment.\n"
    "\n"
    "echo: republishes every payload received on --in unchanged on --out (express, congestion\n"
    "  control block). With --type TYPE (a message of hrc.v2, e.g. HumanState) the payload is\n"
    "  decoded as TYPE and re-encoded before it is published; a payload that does not decode is\n"
    "  counted and logged to stderr, not echoed. Stops after --count N echoes (exit 0), after\n"
    "  --timeout-s S without reaching the count (exit 1), or on SIGINT/SIGTERM (exit 0).\n"
    "\n"
    "publish: waits (up to --wait-s, default 10) until a subscriber matches --key, then publishes\n"
    "  --count N RobotState messages (--interval-ms apart, default 0), waits --linger-ms (default\n"
    "  200) so they leave before the session closes, prints 'published N' and exits 0 (1 when no\n"
    "  subscriber came). Message i (1..N) holds:\n"
    "    header: session = <session>, tick = i, sim_time = 0.5 * i, sender = NAME, seq = i\n"
    "    robot = \"probe_robot\", joint_names = joint_1 .. joint_6,\n"
    "    joint_positions[j] = i + 0.125 * (j + 1) for j = 0..5,\n"
    "    tcp.position = (0.25 * i, -1.5, 2.75), tcp.orientation = (x 0, y 0, z 0.6, w 0.8),\n"
    "    tcp_speed = 0.0625 * i, status = MOTION_STATUS_MOVING, command_id = 1000 + i,\n"
    "    detail = \"probe message i of N\"\n"
    "\n"
    "Exit codes: 0 done, 1 runtime failure, 2 bad command line.\n";

std::string full_key(const hrc::Keys& keys, const std::string& key) {
  if (key.rfind("hrc/", 0) == 0) return key;
  if (key.empty() || key.front() == '/') throw UsageError("invalid key '" + key + "'");
  return keys.prefix() + "/" + key;
}

/// Waits for "done" or a stop signal, with an optional timeout.
class Done {
 public:
  void set(int code) {
    {
      const std::lock_guard<std::mutex> lock(mutex_);
      if (!code_) code_ = code;
    }
    cond_.notify_all();
  }
  /// Returns the code given to set(), or `on_timeout` if timeout_s > 0 passed first.
  int wait(double timeout_s, int on_timeout) {
    std::unique_lock<std::mutex> lock(mutex_);
    const auto ready = [this] { return code_.has_value(); };
    if (timeout_s > 0) {
      if (!cond_.wait_for(lock, std::chrono::duration<double>(timeout_s), ready)) return on_timeout;
    } else {
      cond_.wait(lock, ready);
    }
    return *code_;
  }

 private:
  std::mutex mutex_;
  std::condition_variable cond_;
  std::optional<int> code_;
};

const google::protobuf::Message* prototype_of(const std::string& type) {
  const auto* desc =
      google::protobuf::DescriptorPool::generated_pool()->FindMessageTypeByName("hrc.v2." + type);
  if (desc == nullptr)
    throw UsageError("unknown message type '" + type +
                     "' (a message of hrc/v2/hrc.proto, e.g. HumanState)");
  return google::protobuf::MessageFactory::generated_factory()->GetPrototype(desc);
}

hrc::v2::RobotState probe_state(uint64_t i, uint64_t n) {
  hrc::v2::RobotState s;
  s.set_robot("probe_robot");
  for (int j = 0; j < 6; ++j) {
    s.add_joint_names("joint_" + std::to_string(j + 1));
    s.add_joint_positions(static_cast<double>(i) + 0.125 * (j + 1));
  }
  auto* p = s.mutable_tcp()->mutable_position();
  p->set_x(0.25 * static_cast<double>(i));
  p->set_y(-1.5);
  p->set_z(2.75);
  auto* q = s.mutable_tcp()->mutable_orientation();
  q->set_x(0.0);
  q->set_y(0.0);
  q->set_z(0.6);
  q->set_w(0.8);
  s.set_tcp_speed(0.0625 * static_cast<double>(i));
  s.set_status(hrc::v2::MOTION_STATUS_MOVING);
  s.set_command_id(1000 + i);
  s.set_detail("probe message " + std::to_string(i) + " of " + std::to_string(n));
  return s;
}

/// Joins the signal thread when leaving a scope (also on exceptions), before the state its
/// handler touches goes away.
struct StopSignals {
  hrc::SignalWatcher& watcher;
  ~StopSignals() { watcher.stop(); }
};

void say(const std::string& line) { std::cout << line << std::endl; }  // endl flushes

int echo(hrc::Bus& bus, const hrc::cli::Args& args, hrc::SignalWatcher& signals) {
  const std::string in = full_key(bus.keys(), args.get("--in").value_or(""));
  const std::string out = full_key(bus.keys(), args.get("--out").value_or(""));
  const int64_t count = args.get_int("--count", 0, 0, INT64_MAX);
  const double timeout_s = args.get_double("--timeout-s", 0.0, 0.0, 1e9);
  const google::protobuf::Message* proto =
      args.has("--type") ? prototype_of(*args.get("--type")) : nullptr;

  hrc::TypedPublisher& pub = bus.publisher(out, hrc::PublisherOptions{true, true});
  Done done;
  std::atomic<int64_t> echoed{0};
  hrc::Bus* bus_ptr = &bus;
  bus.stats().add_subscribed(in);
  // Raw subscriber: the echo runs right on the zenoh thread for the lowest round-trip time.
  hrc::Subscriber sub = bus.session().declare_subscriber(in, [&, proto](const hrc::SampleView& s) {
    if (proto != nullptr) {
      std::unique_ptr<google::protobuf::Message> msg(proto->New());
      if (!hrc::Bus::parse(*msg, s.payload)) {
        const std::string key(s.key);
        const uint64_t n = bus_ptr->stats().count_error(key);
        hrc::log::warning("malformed message #" + std::to_string(n) + " on " + key +
                          " from sender '" + std::string(s.attachment) + "': does not decode as " +
                          proto->GetDescriptor()->name());
        return;
      }
      pub.put_raw(msg->SerializeAsString());
    } else {
      pub.put_raw(s.payload);
    }
    if (++echoed == count) done.set(0);
  });
  bus.declare_token();
  signals.start([&done](int) { done.set(0); });
  const StopSignals stop_signals{signals};
  say("ready");
  const int code = done.wait(timeout_s, 1);
  signals.stop();
  if (code != 0) {
    hrc::log::error("echo: timeout after " + std::to_string(timeout_s) + " s with " +
                    std::to_string(echoed.load()) + " of " + std::to_string(count) + " echoes");
  }
  return code;
}

int publish(hrc::Bus& bus, const hrc::cli::Args& args, hrc::SignalWatcher& signals) {
  const std::string key = full_key(bus.keys(), args.get("--key").value_or(""));
  const std::string type = args.get_or("--type", "RobotState");
  if (type != "RobotState")
    throw UsageError("publish supports --type RobotState only, not '" + type + "'");
  const int64_t count = args.get_int("--count", 1, 1, 100000000);
  const int64_t interval_ms = args.get_int("--interval-ms", 0, 0, 3600000);
  const double wait_s = args.get_double("--wait-s", 10.0, 0.0, 86400.0);
  const int64_t linger_ms = args.get_int("--linger-ms", 200, 0, 3600000);

  hrc::TypedPublisher& pub = bus.publisher(key, hrc::PublisherOptions{true, true});
  std::atomic<bool> stop{false};
  bus.declare_token();
  signals.start([&stop](int) { stop = true; });
  const StopSignals stop_signals{signals};
  say("ready");
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(wait_s);
  while (!pub.has_subscribers()) {
    if (stop || std::chrono::steady_clock::now() >= deadline) {
      hrc::log::error("no subscriber on " + key + " within " + std::to_string(wait_s) + " s");
      signals.stop();
      return 1;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  int64_t sent = 0;
  for (int64_t i = 1; i <= count && !stop; ++i) {
    hrc::v2::RobotState s = probe_state(static_cast<uint64_t>(i), static_cast<uint64_t>(count));
    pub.put(s, static_cast<uint64_t>(i), 0.5 * static_cast<double>(i));
    ++sent;
    if (interval_ms > 0 && i < count)
      std::this_thread::sleep_for(std::chrono::milliseconds(interval_ms));
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(linger_ms));
  signals.stop();
  say("published " + std::to_string(sent));
  return 0;
}

int run(const std::vector<std::string>& argv) {
  if (argv.empty() || argv[0] == "--help" || argv[0] == "-h") {
    std::cout << kUsage << "\n" << hrc::cli::bus_usage();
    return argv.empty() ? 2 : 0;
  }
  const std::string mode = argv[0];
  std::unique_ptr<hrc::cli::Args> args;
  hrc::cli::BusArgs bus_args;
  std::string name;
  try {
    if (mode != "echo" && mode != "publish")
      throw UsageError("unknown mode '" + mode + "': use echo or publish");
    auto single = hrc::cli::bus_single_flags();
    single.insert(single.end(), {"--name", "--in", "--out", "--type", "--count", "--timeout-s",
                                 "--key", "--interval-ms", "--wait-s", "--linger-ms"});
    args = std::make_unique<hrc::cli::Args>(std::vector<std::string>(argv.begin() + 1, argv.end()),
                                            single, hrc::cli::bus_repeatable_flags(),
                                            hrc::cli::bus_bool_flags());
    for (const char* required : mode == "echo" ? std::vector<const char*>{"--in", "--out"}
                                               : std::vector<const char*>{"--key", "--count"}) {
      if (!args->has(required)) throw UsageError(mode + " needs " + required);
    }
    name = args->get_or("--name", "bus_probe");
    try {
      hrc::check_name("probe name", name);
    } catch (const std::invalid_argument& e) {
      throw UsageError(e.what());
    }
    bus_args = hrc::cli::bus_args(*args);
  } catch (const UsageError& e) {
    std::cerr << "hrc-bus-probe: error: " << e.what() << "\n" << kUsage;
    return 2;
  }
  hrc::log::set_name(name);
  hrc::SignalWatcher signals;  // before zenoh starts its threads
  try {
    hrc::Bus bus(bus_args.config, bus_args.session, name);
    return mode == "echo" ? echo(bus, *args, signals) : publish(bus, *args, signals);
  } catch (const UsageError& e) {
    std::cerr << "hrc-bus-probe: error: " << e.what() << "\n";
    return 2;
  } catch (const std::exception& e) {
    hrc::log::error(e.what());
    return 1;
  }
}

}  // namespace

int main(int argc, char** argv) { return run(std::vector<std::string>(argv + 1, argv + argc)); }
