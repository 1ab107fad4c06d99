#include "hrc/cli.hpp"

#include <algorithm>
#include <cstdlib>

#include "hrc/keys.hpp"
#include "hrc/lockstep.hpp"

namespace hrc::cli {
namespace {

bool contains(const std::vector<std::string>& v, const std::string& s) {
  return std::find(v.begin(), v.end(), s) != v.end();
}

std::string env_or(const char* name, const std::string& fallback) {
  const char* v = std::getenv(name);
  return v != nullptr ? std::string(v) : fallback;
}

}  // namespace

Args::Args(const std::vector<std::string>& argv, const std::vector<std::string>& single,
           const std::vector<std::string>& repeatable, const std::vector<std::string>& switches) {
  for (std::size_t i = 0; i < argv.size(); ++i) {
    const std::string& a = argv[i];
    if (a.rfind("--", 0) != 0) throw UsageError("unexpected argument '" + a + "'");
    std::string name = a;
    std::optional<std::string> value;
    const auto eq = a.find('=');
    if (eq != std::string::npos) {
      name = a.substr(0, eq);
      value = a.substr(eq + 1);
    }
    if (contains(switches, name)) {
      if (value) throw UsageError("option " + name + " takes no value");
      values_[name].push_back("1");
      continue;
    }
    const bool is_single = contains(single, name);
    if (!is_single && !contains(repeatable, name))
      throw UsageError("unknown option '" + name + "'");
    if (!value) {
      if (i + 1 >= argv.size()) throw UsageError("option " + name + " needs a value");
      value = argv[++i];
    }
    auto& slot = values_[name];
    if (is_single && !slot.empty()) throw UsageError("option " + name + " given more than once");
    slot.push_back(*value);
  }
}

bool Args::has(const std::string& flag) const { return values_.count(flag) > 0; }

std::optional<std::string> Args::get(const std::string& flag) const {
  const auto it = values_.find(flag);
  if (it == values_.end() || it->second.empty()) return std::nullopt;
  return it->second.back();
}

std::string Args::get_or(const std::string& flag, const std::string& fallback) const {
  return get(flag).value_or(fallback);
}

std::vector<std::string> Args::all(const std::string& flag) const {
  const auto it = values_.find(flag);
  return it == values_.end() ? std::vector<std::string>{} : it->second;
}

int64_t Args::get_int(const std::string& flag, int64_t fallback, int64_t min, int64_t max) const {
  const auto v = get(flag);
  if (!v) return fallback;
  char* end = nullptr;
  const long long n = std::strtoll(v->c_str(), &end, 10);
  if (v->empty() || end == nullptr || *end != '\0')
    throw UsageError("option " + flag + ": '" + *v + "' is not an integer");
  if (n < min || n > max) {
    throw UsageError("option " + flag + ": " + *v + " is out of range [" + std::to_string(min) +
                     ", " + std::to_string(max) + "]");
  }
  return n;
}

double Args::get_double(const std::string& flag, double fallback, double min, double max) const {
  const auto v = get(flag);
  if (!v) return fallback;
  char* end = nullptr;
  const double d = std::strtod(v->c_str(), &end);
  if (v->empty() || end == nullptr || *end != '\0')
    throw UsageError("option " + flag + ": '" + *v + "' is not a number");
  if (!(d >= min && d <= max)) {
    throw UsageError("option " + flag + ": " + *v + " is out of range [" + std::to_string(min) +
                     ", " + std::to_string(max) + "]");
  }
  return d;
}

bool Args::flag(const std::string& name) const { return has(name); }

std::vector<std::string> bus_single_flags() {
  return {"--session", "--mode", "--zenoh-mode", "--zenoh-config", "--clock-master"};
}

std::vector<std::string> bus_repeatable_flags() { return {"--connect", "--listen"}; }

std::vector<std::string> bus_bool_flags() { return {"--zenoh-lowlatency"}; }

std::string bus_usage() {
  return "bus options:\n"
         "  --session ID         session id; every key is under hrc/<ID>/ (env HRC_SESSION, "
         "default 'default')\n"
         "  --connect EP         zenoh endpoint to connect to, e.g. tcp/127.0.0.1:7447 "
         "(repeatable;\n"
         "                       env HRC_CONNECT, comma-separated)\n"
         "  --listen EP          zenoh endpoint to listen on (repeatable; default "
         "tcp/127.0.0.1:0)\n"
         "  --mode peer|client|router   zenoh mode (alias --zenoh-mode; env HRC_ZENOH_MODE, "
         "default peer)\n"
         "  --zenoh-config FILE  zenoh JSON5 config file applied before the options above\n"
         "  --zenoh-lowlatency   zenoh's low-latency transport (no QoS, messages <= 64 KiB; both "
         "ends\n"
         "                       of a link must ask for it; env HRC_ZENOH_LOWLATENCY=1)\n"
         "  --clock-master NAME  the service whose clock this one follows (default " +
         LockstepOptions{}.clock_master + ")\n";
}

BusArgs bus_args(const Args& args) {
  BusArgs out;
  out.session = args.get_or("--session", env_or("HRC_SESSION", "default"));
  try {
    Keys{out.session};
  } catch (const std::invalid_argument& e) {
    throw UsageError(e.what());
  }
  out.clock_master = args.get("--clock-master");
  try {
    if (out.clock_master) check_name("clock master", *out.clock_master);
  } catch (const std::invalid_argument& e) {
    throw UsageError(e.what());
  }
  if (args.has("--mode") && args.has("--zenoh-mode"))
    throw UsageError("give --mode or --zenoh-mode, not both");
  out.config.mode =
      args.get_or("--mode", args.get_or("--zenoh-mode", env_or("HRC_ZENOH_MODE", "peer")));
  if (args.has("--connect")) {
    out.config.connect = args.all("--connect");
  } else {
    const std::string env = env_or("HRC_CONNECT", "");
    std::size_t start = 0;
    while (start <= env.size()) {
      const auto comma = env.find(',', start);
      const std::string item =
          env.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
      if (!item.empty()) out.config.connect.push_back(item);
      if (comma == std::string::npos) break;
      start = comma + 1;
    }
  }
  if (args.has("--listen")) {
    out.config.listen = args.all("--listen");
  } else if (out.config.mode == "client") {
    out.config.listen.clear();  // a client only connects
  }
  out.config.config_file = args.get_or("--zenoh-config", "");
  const std::string ll_env = env_or("HRC_ZENOH_LOWLATENCY", "");
  out.config.lowlatency = args.flag("--zenoh-lowlatency") || (!ll_env.empty() && ll_env != "0");
  try {
    out.config.validate();
  } catch (const std::invalid_argument& e) {
    throw UsageError(e.what());
  }
  return out;
}

}  // namespace hrc::cli
