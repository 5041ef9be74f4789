// The output folder of an importer: checked before any work, built in a hidden
// sibling folder and swapped in whole at the end, so a failed import never
// leaves a partial dataset (and a replaced one is either the old or the new).
#pragma once

#include <filesystem>

namespace scenecal::io {

// The absolute output folder. InputError when it exists and is not an empty
// folder, unless overwrite (then Commit replaces it).
std::filesystem::path CheckOutputFolder(const std::filesystem::path& output, bool overwrite);

class StagedOutput {
 public:
  // Creates the hidden staging folder beside target (".<name>.import-<hex>").
  explicit StagedOutput(std::filesystem::path target);
  ~StagedOutput();  // removes the staging folder unless committed
  StagedOutput(const StagedOutput&) = delete;
  StagedOutput& operator=(const StagedOutput&) = delete;

  const std::filesystem::path& Staging() const { return staging_; }  // write here
  // Renames the staging folder to the target; an existing target is moved
  // aside first and removed after.
  void Commit();

 private:
  std::filesystem::path target_, staging_;
  bool committed_ = false;
};

}  // namespace scenecal::io
