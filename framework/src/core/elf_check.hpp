// A look at a shared library's ELF headers before the dynamic loader maps it: a truncated
// or corrupt file would otherwise be mapped past its end and kill the process (SIGBUS)
// when the loader touches the missing pages.
#pragma once

#include <filesystem>
#include <string>

namespace pinsim {

/// "" if `file` is a complete ELF shared object of this machine's class, byte order and
/// architecture whose program headers, loadable segments and section headers all lie
/// within the file; else what is wrong ("truncated: ...", "not an ELF file", ...).
std::string elf_problem(const std::filesystem::path& file);

}  // namespace pinsim
