#include "core/recorder.hpp"

#include <charconv>
#include <stdexcept>
#include <string_view>
#include <system_error>

namespace fs = std::filesystem;

namespace pinsim {

const char* const kRunFolderFiles[8] = {"trajectory.csv", "events.csv",   "contacts.csv",
                                        "summary.json",   "scene.json",   "picture.png",
                                        "replay.html",    "trajectory.h5"};

namespace {
/// NAME, NAME.tmp.PID or NAME.crash.PID for a NAME of kRunFolderFiles.
bool written_by_pinsim(const std::string& name) {
  for (const char* f : kRunFolderFiles) {
    const std::string_view n(f);
    if (name == n) return true;
    if (name.size() > n.size() && name.compare(0, n.size(), n) == 0 &&
        (name.compare(n.size(), 5, ".tmp.") == 0 || name.compare(n.size(), 7, ".crash.") == 0))
      return true;
  }
  return false;
}
}  // namespace

void remove_run_outputs(const fs::path& dir) {
  std::vector<fs::path> ours;
  std::error_code ec;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    std::error_code type_ec;
    if (written_by_pinsim(it->path().filename().string()) && !it->is_directory(type_ec))
      ours.push_back(it->path());
  }
  if (ec)
    throw std::runtime_error(dir.string() + ": cannot list the output folder (" + ec.message() +
                             ")");
  for (const fs::path& p : ours) {
    fs::remove(p, ec);
    if (ec)
      throw std::runtime_error(p.string() + ": cannot remove the earlier run's file (" +
                               ec.message() + ")");
  }
}

void append_number(std::string& out, double v) {
  char buf[32];
  auto r = std::to_chars(buf, buf + sizeof buf, v);
  out.append(buf, r.ptr);
}

namespace {
void append_int(std::string& out, long long v) {
  char buf[24];
  auto r = std::to_chars(buf, buf + sizeof buf, v);
  out.append(buf, r.ptr);
}

}  // namespace

Recorder::Recorder(const fs::path& dir, const Scene& scene, bool overwrite, bool hdf5_background)
    : dir_(dir), scene_(scene), mode_(scene.output_events) {
  std::error_code ec;
  if (fs::exists(dir_, ec) && !fs::is_directory(dir_, ec))
    throw std::runtime_error(dir_.string() + ": output folder is a file");
  fs::create_directories(dir_, ec);
  if (ec)
    throw std::runtime_error(dir_.string() + ": cannot create output folder (" + ec.message() +
                             ")");
  if (!overwrite) {
    for (const char* f : {"trajectory.csv", "trajectory.h5", "events.csv", "summary.json"})
      if (fs::exists(dir_ / f, ec))
        throw std::runtime_error(dir_.string() + ": holds an earlier run (" + f +
                                 "); choose another --out or pass --overwrite");
  } else {
    remove_run_outputs(dir_);
  }
  // The scene exactly as run (after --set overrides; the embedded one too), so that render,
  // replay and a rerun need nothing else from the run folder.
  // Indented for reading, unless indentation would dwarf the content: it grows with the
  // square of the nesting depth (a 40 KB scene nested 250 deep is 10 MB indented).
  const std::string compact = scene.doc.dump();
  std::string text = scene.doc.dump(2);
  if (text.size() > 4 * compact.size() + 4096) text = compact;
  write_file_atomically(dir_ / "scene.json", text + "\n");
  if (scene.output_format == "hdf5")
    traj_h5_ = std::make_unique<Hdf5TrajectoryWriter>(dir_ / "trajectory.h5", scene.initial_state(),
                                                      scene.name, scene.dt, hdf5_background,
                                                      scene.output_compression);
  else
    traj_ = std::make_unique<LineFile>(dir_ / "trajectory.csv", "t,particle,x,y,vx,vy\n");
  events_ = std::make_unique<LineFile>(
      dir_ / "events.csv", "t,particle,obstacle,other_particle,x,y,nx,ny,vn_before,vn_after\n");
  if (mode_ == "impacts") {
    spans_ = std::make_unique<LineFile>(
        dir_ / "contacts.csv",
        "t_begin,t_end,particle,obstacle,other_particle,impulses,impulse,open\n");
    tracker_ = std::make_unique<ContactTracker>(scene.particles.inv_mass);
  }
  // Obstacle ids once: looking them up per event in the scene's JSON cost most of a run's
  // time when events are many.
  const std::size_t n_obstacles = scene.backend_scene.is_object() &&
                                          scene.backend_scene.contains("obstacles") &&
                                          scene.backend_scene["obstacles"].is_array()
                                      ? scene.backend_scene["obstacles"].size()
                                      : 0;
  obstacle_id_.reserve(n_obstacles);
  for (std::size_t k = 0; k < n_obstacles; ++k)
    obstacle_id_.push_back(scene.obstacle_id(static_cast<int64_t>(k)));
}

void Recorder::close() {
  if (tracker_) {
    tracker_->close_all(closed_);
    write_spans();
  }
  if (traj_h5_) traj_h5_->close();
  if (traj_) traj_->close();
  events_->close();
  if (spans_) spans_->close();
}

void Recorder::flush_buffer(LineFile& f) {
  if (buf_.empty()) return;
  try {
    f.append(buf_);
  } catch (const OutputError&) {
    buf_.clear();
    throw;
  }
  buf_.clear();
}

void Recorder::write_state(const State& s) {
  if (traj_h5_) return traj_h5_->write(s);
  for (std::size_t i = 0; i < s.size(); ++i) {
    const auto c = static_cast<Eigen::Index>(i);
    append_number(buf_, s.t);
    buf_ += ',';
    append_int(buf_, static_cast<long long>(i));
    for (double v : {s.x(0, c), s.x(1, c), s.v(0, c), s.v(1, c)}) {
      buf_ += ',';
      append_number(buf_, v);
    }
    buf_ += '\n';
  }
  flush_buffer(*traj_);
}

void Recorder::append_event(const pinsim_event& e) {
  append_number(buf_, e.t);
  buf_ += ',';
  append_int(buf_, e.particle);
  buf_ += ',';
  if (e.obstacle >= 0) {
    const auto k = static_cast<std::size_t>(e.obstacle);
    if (k < obstacle_id_.size()) buf_ += obstacle_id_[k];
  }
  buf_ += ',';
  if (e.other >= 0) append_int(buf_, e.other);
  for (double v : {e.point[0], e.point[1], e.normal[0], e.normal[1], e.vn_before, e.vn_after}) {
    buf_ += ',';
    append_number(buf_, v);
  }
  buf_ += '\n';
}

void Recorder::write_spans() {
  for (const ContactSpan& c : closed_) {
    append_number(buf_, c.t_begin);
    buf_ += ',';
    append_number(buf_, c.t_end);
    buf_ += ',';
    append_int(buf_, c.particle);
    buf_ += ',';
    if (c.obstacle >= 0) {
      const auto k = static_cast<std::size_t>(c.obstacle);
      if (k < obstacle_id_.size()) buf_ += obstacle_id_[k];
    }
    buf_ += ',';
    if (c.other >= 0) append_int(buf_, c.other);
    buf_ += ',';
    append_int(buf_, static_cast<long long>(c.impulses));
    buf_ += ',';
    append_number(buf_, c.impulse);
    buf_ += c.open ? ",1\n" : ",0\n";
  }
  contact_rows_ += closed_.size();
  closed_.clear();
  flush_buffer(*spans_);
}

void Recorder::write_events(const std::vector<pinsim_event>& events, uint64_t step) {
  contacts_ += events.size();
  if (mode_ == "all") {
    if (events.empty()) return;
    for (const auto& e : events) append_event(e);
    event_rows_ += events.size();
    flush_buffer(*events_);
  } else if (tracker_) {
    if (events.empty() && tracker_->open() == 0) return;
    impacts_.clear();
    tracker_->step(step, events, impacts_, closed_);
    if (!impacts_.empty()) {
      for (const auto& e : impacts_) append_event(e);
      event_rows_ += impacts_.size();
      flush_buffer(*events_);
    }
    if (!closed_.empty()) write_spans();
  }
}

void Recorder::write_summary(const nlohmann::json& summary) {
  write_file_atomically(dir_ / "summary.json", summary.dump(2) + "\n");
}

}  // namespace pinsim
