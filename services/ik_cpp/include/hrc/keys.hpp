// Key expressions of one session: the only place C++ spells them (Python twin: hrc.bus.keys.Keys,
// table in docs/ARCHITECTURE.md). Every key lives under hrc/<session>/.
#pragma once

#include <string>
#include <string_view>

namespace hrc {

/// Throws std::invalid_argument unless `value` is 1-64 characters of A-Z a-z 0-9 _ - (so an id
/// can never break or widen a key expression with '/', '*', '$', ...). Returns `value`.
const std::string& check_name(std::string_view kind, const std::string& value);

class Keys {
 public:
  static constexpr const char* kRoot = "hrc";

  /// Throws std::invalid_argument for a session id that is not a valid name.
  explicit Keys(std::string session);

  const std::string& session() const { return session_; }
  const std::string& prefix() const { return prefix_; }

  std::string all() const;  // hrc/<s>/**
  std::string clock() const;
  std::string clock_ack(const std::string& participant) const;
  std::string clock_acks() const;                            // clock/ack/*
  std::string run_control(const std::string& sender) const;  // run/control/<sender>
  std::string run_controls() const;                          // run/control/*
  std::string run_end() const;
  std::string alive(const std::string& service) const;
  std::string alive_all() const;  // alive/*
  std::string stats(const std::string& service) const;
  std::string replay(const std::string& service) const;  // docs/ARCHITECTURE.md, "Lost messages"
  std::string scenario() const;
  std::string robot_command(const std::string& robot) const;
  std::string robot_commands() const;  // robot/*/command
  std::string robot_state(const std::string& robot) const;
  std::string robot_states() const;  // robot/*/state
  std::string robot_reach() const;
  std::string human_state() const;
  std::string world_objects() const;
  std::string world_contacts() const;
  std::string world_separation() const;  // physics, only under safety_policy = ssm
  std::string world_commands() const;
  std::string task_events() const;
  std::string task_indicators() const;
  std::string task_metrics() const;
  std::string bench(const std::string& name) const;

  /// The final segment of a key, e.g. the service of alive/<service>.
  static std::string last_segment(std::string_view key);
  /// The robot id in hrc/<s>/robot/<id>/..., or "" if the key is shorter.
  static std::string robot_of(std::string_view key);

 private:
  std::string k(std::string_view a) const;
  std::string k(std::string_view a, std::string_view b) const;
  std::string k(std::string_view a, std::string_view b, std::string_view c) const;

  std::string session_;
  std::string prefix_;
};

}  // namespace hrc
