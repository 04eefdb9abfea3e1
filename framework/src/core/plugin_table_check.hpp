// Whether the host can read a plugin table, and whether it is consistent with itself.
// First its version (major, minor and length, pinsim/abi.h), read without touching a byte
// past its struct_size; then the table as the host reads it (entries it does not hold
// absent): every function pointer present exactly when its capability flag says so, every
// count bounded and every string and array it counts present. The host checks this once,
// when a table is loaded (or built by the grader's proxy for a sandboxed submission),
// before it calls anything; a table that fails is that plugin's error, so no later call can
// go through a NULL pointer.
#pragma once

#include <pinsim/abi.h>

#include <cstdint>
#include <string>

namespace pinsim {

/// The ABI version a table was built against.
struct TableVersion {
  uint32_t major = 0;
  uint32_t minor = 0;  ///< 0 when the table ends before abi_minor (a 4.0 table)
};

/// The version `table` states; reads abi_minor only when struct_size covers it.
TableVersion table_version(const pinsim_plugin& table);

/// "" if the host can read `table`; else why not, naming the table's version and this
/// pinsim's: another major, a table shorter than its major's or its minor's layout, a
/// newer minor, or a table that holds abi_minor but states minor 0. Reads abi_version and
/// struct_size, and the entries struct_size covers.
std::string table_version_problem(const pinsim_plugin& table);

/// `table` as the host reads it (call after table_version_problem returned ""): the
/// entries its struct_size covers and its minor has, every other entry of this ABI zero,
/// that is absent. Pointers still point into the plugin.
pinsim_plugin table_as_read(const pinsim_plugin& table);

/// Most parameters a table may declare.
inline constexpr uint32_t kMaxPluginParams = 1024;
/// Largest fixed force arity (particles per element) a table may declare.
inline constexpr uint32_t kMaxForceArity = 4096;

/// "" if `table` is consistent; else every inconsistency found, "; "-separated, each naming
/// the field and the flag ("declares PINSIM_CAP_ENERGY but its energy function is NULL").
/// `table` is a whole table of this ABI as the host reads it (table_as_read, or one the host
/// built): an entry the plugin's table does not hold is NULL there, so a flag whose
/// function it lacks is reported like any NULL function. Reads that table and the strings
/// and parameters it points to.
std::string plugin_table_problems(const pinsim_plugin& table);

}  // namespace pinsim
