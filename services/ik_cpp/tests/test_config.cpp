#include <gtest/gtest.h>

#include <stdexcept>

#include "hrc/bus.hpp"
#include "hrc/cli.hpp"

namespace {

TEST(BusConfig, DefaultsArePeerOnLoopbackWithoutMulticast) {
  const hrc::BusConfig c;
  EXPECT_EQ(c.to_json5(),
            "{\n"
            "  mode: \"peer\",\n"
            "  scouting: { multicast: { enabled: false }, gossip: { enabled: true } },\n"
            "  listen: { endpoints: [\"tcp/127.0.0.1:0\"] },\n"
            "}\n");
  const auto ins = c.insertions();
  ASSERT_EQ(ins.size(), 4u);
  EXPECT_EQ(ins[0], (std::pair<std::string, std::string>{"mode", "\"peer\""}));
  EXPECT_EQ(ins[1], (std::pair<std::string, std::string>{"scouting/multicast/enabled", "false"}));
  EXPECT_EQ(ins[2], (std::pair<std::string, std::string>{"scouting/gossip/enabled", "true"}));
  EXPECT_EQ(ins[3],
            (std::pair<std::string, std::string>{"listen/endpoints", "[\"tcp/127.0.0.1:0\"]"}));
}

TEST(BusConfig, ClientWithSeveralEndpoints) {
  hrc::BusConfig c;
  c.mode = "client";
  c.connect = {"tcp/10.0.0.1:7447", "tcp/10.0.0.2:7447"};
  c.listen.clear();
  c.multicast_scouting = true;
  EXPECT_EQ(c.to_json5(),
            "{\n"
            "  mode: \"client\",\n"
            "  scouting: { multicast: { enabled: true }, gossip: { enabled: true } },\n"
            "  connect: { endpoints: [\"tcp/10.0.0.1:7447\", \"tcp/10.0.0.2:7447\"], "
            "timeout_ms: 60000, retry: { period_init_ms: 10, period_max_ms: 50, "
            "period_increase_factor: 2 } },\n"
            "}\n");
  EXPECT_NO_THROW(c.validate());
}

TEST(BusConfig, ValidateNamesTheBadField) {
  hrc::BusConfig c;
  c.mode = "server";
  try {
    c.validate();
    FAIL() << "expected invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("'server'"), std::string::npos) << e.what();
  }
  c = hrc::BusConfig{};
  c.connect = {"127.0.0.1:7447"};
  EXPECT_THROW(c.validate(), std::invalid_argument);
  c = hrc::BusConfig{};
  c.mode = "client";
  EXPECT_THROW(c.validate(), std::invalid_argument);  // a client needs somewhere to connect
}

TEST(BusConfig, JsonQuoteEscapes) { EXPECT_EQ(hrc::json_quote("a\"b\\c\n"), "\"a\\\"b\\\\c\\n\""); }

TEST(BusConfig, GeneratedJson5OpensAZenohSession) {
  hrc::BusConfig c;  // listens on an ephemeral loopback port, connects nowhere
  hrc::Session s = hrc::Session::open_json5(c.to_json5());
  EXPECT_TRUE(static_cast<bool>(s));
  hrc::Session s2 = hrc::Session::open(c);
  EXPECT_TRUE(static_cast<bool>(s2));
}

TEST(BusConfig, BadJson5IsABusErrorWithZenohsText) {
  try {
    hrc::Session::open_json5("{ mode: ");
    FAIL() << "expected BusError";
  } catch (const hrc::BusError& e) {
    EXPECT_NE(std::string(e.what()).find("invalid zenoh config"), std::string::npos) << e.what();
  }
}

TEST(BusConfig, MissingConfigFileIsNamed) {
  hrc::BusConfig c;
  c.config_file = "/nonexistent/zenoh.json5";
  try {
    hrc::Session::open(c);
    FAIL() << "expected BusError";
  } catch (const hrc::BusError& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/zenoh.json5"), std::string::npos)
        << e.what();
  }
}

hrc::cli::BusArgs parse_bus(const std::vector<std::string>& argv) {
  const hrc::cli::Args args(argv, hrc::cli::bus_single_flags(), hrc::cli::bus_repeatable_flags(),
                            hrc::cli::bus_bool_flags());
  return hrc::cli::bus_args(args);
}

TEST(BusArgs, ClockMasterIsTakenFromTheCommandLine) {
  EXPECT_FALSE(parse_bus({}).clock_master.has_value());  // the participant's default applies
  EXPECT_EQ(parse_bus({"--clock-master", "world"}).clock_master, "world");
  EXPECT_THROW(parse_bus({"--clock-master", "a/b"}), hrc::cli::UsageError);
}

}  // namespace
