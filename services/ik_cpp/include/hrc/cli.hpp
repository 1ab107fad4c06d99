// Command-line parsing shared by the hrc C++ executables: the bus options every service takes
// (same names and environment defaults as Python hrc.bus.config.add_bus_arguments) plus a small
// "--flag value" / "--flag=value" reader.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "hrc/bus.hpp"

namespace hrc::cli {

/// Bad command line; main() prints what() and exits with code 2.
class UsageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Parsed "--name value" options. Flags listed as repeatable may occur several times; the others
/// at most once. Unknown flags and stray arguments are UsageErrors naming them.
class Args {
 public:
  Args(const std::vector<std::string>& argv, const std::vector<std::string>& single,
       const std::vector<std::string>& repeatable, const std::vector<std::string>& switches = {});

  bool has(const std::string& flag) const;
  std::optional<std::string> get(const std::string& flag) const;
  std::string get_or(const std::string& flag, const std::string& fallback) const;
  std::vector<std::string> all(const std::string& flag) const;
  /// Integer option with a range check; the error names the flag.
  int64_t get_int(const std::string& flag, int64_t fallback, int64_t min, int64_t max) const;
  double get_double(const std::string& flag, double fallback, double min, double max) const;
  bool flag(const std::string& name) const;

 private:
  std::map<std::string, std::vector<std::string>> values_;
};

/// Bus flags: --session --connect --listen --mode/--zenoh-mode --zenoh-config --clock-master.
std::vector<std::string> bus_single_flags();
std::vector<std::string> bus_repeatable_flags();
/// The bus options that take no value.
std::vector<std::string> bus_bool_flags();
/// Usage text for the bus flags.
std::string bus_usage();

struct BusArgs {
  std::string session;
  BusConfig config;
  // --clock-master: whose clock to follow (hrc run passes it); empty: LockstepOptions' default.
  std::optional<std::string> clock_master;
};

/// Reads the bus flags with the environment defaults HRC_SESSION, HRC_CONNECT (comma-separated),
/// HRC_ZENOH_MODE; validates them (UsageError names the bad value).
BusArgs bus_args(const Args& args);

}  // namespace hrc::cli
