// trajectory.h5: the run's trajectory in HDF5 (scene "output": {"format": "hdf5"}), for big
// runs. Layout (README "Run output"): /t [frames], /x, /y, /vx, /vy [frames x particles],
// all float64, chunked and extendible along the frames; root attributes scene, dt, units,
// particles, frames_complete. Written frame by frame; after each frame the file is flushed
// (H5Fflush) and frames_complete updated, so a run killed at any point (kill -9) leaves a
// file that h5py, h5dump and pinsim read up to the last flushed frame.
#pragma once

#include <cstddef>
#include <filesystem>
#include <memory>
#include <pinsim/state.hpp>
#include <string>
#include <vector>

namespace pinsim {

/// True if this build writes and reads HDF5 (CMake option PINSIM_WITH_HDF5).
bool hdf5_supported();

/// Writes trajectory.h5 frame by frame. Every HDF5 failure is an OutputError naming the file.
class Hdf5TrajectoryWriter {
 public:
  /// Creates (truncates) `file` for `particles` particles; `scene_name` and `dt` become
  /// root attributes.
  Hdf5TrajectoryWriter(const std::filesystem::path& file, std::size_t particles,
                       const std::string& scene_name, double dt);
  ~Hdf5TrajectoryWriter();
  Hdf5TrajectoryWriter(const Hdf5TrajectoryWriter&) = delete;
  Hdf5TrajectoryWriter& operator=(const Hdf5TrajectoryWriter&) = delete;

  /// Appends one frame (s.t, s.x, s.v: the exact doubles), then flushes the file and sets
  /// frames_complete. Throws OutputError; later writes are then refused.
  void write(const State& s);
  /// Closes the file. Throws OutputError. Does nothing once closed.
  void close();

  std::size_t frames() const { return frames_; }

 private:
  struct Handles;
  std::unique_ptr<Handles> h_;
  std::filesystem::path file_;
  [[maybe_unused]] std::size_t particles_ = 0;  // unused in a build without HDF5
  std::size_t frames_ = 0;
  std::vector<double> buf_;
};

/// A trajectory.h5 read back: the first frames_complete frames.
struct Hdf5Trajectory {
  std::size_t particles = 0;
  std::vector<double> t;             ///< [frames]
  std::vector<double> x, y, vx, vy;  ///< [frames x particles], row-major
  std::size_t frames() const { return t.size(); }
};

/// Reads `file`. Throws std::runtime_error naming the file and what is wrong.
Hdf5Trajectory read_hdf5_trajectory(const std::filesystem::path& file);

}  // namespace pinsim
