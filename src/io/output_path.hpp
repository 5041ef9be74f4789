// Checks of output paths made before any work, so that a run that could not
// write its result stops at once with a message naming the path (exit 2),
// instead of failing after the work or leaving part of its output.
#pragma once

#include <filesystem>
#include <string>

namespace scenecal::io {

// `path` is to be written as a file: its folder exists and is a writable
// directory, and `path` itself is not a directory. `option` names the
// command-line option in the message (e.g. "--output"). InputError otherwise.
void CheckOutputFile(const std::filesystem::path& path, const std::string& option);

// `path` is a folder to be created (with missing parents) or replaced: its
// nearest existing ancestor is a writable directory. InputError otherwise.
void CheckOutputFolderWritable(const std::filesystem::path& path, const std::string& option);

}  // namespace scenecal::io
