// What to change on the command line for the core's structured warnings: the
// core words its warnings without option names; `calibrate` adds them here.
#pragma once

#include "core/calibrate.hpp"

namespace scenecal::cli {

// The options that close alt's gap between its levels, e.g. "--alternations 18
// --stage-alternations 12" or "a larger --time-budget".
std::string LevelsApartOptions(const LevelsApart& apart);

// Appends to the result's warning of each structured warning of the outcome
// the options that act on it ("; on the command line: ...").
void AddOptionAdvice(CalibrationOutcome* outcome);

}  // namespace scenecal::cli
