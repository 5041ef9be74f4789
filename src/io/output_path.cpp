#include "io/output_path.hpp"

#include <system_error>

#include <unistd.h>

#include "io/yaml_fields.hpp"

namespace scenecal::io {

namespace fs = std::filesystem;

namespace {

// access(2) answers for the real user (root passes any permission bits, as it
// would when writing), and EROFS for a read-only file system.
void CheckWritableDirectory(const fs::path& folder, const std::string& option, const fs::path& output) {
  std::error_code error;
  if (!fs::is_directory(folder, error)) {
    detail::Fail(output.string(), option, "'" + folder.string() + "' is not a directory",
                 "a path inside an existing, writable folder");
  }
  if (::access(folder.c_str(), W_OK | X_OK) != 0) {
    detail::Fail(output.string(), option,
                 "folder '" + folder.string() + "' is not writable (" + std::generic_category().message(errno) + ")",
                 "a path inside a writable folder");
  }
}

}  // namespace

void CheckOutputFile(const fs::path& path, const std::string& option) {
  const fs::path target = fs::absolute(path).lexically_normal();
  std::error_code error;
  if (!target.has_filename() || fs::is_directory(target, error)) {
    detail::Fail(path.string(), option, "a directory", "a file name");
  }
  const fs::path folder = target.parent_path();
  if (!fs::exists(folder, error)) {
    detail::Fail(path.string(), option, "folder '" + folder.string() + "' does not exist",
                 "a path inside an existing folder (create it first)");
  }
  CheckWritableDirectory(folder, option, path);
}

void CheckOutputFolderWritable(const fs::path& path, const std::string& option) {
  fs::path target = fs::absolute(path).lexically_normal();
  if (!target.has_filename()) target = target.parent_path();  // "out/" -> "out"
  std::error_code error;
  if (fs::exists(target, error) && !fs::is_directory(target, error)) {
    detail::Fail(path.string(), option, "an existing file", "a folder path");
  }
  // Outputs are built beside the target and renamed into place, and missing
  // parents are created: the nearest existing ancestor must take new entries.
  fs::path folder = target.parent_path();
  while (!fs::exists(folder, error) && folder.has_relative_path()) folder = folder.parent_path();
  CheckWritableDirectory(folder, option, path);
}

}  // namespace scenecal::io
