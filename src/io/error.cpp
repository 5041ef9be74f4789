#include "io/error.hpp"

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <system_error>

#include <fcntl.h>
#include <unistd.h>

#include "io/temporary_paths.hpp"

namespace scenecal::io {

void WriteFileAtomically(const std::string& path, const std::string& content) {
  namespace fs = std::filesystem;
  const fs::path target(path);
  const fs::path directory = target.has_parent_path() ? target.parent_path() : fs::path(".");
  std::random_device entropy;
  const fs::path temporary = directory / ("." + target.filename().string() + ".tmp" + std::to_string(entropy()));
  const RegisteredTemporaryPath registration(temporary);  // for a process that must end at once
  const int fd = ::open(temporary.c_str(), O_WRONLY | O_CREAT | O_EXCL, 0644);
  if (fd < 0) throw std::runtime_error("cannot create " + temporary.string() + " to write " + path);
  std::size_t written = 0;
  while (written < content.size()) {
    const ssize_t n = ::write(fd, content.data() + written, content.size() - written);
    if (n <= 0) {
      ::close(fd);
      ::unlink(temporary.c_str());
      throw std::runtime_error("cannot write " + path + " (disk full?)");
    }
    written += static_cast<std::size_t>(n);
  }
  // The data must be on disk before the rename makes it visible.
  if (::fsync(fd) != 0 || ::close(fd) != 0) {
    ::unlink(temporary.c_str());
    throw std::runtime_error("cannot flush " + path);
  }
  std::error_code error;
  fs::rename(temporary, target, error);
  if (error) {
    ::unlink(temporary.c_str());
    throw std::runtime_error("cannot rename the temporary file onto " + path + ": " + error.message());
  }
}

}  // namespace scenecal::io
