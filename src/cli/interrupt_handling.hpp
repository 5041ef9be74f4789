// Ctrl-C (SIGINT) and SIGTERM for the scenecal process.
//
// The first signal only sets the core's interrupt flag (scenecal::
// RequestInterrupt, async-signal-safe): the running command's long loops
// throw scenecal::Interrupted at their next check (within ~2 s), the stack
// unwinds and the destructors remove the temporary files and staging folders,
// so no output is partly written (an output that existed before is left as it
// was). main then exits 130 (SIGINT) or 143 (SIGTERM) with one log line.
//
// A second signal ends the process at once with the same code: a watcher
// thread removes the registered temporary paths (io::RemoveRegisteredTemporary-
// Paths: staging folders, files being written atomically) and calls _exit. A
// file the command is creating in a staging folder at that very moment may
// survive the removal in the hidden folder ".<output>.<purpose>-<hex>" beside
// the output; the output itself is never partly written.
#pragma once

namespace scenecal::cli {

// Installs the handlers of SIGINT and SIGTERM and starts the watcher thread.
// Call once, early in main (before any thread is started).
void InstallInterruptHandlers();

// The first signal received (SIGINT or SIGTERM), 0 when none.
int ReceivedInterruptSignal();

// 128 + the first signal (130 for SIGINT, 143 for SIGTERM); 130 when none.
int InterruptExitCode();

// "SIGINT", "SIGTERM" (or "a signal").
const char* InterruptSignalName();

}  // namespace scenecal::cli
