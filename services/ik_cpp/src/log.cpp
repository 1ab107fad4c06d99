#include "hrc/log.hpp"

#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <string>

namespace hrc::log {
namespace {

Level level_from_env() {
  const char* v = std::getenv("HRC_LOG_LEVEL");
  if (v == nullptr) return Level::Info;
  if (std::strcmp(v, "debug") == 0 || std::strcmp(v, "DEBUG") == 0) return Level::Debug;
  if (std::strcmp(v, "warning") == 0 || std::strcmp(v, "WARNING") == 0) return Level::Warning;
  if (std::strcmp(v, "error") == 0 || std::strcmp(v, "ERROR") == 0) return Level::Error;
  return Level::Info;
}

std::mutex& name_mutex() {
  static std::mutex m;
  return m;
}
std::string& name_storage() {
  static std::string n = "hrc";
  return n;
}
std::atomic<int>& level_storage() {
  static std::atomic<int> l{static_cast<int>(level_from_env())};
  return l;
}

const char* label(Level level) {
  switch (level) {
    case Level::Debug: return "DEBUG";
    case Level::Info: return "INFO";
    case Level::Warning: return "WARNING";
    case Level::Error: return "ERROR";
  }
  return "?";
}

}  // namespace

void set_name(std::string_view name) {
  const std::lock_guard<std::mutex> lock(name_mutex());
  name_storage() = std::string(name);
}

void set_level(Level level) { level_storage() = static_cast<int>(level); }

bool enabled(Level level) { return static_cast<int>(level) >= level_storage().load(); }

void write(Level level, std::string_view message) {
  if (!enabled(level)) return;
  std::string line;
  {
    const std::lock_guard<std::mutex> lock(name_mutex());
    line = std::string(label(level)) + " [" + name_storage() + "] ";
  }
  line.append(message.data(), message.size());
  line.push_back('\n');
  // One fwrite per line keeps lines from different threads whole.
  std::fwrite(line.data(), 1, line.size(), stderr);
  std::fflush(stderr);
}

}  // namespace hrc::log
