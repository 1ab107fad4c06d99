#include <gtest/gtest.h>

#include <cmath>

#include "hrc/ik_service.hpp"

namespace {

TEST(IkService, ValidatesCommands) {
  hrc::v1::RobotCommand c;
  c.set_robot("r1");
  c.mutable_target()->set_x(0.4);
  EXPECT_EQ(hrc::IkService::validate_command("hrc/s/robot/r1/command", c), "");
  EXPECT_NE(hrc::IkService::validate_command("hrc/s/robot/r2/command", c).find("'r2'"), std::string::npos);
  c.mutable_target()->set_y(std::nan(""));
  EXPECT_NE(hrc::IkService::validate_command("hrc/s/robot/r1/command", c).find("NaN"), std::string::npos);
  c.mutable_target()->set_y(0);
  c.set_max_speed(-1);
  EXPECT_NE(hrc::IkService::validate_command("hrc/s/robot/r1/command", c), "");
}

TEST(IkService, KeepsTheLatestGoodCommandPerRobotAndCountsBadOnes) {
  hrc::Bus bus(hrc::BusConfig{}, "iks", "ik_cpp");
  hrc::LockstepParticipant participant(bus);
  hrc::IkService service(bus, participant);
  hrc::v1::RobotCommand c;
  c.set_robot("r1");
  c.set_command_id(1);
  service.on_command("hrc/iks/robot/r1/command", c);
  c.set_command_id(2);
  service.on_command("hrc/iks/robot/r1/command", c);
  service.on_command("hrc/iks/robot/r9/command", c);  // robot field says r1: rejected
  EXPECT_EQ(service.commands_received(), 2u);
  ASSERT_EQ(service.latest_commands().size(), 1u);
  EXPECT_EQ(service.latest_commands().at("r1").command_id(), 2u);
  EXPECT_EQ(bus.stats().decode_errors("hrc/iks/robot/r9/command"), 1u);
}

}  // namespace
