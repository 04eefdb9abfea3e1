// The trusted side of the worker channel: a plugin table whose functions forward every call
// to the sandboxed worker and check each reply strictly (exact sizes, indices in range).
// To the rest of pinsim it is an ordinary LoadedPlugin, so check-plugin's checks, the
// reference comparison and whole simulations run in the grader, on numbers the submission
// computed in its sandbox. A worker that crashes, hangs, exits or breaks the protocol makes
// every later call fail fast with the reason (see failure()).
#pragma once

#include <memory>
#include <string>

#include "core/plugin_loader.hpp"
#include "grading/sandbox.hpp"
#include "grading/text.hpp"
#include "grading/wire.hpp"

namespace pinsim::grading {

/// What went wrong with the worker, for the grader's decisions.
enum class WorkerFault { None, TimedOut, Died, Protocol };

class RemoteWorker {
 public:
  /// Takes over a started worker; every call must finish before `deadline` (steady clock, s).
  RemoteWorker(Sandboxed process, SandboxLimits limits, double deadline, std::size_t output_limit);
  ~RemoteWorker();
  RemoteWorker(const RemoteWorker&) = delete;
  RemoteWorker& operator=(const RemoteWorker&) = delete;

  /// Opens the submission's plugin `name` of `kind` (PINSIM_KIND_*). The returned table
  /// forwards to this worker; only one worker may have open tables at a time. Throws
  /// std::runtime_error with the worker's message (no such plugin, wrong kind, bad ABI).
  std::shared_ptr<const LoadedPlugin> open(const std::string& name, uint32_t kind);

  /// One request. Returns the reply payload; throws PluginCallError with the plugin's own
  /// message, or WorkerGone when the worker is (now) unusable.
  std::string call(Op op, const std::string& payload, uint64_t max_reply);

  /// Starts a test: calls must finish before `deadline` (steady clock, s), the tables of
  /// this worker become the live ones, and the captured printing starts afresh.
  void begin_test(double deadline);
  /// Ends a test: what the submission printed during it (sanitized, bounded).
  std::string end_test();
  /// Bytes printed during the last ended test (all of them, shown or not).
  std::size_t printed_bytes() const { return last_printed_bytes_; }

  /// Asks the worker to quit, then kills whatever is left of the sandbox.
  void finish();

  WorkerFault fault() const { return fault_; }
  /// One line for the student ("" while the worker is healthy).
  const std::string& failure() const { return failure_; }
  /// The request that was running when the worker failed ("create", "add_force", ...).
  const std::string& failed_during() const { return failed_op_; }

 private:
  void fail(WorkerFault fault, const std::string& why, Op op);
  void drain_output();

  Sandboxed proc_;
  SandboxLimits limits_;
  double deadline_;
  std::size_t output_limit_;
  BoundedText printed_;
  std::size_t last_printed_bytes_ = 0;
  WorkerFault fault_ = WorkerFault::None;
  std::string failure_, failed_op_;
  struct Table;
  std::unique_ptr<Table> table_;
};

/// A call the plugin itself reported as failed (its error code and message).
class PluginCallError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};
/// The worker crashed, hung, exited or broke the protocol.
class WorkerGone : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// The request's name, for messages ("create", "add_force", ...).
const char* op_name(Op op);

}  // namespace pinsim::grading
