// The project's robots/ folder for the C++ tests, found from the test binary's own path (it is
// built inside the clone, under build/): no path compiled in, so a test file compiles the same
// in every clone and ccache (scripts/setup.sh) reuses it. HRC_ROBOTS_DIR overrides.
#pragma once

#include <cstdlib>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <system_error>

namespace hrc::testing {

inline std::string robots_dir() {
  namespace fs = std::filesystem;
  if (const char* env = std::getenv("HRC_ROBOTS_DIR"); env != nullptr && *env != '\0') {
    return env;
  }
  std::error_code ec;
  fs::path p = fs::read_symlink("/proc/self/exe", ec).parent_path();
  for (int up = 0; up < 8 && !ec && !p.empty(); ++up, p = p.parent_path()) {
    if (fs::exists(p / "robots" / "arm5.urdf", ec)) return (p / "robots").string();
    if (p == p.parent_path()) break;
  }
  throw std::runtime_error("robots/arm5.urdf not found above the test binary; set HRC_ROBOTS_DIR");
}

}  // namespace hrc::testing
