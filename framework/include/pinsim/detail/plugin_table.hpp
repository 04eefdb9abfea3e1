// pinsim/detail/plugin_table.hpp: the machinery behind PINSIM_PLUGIN (pinsim/plugin.hpp
// includes it; an author reads that header, not this one). It detects which members a
// plugin class has, builds the class's C table of pinsim/abi.h once (strings and parameter
// array owned for the library's lifetime), wraps every member in a function that turns
// exceptions into an error code plus message, and defines the exported entry function.
#pragma once

#include <pinsim/abi.h>

#include <concepts>
#include <cstring>
#include <exception>
#include <optional>
#include <pinsim/plugin.hpp>
#include <span>
#include <string>
#include <utility>
#include <vector>

namespace pinsim {
namespace detail {

inline void write_error(pinsim_error* err, const char* msg) {
  if (err == nullptr || err->message == nullptr || err->capacity == 0) return;
  std::strncpy(err->message, msg, err->capacity - 1);
  err->message[err->capacity - 1] = '\0';
}

/// Runs f, converting any exception into return code 1 plus message.
template <class F>
int guarded(pinsim_error* err, F&& f) noexcept {
  try {
    f();
    return 0;
  } catch (const std::exception& e) {
    write_error(err, e.what());
  } catch (...) {
    write_error(err, "unknown exception");
  }
  return 1;
}

template <class T>
concept ForcePlugin = requires(const T& t, const StateView& s, ForceOut& f) {
  t.add_force(s, f);
};
template <class T>
concept BackendPlugin = requires(T& t, MutableState& s, double dt, EventSink& e) {
  t.advance(s, dt, e);
};
template <class T>
concept HasEnergy = requires(const T& t, const StateView& s) {
  { t.energy(s) } -> std::convertible_to<double>;
};
template <class T>
concept HasDfdx = requires(const T& t, const StateView& s, Triplets& j) {
  t.add_dfdx(s, j);
};
template <class T>
concept HasDfdv = requires(const T& t, const StateView& s, Triplets& j) {
  t.add_dfdv(s, j);
};
/// Optional: both Jacobians in one pass, add_jacobians(s, Triplets* dfdx, Triplets* dfdv)
/// (either may be null); used instead of add_dfdx and add_dfdv when present.
template <class T>
concept HasJacobians = requires(const T& t, const StateView& s, Triplets* j) {
  t.add_jacobians(s, j, j);
};
/// Optional (forces, ABI 4.4): add_dforce_dparam(s, name, component, df) -> add_dforce_dparam,
/// for the parameters declared .differentiable() (none declared: the member is not used).
template <class T>
concept HasDparam = requires(const T& t, const StateView& s, std::string_view name, int c,
                             ForceOut& f) {
  t.add_dforce_dparam(s, name, c, f);
};
/// Optional (forces, ABI 4.4): add_jacobian_products(s, w, gx, gv) -> add_jacobian_products
/// (used with add_dfdx only).
template <class T>
concept HasJacobianProducts = requires(const T& t, const StateView& s, const Field& w,
                                       ForceOut& g) {
  t.add_jacobian_products(s, w, g, &g);
};
/// Optional (forces, ABI 4.5): add_adjoint_products(s, w, gx, gv, gp) -> add_adjoint_products
/// (used with add_jacobian_products and differentiable parameters only); gp a std::span<double>
/// with one slot per differentiable parameter component, in declaration order.
template <class T>
concept HasAdjointProducts = requires(const T& t, const StateView& s, const Field& w, ForceOut& g,
                                      std::span<double> gp) {
  t.add_adjoint_products(s, w, g, &g, gp);
};
/// Optional: the force as soft constraints (pinsim_constraint_set): both members or neither.
template <class T>
concept HasConstraints = requires(const T& t, const double* x, const uint64_t* which,
                                  std::size_t count, double* out) {
  { t.constraint_set() } -> std::convertible_to<ConstraintSet>;
  t.constraints(x, which, count, out, out);
};
template <class T>
concept HasDistance = requires(const T& t, const Vec2& p, double time, int64_t* o) {
  { t.distance(p, time, o) } -> std::convertible_to<double>;
};
template <class T>
concept HasInput = requires(T& t, const std::string& name, bool pressed, double time) {
  t.input(name, pressed, time);
};
/// Optional (backends, ABI 4.3): record_drift(const pinsim_drift_sink*) -> record_drift;
/// such a backend must declare PINSIM_CAP_DIFFERENTIABLE in its info().
template <class T>
concept HasRecordDrift = requires(T& t, const pinsim_drift_sink* sink) {
  t.record_drift(sink);
};
template <class T>
concept HasOutline = requires(const T& t, const StateView& s, double tolerance) {
  { t.outline(s, tolerance) } -> std::convertible_to<OutlineSet>;
};

/// Hands each obstacle of `set` to the sink as a pinsim_outline.
inline void emit_outlines(const OutlineSet& set, const pinsim_outline_sink* sink) {
  if (sink == nullptr || sink->emit == nullptr) return;
  std::vector<uint32_t> sizes;
  std::vector<double> points;
  for (const ObstacleOutline& o : set.obstacles) {
    sizes.clear();
    points.clear();
    for (const auto& ring : o.rings) {
      sizes.push_back(static_cast<uint32_t>(ring.size()));
      for (const Vec2& p : ring) {
        points.push_back(p.x());
        points.push_back(p.y());
      }
    }
    const pinsim_outline c{
        o.obstacle,   o.id.c_str(), o.bounds, o.sweep, static_cast<uint32_t>(sizes.size()),
        sizes.data(), points.data()};
    sink->emit(sink->context, &c);
  }
}

/// Owns the strings behind the C table for the library's lifetime.
struct TableStorage {
  PluginInfo info;
  std::vector<pinsim_param> params;
  pinsim_plugin table{};
  /// The differentiable parameters' components (add_adjoint_products' gp length).
  uint32_t dparam_slots = 0;
};

template <class T>
void* create(const pinsim_create_args* a, pinsim_error* err) noexcept {
  T* out = nullptr;
  guarded(err, [&] {
    nlohmann::json params = nlohmann::json::parse(a->params_json ? a->params_json : "{}");
    nlohmann::json scene = a->scene_json ? nlohmann::json::parse(a->scene_json) : nlohmann::json();
    if constexpr (ForcePlugin<T>) {
      // A host older than variable-length elements passes them as arity 1.
      if (T::info().arity == PINSIM_ARITY_VARIABLE && a->arity != PINSIM_ARITY_VARIABLE)
        throw Error(std::string(a->context ? a->context : "") +
                    ": this plugin takes whole bodies (variable-length elements), but the "
                    "pinsim loading it passed elements of " +
                    std::to_string(a->arity) + " particle(s): use a newer pinsim");
    }
    CreateContext ctx{
        Params(std::move(params)), std::move(scene), StateView(*a->initial),
        Elements::from_abi(a->elements, static_cast<std::size_t>(a->n_elements), a->arity),
        a->context ? a->context : ""};
    out = new T(ctx);
  });
  return out;
}

template <class T>
void destroy(void* self) noexcept {
  delete static_cast<T*>(self);
}

template <class T>
const pinsim_plugin* make_table() {
  // The table points into its storage (names, docs, parameters), so the storage is filled
  // where it lives and never copied or moved: a short name sits inside the std::string
  // itself (small-string buffer), and a copy would leave the table pointing at the old one.
  static TableStorage st;
  static const bool filled = [] {
    TableStorage& s = st;
    s.info = T::info();
    for (const auto& p : s.info.params) {
      pinsim_param c{};
      c.name = p.name.c_str();
      c.type = p.type;
      c.flags = p.flags;
      c.default_value[0] = p.default_value[0];
      c.default_value[1] = p.default_value[1];
      c.default_string = p.type == PINSIM_PARAM_STRING ? p.default_string.c_str() : nullptr;
      c.choices = p.choices_text.empty() ? nullptr : p.choices_text.c_str();
      c.min = p.min_value;
      c.max = p.max_value;
      c.units = p.units_text.c_str();
      c.doc = p.doc_text.c_str();
      s.params.push_back(c);
    }
    pinsim_plugin& t = s.table;
    t.abi_version = PINSIM_ABI_MAJOR;
    t.struct_size = sizeof(pinsim_plugin);
    t.abi_minor = PINSIM_ABI_MINOR;
    t.arity = s.info.arity;
    t.name = s.info.name.c_str();
    t.version = s.info.version.c_str();
    t.doc = s.info.doc.c_str();
    t.params = s.params.data();
    t.n_params = static_cast<uint32_t>(s.params.size());
    t.capabilities = s.info.capabilities;
    t.create = &create<T>;
    t.destroy = &destroy<T>;
    if constexpr (ForcePlugin<T>) {
      t.kind = PINSIM_KIND_FORCE;
      t.force.add_force = [](void* self, const pinsim_state_view* sv, double* f,
                             pinsim_error* err) noexcept {
        return guarded(err, [&] {
          StateView s(*sv);
          ForceOut fo(f, 2, static_cast<Eigen::Index>(sv->n));
          static_cast<const T*>(self)->add_force(s, fo);
        });
      };
      if constexpr (HasEnergy<T>) {
        t.capabilities |= PINSIM_CAP_ENERGY;
        t.force.energy = [](void* self, const pinsim_state_view* sv, double* e,
                            pinsim_error* err) noexcept {
          return guarded(err, [&] { *e = static_cast<const T*>(self)->energy(StateView(*sv)); });
        };
      }
      if constexpr (HasConstraints<T>) {
        t.capabilities |= PINSIM_CAP_CONSTRAINTS;
        t.constraint_set = [](void* self, pinsim_constraint_set* out, pinsim_error* err) noexcept {
          return guarded(err, [&] { *out = static_cast<const T*>(self)->constraint_set(); });
        };
        t.constraints = [](void* self, const double* x, const uint64_t* which, uint64_t count,
                           double* c, double* dc, pinsim_error* err) noexcept {
          return guarded(err, [&] {
            static_cast<const T*>(self)->constraints(x, which, static_cast<std::size_t>(count), c,
                                                     dc);
          });
        };
      }
      if constexpr (HasDparam<T>) {
        bool any = false;
        for (const pinsim_param& p : s.params) any = any || (p.flags & PINSIM_PARAM_DIFFERENTIABLE);
        if (any) {
          t.capabilities |= PINSIM_CAP_DPARAM;
          t.add_dforce_dparam = [](void* self, const pinsim_state_view* sv, uint32_t param,
                                   uint32_t component, double* df, pinsim_error* err) noexcept {
            return guarded(err, [&] {
              const TableStorage& ts = st;
              if (param >= ts.params.size() ||
                  !(ts.params[param].flags & PINSIM_PARAM_DIFFERENTIABLE))
                throw Error("add_dforce_dparam: parameter " + std::to_string(param) +
                            " is not declared differentiable");
              const int n_components = ts.params[param].type == PINSIM_PARAM_VEC2 ? 2 : 1;
              if (component >= static_cast<uint32_t>(n_components))
                throw Error(std::string("add_dforce_dparam: parameter '") + ts.params[param].name +
                            "' has no component " + std::to_string(component));
              ForceOut fo(df, 2, static_cast<Eigen::Index>(sv->n));
              static_cast<const T*>(self)->add_dforce_dparam(
                  StateView(*sv), std::string_view(ts.params[param].name),
                  static_cast<int>(component), fo);
            });
          };
        }
      }
      if constexpr (HasJacobianProducts<T> && HasDfdx<T>) {
        t.capabilities |= PINSIM_CAP_JACOBIAN_PRODUCTS;
        t.add_jacobian_products = [](void* self, const pinsim_state_view* sv, const double* w,
                                     double* gx, double* gv, pinsim_error* err) noexcept {
          return guarded(err, [&] {
            const auto n = static_cast<Eigen::Index>(sv->n);
            const Field wf(w, 2, n);
            ForceOut ox(gx, 2, n);
            if (gv == nullptr) {
              static_cast<const T*>(self)->add_jacobian_products(StateView(*sv), wf, ox, nullptr);
              return;
            }
            ForceOut ov(gv, 2, n);
            static_cast<const T*>(self)->add_jacobian_products(StateView(*sv), wf, ox, &ov);
          });
        };
      }
      if constexpr (HasAdjointProducts<T> && HasJacobianProducts<T> && HasDfdx<T> && HasDparam<T>) {
        for (const pinsim_param& p : s.params)
          if (p.flags & PINSIM_PARAM_DIFFERENTIABLE)
            s.dparam_slots += p.type == PINSIM_PARAM_VEC2 ? 2 : 1;
        if (s.dparam_slots > 0) {
          t.capabilities |= PINSIM_CAP_ADJOINT_PRODUCTS;
          t.add_adjoint_products = [](void* self, const pinsim_state_view* sv, const double* w,
                                      double* gx, double* gv, double* gp,
                                      pinsim_error* err) noexcept {
            return guarded(err, [&] {
              const auto n = static_cast<Eigen::Index>(sv->n);
              const Field wf(w, 2, n);
              ForceOut ox(gx, 2, n);
              const std::span<double> g(gp, st.dparam_slots);
              if (gv == nullptr) {
                static_cast<const T*>(self)->add_adjoint_products(StateView(*sv), wf, ox, nullptr,
                                                                  g);
                return;
              }
              ForceOut ov(gv, 2, n);
              static_cast<const T*>(self)->add_adjoint_products(StateView(*sv), wf, ox, &ov, g);
            });
          };
        }
      }
      if constexpr (HasDfdx<T>) t.capabilities |= PINSIM_CAP_DFDX;
      if constexpr (HasDfdv<T>) t.capabilities |= PINSIM_CAP_DFDV;
      if constexpr (HasDfdx<T> || HasDfdv<T>) {
        t.force.add_jacobians = [](void* self, const pinsim_state_view* sv,
                                   const pinsim_triplet_sink* dx, const pinsim_triplet_sink* dv,
                                   pinsim_error* err) noexcept {
          return guarded(err, [&] {
            StateView s(*sv);
            const T* p = static_cast<const T*>(self);
            if constexpr (HasJacobians<T> && HasDfdx<T> && HasDfdv<T>) {
              std::optional<Triplets> jx, jv;
              if (dx != nullptr) jx.emplace(*dx);
              if (dv != nullptr) jv.emplace(*dv);
              p->add_jacobians(s, jx ? &*jx : nullptr, jv ? &*jv : nullptr);
              return;
            }
            if constexpr (HasDfdx<T>) {
              if (dx != nullptr) {
                Triplets j(*dx);
                p->add_dfdx(s, j);
              }
            }
            if constexpr (HasDfdv<T>) {
              if (dv != nullptr) {
                Triplets j(*dv);
                p->add_dfdv(s, j);
              }
            }
          });
        };
      }
    } else {
      static_assert(BackendPlugin<T>,
                    "PINSIM_PLUGIN: class needs add_force(StateView, ForceOut&) const "
                    "or advance(MutableState&, double, EventSink&)");
      t.kind = PINSIM_KIND_BACKEND;
      t.backend.advance = [](void* self, pinsim_state_mut* sm, double dt,
                             const pinsim_event_sink* ev, pinsim_error* err) noexcept {
        return guarded(err, [&] {
          MutableState s(*sm);
          EventSink sink(ev);
          static_cast<T*>(self)->advance(s, dt, sink);
        });
      };
      if constexpr (HasDistance<T>) {
        t.capabilities |= PINSIM_CAP_DISTANCE;
        t.backend.distance = [](void* self, const double* p, double time, double* d, int64_t* o,
                                pinsim_error* err) noexcept {
          return guarded(
              err, [&] { *d = static_cast<const T*>(self)->distance(Vec2(p[0], p[1]), time, o); });
        };
      }
      if constexpr (HasOutline<T>) {
        t.capabilities |= PINSIM_CAP_OUTLINES;
        t.backend.outline = [](void* self, const pinsim_state_view* sv, double tolerance,
                               const pinsim_outline_sink* sink, pinsim_bounds* bounds,
                               pinsim_bounds* sweep, pinsim_error* err) noexcept {
          return guarded(err, [&] {
            const OutlineSet set = static_cast<const T*>(self)->outline(StateView(*sv), tolerance);
            emit_outlines(set, sink);
            if (bounds != nullptr) *bounds = set.bounds;
            if (sweep != nullptr) *sweep = set.sweep;
          });
        };
      }
      if constexpr (HasRecordDrift<T>) {
        t.record_drift = [](void* self, const pinsim_drift_sink* sink, pinsim_error* err) noexcept {
          return guarded(err, [&] { static_cast<T*>(self)->record_drift(sink); });
        };
      }
      if constexpr (HasInput<T>) {
        t.capabilities |= PINSIM_CAP_INPUTS;
        t.backend.input = [](void* self, const char* name, int pressed, double time,
                             pinsim_error* err) noexcept {
          return guarded(err, [&] {
            static_cast<T*>(self)->input(std::string(name ? name : ""), pressed != 0, time);
          });
        };
      }
    }
    return true;
  }();
  (void)filled;
  return &st.table;
}

}  // namespace detail
}  // namespace pinsim

/// The entry function's name: pinsim_plugin_entry in a plugin library. A plugin compiled to
/// be linked into the program (a static plugin: the web build, PINSIM_STATIC_PLUGINS) is
/// compiled with -DPINSIM_STATIC_ENTRY=pinsim_static_entry_<name>, so that several can live in
/// one program; the static registry (framework/src/core/static_plugins.hpp) lists them.
#ifdef PINSIM_STATIC_ENTRY
#define PINSIM_ENTRY_FUNCTION PINSIM_STATIC_ENTRY
#else
#define PINSIM_ENTRY_FUNCTION pinsim_plugin_entry
#endif

/// Registers CLASS as this library's plugin and exports the entry function.
#define PINSIM_PLUGIN(CLASS)                                                                    \
  extern "C" __attribute__((visibility("default"))) const pinsim_plugin* PINSIM_ENTRY_FUNCTION( \
      void) {                                                                                   \
    try {                                                                                       \
      return ::pinsim::detail::make_table<CLASS>();                                             \
    } catch (...) {                                                                             \
      return nullptr;                                                                           \
    }                                                                                           \
  }
