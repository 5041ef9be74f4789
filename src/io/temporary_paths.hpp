// The temporary files and folders a command has beside its outputs (staging
// folders, files being written atomically), so that a process that must end
// at once (a second Ctrl-C, see cli/interrupt_handling.hpp) can still remove
// them. Normally their owners rename or remove them; the registry only lists.
#pragma once

#include <filesystem>

namespace scenecal::io {

// Lists `path` while it lives; the destructor takes it off the list (it does
// not remove the path: that stays the owner's job).
class RegisteredTemporaryPath {
 public:
  explicit RegisteredTemporaryPath(std::filesystem::path path);
  ~RegisteredTemporaryPath();
  RegisteredTemporaryPath(const RegisteredTemporaryPath&) = delete;
  RegisteredTemporaryPath& operator=(const RegisteredTemporaryPath&) = delete;

 private:
  std::filesystem::path path_;
};

// Removes every listed path (recursively), ignoring errors. Thread-safe; not
// async-signal-safe (call it from a thread, not from a signal handler).
void RemoveRegisteredTemporaryPaths() noexcept;

}  // namespace scenecal::io
