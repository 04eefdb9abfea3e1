// trajectory.h5: the run's trajectory in HDF5 (scene "output": {"format": "hdf5"}), for big
// runs. Layout (docs/running.md): /t [frames], /x, /y, /vx, /vy [frames x particles], all
// float64, chunked and extendible along the frames (deflate-compressed at the scene's
// output.compression level); /radius, /mass (inf where pinned) and /pinned (uint8)
// [particles]; root attributes scene, dt, units, particles, compression, frames_complete. Written
// frame by frame; after each frame the file is flushed (H5Fflush) and frames_complete updated, so a
// run killed at any point (kill -9) leaves a file that h5py, h5dump and pinsim read up to the last
// flushed frame. The HDF5 calls run on a writer thread: the step thread copies the state into one
// of two frame buffers and goes on (back-pressure: it waits when both are still queued), so memory
// stays at two frames whatever the run's length. The writer makes the same calls in the same
// order as a writer without a thread would: the file's bytes do not depend on timing.
#pragma once

#include <cstddef>
#include <cstdint>
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
  /// Creates (truncates) `file` for the particles of `initial`, whose radii, masses and
  /// pinned flags it writes once (/radius, /mass, /pinned); `scene_name` and `dt` become root
  /// attributes. `background`: write on a writer thread (see the file comment; inside write()
  /// if no thread can be started); false writes each frame inside write() (the same bytes;
  /// for benchmarks and tests). `compression`: the deflate level of the frame datasets, 0
  /// (none) to 9.
  Hdf5TrajectoryWriter(const std::filesystem::path& file, const State& initial,
                       const std::string& scene_name, double dt, bool background = true,
                       int compression = 0);
  /// Writes the frames still queued and closes the file (errors are dropped: call close()).
  ~Hdf5TrajectoryWriter();
  Hdf5TrajectoryWriter(const Hdf5TrajectoryWriter&) = delete;
  Hdf5TrajectoryWriter& operator=(const Hdf5TrajectoryWriter&) = delete;

  /// Appends one frame (s.t, s.x, s.v: the exact doubles), then flushes the file and sets
  /// frames_complete; in the background, queues a copy of it. Throws OutputError (in the
  /// background: the writer's failure on an earlier frame); later writes are then refused.
  void write(const State& s);
  /// Writes the queued frames, stops the writer thread and closes the file. Throws
  /// OutputError, also for a queued frame that failed. Does nothing once closed.
  void close();

  /// Frames handed to write() so far (written, or queued in the background).
  std::size_t frames() const { return frames_; }

 private:
  struct Handles;
  struct Queue;
  /// One frame as copied from the state: t, then x and v as State holds them (x0 y0 x1 ...).
  struct Frame {
    double t = 0.0;
    std::vector<double> xv;  ///< [4 x particles]: x columns, then v columns
  };
  void fill(Frame& f, const State& s) const;
  /// The HDF5 calls for frame number `written_`. Throws OutputError.
  void write_frame(const Frame& f);
  void writer_loop();
  void stop_writer();

  std::unique_ptr<Handles> h_;
  std::unique_ptr<Queue> q_;  ///< background writing only
  std::filesystem::path file_;
  [[maybe_unused]] std::size_t particles_ = 0;  // unused in a build without HDF5
  std::size_t frames_ = 0;                      ///< handed over
  std::size_t written_ = 0;                     ///< in the file (writer thread)
  std::vector<double> buf_;                     ///< one column of a frame (writer thread)
  std::unique_ptr<Frame> sync_frame_;
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
