#include "hrc/keys.hpp"

#include <stdexcept>
#include <utility>
#include <vector>

namespace hrc {
namespace {

bool valid_name(const std::string& v) {
  if (v.empty() || v.size() > 64) return false;
  for (const char c : v) {
    const bool ok = (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') ||
                    c == '_' || c == '-';
    if (!ok) return false;
  }
  return true;
}

}  // namespace

const std::string& check_name(std::string_view kind, const std::string& value) {
  if (!valid_name(value)) {
    throw std::invalid_argument("invalid " + std::string(kind) + " '" + value +
                                "': use 1-64 characters of A-Z a-z 0-9 _ -");
  }
  return value;
}

Keys::Keys(std::string session) : session_(std::move(session)) {
  if (!valid_name(session_)) {
    throw std::invalid_argument("invalid session id '" + session_ +
                                "': use 1-64 characters of A-Z a-z 0-9 _ -");
  }
  prefix_ = std::string(kRoot) + "/" + session_;
}

std::string Keys::k(std::string_view a) const { return prefix_ + "/" + std::string(a); }
std::string Keys::k(std::string_view a, std::string_view b) const {
  return prefix_ + "/" + std::string(a) + "/" + std::string(b);
}
std::string Keys::k(std::string_view a, std::string_view b, std::string_view c) const {
  return prefix_ + "/" + std::string(a) + "/" + std::string(b) + "/" + std::string(c);
}

std::string Keys::all() const { return k("**"); }
std::string Keys::clock() const { return k("clock"); }
std::string Keys::clock_ack(const std::string& p) const {
  return k("clock", "ack", check_name("participant", p));
}
std::string Keys::clock_acks() const { return k("clock", "ack", "*"); }
std::string Keys::run_control(const std::string& s) const {
  return k("run", "control", check_name("sender", s));
}
std::string Keys::run_controls() const { return k("run", "control", "*"); }
std::string Keys::run_end() const { return k("run", "end"); }
std::string Keys::alive(const std::string& s) const { return k("alive", check_name("service", s)); }
std::string Keys::alive_all() const { return k("alive", "*"); }
std::string Keys::stats(const std::string& s) const { return k("stats", check_name("service", s)); }
std::string Keys::replay(const std::string& s) const {
  return k("replay", check_name("service", s));
}
std::string Keys::scenario() const { return k("scenario"); }
std::string Keys::robot_command(const std::string& r) const {
  return k("robot", check_name("robot id", r), "command");
}
std::string Keys::robot_commands() const { return k("robot", "*", "command"); }
std::string Keys::robot_state(const std::string& r) const {
  return k("robot", check_name("robot id", r), "state");
}
std::string Keys::robot_states() const { return k("robot", "*", "state"); }
std::string Keys::robot_reach() const { return k("robot", "reach"); }
std::string Keys::human_state() const { return k("human", "state"); }
std::string Keys::world_objects() const { return k("world", "objects"); }
std::string Keys::world_contacts() const { return k("world", "contacts"); }
std::string Keys::world_separation() const { return k("world", "separation"); }
std::string Keys::world_commands() const { return k("world", "commands"); }
std::string Keys::task_events() const { return k("task", "events"); }
std::string Keys::task_indicators() const { return k("task", "indicators"); }
std::string Keys::task_metrics() const { return k("task", "metrics"); }
std::string Keys::bench(const std::string& name) const {
  return k("bench", check_name("bench key", name));
}

std::string Keys::last_segment(std::string_view key) {
  const auto pos = key.rfind('/');
  return std::string(pos == std::string_view::npos ? key : key.substr(pos + 1));
}

std::string Keys::robot_of(std::string_view key) {
  std::vector<std::string_view> parts;
  std::size_t start = 0;
  while (true) {
    const auto pos = key.find('/', start);
    parts.push_back(
        key.substr(start, pos == std::string_view::npos ? std::string_view::npos : pos - start));
    if (pos == std::string_view::npos) break;
    start = pos + 1;
  }
  return parts.size() > 3 ? std::string(parts[3]) : std::string();
}

}  // namespace hrc
