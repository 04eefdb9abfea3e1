// Run output: trajectory.csv, events.csv, contacts.csv, summary.json and scene.json, written
// incrementally so that a failed or interrupted run leaves valid files.
#pragma once

#include <pinsim/abi.h>

#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>
#include <pinsim/state.hpp>
#include <string>
#include <vector>

#include "core/contact_tracker.hpp"
#include "core/output_file.hpp"
#include "core/scene.hpp"
#include "core/trajectory_hdf5.hpp"

namespace pinsim {

/// The files pinsim writes into a run folder (`run`, and `render` / `replay` by default):
/// what `--overwrite` removes before a run, with the temporaries of these names
/// (NAME.tmp.PID, NAME.crash.PID). Nothing else in the folder is touched.
extern const char* const kRunFolderFiles[8];

class Recorder {
 public:
  /// Creates `dir` (and parents) and opens the files. Refuses to replace an earlier run's
  /// files unless `overwrite`; with it, first removes the files of kRunFolderFiles (so no
  /// picture or page of the earlier run stays beside the new files). Throws
  /// std::runtime_error naming the folder, or OutputError naming a file.
  /// `hdf5_background`: trajectory.h5 frames are written on a writer thread (the same bytes
  /// either way; false for benchmarks comparing the two).
  Recorder(const std::filesystem::path& dir, const Scene& scene, bool overwrite,
           bool hdf5_background = true);
  Recorder(const Recorder&) = delete;
  Recorder& operator=(const Recorder&) = delete;

  /// One row per particle: t,particle,x,y,vx,vy. Whole lines only; throws OutputError (the
  /// file then ends with its last whole line). With output.format "hdf5", one frame of
  /// trajectory.h5 instead (Hdf5TrajectoryWriter: a copy handed to its writer thread; its
  /// failure is thrown by a later write_state or by close()).
  void write_state(const State& s);
  /// The impulses of step `step`; call it for every step, with or without impulses. By the
  /// scene's output.events: "all" writes one events.csv row per impulse; "impacts" one per
  /// impulse that begins a touch (ContactTracker) and one contacts.csv row per touch when it
  /// ends; "none" nothing. As write_state.
  void write_events(const std::vector<pinsim_event>& events, uint64_t step);
  /// Writes summary.json atomically (temporary file, then rename). Throws OutputError.
  void write_summary(const nlohmann::json& summary);
  /// Writes the touches still open (marked open, their end the last impulse's time), writes
  /// the trajectory.h5 frames still queued and closes trajectory.csv or .h5, events.csv and
  /// contacts.csv, checking the closes. Throws OutputError.
  void close();

  const std::filesystem::path& dir() const { return dir_; }
  uint64_t contacts() const { return contacts_; }
  /// Rows written to events.csv and contacts.csv so far.
  uint64_t event_rows() const { return event_rows_; }
  uint64_t contact_rows() const { return contact_rows_; }

 private:
  void flush_buffer(LineFile& f);
  void append_event(const pinsim_event& e);
  void write_spans();

  std::filesystem::path dir_;
  const Scene& scene_;
  std::unique_ptr<LineFile> traj_;
  std::unique_ptr<Hdf5TrajectoryWriter> traj_h5_;  ///< instead of traj_ for "hdf5"
  std::unique_ptr<LineFile> events_;
  std::unique_ptr<LineFile> spans_;  ///< contacts.csv ("impacts" only)
  std::string buf_;
  uint64_t contacts_ = 0;
  uint64_t event_rows_ = 0, contact_rows_ = 0;
  std::string mode_;                      ///< the scene's output.events
  std::vector<std::string> obstacle_id_;  ///< index -> id, built once
  std::unique_ptr<ContactTracker> tracker_;
  std::vector<pinsim_event> impacts_;  ///< scratch, reused every step
  std::vector<ContactSpan> closed_;    ///< scratch, reused every step
};

/// Removes the files of kRunFolderFiles (and their temporaries) from `dir`. Throws
/// std::runtime_error naming a file that cannot be removed.
void remove_run_outputs(const std::filesystem::path& dir);

/// Appends a double in its shortest exact decimal form.
void append_number(std::string& out, double v);

}  // namespace pinsim
