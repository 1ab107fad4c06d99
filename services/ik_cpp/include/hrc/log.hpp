// Minimal stderr logging shared by the hrc C++ processes: one line per call, thread-safe,
// "LEVEL [name] message" (the process name is set once by main()).
#pragma once

#include <string_view>

namespace hrc::log {

enum class Level { Debug = 0, Info = 1, Warning = 2, Error = 3 };

/// Name shown in every line (default "hrc").
void set_name(std::string_view name);
/// Lines below `level` are dropped (default info; env HRC_LOG_LEVEL=debug|info|warning|error).
void set_level(Level level);
bool enabled(Level level);
void write(Level level, std::string_view message);

inline void debug(std::string_view m) { write(Level::Debug, m); }
inline void info(std::string_view m) { write(Level::Info, m); }
inline void warning(std::string_view m) { write(Level::Warning, m); }
inline void error(std::string_view m) { write(Level::Error, m); }

}  // namespace hrc::log
