#include "io/temporary_paths.hpp"

#include <mutex>
#include <set>
#include <system_error>
#include <utility>

namespace scenecal::io {
namespace {

struct Registry {
  std::mutex mutex;
  std::multiset<std::filesystem::path> paths;
};

// Never destroyed: a thread that ends the process may use it during exit.
Registry& TheRegistry() {
  static Registry* registry = new Registry;
  return *registry;
}

}  // namespace

RegisteredTemporaryPath::RegisteredTemporaryPath(std::filesystem::path path) : path_(std::move(path)) {
  Registry& registry = TheRegistry();
  const std::lock_guard lock(registry.mutex);
  registry.paths.insert(path_);
}

RegisteredTemporaryPath::~RegisteredTemporaryPath() {
  Registry& registry = TheRegistry();
  const std::lock_guard lock(registry.mutex);
  const auto it = registry.paths.find(path_);
  if (it != registry.paths.end()) registry.paths.erase(it);
}

void RemoveRegisteredTemporaryPaths() noexcept {
  Registry& registry = TheRegistry();
  const std::lock_guard lock(registry.mutex);
  for (const std::filesystem::path& path : registry.paths) {
    std::error_code ignored;
    std::filesystem::remove_all(path, ignored);
  }
}

}  // namespace scenecal::io
