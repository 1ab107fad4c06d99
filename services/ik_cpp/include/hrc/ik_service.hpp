// The ik_cpp service logic behind hrc-ik. Today it takes part in the clock and keeps the latest
// RobotCommand per robot; the kinematics engineer extends step() to publish robot/<id>/state
// (and may add the robot/reach queryable in the constructor).
#pragma once

#include <cstdint>
#include <map>
#include <string>

#include "hrc/lockstep.hpp"
#include "hrc/typed_bus.hpp"

namespace hrc {

class IkService {
 public:
  /// Registers the inputs (robot/*/command) and the step with the participant; call before
  /// participant.start().
  IkService(Bus& bus, LockstepParticipant& participant);
  IkService(const IkService&) = delete;
  IkService& operator=(const IkService&) = delete;

  /// A well-formed command, delivered in deterministic order before the step of its tick.
  void on_command(const std::string& key, const v1::RobotCommand& command);
  /// Tick k: compute and publish the outputs of k (extension point: RobotState per robot).
  void step(const v1::ClockTick& tick);

  /// Rejects commands whose robot field disagrees with the key or whose numbers are not finite.
  static std::string validate_command(const std::string& key, const v1::RobotCommand& command);

  uint64_t commands_received() const { return commands_received_; }
  /// Latest command per robot id (the id from the key).
  const std::map<std::string, v1::RobotCommand>& latest_commands() const { return latest_; }

 private:
  Bus& bus_;
  // Touched only from the participant's tick processing (one tick at a time): no lock needed.
  std::map<std::string, v1::RobotCommand> latest_;
  uint64_t commands_received_ = 0;
};

}  // namespace hrc
