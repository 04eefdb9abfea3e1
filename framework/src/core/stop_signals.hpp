// The catchable signals whose default action ends a process without a crash (kStopSignals:
// SIGINT, SIGTERM, SIGHUP, SIGQUIT, SIGPIPE, SIGUSR1, SIGUSR2, SIGALRM, SIGVTALRM, SIGXCPU)
// ask a long command (run, bench, stress, crosscheck, grade) to stop cleanly: it finishes
// its current step, point or test, writes what is done and exits with 128 + the signal's
// number. A second signal of the same kind ends the process at once (the signal's default
// action), after the second-stop action (a run's summary.json); except SIGPIPE, which a
// closed pipe raises at every write: later ones are only noted (the writes fail, EPIPE).
// Not caught: SIGPROF (profilers), real-time signals, and SIGXFSZ (ignored by main: a write
// past the file-size limit fails instead).
#pragma once

#include <atomic>
#include <string>

namespace pinsim {

/// The stop signals.
extern const int kStopSignals[10];

/// Installs the handlers for the stop signals; SIGHUP stays ignored if it is ignored when
/// this is called (nohup). Safe to call more than once.
void install_stop_handlers();

/// The first stop signal received since the handlers were installed, or 0. The run loop
/// polls it (RunSettings::stop).
const std::atomic<int>& stop_signal();

/// Records `sig` as if it had arrived (tests, and code that stops for its own reasons).
void request_stop(int sig) noexcept;

/// What a second stop signal of the same kind does before the process dies of it (a run
/// writes its summary.json: CrashSummary). It runs in the signal handler, so it must be
/// async-signal-safe. nullptr (the default): nothing.
using SecondStopAction = void (*)(int sig);
void set_second_stop_action(SecondStopAction action) noexcept;

/// "SIGINT", "SIGSEGV", ...; "signal N" for one without a name here. Async-signal-safe (a
/// static string; "signal" for unknown ones).
const char* signal_abbrev(int sig) noexcept;

/// signal_abbrev, with the number for unknown signals.
std::string signal_name(int sig);

/// 128 + sig: the exit status of a command that stopped because of `sig`.
inline int stop_exit_code(int sig) { return 128 + sig; }

}  // namespace pinsim
