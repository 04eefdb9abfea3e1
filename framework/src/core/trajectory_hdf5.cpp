#include "core/trajectory_hdf5.hpp"

#include <fcntl.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <condition_variable>
#include <cstring>
#include <deque>
#include <mutex>
#include <stdexcept>
#include <system_error>
#include <thread>

#include "core/output_file.hpp"

#if PINSIM_WITH_HDF5
#include <hdf5.h>
#endif

namespace fs = std::filesystem;

namespace pinsim {

#if PINSIM_WITH_HDF5

bool hdf5_supported() { return true; }

namespace {

constexpr const char* kColumns[] = {"x", "y", "vx", "vy"};

/// Closes an HDF5 handle with `close` when it goes out of scope.
struct Hid {
  hid_t id = -1;
  herr_t (*close)(hid_t) = nullptr;
  Hid() = default;
  Hid(hid_t i, herr_t (*c)(hid_t)) : id(i), close(c) {}
  Hid(const Hid&) = delete;
  Hid& operator=(const Hid&) = delete;
  Hid(Hid&& o) noexcept : id(o.id), close(o.close) { o.id = -1; }
  Hid& operator=(Hid&& o) noexcept {
    reset();
    id = o.id;
    close = o.close;
    o.id = -1;
    return *this;
  }
  ~Hid() { reset(); }
  void reset() {
    if (id >= 0 && close) close(id);
    id = -1;
  }
  operator hid_t() const { return id; }
};

/// Silences HDF5's own error stack printing for the handle's lifetime (errors become
/// exceptions that name the file).
struct QuietHdf5 {
  H5E_auto2_t func = nullptr;
  void* data = nullptr;
  QuietHdf5() {
    H5Eget_auto2(H5E_DEFAULT, &func, &data);
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  }
  ~QuietHdf5() { H5Eset_auto2(H5E_DEFAULT, func, data); }
  QuietHdf5(const QuietHdf5&) = delete;
  QuietHdf5& operator=(const QuietHdf5&) = delete;
};

void write_string_attr(hid_t obj, const char* name, const std::string& value) {
  Hid type(H5Tcopy(H5T_C_S1), H5Tclose);
  H5Tset_size(type, value.size() + 1);  // with the terminating NUL
  H5Tset_strpad(type, H5T_STR_NULLTERM);
  Hid space(H5Screate(H5S_SCALAR), H5Sclose);
  Hid attr(H5Acreate2(obj, name, type, space, H5P_DEFAULT, H5P_DEFAULT), H5Aclose);
  if (attr < 0 || H5Awrite(attr, type, value.c_str()) < 0)
    throw std::runtime_error(std::string("cannot write attribute ") + name);
}

template <class T>
void write_scalar_attr(hid_t obj, const char* name, hid_t type, T value) {
  Hid space(H5Screate(H5S_SCALAR), H5Sclose);
  Hid attr(H5Acreate2(obj, name, type, space, H5P_DEFAULT, H5P_DEFAULT), H5Aclose);
  if (attr < 0 || H5Awrite(attr, type, &value) < 0)
    throw std::runtime_error(std::string("cannot write attribute ") + name);
}

/// A contiguous 1D dataset of `n` values (stored as `file_type`, given as `mem_type`).
void write_vector(hid_t file, const char* name, hid_t file_type, hid_t mem_type, const void* data,
                  std::size_t n) {
  const hsize_t dims[1] = {n};
  Hid space(H5Screate_simple(1, dims, nullptr), H5Sclose);
  Hid dcpl(H5Pcreate(H5P_DATASET_CREATE), H5Pclose);
  if (H5Pset_obj_track_times(dcpl, false) < 0)
    throw std::runtime_error(std::string("dataset /") + name);
  Hid d(H5Dcreate2(file, name, file_type, space, H5P_DEFAULT, dcpl, H5P_DEFAULT), H5Dclose);
  if (d < 0 || (n > 0 && H5Dwrite(d, mem_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, data) < 0))
    throw std::runtime_error(std::string("cannot write dataset /") + name);
}

/// The system's reason for the innermost failure on this thread's HDF5 error stack (the
/// file driver records it as "... error message = 'File too large' ..."), or "".
std::string hdf5_system_error() {
  std::string reason;
  H5Ewalk2(
      H5E_DEFAULT, H5E_WALK_UPWARD,
      [](unsigned, const H5E_error2_t* e, void* data) -> herr_t {
        auto& out = *static_cast<std::string*>(data);
        const char* key = "error message = '";
        const char* at = e->desc ? std::strstr(e->desc, key) : nullptr;
        if (out.empty() && at) {
          at += std::strlen(key);
          const char* end = std::strchr(at, '\'');
          out.assign(at, end ? static_cast<std::size_t>(end - at) : std::strlen(at));
        }
        return 0;
      },
      &reason);
  return reason;
}

/// Tells HDF5, once and before its first call, not to close the files left open at exit:
/// HDF5 1.10 crashes there (H5F__close_cb) on a file whose close failed, and a file whose
/// writing failed is left open on purpose (Handles).
void hdf5_no_atexit() {
  static std::once_flag once;
  std::call_once(once, [] { H5dont_atexit(); });
}

struct Hdf5NoAtexit {
  Hdf5NoAtexit() { hdf5_no_atexit(); }
};

}  // namespace

struct Hdf5TrajectoryWriter::Handles {
  Hdf5NoAtexit no_atexit;
  QuietHdf5 quiet;
  Hid file, t, cols[4], frames_attr;
  bool failed = false;
  int fd = -1;              ///< the file's descriptor (sec2 driver), for the reservation
  hsize_t frame_bound = 0;  ///< most bytes one frame can add to the file
  hsize_t reserved = 0;     ///< disk blocks allocated up to here
  rlim_t fsize_limit = RLIM_INFINITY;
  /// After a failed write the handles are dropped, not closed: closing flushes metadata
  /// again (a B-tree node, the frames_complete of the failed frame) into a file that can
  /// no longer take it; left alone, the file is the one of the last successful H5Fflush.
  ~Handles() {
    if (!failed) return;
    file.id = t.id = frames_attr.id = -1;
    for (Hid& c : cols) c.id = -1;
  }
  Handles() = default;
  Handles(const Handles&) = delete;
  Handles& operator=(const Handles&) = delete;
};

/// Two frame buffers between the step thread and the writer thread.
struct Hdf5TrajectoryWriter::Queue {
  static constexpr int kBuffers = 2;
  std::mutex m;
  std::condition_variable cv;
  std::vector<std::unique_ptr<Frame>> free;  ///< to fill
  std::deque<std::unique_ptr<Frame>> ready;  ///< to write, oldest first
  bool stop = false;
  std::string error;  ///< the writer's first failure; it then writes nothing more
  bool error_reported = false;
  std::thread thread;
};

Hdf5TrajectoryWriter::Hdf5TrajectoryWriter(const fs::path& file, const State& initial,
                                           const std::string& scene_name, double dt,
                                           bool background, int compression)
    : h_(std::make_unique<Handles>()), file_(file), particles_(initial.size()) {
  auto fail = [&](const std::string& what) {
    h_.reset();
    throw OutputError(file_.string() + ": cannot create the HDF5 trajectory (" + what + ")");
  };
  // The earliest file format (superblock 0, version-1 B-trees): no "file open for write"
  // flag, so a killed run's file opens without h5clear. Metadata is written only by
  // H5Fflush (evictions off): between flushes the file on disk is the last flushed one.
  Hid fapl(H5Pcreate(H5P_FILE_ACCESS), H5Pclose);
  H5AC_cache_config_t mdc;
  mdc.version = H5AC__CURR_CACHE_CONFIG_VERSION;
  if (H5Pget_mdc_config(fapl, &mdc) < 0) fail("metadata cache settings");
  mdc.evictions_enabled = false;
  mdc.incr_mode = H5C_incr__off;
  mdc.flash_incr_mode = H5C_flash_incr__off;
  mdc.decr_mode = H5C_decr__off;
  if (H5Pset_mdc_config(fapl, &mdc) < 0) fail("metadata cache settings");
  h_->file = Hid(H5Fcreate(file.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, fapl), H5Fclose);
  if (h_->file < 0) fail("H5Fcreate failed");

  // [frames x particles], extendible along the frames. A chunk holds one frame of a
  // column (or several frames when there are few particles: chunks of >= 8 KB).
  const hsize_t n = particles_;
  const hsize_t rows = std::clamp<hsize_t>(1024 / std::max<hsize_t>(n, 1), 1, 1024);
  Hid dcpl(H5Pcreate(H5P_DATASET_CREATE), H5Pclose);
  const hsize_t dims[2] = {0, n}, maxdims[2] = {H5S_UNLIMITED, n > 0 ? n : H5S_UNLIMITED},
                chunk[2] = {rows, std::max<hsize_t>(n, 1)};
  Hid space(H5Screate_simple(2, dims, maxdims), H5Sclose);
  // No creation/modification times in the object headers: the same run, the same bytes.
  if (H5Pset_chunk(dcpl, 2, chunk) < 0 || H5Pset_obj_track_times(dcpl, false) < 0)
    fail("chunk layout");
  if (compression < 0 || compression > 9)
    fail("compression level " + std::to_string(compression) + " is not in 0 to 9");
  const bool deflate = compression > 0;
  if (deflate && H5Zfilter_avail(H5Z_FILTER_DEFLATE) <= 0)
    fail("this HDF5 library has no deflate filter for output.compression");
  if (deflate && H5Pset_deflate(dcpl, static_cast<unsigned>(compression)) < 0)
    fail("deflate filter");
  // A frame that fills whole chunks (rows == 1) goes straight to the file: no chunk cache,
  // so no copy into it and no second pass at H5Fflush.
  Hid dapl(H5Pcreate(H5P_DATASET_ACCESS), H5Pclose);
  if (rows == 1 && H5Pset_chunk_cache(dapl, 0, 0, H5D_CHUNK_CACHE_W0_DEFAULT) < 0)
    fail("chunk cache");
  for (int c = 0; c < 4; ++c) {
    h_->cols[c] =
        Hid(H5Dcreate2(h_->file, kColumns[c], H5T_IEEE_F64LE, space, H5P_DEFAULT, dcpl, dapl),
            H5Dclose);
    if (h_->cols[c] < 0) fail(std::string("dataset /") + kColumns[c]);
  }
  const hsize_t tdims[1] = {0}, tmax[1] = {H5S_UNLIMITED}, tchunk[1] = {1024};
  Hid tspace(H5Screate_simple(1, tdims, tmax), H5Sclose);
  Hid tdcpl(H5Pcreate(H5P_DATASET_CREATE), H5Pclose);
  if (H5Pset_chunk(tdcpl, 1, tchunk) < 0 || H5Pset_obj_track_times(tdcpl, false) < 0 ||
      (deflate && H5Pset_deflate(tdcpl, static_cast<unsigned>(compression)) < 0))
    fail("chunk layout");
  h_->t = Hid(H5Dcreate2(h_->file, "t", H5T_IEEE_F64LE, tspace, H5P_DEFAULT, tdcpl, H5P_DEFAULT),
              H5Dclose);
  if (h_->t < 0) fail("dataset /t");
  // The particles' constant properties, once: radius, mass (+inf where pinned), pinned.
  try {
    std::vector<double> mass(particles_);
    std::vector<uint8_t> pinned(particles_);
    for (std::size_t i = 0; i < particles_; ++i) {
      const double w = initial.inv_mass[static_cast<Eigen::Index>(i)];
      pinned[i] = w > 0.0 ? 0 : 1;
      mass[i] = w > 0.0 ? 1.0 / w : HUGE_VAL;
    }
    write_vector(h_->file, "radius", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, initial.radius.data(),
                 particles_);
    write_vector(h_->file, "mass", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, mass.data(), particles_);
    write_vector(h_->file, "pinned", H5T_STD_U8LE, H5T_NATIVE_UINT8, pinned.data(), particles_);
  } catch (const std::exception& e) {
    fail(e.what());
  }
  try {
    write_string_attr(h_->file, "format", "pinsim trajectory 1");
    write_string_attr(h_->file, "scene", scene_name);
    write_scalar_attr(h_->file, "dt", H5T_NATIVE_DOUBLE, dt);
    write_string_attr(h_->file, "units", "t: s; x, y, radius: m; vx, vy: m/s; mass: kg");
    write_string_attr(h_->file, "layout",
                      "/t [frames]; /x, /y, /vx, /vy [frames x particles], float64; read the "
                      "first frames_complete frames; /radius, /mass (inf where pinned) float64 "
                      "and /pinned uint8 [particles]");
    write_scalar_attr(h_->file, "compression", H5T_NATIVE_UINT64,
                      static_cast<uint64_t>(compression));
    write_scalar_attr(h_->file, "particles", H5T_NATIVE_UINT64, static_cast<uint64_t>(n));
    write_scalar_attr(h_->file, "frames_complete", H5T_NATIVE_UINT64, uint64_t{0});
  } catch (const std::exception& e) {
    fail(e.what());
  }
  h_->frames_attr = Hid(H5Aopen(h_->file, "frames_complete", H5P_DEFAULT), H5Aclose);
  if (h_->frames_attr < 0 || H5Fflush(h_->file, H5F_SCOPE_LOCAL) < 0) fail("H5Fflush failed");
  buf_.resize(particles_);
  // A frame adds at most: a new chunk of each column, a new /t chunk, B-tree nodes and
  // object header room (generously 256 KB).
  h_->frame_bound = 4 * chunk[0] * chunk[1] * sizeof(double) + tchunk[0] * sizeof(double) + 262144;
  void* fd = nullptr;
  if (H5Fget_vfd_handle(h_->file, H5P_DEFAULT, &fd) >= 0 && fd) h_->fd = *static_cast<int*>(fd);
  rlimit lim{};
  if (getrlimit(RLIMIT_FSIZE, &lim) == 0) h_->fsize_limit = lim.rlim_cur;
  auto frame = [&] {
    auto f = std::make_unique<Frame>();
    f->xv.resize(4 * particles_);
    return f;
  };
  if (background) {
    q_ = std::make_unique<Queue>();
    for (int i = 0; i < Queue::kBuffers; ++i) q_->free.push_back(frame());
    try {
      q_->thread = std::thread([this] { writer_loop(); });
      return;
    } catch (const std::system_error&) {
      q_.reset();  // no thread to be had (a process limit): write in the step's thread
    }
  }
  sync_frame_ = frame();
}

Hdf5TrajectoryWriter::~Hdf5TrajectoryWriter() { stop_writer(); }

void Hdf5TrajectoryWriter::fill(Frame& f, const State& s) const {
  f.t = s.t;
  const std::size_t n2 = 2 * particles_;
  if (n2 == 0) return;
  std::memcpy(f.xv.data(), s.x.data(), n2 * sizeof(double));
  std::memcpy(f.xv.data() + n2, s.v.data(), n2 * sizeof(double));
}

void Hdf5TrajectoryWriter::write(const State& s) {
  // (h_->failed belongs to the writer thread in the background: its failure is q_->error.)
  if (!h_ || (!q_ && h_->failed))
    throw OutputError(file_.string() + ": cannot write (an earlier write failed)");
  if (s.size() != particles_)
    throw OutputError(file_.string() + ": the particle count changed during the run");
  if (!q_) {
    fill(*sync_frame_, s);
    write_frame(*sync_frame_);
    ++frames_;
    return;
  }
  // A free buffer (waiting while the writer holds both), filled outside the lock.
  std::unique_ptr<Frame> f;
  {
    std::unique_lock lock(q_->m);
    q_->cv.wait(lock, [&] { return !q_->free.empty() || !q_->error.empty(); });
    if (!q_->error.empty()) {
      q_->error_reported = true;
      throw OutputError(q_->error);
    }
    f = std::move(q_->free.back());
    q_->free.pop_back();
  }
  fill(*f, s);
  {
    std::lock_guard lock(q_->m);
    q_->ready.push_back(std::move(f));
  }
  q_->cv.notify_all();
  ++frames_;
}

void Hdf5TrajectoryWriter::writer_loop() {
  QuietHdf5 quiet;  // per thread in a thread-safe HDF5
  for (;;) {
    std::unique_ptr<Frame> f;
    {
      std::unique_lock lock(q_->m);
      q_->cv.wait(lock, [&] { return !q_->ready.empty() || q_->stop; });
      if (q_->ready.empty()) return;  // stopped, and every frame written
      f = std::move(q_->ready.front());
      q_->ready.pop_front();
    }
    std::string error;
    if (!h_->failed) {
      try {
        write_frame(*f);
      } catch (const std::exception& e) {  // OutputError, or no memory for its message
        h_->failed = true;                 // no frame after a missing one
        error = e.what();
      }
    }
    {
      std::lock_guard lock(q_->m);
      if (!error.empty() && q_->error.empty()) q_->error = error;
      q_->free.push_back(std::move(f));
    }
    q_->cv.notify_all();
  }
}

void Hdf5TrajectoryWriter::stop_writer() {
  if (!q_ || !q_->thread.joinable()) return;
  {
    std::lock_guard lock(q_->m);
    q_->stop = true;
  }
  q_->cv.notify_all();
  q_->thread.join();
}

void Hdf5TrajectoryWriter::write_frame(const Frame& fr) {
  auto fail = [&](const std::string& what) {
    h_->failed = true;
    const std::string reason = hdf5_system_error();
    throw OutputError(file_.string() + ": cannot write frame " + std::to_string(written_) + " (" +
                      what + (reason.empty() ? "" : ": " + reason) + ")");
  };
  // 0. Room for the frame first. HDF5 goes on flushing metadata after a failed write
  // (the superblock then names an end of file the file never reached, and no reader opens
  // it), so a full disk or a file-size limit must stop the frame before its first write:
  // the file stays the last flushed one. The limit is checked, the disk blocks allocated
  // (fallocate, the file's size unchanged; where the file system cannot, nothing).
  {
    hsize_t end = 0;
    if (H5Fget_filesize(h_->file, &end) < 0) fail("H5Fget_filesize");
    const hsize_t need = end + h_->frame_bound;
    if (h_->fsize_limit != RLIM_INFINITY && need > h_->fsize_limit) fail(std::strerror(EFBIG));
    if (h_->fd >= 0 && need > h_->reserved) {
      // In steps of 16 frames (at least 4 MB), or just this frame's room if that fails.
      const hsize_t ahead = std::max<hsize_t>(16 * h_->frame_bound, 4u << 20);
      int r = fallocate(h_->fd, FALLOC_FL_KEEP_SIZE, static_cast<off_t>(end),
                        static_cast<off_t>(ahead));
      if (r == 0) {
        h_->reserved = end + ahead;
      } else if (errno == EOPNOTSUPP || errno == ENOSYS) {
        h_->fd = -1;  // no reservation on this file system
      } else {
        r = fallocate(h_->fd, FALLOC_FL_KEEP_SIZE, static_cast<off_t>(end),
                      static_cast<off_t>(h_->frame_bound));
        if (r != 0) fail(std::strerror(errno));
        h_->reserved = need;
      }
    }
  }
  const hsize_t f = written_, n = particles_;
  // 1. the columns, 2. /t, 3. frames_complete, 4. flush: a reader of the flushed file
  // trusts the first frames_complete frames (and never more than each dataset holds).
  const hsize_t dims[2] = {f + 1, n}, start[2] = {f, 0}, count[2] = {1, n};
  Hid mem(H5Screate_simple(1, &count[1], nullptr), H5Sclose);
  for (int c = 0; c < 4; ++c) {
    const double* src = fr.xv.data() + (c < 2 ? 0 : 2 * particles_) + (c & 1);
    for (std::size_t i = 0; i < particles_; ++i) buf_[i] = src[2 * i];
    if (H5Dset_extent(h_->cols[c], dims) < 0) fail("H5Dset_extent");
    if (n == 0) continue;
    Hid fspace(H5Dget_space(h_->cols[c]), H5Sclose);
    if (fspace < 0 ||
        H5Sselect_hyperslab(fspace, H5S_SELECT_SET, start, nullptr, count, nullptr) < 0 ||
        H5Dwrite(h_->cols[c], H5T_NATIVE_DOUBLE, mem, fspace, H5P_DEFAULT, buf_.data()) < 0)
      fail("H5Dwrite");
  }
  const hsize_t tdims[1] = {f + 1}, one[1] = {1};
  if (H5Dset_extent(h_->t, tdims) < 0) fail("H5Dset_extent");
  Hid tspace(H5Dget_space(h_->t), H5Sclose);
  Hid tmem(H5Screate_simple(1, one, nullptr), H5Sclose);
  if (tspace < 0 ||
      H5Sselect_hyperslab(tspace, H5S_SELECT_SET, &start[0], nullptr, one, nullptr) < 0 ||
      H5Dwrite(h_->t, H5T_NATIVE_DOUBLE, tmem, tspace, H5P_DEFAULT, &fr.t) < 0)
    fail("H5Dwrite");
  const uint64_t complete = f + 1;
  if (H5Awrite(h_->frames_attr, H5T_NATIVE_UINT64, &complete) < 0) fail("frames_complete");
  if (H5Fflush(h_->file, H5F_SCOPE_LOCAL) < 0) fail("H5Fflush");
  ++written_;
}

void Hdf5TrajectoryWriter::close() {
  if (!h_) return;
  stop_writer();
  std::string queued_error;
  if (q_ && !q_->error.empty() && !q_->error_reported) queued_error = q_->error;
  q_.reset();
  const bool failed = h_->failed;
  herr_t r = 0;
  if (!failed) {
    h_->frames_attr.reset();
    h_->t.reset();
    for (auto& c : h_->cols) c.reset();
    r = h_->file >= 0 ? H5Fclose(h_->file) : 0;
    h_->file.id = -1;
    // Gives back the disk blocks reserved past the end (truncating to the same size).
    std::error_code ec;
    const auto size = fs::file_size(file_, ec);
    if (r >= 0 && !ec && h_->reserved > size)
      (void)::truncate(file_.c_str(), static_cast<off_t>(size));
  }
  h_.reset();
  if (!queued_error.empty()) throw OutputError(queued_error);
  if (r < 0 && !failed) throw OutputError(file_.string() + ": cannot close (H5Fclose failed)");
}

Hdf5Trajectory read_hdf5_trajectory(const fs::path& file) {
  hdf5_no_atexit();
  QuietHdf5 quiet;
  auto fail = [&](const std::string& what) -> void {
    throw std::runtime_error(file.string() + ": " + what);
  };
  Hid f(H5Fopen(file.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
  if (f < 0) fail("cannot open as HDF5");
  uint64_t complete = 0;
  {
    Hid a(H5Aopen(f, "frames_complete", H5P_DEFAULT), H5Aclose);
    if (a < 0 || H5Aread(a, H5T_NATIVE_UINT64, &complete) < 0)
      fail("no frames_complete attribute (not a pinsim trajectory)");
  }
  Hdf5Trajectory out;
  auto open = [&](const char* name, int rank, hsize_t* dims) {
    Hid d(H5Dopen2(f, name, H5P_DEFAULT), H5Dclose);
    if (d < 0) fail(std::string("no dataset /") + name);
    Hid sp(H5Dget_space(d), H5Sclose);
    if (H5Sget_simple_extent_ndims(sp) != rank)
      fail(std::string("/") + name + " has rank " + std::to_string(H5Sget_simple_extent_ndims(sp)) +
           ", expected " + std::to_string(rank));
    H5Sget_simple_extent_dims(sp, dims, nullptr);
    return d;
  };
  hsize_t tdims[1] = {0};
  Hid t = open("t", 1, tdims);
  hsize_t frames = std::min<hsize_t>(complete, tdims[0]);
  Hid cols[4];
  hsize_t n = 0;
  for (int c = 0; c < 4; ++c) {
    hsize_t d[2] = {0, 0};
    cols[c] = open(kColumns[c], 2, d);
    if (c > 0 && d[1] != n) fail(std::string("/") + kColumns[c] + " has another particle count");
    n = d[1];
    frames = std::min(frames, d[0]);
  }
  out.particles = n;
  auto read = [&](hid_t d, std::vector<double>& v, int rank, const hsize_t* count) {
    v.resize(rank == 1 ? count[0] : count[0] * count[1]);
    if (v.empty()) return;
    const hsize_t start[2] = {0, 0};
    Hid fs(H5Dget_space(d), H5Sclose);
    Hid ms(H5Screate_simple(rank, count, nullptr), H5Sclose);
    if (H5Sselect_hyperslab(fs, H5S_SELECT_SET, start, nullptr, count, nullptr) < 0 ||
        H5Dread(d, H5T_NATIVE_DOUBLE, ms, fs, H5P_DEFAULT, v.data()) < 0)
      fail("cannot read the first " + std::to_string(frames) + " frames");
  };
  const hsize_t tc[1] = {frames}, cc[2] = {frames, n};
  read(t, out.t, 1, tc);
  read(cols[0], out.x, 2, cc);
  read(cols[1], out.y, 2, cc);
  read(cols[2], out.vx, 2, cc);
  read(cols[3], out.vy, 2, cc);
  return out;
}

#else  // !PINSIM_WITH_HDF5

bool hdf5_supported() { return false; }

struct Hdf5TrajectoryWriter::Handles {};
struct Hdf5TrajectoryWriter::Queue {};

Hdf5TrajectoryWriter::Hdf5TrajectoryWriter(const fs::path& file, const State& initial,
                                           const std::string&, double, bool, int)
    : file_(file), particles_(initial.size()) {
  throw OutputError(file.string() + ": this pinsim was built without HDF5 (PINSIM_WITH_HDF5=OFF)");
}
Hdf5TrajectoryWriter::~Hdf5TrajectoryWriter() = default;
void Hdf5TrajectoryWriter::write(const State&) {}
void Hdf5TrajectoryWriter::close() {}

Hdf5Trajectory read_hdf5_trajectory(const fs::path& file) {
  throw std::runtime_error(file.string() +
                           ": this pinsim was built without HDF5 (PINSIM_WITH_HDF5=OFF)");
}

#endif

}  // namespace pinsim
