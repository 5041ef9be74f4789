// Cooperative interruption of long computations. A front end (the CLI, on
// SIGINT or SIGTERM) calls RequestInterrupt; the long loops of the core, the
// simulator, the importers and the MPI backend call ThrowIfInterrupted often
// enough (at least every ~0.2 s of work on a core) that the process unwinds
// soon after, and the destructors on the way remove temporary output. The core
// knows nothing of signals: the flag is a plain process-wide atomic.
#pragma once

namespace scenecal {

// Thrown by ThrowIfInterrupted. Deliberately not a std::exception, so that no
// `catch (const std::exception&)` that turns failures into statuses or retries
// swallows it; TBB carries it out of parallel loops like any exception.
class Interrupted {
 public:
  const char* what() const noexcept { return "interrupted"; }
};

// Sets the flag. Async-signal-safe (a lock-free atomic store), so a signal
// handler may call it.
void RequestInterrupt() noexcept;
// Clears the flag (tests; a front end that goes on after an interruption).
void ClearInterruptRequest() noexcept;
bool InterruptRequested() noexcept;
// Throws Interrupted when the flag is set. Cheap (one relaxed load): call it
// in loops freely.
void ThrowIfInterrupted();

}  // namespace scenecal
