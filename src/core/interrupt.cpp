#include "core/interrupt.hpp"

#include <atomic>

namespace scenecal {
namespace {

// A signal handler may only touch lock-free atomics.
static_assert(std::atomic<bool>::is_always_lock_free);
std::atomic<bool> interrupt_requested{false};

}  // namespace

void RequestInterrupt() noexcept { interrupt_requested.store(true, std::memory_order_relaxed); }

void ClearInterruptRequest() noexcept { interrupt_requested.store(false, std::memory_order_relaxed); }

bool InterruptRequested() noexcept { return interrupt_requested.load(std::memory_order_relaxed); }

void ThrowIfInterrupted() {
  if (InterruptRequested()) throw Interrupted();
}

}  // namespace scenecal
