#include "cli/warning_advice.hpp"

#include <string>

#include "core/calibrate_alternating.hpp"

namespace scenecal::cli {

std::string LevelsApartOptions(const LevelsApart& apart) {
  switch (apart.remedy) {
    case LevelsApart::Remedy::kLargerTimeBudget:
      return "a larger --time-budget";
    case LevelsApart::Remedy::kStagesOnFirstAlternations:
      return "--alternations " + std::to_string(apart.suggested_alternations) + " --stage-alternations " +
             std::to_string(apart.suggested_stage_alternations);
    case LevelsApart::Remedy::kMoreAlternations:
      return "--alternations " + std::to_string(apart.suggested_alternations);
  }
  return "";
}

void AddOptionAdvice(CalibrationOutcome* outcome) {
  if (!outcome->levels_apart) return;
  const std::string core_words = DescribeLevelsApart(*outcome->levels_apart);
  for (std::string& warning : outcome->result.warnings) {
    if (warning == core_words) warning += "; on the command line: " + LevelsApartOptions(*outcome->levels_apart);
  }
}

}  // namespace scenecal::cli
