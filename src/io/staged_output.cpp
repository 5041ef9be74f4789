#include "io/staged_output.hpp"

#include <random>
#include <string>
#include <system_error>
#include <vector>

#include <fmt/format.h>

#include "io/yaml_fields.hpp"

namespace scenecal::io {

namespace fs = std::filesystem;

namespace {

fs::path SiblingTemporary(const fs::path& target, const std::string& purpose) {
  std::random_device entropy;
  return target.parent_path() / fmt::format(".{}.{}-{:08x}", target.filename().string(), purpose, entropy());
}

}  // namespace

fs::path CheckOutputFolder(const fs::path& output, bool overwrite) {
  fs::path target = fs::absolute(output).lexically_normal();
  if (!target.has_filename()) target = target.parent_path();  // "out/" -> "out"
  std::error_code error;
  if (fs::exists(target, error)) {
    const bool empty_folder = fs::is_directory(target, error) && fs::is_empty(target, error);
    if (!empty_folder && !overwrite) {
      detail::Fail(target.string(), "output", "exists and is not an empty folder",
                   "a new or empty folder (or --force to replace it)");
    }
  }
  return target;
}

StagedOutput::StagedOutput(fs::path target, const std::string& purpose)
    : target_(std::move(target)), staging_(SiblingTemporary(target_, purpose)) {
  registration_ = std::make_unique<RegisteredTemporaryPath>(staging_);
  fs::create_directories(staging_);
}

StagedOutput::~StagedOutput() {
  if (committed_) return;
  std::error_code ignored;
  fs::remove_all(staging_, ignored);
}

void StagedOutput::Commit() {
  std::error_code error;
  fs::path aside;
  if (fs::exists(target_, error)) {
    aside = SiblingTemporary(target_, "old");
    fs::rename(target_, aside);
  }
  fs::rename(staging_, target_);
  committed_ = true;
  if (!aside.empty()) fs::remove_all(aside, error);
}

void StagedOutput::CommitEntries() {
  fs::create_directories(target_);
  std::vector<fs::path> entries;  // listed first: the loop below empties the folder
  for (const fs::directory_entry& entry : fs::directory_iterator(staging_)) entries.push_back(entry.path());
  for (const fs::path& entry : entries) {
    const fs::path destination = target_ / entry.filename();
    std::error_code error;
    fs::path aside;
    if (fs::exists(fs::symlink_status(destination, error))) {
      aside = SiblingTemporary(destination, "old");
      fs::rename(destination, aside);
    }
    fs::rename(entry, destination);
    if (!aside.empty()) fs::remove_all(aside, error);
  }
  committed_ = true;
  std::error_code ignored;
  fs::remove_all(staging_, ignored);
}

}  // namespace scenecal::io
