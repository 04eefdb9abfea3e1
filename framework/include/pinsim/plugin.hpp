// pinsim/plugin.hpp: write a plugin as an ordinary C++ class (header-only).
//
// A force plugin is a class with
//   static pinsim::PluginInfo info();                       // name, doc, parameters, arity
//   explicit MyForce(const pinsim::CreateContext& ctx);     // throws pinsim::Error on bad input
//   void add_force(const pinsim::StateView& s, pinsim::ForceOut& f) const;   // f += force
// and optionally
//   double energy(const pinsim::StateView& s) const;                          // -> CAP_ENERGY
//   void add_dfdx(const pinsim::StateView& s, pinsim::Triplets& J) const;     // -> CAP_DFDX
//   void add_dfdv(const pinsim::StateView& s, pinsim::Triplets& J) const;     // -> CAP_DFDV
//   void add_dforce_dparam(const pinsim::StateView& s, std::string_view param, int component,
//                          pinsim::ForceOut& df) const;                 // -> CAP_DPARAM
//     (df += d f / d param, for each parameter declared .differentiable(); `component` 0, or
//     0/1 for a vec2; `pinsim grad` uses it, check-plugin compares it with differences)
//   void add_jacobian_products(const pinsim::StateView& s, const pinsim::Field& w,
//                              pinsim::ForceOut& gx, pinsim::ForceOut* gv) const;
//                                                             // -> CAP_JACOBIAN_PRODUCTS
//     (gx += (df/dx)^T w, and gv += (df/dv)^T w when gv is not null: what `pinsim grad`
//     takes each step, cheaper than the Jacobians' entries; needs add_dfdx)
//   void add_adjoint_products(const pinsim::StateView& s, const pinsim::Field& w,
//                             pinsim::ForceOut& gx, pinsim::ForceOut* gv,
//                             std::span<double> gp) const;         // -> CAP_ADJOINT_PRODUCTS
//     (add_jacobian_products and, in the same pass, gp[j] += w . d f / d theta_j for each
//     differentiable parameter component, declaration order, a vec2 two slots: one call per
//     step of `pinsim grad` instead of one plus one per parameter; needs both of those)
//   pinsim::ConstraintSet constraint_set() const;                   // both -> CAP_CONSTRAINTS
//   void constraints(const double* x, const uint64_t* which, std::size_t count, double* c,
//                    double* dc) const;
//     (the force as soft constraints, E = sum ks/2 C^2: pinsim_constraint_set in pinsim/abi.h;
//     pinsim/constraint_spring.hpp provides both)
// A backend plugin is a class with
//   static pinsim::PluginInfo info();
//   explicit MyBackend(const pinsim::CreateContext& ctx);   // ctx.scene holds obstacles, inputs
//   void advance(pinsim::MutableState& s, double dt, pinsim::EventSink& events);
//     (once per step: move each particle with inv_mass > 0 over [s.t, s.t + dt] along v,
//     change v only by contact impulses and emit one event per impulse, touch nothing else,
//     the same bits for the same inputs on any thread count: the contract in pinsim/abi.h
//     above pinsim_backend_api)
// and optionally
//   double distance(const pinsim::Vec2& p, double t, int64_t* obstacle) const; // -> CAP_DISTANCE
//   void input(const std::string& name, bool pressed, double t);               // -> CAP_INPUTS
//     (a live press/release at time t, between steps, in time order; throw on an unknown name)
//   pinsim::OutlineSet outline(const pinsim::StateView& s, double tolerance) const;
//                                                                       // -> CAP_OUTLINES
//     (each obstacle's boundary as closed polylines at s.t, and bounds; for pictures)
//
// Then, once, at namespace scope in one .cpp file:  PINSIM_PLUGIN(MyForce)
// The macro builds the C table of pinsim/abi.h, exports `pinsim_plugin_entry`, derives the
// capability flags from the members that exist, and turns every exception into an error
// code plus message at the boundary. This header holds the types a plugin is written with;
// the machinery behind the macro is in pinsim/detail/plugin_table.hpp (included below),
// which an author never needs to read.
#pragma once

#include <pinsim/abi.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace pinsim {

using Vec2 = Eigen::Vector2d;
using Mat2 = Eigen::Matrix2d;
/// A force's soft constraints (count, arity, particles, ks and kd per constraint; arrays owned
/// by the instance): what constraint_set() returns.
using ConstraintSet = pinsim_constraint_set;

/// The error a plugin throws for bad parameters or bad input; the message reaches the user.
class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Read-only state: positions and velocities as 2xN matrices (one column per particle).
struct StateView {
  std::size_t n;                               ///< number of particles
  double t;                                    ///< time, s
  Eigen::Map<const Eigen::Matrix2Xd> x;        ///< positions, scene units
  Eigen::Map<const Eigen::Matrix2Xd> v;        ///< velocities, units/s
  Eigen::Map<const Eigen::VectorXd> inv_mass;  ///< 1/mass, 0 for pinned particles
  Eigen::Map<const Eigen::VectorXd> radius;    ///< radius, scene units

  explicit StateView(const pinsim_state_view& s)
      : n(s.n),
        t(s.t),
        x(s.x, 2, static_cast<Eigen::Index>(s.n)),
        v(s.v, 2, static_cast<Eigen::Index>(s.n)),
        inv_mass(s.inv_mass, static_cast<Eigen::Index>(s.n)),
        radius(s.radius, static_cast<Eigen::Index>(s.n)) {}
};

/// Positions and velocities a backend may change during advance().
struct MutableState {
  std::size_t n;
  double t;  ///< time at the start of the step, s
  Eigen::Map<Eigen::Matrix2Xd> x;
  Eigen::Map<Eigen::Matrix2Xd> v;
  Eigen::Map<const Eigen::VectorXd> inv_mass;
  Eigen::Map<const Eigen::VectorXd> radius;

  explicit MutableState(const pinsim_state_mut& s)
      : n(s.n),
        t(s.t),
        x(s.x, 2, static_cast<Eigen::Index>(s.n)),
        v(s.v, 2, static_cast<Eigen::Index>(s.n)),
        inv_mass(s.inv_mass, static_cast<Eigen::Index>(s.n)),
        radius(s.radius, static_cast<Eigen::Index>(s.n)) {}
};

/// Force accumulator: add to column i the force on particle i.
using ForceOut = Eigen::Map<Eigen::Matrix2Xd>;
/// A read-only 2xN field over the particles (one column per particle), e.g. the w of
/// add_jacobian_products.
using Field = Eigen::Map<const Eigen::Matrix2Xd>;

/// Sparse Jacobian accumulator; rows and columns are dofs (2*particle + component).
/// add_block() collects blocks and hands them to the host kBatch at a time through the
/// sink's add_blocks() (one call instead of four per block), or entry by entry through add()
/// if the host's sink has no add_blocks; add() and the destructor hand over the collected
/// blocks first, so the host receives every entry in the order they were added.
class Triplets {
 public:
  explicit Triplets(const pinsim_triplet_sink& s) : sink_(s) {}
  Triplets(const Triplets&) = delete;
  Triplets& operator=(const Triplets&) = delete;
  ~Triplets() { flush(); }
  void add(uint32_t row, uint32_t col, double value) {
    flush();
    sink_.add(sink_.context, row, col, value);
  }
  /// Adds the 2x2 block d f_i / d x_j.
  void add_block(uint32_t i, uint32_t j, const Mat2& b) {
    add_block(i, j, b(0, 0), b(1, 0), b(0, 1), b(1, 1));
  }
  /// Adds the 2x2 block d f_i / d x_j given entry by entry, column by column (b_00, b_10,
  /// b_01, b_11): for a hot loop, which then writes its values straight into the batch (no
  /// Mat2 on the stack copied in).
  void add_block(uint32_t i, uint32_t j, double b00, double b10, double b01, double b11) {
    if (sink_.add_blocks == nullptr) {
      sink_.add(sink_.context, 2 * i, 2 * j, b00);
      sink_.add(sink_.context, 2 * i, 2 * j + 1, b01);
      sink_.add(sink_.context, 2 * i + 1, 2 * j, b10);
      sink_.add(sink_.context, 2 * i + 1, 2 * j + 1, b11);
      return;
    }
    particles_[2 * count_] = i;
    particles_[2 * count_ + 1] = j;
    double* v = values_ + 4 * count_;  // column-major
    v[0] = b00;
    v[1] = b10;
    v[2] = b01;
    v[3] = b11;
    if (++count_ == kBatch) flush();
  }
  /// Hands the collected blocks to the host (add() and the destructor do it too).
  void flush() {
    if (count_ == 0) return;
    sink_.add_blocks(sink_.context, particles_, values_, count_);
    count_ = 0;
  }

 private:
  static constexpr uint32_t kBatch = 64;
  pinsim_triplet_sink sink_;
  uint32_t count_ = 0;
  uint32_t particles_[2 * kBatch];
  double values_[4 * kBatch];
};

/// Contact event sink for backends.
class EventSink {
 public:
  explicit EventSink(const pinsim_event_sink* s) : sink_(s) {}
  void emit(const pinsim_event& e) {
    if (sink_ != nullptr && sink_->emit != nullptr) sink_->emit(sink_->context, &e);
  }

 private:
  const pinsim_event_sink* sink_;
};

/// A rectangle with nothing in it (any add_bounds replaces it).
inline pinsim_bounds empty_bounds() { return {HUGE_VAL, HUGE_VAL, -HUGE_VAL, -HUGE_VAL}; }
/// Grows b to hold o (an empty o adds nothing).
inline void add_bounds(pinsim_bounds& b, const pinsim_bounds& o) {
  if (!(o.x0 <= o.x1 && o.y0 <= o.y1)) return;
  b.x0 = std::min(b.x0, o.x0);
  b.y0 = std::min(b.y0, o.y0);
  b.x1 = std::max(b.x1, o.x1);
  b.y1 = std::max(b.y1, o.y1);
}

/// One obstacle's outline, as a backend's outline() reports it (pinsim_outline).
struct ObstacleOutline {
  int64_t obstacle = -1;                  ///< index into the scene's "obstacles"
  std::string id;                         ///< the obstacle's id
  pinsim_bounds bounds = empty_bounds();  ///< its boundary's bounds at the state's time
  pinsim_bounds sweep = empty_bounds();   ///< ... over every pose its motion can take
  std::vector<std::vector<Vec2>> rings;   ///< closed polylines, solid on the left, scene units
};

/// What outline() returns: each obstacle in scene order, and the bounds of the whole set.
struct OutlineSet {
  std::vector<ObstacleOutline> obstacles;
  pinsim_bounds bounds = empty_bounds();  ///< every obstacle's bounds
  pinsim_bounds sweep = empty_bounds();   ///< every obstacle's sweep
};

/// Element lists: element e has particles (e, 0) ... (e, size(e) - 1). For a fixed arity
/// every element has `arity` particles; for PINSIM_ARITY_VARIABLE (arity 0) each element is
/// a whole body or closed ring of its own length, e.g. a ring blob's `boundary` set: its
/// particles in ring order, counter-clockwise, the last one joined to the first.
struct Elements {
  const uint32_t* data = nullptr;  ///< as in pinsim_create_args (length-prefixed if arity 0)
  std::size_t count = 0;           ///< number of elements
  uint32_t arity = 0;              ///< particles per element, 0 = variable
  std::vector<std::size_t> start;  ///< arity 0: offset in data of element e's first index

  /// Wraps the host's arrays; for arity 0 indexes where each element starts.
  static Elements from_abi(const uint32_t* data, std::size_t count, uint32_t arity) {
    Elements el{data, count, arity, {}};
    if (arity == PINSIM_ARITY_VARIABLE) {
      el.start.reserve(count);
      std::size_t at = 0;
      for (std::size_t e = 0; e < count; ++e) {
        el.start.push_back(at + 1);
        at += 1 + data[at];
      }
    }
    return el;
  }
  /// Number of particles of element e.
  std::size_t size(std::size_t e) const {
    return arity != 0 ? arity : static_cast<std::size_t>(data[start[e] - 1]);
  }
  /// Particle k of element e.
  uint32_t operator()(std::size_t e, std::size_t k) const {
    return arity != 0 ? data[e * arity + k] : data[start[e] + k];
  }
  /// Element e's particle indices, in order.
  std::vector<uint32_t> element(std::size_t e) const {
    const uint32_t* p = arity != 0 ? data + e * arity : data + start[e];
    return std::vector<uint32_t>(p, p + size(e));
  }
};

/// Validated parameter values (defaults already filled in by the host).
class Params {
 public:
  explicit Params(nlohmann::json j) : j_(std::move(j)) {}
  double real(const char* name) const { return j_.at(name).get<double>(); }
  long integer(const char* name) const { return j_.at(name).get<long>(); }
  bool boolean(const char* name) const { return j_.at(name).get<bool>(); }
  std::string string(const char* name) const { return j_.at(name).get<std::string>(); }
  Vec2 vec2(const char* name) const {
    const auto& a = j_.at(name);
    return {a.at(0).get<double>(), a.at(1).get<double>()};
  }
  const nlohmann::json& json() const { return j_; }

 private:
  nlohmann::json j_;
};

/// Everything a plugin constructor receives.
struct CreateContext {
  Params params;
  nlohmann::json scene;  ///< backends: the scene subset (obstacles, inputs, ...); forces: null
  StateView initial;
  Elements elements;
  std::string context;  ///< e.g. "scene.json: forces[2]", for error messages
};

/// The element list of `ctx` as a flat array of particle indices, `arity` per element,
/// after checking that the elements have that arity and that every index names a particle
/// of the initial state; throws Error naming ctx.context otherwise. The one element check
/// every force plugin starts with.
inline std::vector<uint32_t> element_indices(const CreateContext& ctx, uint32_t arity) {
  if (ctx.elements.arity != arity)
    throw Error(ctx.context + ": elements have " + std::to_string(ctx.elements.arity) +
                " particles each, this force needs " + std::to_string(arity));
  std::vector<uint32_t> idx(ctx.elements.data, ctx.elements.data + ctx.elements.count * arity);
  for (uint32_t i : idx)
    if (i >= ctx.initial.n)
      throw Error(ctx.context + ": particle index " + std::to_string(i) + " out of range (" +
                  std::to_string(ctx.initial.n) + " particles)");
  return idx;
}

/// One declared parameter, built fluently: real("k", 100).min(0, true).units("N/m").doc("...")
struct ParamDecl {
  // Fields as in the C table (pinsim_param); the fluent setters below fill them.
  std::string name;
  pinsim_param_type type = PINSIM_PARAM_REAL;
  uint32_t flags = 0;
  double default_value[2] = {0.0, 0.0};
  std::string default_string;
  std::string choices_text;  ///< "a|b|c", or empty for any string
  double min_value = -HUGE_VAL;
  double max_value = HUGE_VAL;
  std::string units_text = "1";
  std::string doc_text;

  ParamDecl& min(double v, bool exclusive = false) {
    min_value = v;
    if (exclusive) flags |= PINSIM_PARAM_MIN_EXCLUSIVE;
    return *this;
  }
  ParamDecl& max(double v, bool exclusive = false) {
    max_value = v;
    if (exclusive) flags |= PINSIM_PARAM_MAX_EXCLUSIVE;
    return *this;
  }
  ParamDecl& required() {
    flags |= PINSIM_PARAM_REQUIRED;
    return *this;
  }
  /// The force's add_dforce_dparam() gives its derivative in this (real or vec2) parameter.
  ParamDecl& differentiable() {
    flags |= PINSIM_PARAM_DIFFERENTIABLE;
    return *this;
  }
  ParamDecl& units(std::string u) {
    units_text = std::move(u);
    return *this;
  }
  ParamDecl& doc(std::string d) {
    doc_text = std::move(d);
    return *this;
  }
  ParamDecl& choices(std::string c) {
    choices_text = std::move(c);
    return *this;
  }
};

inline ParamDecl real(std::string name, double def) {
  ParamDecl p;
  p.name = std::move(name);
  p.type = PINSIM_PARAM_REAL;
  p.default_value[0] = def;
  return p;
}
inline ParamDecl integer(std::string name, long def) {
  ParamDecl p = real(std::move(name), static_cast<double>(def));
  p.type = PINSIM_PARAM_INT;
  return p;
}
inline ParamDecl boolean(std::string name, bool def) {
  ParamDecl p = real(std::move(name), def ? 1.0 : 0.0);
  p.type = PINSIM_PARAM_BOOL;
  return p;
}
inline ParamDecl string(std::string name, std::string def) {
  ParamDecl p;
  p.name = std::move(name);
  p.type = PINSIM_PARAM_STRING;
  p.default_string = std::move(def);
  return p;
}
inline ParamDecl vec2(std::string name, double x, double y) {
  ParamDecl p = real(std::move(name), x);
  p.type = PINSIM_PARAM_VEC2;
  p.default_value[1] = y;
  return p;
}

/// What a plugin says about itself.
struct PluginInfo {
  std::string name;
  std::string version = "1.0.0";
  std::string doc;
  /// forces: particles per element (1, 2, 3, ...), or PINSIM_ARITY_VARIABLE for elements
  /// that are whole bodies or closed rings of any length (`Elements::size(e)`)
  uint32_t arity = 1;
  uint32_t capabilities = 0;  ///< extra flags: PINSIM_CAP_INTERNAL, _DISSIPATIVE, _PARTICLE_CONTACT
  std::vector<ParamDecl> params;
};

}  // namespace pinsim

#include <pinsim/detail/plugin_table.hpp>
