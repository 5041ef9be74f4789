#pragma once

#include <stdexcept>
#include <string>

namespace scenecal::io {

// Bad input data. The message names the file and the field or line, what was
// found and what was expected. The CLI maps it to exit code 2.
class InputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Writes content to path atomically: a temporary file in the same directory,
// flushed, then renamed over path. A crash never leaves a partial file.
// Throws std::runtime_error when the file cannot be written.
void WriteFileAtomically(const std::string& path, const std::string& content);

}  // namespace scenecal::io
