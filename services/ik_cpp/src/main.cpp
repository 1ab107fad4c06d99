// hrc-ik: the ik_cpp service process (see services/ik_cpp/README.md).
// Exit codes: 0 run ended ok (or stopped by SIGINT/SIGTERM), 1 run ended with an error or the
// clock master disappeared, 2 bad command line.
#include <csignal>
#include <cstring>
#include <exception>
#include <iostream>
#include <string>
#include <vector>

#include "hrc/cli.hpp"
#include "hrc/ik_service.hpp"
#include "hrc/lockstep.hpp"
#include "hrc/log.hpp"
#include "hrc/signals.hpp"
#include "hrc/typed_bus.hpp"

namespace {

const char* kUsage =
    "usage: hrc-ik [--name NAME] [bus options]\n"
    "\n"
    "The ik_cpp service: subscribes to hrc/<session>/robot/*/command, takes part in the lockstep\n"
    "clock (acks on clock/ack/<name>), serves stats/<name>, and declares alive/<name> when ready.\n"
    "\n"
    "  --name NAME          service name (default ik_cpp)\n"
    "  --input-timeout S    lockstep: seconds a tick may wait for its inputs (default 10)\n"
    "  --help               this text\n";

int run(const std::vector<std::string>& argv) {
  using hrc::cli::UsageError;
  std::string name;
  hrc::cli::BusArgs bus_args;
  double input_timeout = 10.0;
  try {
    auto single = hrc::cli::bus_single_flags();
    single.insert(single.end(), {"--name", "--input-timeout"});
    const hrc::cli::Args args(argv, single, hrc::cli::bus_repeatable_flags(), {"--help"});
    if (args.flag("--help")) {
      std::cout << kUsage << "\n" << hrc::cli::bus_usage();
      return 0;
    }
    name = args.get_or("--name", "ik_cpp");
    try {
      hrc::check_name("service name", name);
    } catch (const std::invalid_argument& e) {
      throw UsageError(e.what());
    }
    input_timeout = args.get_double("--input-timeout", 10.0, 0.001, 86400.0);
    bus_args = hrc::cli::bus_args(args);
  } catch (const UsageError& e) {
    std::cerr << "hrc-ik: error: " << e.what() << "\n" << kUsage;
    return 2;
  }
  hrc::log::set_name(name);

  // Before zenoh starts its threads, so they inherit the blocked signal mask.
  hrc::SignalWatcher signals;
  try {
    hrc::Bus bus(bus_args.config, bus_args.session, name);
    hrc::LockstepOptions options;
    options.input_timeout_s = input_timeout;
    hrc::LockstepParticipant participant(bus, options);
    hrc::IkService service(bus, participant);
    signals.start([&participant](int sig) {
      participant.stop(std::string("stopped by signal ") + (sig == SIGINT ? "SIGINT" : "SIGTERM"));
    });
    // Destroyed before the participant: no signal can reach a participant that is gone.
    struct StopWatching {
      hrc::SignalWatcher& watcher;
      ~StopWatching() { watcher.stop(); }
    } stop_watching{signals};
    participant.start();
    hrc::log::info("ready: session '" + bus_args.session + "', alive/" + name + " declared");
    const hrc::Outcome outcome = participant.run();
    if (outcome.stopped) {
      hrc::log::info(outcome.reason);
      return 0;
    }
    if (outcome.ok) {
      hrc::log::info("run ended: " + outcome.reason + " after " + std::to_string(bus.stats().ticks_seen()) +
                     " ticks; " + std::to_string(service.commands_received()) + " commands");
    } else {
      hrc::log::error("run ended with an error: " + outcome.reason);
    }
    return outcome.exit_code();
  } catch (const std::exception& e) {
    hrc::log::error(e.what());
    return 1;
  }
}

}  // namespace

int main(int argc, char** argv) {
  return run(std::vector<std::string>(argv + 1, argv + argc));
}
