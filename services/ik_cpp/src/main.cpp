// hrc-ik: the ik_cpp service process (see services/ik_cpp/README.md).
// Exit codes: 0 run ended ok (or stopped by SIGINT/SIGTERM), 1 run ended with an error, the clock
// master disappeared, no scenario came or it could not be loaded, 2 bad command line.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <exception>
#include <iostream>
#include <iterator>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "hrc/cli.hpp"
#include "hrc/ik_service.hpp"
#include "hrc/lockstep.hpp"
#include "hrc/log.hpp"
#include "hrc/signals.hpp"
#include "hrc/typed_bus.hpp"

namespace {

constexpr const char* kUsage =
    "usage: hrc-ik [--name NAME] [--input-timeout S] [--start-timeout S] [--standalone-hz HZ]\n"
    "              [bus options]\n"
    "\n"
    "The ik_cpp service: fetches the scenario from hrc/<session>/scenario, moves every robot of "
    "it\n"
    "(one motion generator per arm), takes robot/*/command, publishes robot/<id>/state every "
    "tick,\n"
    "serves robot/reach and stats/<name>, takes part in the lockstep clock (acks on\n"
    "clock/ack/<name>), and declares alive/<name> when ready.\n"
    "\n"
    "  --name NAME          service name (default ik_cpp)\n"
    "  --input-timeout S    lockstep: seconds a tick may wait for its inputs (default 10)\n"
    "  --start-timeout S    seconds to wait for the scenario queryable (default 60)\n"
    "  --standalone-hz HZ   no clock master: step at HZ by an own timer (dt = 1/HZ) until\n"
    "                       SIGINT/SIGTERM or run/end (for 1 kHz tests and benchmarks)\n"
    "  --check-moves        no bus: read a MotionCheckRequest (protobuf) on stdin, plan and run\n"
    "                       each move with the service's motion generators, write the\n"
    "                       MotionCheckReply on stdout (hrc validate uses it)\n"
    "  --help               this text\n";

// hrc-ik --check-moves: exit 0 with a reply, 1 (message on stderr) for a request that cannot
// be read or whose robots do not load.
int check_moves_main() {
  std::ios::sync_with_stdio(false);
  const std::string input{std::istreambuf_iterator<char>(std::cin),
                          std::istreambuf_iterator<char>()};
  hrc::v2::MotionCheckRequest request;
  if (!request.ParseFromString(input)) {
    std::cerr << "hrc-ik --check-moves: stdin is not a MotionCheckRequest\n";
    return 1;
  }
  try {
    const hrc::v2::MotionCheckReply reply = hrc::check_moves(request);
    if (!reply.SerializeToOstream(&std::cout)) return 1;
    std::cout.flush();
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "hrc-ik --check-moves: " << e.what() << "\n";
    return 1;
  }
}

// Short numbers for log lines ("0.004167", "60", "1000").
std::string num(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

struct Options {
  std::string name;
  hrc::cli::BusArgs bus;
  double input_timeout = 10.0;
  double start_timeout = 60.0;
  double standalone_hz = 0.0;  // 0: lockstep participant
};

// The scenario from the orchestrator's queryable; it may still be starting, so ask until it
// answers (like the Python services' Bus.get_one) or `timeout_s` passes.
std::optional<hrc::v2::Scenario> fetch_scenario(const hrc::Bus& bus, double timeout_s,
                                                const std::atomic<bool>& stop) {
  using Clock = std::chrono::steady_clock;
  const auto deadline = Clock::now() + std::chrono::duration_cast<Clock::duration>(
                                           std::chrono::duration<double>(timeout_s));
  while (!stop) {
    const auto left =
        std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now());
    const auto wait =
        std::clamp(left, std::chrono::milliseconds(50), std::chrono::milliseconds(1000));
    auto replies = bus.get<hrc::v2::Scenario>(bus.keys().scenario(), nullptr, wait);
    if (!replies.empty()) return std::move(replies.front());
    if (Clock::now() >= deadline) break;
    // A query no server matched ends at once: ask again soon (the clock waits for our token).
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  return std::nullopt;
}

int run(const std::vector<std::string>& argv) {
  using hrc::cli::UsageError;
  Options opt;
  try {
    auto single = hrc::cli::bus_single_flags();
    single.insert(single.end(),
                  {"--name", "--input-timeout", "--start-timeout", "--standalone-hz"});
    auto flags = hrc::cli::bus_bool_flags();
    flags.emplace_back("--help");
    flags.emplace_back("--check-moves");
    const hrc::cli::Args args(argv, single, hrc::cli::bus_repeatable_flags(), flags);
    if (args.flag("--help")) {
      std::cout << kUsage << "\n" << hrc::cli::bus_usage();
      return 0;
    }
    if (args.flag("--check-moves")) return check_moves_main();
    opt.name = args.get_or("--name", "ik_cpp");
    try {
      hrc::check_name("service name", opt.name);
    } catch (const std::invalid_argument& e) {
      throw UsageError(e.what());
    }
    opt.input_timeout = args.get_double("--input-timeout", 10.0, 0.001, 86400.0);
    opt.start_timeout = args.get_double("--start-timeout", 60.0, 0.0, 86400.0);
    if (args.has("--standalone-hz"))
      opt.standalone_hz = args.get_double("--standalone-hz", 0.0, 1.0, 100000.0);
    opt.bus = hrc::cli::bus_args(args);
  } catch (const UsageError& e) {
    std::cerr << "hrc-ik: error: " << e.what() << "\n" << kUsage;
    return 2;
  }
  hrc::log::set_name(opt.name);

  // Declared before the watcher: its thread may touch them until the watcher is destroyed.
  std::atomic<bool> stop_requested{false};
  std::mutex active_mutex;
  hrc::LockstepParticipant* active = nullptr;  // set while participant.run() may be stopped
  // Before zenoh starts its threads, so they inherit the blocked signal mask.
  hrc::SignalWatcher signals;
  signals.start([&](int sig) {
    const std::string reason =
        std::string("stopped by signal ") + (sig == SIGINT ? "SIGINT" : "SIGTERM");
    stop_requested = true;
    const std::lock_guard<std::mutex> lock(active_mutex);
    if (active != nullptr) active->stop(reason);
  });
  // Joins the watcher before anything it touches goes away (declared after them: destroyed first).
  struct StopWatching {
    hrc::SignalWatcher& watcher;
    ~StopWatching() { watcher.stop(); }
  };
  try {
    hrc::Bus bus(opt.bus.config, opt.bus.session, opt.name);
    const auto scenario = fetch_scenario(bus, opt.start_timeout, stop_requested);
    if (!scenario) {
      if (stop_requested) {
        hrc::log::info("stopped by a signal before the scenario came");
        return 0;
      }
      hrc::log::error("no scenario: nobody answered on " + bus.keys().scenario() + " within " +
                      num(opt.start_timeout) + " s");
      return 1;
    }
    const double dt = opt.standalone_hz > 0 ? 1.0 / opt.standalone_hz : hrc::tick_dt(*scenario);
    const auto t_load = std::chrono::steady_clock::now();
    hrc::IkEngine engine(hrc::robots_from_scenario(*scenario), dt);
    // The declared joint speeds cover the longest exchange (docs/ARCHITECTURE.md, "Exchange step").
    engine.set_speed_window(scenario->info().max_exchange_ticks());
    std::string robots;
    for (const auto& id : engine.robot_ids()) robots += (robots.empty() ? "" : ", ") + id;
    if (robots.empty()) {
      robots = "(none)";
      hrc::log::warning("the scenario has no robots: no robot states will be published");
    }
    hrc::log::info(
        "scenario '" + scenario->info().name() + "': robots " + robots + ", dt " + num(dt) +
        " s; models loaded in " +
        num(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t_load)
                .count()) +
        " ms");

    hrc::LockstepOptions options;
    options.input_timeout_s = opt.input_timeout;
    if (opt.bus.clock_master) options.clock_master = *opt.bus.clock_master;
    options.inline_ticks = !opt.bus.config.lowlatency;
    hrc::LockstepParticipant participant(bus, options);
    hrc::IkService service(bus, participant, engine);
    StopWatching stop_watching{signals};
    struct Deactivate {
      std::mutex& m;
      hrc::LockstepParticipant*& p;
      ~Deactivate() {
        const std::lock_guard<std::mutex> lock(m);
        p = nullptr;
      }
    } deactivate{active_mutex, active};
    {
      const std::lock_guard<std::mutex> lock(active_mutex);
      active = &participant;
    }
    if (stop_requested) participant.stop("stopped by a signal during startup");

    if (opt.standalone_hz > 0) {
      hrc::log::info("ready (standalone at " + num(opt.standalone_hz) + " Hz): session '" +
                     opt.bus.session + "', alive/" + opt.name + " declared");
      const uint64_t steps =
          service.run_standalone(opt.standalone_hz, [&] { return !stop_requested.load(); });
      hrc::log::info("standalone run ended after " + std::to_string(steps) + " steps; " +
                     std::to_string(service.commands_received()) + " commands, " +
                     std::to_string(service.commands_rejected()) + " rejected");
      hrc::log::info(service.timing_summary());
      return 0;
    }

    participant.start();
    hrc::log::info("ready: session '" + opt.bus.session + "', alive/" + opt.name + " declared");
    const hrc::Outcome outcome = participant.run();
    const std::string counts = std::to_string(bus.stats().ticks_seen()) + " ticks; " +
                               std::to_string(service.commands_received()) + " commands, " +
                               std::to_string(service.commands_rejected()) + " rejected";
    if (outcome.stopped) {
      hrc::log::info(outcome.reason + " after " + counts);
    } else if (outcome.ok) {
      hrc::log::info("run ended: " + outcome.reason + " after " + counts);
    } else {
      hrc::log::error("run ended with an error: " + outcome.reason + " (after " + counts + ")");
    }
    hrc::log::info(service.timing_summary());
    return outcome.stopped ? 0 : outcome.exit_code();
  } catch (const std::exception& e) {
    hrc::log::error(e.what());
    return 1;
  }
}

}  // namespace

int main(int argc, char** argv) { return run(std::vector<std::string>(argv + 1, argv + argc)); }
