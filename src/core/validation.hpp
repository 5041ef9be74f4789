// The failure path of the IsValid(std::string* why) checks of option structs:
//   if (!(step_m > 0.0)) return Invalid(why, "step_m must be positive");
#pragma once

#include <string>
#include <utility>

namespace scenecal {

// Stores message in *why when the caller asked for a reason (why != nullptr)
// and returns false, the verdict of the failed check.
inline bool Invalid(std::string* why, std::string message) {
  if (why != nullptr) *why = std::move(message);
  return false;
}

}  // namespace scenecal
