// Numbers in messages and the result's settings: six significant digits, the
// shortest form (0.05, 1e-05, 500).
#pragma once

#include <sstream>
#include <string>

namespace scenecal {

inline std::string NumberText(double value) {
  std::ostringstream out;
  out.precision(6);
  out << value;
  return out.str();
}

}  // namespace scenecal
