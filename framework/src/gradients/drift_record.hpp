// The host's side of a backend's record_drift (ABI 4.3): what the backend reports of each
// drift (pinsim_drift_sink), gathered into the DriftTape the adjoint reads.
#pragma once

#include <pinsim/abi.h>

#include "core/plugin_instance.hpp"
#include "gradients/drift_tape.hpp"

namespace pinsim::grad {

/// Records the drifts of `backend` while it lives: each advance() fills the tape set by
/// into(). Stops the recording when destroyed.
class DriftRecording {
 public:
  explicit DriftRecording(BackendInstance& backend);
  ~DriftRecording();
  DriftRecording(const DriftRecording&) = delete;
  DriftRecording& operator=(const DriftRecording&) = delete;

  /// The next drift goes into `tape` (cleared when the drift begins).
  void into(DriftTape* tape) {
    tape_ = tape;
    began_ = false;
  }
  /// Whether a drift was recorded into the tape since into().
  bool began() const { return began_; }

 private:
  static void on_begin(void* self, const pinsim_state_view* s, double dt);
  static void on_pair(void* self, const pinsim_drift_pair* h);
  static void on_impact(void* self, const pinsim_drift_impact* m);
  static void on_finding(void* self, const pinsim_drift_finding* f);

  BackendInstance& backend_;
  pinsim_drift_sink sink_{};
  DriftTape* tape_ = nullptr;
  bool began_ = false;
};

}  // namespace pinsim::grad
