#include "core/recorder.hpp"

#include <charconv>
#include <fstream>
#include <stdexcept>
#include <system_error>

namespace fs = std::filesystem;

namespace pinsim {

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

std::FILE* open_file(const fs::path& p, const char* header) {
  std::FILE* f = std::fopen(p.c_str(), "w");
  if (f == nullptr)
    throw std::runtime_error(p.string() + ": cannot write output file (" +
                             std::error_code(errno, std::generic_category()).message() + ")");
  std::fputs(header, f);
  std::fflush(f);
  return f;
}
}  // namespace

Recorder::Recorder(const fs::path& dir, const Scene& scene, bool overwrite)
    : dir_(dir), scene_(scene) {
  std::error_code ec;
  if (fs::exists(dir_, ec) && !fs::is_directory(dir_, ec))
    throw std::runtime_error(dir_.string() + ": output folder is a file");
  fs::create_directories(dir_, ec);
  if (ec)
    throw std::runtime_error(dir_.string() + ": cannot create output folder (" + ec.message() +
                             ")");
  if (!overwrite) {
    for (const char* f : {"trajectory.csv", "events.csv", "summary.json"})
      if (fs::exists(dir_ / f, ec))
        throw std::runtime_error(dir_.string() + ": holds an earlier run (" + f +
                                 "); choose another --out or pass --overwrite");
  }
  // The scene exactly as run (after --set overrides; the embedded one too), so that render,
  // replay and a rerun need nothing else from the run folder.
  {
    std::ofstream out(dir_ / "scene.json");
    out << scene.doc.dump(2) << "\n";
    if (!out) throw std::runtime_error((dir_ / "scene.json").string() + ": cannot write");
  }
  traj_ = open_file(dir_ / "trajectory.csv", "t,particle,x,y,vx,vy\n");
  events_ = open_file(dir_ / "events.csv",
                      "t,particle,obstacle,other_particle,x,y,nx,ny,vn_before,vn_after\n");
}

Recorder::~Recorder() {
  if (traj_) std::fclose(traj_);
  if (events_) std::fclose(events_);
}

void Recorder::flush_buffer(std::FILE* f, std::string& buf) {
  if (buf.empty()) return;
  const std::size_t n = std::fwrite(buf.data(), 1, buf.size(), f);
  std::fflush(f);
  buf.clear();
  if (n == 0) throw std::runtime_error(dir_.string() + ": writing output failed (disk full?)");
}

void Recorder::write_state(const State& s) {
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
  flush_buffer(traj_, buf_);
}

void Recorder::write_events(const std::vector<pinsim_event>& events) {
  for (const auto& e : events) {
    append_number(buf_, e.t);
    buf_ += ',';
    append_int(buf_, e.particle);
    buf_ += ',';
    buf_ += e.obstacle >= 0 ? scene_.obstacle_id(e.obstacle) : std::string();
    buf_ += ',';
    if (e.other >= 0) append_int(buf_, e.other);
    for (double v : {e.point[0], e.point[1], e.normal[0], e.normal[1], e.vn_before, e.vn_after}) {
      buf_ += ',';
      append_number(buf_, v);
    }
    buf_ += '\n';
  }
  contacts_ += events.size();
  flush_buffer(events_, buf_);
}

void Recorder::write_summary(const nlohmann::json& summary) {
  const fs::path tmp = dir_ / "summary.json.tmp";
  {
    std::ofstream out(tmp);
    out << summary.dump(2) << "\n";
    if (!out) throw std::runtime_error(tmp.string() + ": cannot write summary");
  }
  fs::rename(tmp, dir_ / "summary.json");
}

}  // namespace pinsim
