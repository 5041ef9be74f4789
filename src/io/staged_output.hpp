// The output folder of an importer: checked before any work, built in a hidden
// sibling folder and swapped in whole at the end, so a failed import never
// leaves a partial dataset (and a replaced one is either the old or the new).
#pragma once

#include <filesystem>
#include <memory>
#include <string>

#include "io/temporary_paths.hpp"

namespace scenecal::io {

// The absolute output folder. InputError when it exists and is not an empty
// folder, unless overwrite (then Commit replaces it).
std::filesystem::path CheckOutputFolder(const std::filesystem::path& output, bool overwrite);

class StagedOutput {
 public:
  // Creates the hidden staging folder beside target (".<name>.<purpose>-<hex>"),
  // listed in io::RemoveRegisteredTemporaryPaths while it exists.
  explicit StagedOutput(std::filesystem::path target, const std::string& purpose = "import");
  // Removes the staging folder unless committed (also while unwinding from an
  // error or an interruption: the target is then left as it was).
  ~StagedOutput();
  StagedOutput(const StagedOutput&) = delete;
  StagedOutput& operator=(const StagedOutput&) = delete;

  const std::filesystem::path& Staging() const { return staging_; }  // write here
  // Renames the staging folder to the target; an existing target is moved
  // aside first and removed after.
  void Commit();
  // Moves every entry of the staging folder into the target folder (created
  // when missing), each replacing an entry of the same name; the target's other
  // entries stay. For outputs that share a folder with the user's own files
  // (`experiment --output DIR`). Then removes the staging folder.
  void CommitEntries();

 private:
  std::filesystem::path target_, staging_;
  std::unique_ptr<RegisteredTemporaryPath> registration_;
  bool committed_ = false;
};

}  // namespace scenecal::io
