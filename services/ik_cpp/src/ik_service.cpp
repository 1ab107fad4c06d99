#include "hrc/ik_service.hpp"

#include <cmath>

namespace hrc {

IkService::IkService(Bus& bus, LockstepParticipant& participant) : bus_(bus) {
  participant.input<v1::RobotCommand>(
      bus_.keys().robot_commands(),
      [this](const std::string& key, const v1::RobotCommand& c) { on_command(key, c); });
  participant.on_tick([this](const v1::ClockTick& t) { step(t); });
}

std::string IkService::validate_command(const std::string& key, const v1::RobotCommand& c) {
  const std::string robot = Keys::robot_of(key);
  if (!c.robot().empty() && c.robot() != robot) {
    return "robot field '" + c.robot() + "' does not match the key's robot '" + robot + "'";
  }
  const double nums[] = {c.target().x(), c.target().y(), c.target().z(), c.yaw_deg(),
                         c.approach_height(), c.depart_height(), c.max_speed()};
  for (const double v : nums) {
    if (!std::isfinite(v)) return "command has a NaN or infinite number";
  }
  if (c.max_speed() < 0) return "max_speed is negative";
  return {};
}

void IkService::on_command(const std::string& key, const v1::RobotCommand& command) {
  const std::string problem = validate_command(key, command);
  if (!problem.empty()) {
    // Counted like a malformed payload so it shows in stats/ik_cpp and never drives the arm.
    const uint64_t n = bus_.stats().count_error(key);
    log::warning("rejected command #" + std::to_string(n) + " on " + key + " from sender '" +
                 command.header().sender() + "': " + problem);
    return;
  }
  ++commands_received_;
  latest_[Keys::robot_of(key)] = command;
}

void IkService::step(const v1::ClockTick& tick) {
  // Extension point: for each robot, advance the motion toward latest_[robot] and publish
  // v1::RobotState on bus_.keys().robot_state(robot) with
  // bus_.publisher(key).put(state, tick.header().tick(), tick.header().sim_time()).
  (void)tick;
}

}  // namespace hrc
