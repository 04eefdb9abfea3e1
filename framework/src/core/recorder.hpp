// Run output: trajectory.csv, events.csv and summary.json, written incrementally so that a
// failed or interrupted run leaves valid files.
#pragma once

#include <pinsim/abi.h>

#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <pinsim/state.hpp>
#include <string>
#include <vector>

#include "core/scene.hpp"

namespace pinsim {

class Recorder {
 public:
  /// Creates `dir` (and parents) and opens the files. Refuses to replace an earlier run's
  /// files unless `overwrite`. Throws std::runtime_error naming the folder.
  Recorder(const std::filesystem::path& dir, const Scene& scene, bool overwrite);
  ~Recorder();
  Recorder(const Recorder&) = delete;
  Recorder& operator=(const Recorder&) = delete;

  /// One row per particle: t,particle,x,y,vx,vy. Complete lines only, flushed.
  void write_state(const State& s);
  /// One row per contact.
  void write_events(const std::vector<pinsim_event>& events);
  /// Writes summary.json atomically (temporary file, then rename).
  void write_summary(const nlohmann::json& summary);

  const std::filesystem::path& dir() const { return dir_; }
  uint64_t contacts() const { return contacts_; }

 private:
  void flush_buffer(std::FILE* f, std::string& buf);

  std::filesystem::path dir_;
  const Scene& scene_;
  std::FILE* traj_ = nullptr;
  std::FILE* events_ = nullptr;
  std::string buf_;
  uint64_t contacts_ = 0;
};

/// Appends a double in its shortest exact decimal form.
void append_number(std::string& out, double v);

}  // namespace pinsim
