#include "cli/interrupt_handling.hpp"

#include <atomic>
#include <cerrno>
#include <csignal>
#include <cstring>
#include <thread>

#include <fcntl.h>
#include <unistd.h>

#include "core/interrupt.hpp"
#include "io/temporary_paths.hpp"

namespace scenecal::cli {
namespace {

static_assert(std::atomic<int>::is_always_lock_free);
std::atomic<int> first_signal{0};
std::atomic<int> signal_count{0};
int second_signal_pipe[2] = {-1, -1};  // the handler writes, the watcher thread reads

// Async-signal-safe only: atomics, write(2), errno restored.
void OnInterruptSignal(int signal_number) {
  const int saved_errno = errno;
  int none = 0;
  first_signal.compare_exchange_strong(none, signal_number);
  RequestInterrupt();
  if (signal_count.fetch_add(1) + 1 >= 2 && second_signal_pipe[1] >= 0) {
    const char byte = 1;
    [[maybe_unused]] const ssize_t written = ::write(second_signal_pipe[1], &byte, 1);
  }
  errno = saved_errno;
}

void WriteToStderr(const char* text) {
  [[maybe_unused]] const ssize_t written = ::write(STDERR_FILENO, text, std::strlen(text));
}

// Waits for a second signal, then removes the temporary paths and ends the process.
void WatchForSecondSignal() {
  char byte = 0;
  for (;;) {
    const ssize_t n = ::read(second_signal_pipe[0], &byte, 1);
    if (n == 1) break;
    if (n < 0 && errno == EINTR) continue;
    return;  // the pipe is gone: nothing to watch
  }
  WriteToStderr("scenecal: second signal: removing temporary files and exiting at once\n");
  io::RemoveRegisteredTemporaryPaths();
  ::_exit(InterruptExitCode());
}

}  // namespace

void InstallInterruptHandlers() {
  if (::pipe2(second_signal_pipe, O_CLOEXEC) == 0) std::thread(WatchForSecondSignal).detach();
  struct sigaction action {};
  action.sa_handler = OnInterruptSignal;
  sigemptyset(&action.sa_mask);
  action.sa_flags = SA_RESTART;  // system calls in progress carry on; the loops poll the flag
  sigaction(SIGINT, &action, nullptr);
  sigaction(SIGTERM, &action, nullptr);
}

int ReceivedInterruptSignal() { return first_signal.load(); }

int InterruptExitCode() {
  const int signal_number = first_signal.load();
  return 128 + (signal_number != 0 ? signal_number : SIGINT);
}

const char* InterruptSignalName() {
  switch (first_signal.load()) {
    case SIGINT: return "SIGINT";
    case SIGTERM: return "SIGTERM";
    default: return "a signal";
  }
}

}  // namespace scenecal::cli
