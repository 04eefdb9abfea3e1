// Whether a plugin table is consistent with itself: every function pointer present exactly
// when its capability flag says so, every count bounded and every string and array it
// counts present. The host checks this once, when a table is loaded (or built by the
// grader's proxy for a sandboxed submission), before it calls anything; a table that fails
// is that plugin's error, so no later call can go through a NULL pointer.
#pragma once

#include <pinsim/abi.h>

#include <string>

namespace pinsim {

/// Most parameters a table may declare.
inline constexpr uint32_t kMaxPluginParams = 1024;
/// Largest fixed force arity (particles per element) a table may declare.
inline constexpr uint32_t kMaxForceArity = 4096;

/// "" if `table` is consistent; else every inconsistency found, "; "-separated, each naming
/// the field and the flag ("declares PINSIM_CAP_ENERGY but its energy function is NULL").
/// Reads only the fields of this ABI version (the caller has checked abi_version and
/// struct_size) and the strings and parameters the table points to.
std::string plugin_table_problems(const pinsim_plugin& table);

}  // namespace pinsim
