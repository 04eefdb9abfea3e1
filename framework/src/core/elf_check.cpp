#include "core/elf_check.hpp"

#include <elf.h>

#include <bit>
#include <cstring>
#include <fstream>
#include <vector>

namespace pinsim {
namespace {

#if defined(__x86_64__)
constexpr uint16_t kMachine = EM_X86_64;
#elif defined(__aarch64__)
constexpr uint16_t kMachine = EM_AARCH64;
#else
constexpr uint16_t kMachine = 0;  // (not checked)
#endif

/// offset + count * size <= limit, without overflow.
bool fits(uint64_t offset, uint64_t count, uint64_t size, uint64_t limit) {
  if (offset > limit) return false;
  return size == 0 || count <= (limit - offset) / size;
}

}  // namespace

std::string elf_problem(const std::filesystem::path& file) {
  std::error_code ec;
  const uint64_t size = std::filesystem::file_size(file, ec);
  if (ec) return "cannot be read (" + ec.message() + ")";
  std::ifstream in(file, std::ios::binary);
  Elf64_Ehdr eh{};
  if (!in.read(reinterpret_cast<char*>(&eh), sizeof eh))
    return "not an ELF shared library (" + std::to_string(size) +
           " bytes, shorter than an ELF header)";
  if (std::memcmp(eh.e_ident, ELFMAG, SELFMAG) != 0) return "not an ELF shared library";
  if (eh.e_ident[EI_CLASS] != ELFCLASS64) return "not a 64-bit ELF library";
  const unsigned char order =
      std::endian::native == std::endian::little ? ELFDATA2LSB : ELFDATA2MSB;
  if (eh.e_ident[EI_DATA] != order) return "an ELF library of the other byte order";
  if (eh.e_type != ET_DYN) return "an ELF file, but not a shared library";
  if (kMachine != 0 && eh.e_machine != kMachine)
    return "an ELF library for another architecture (e_machine " + std::to_string(eh.e_machine) +
           ")";
  const std::string truncated = "truncated or corrupt (" + std::to_string(size) + " bytes): ";
  if (eh.e_phentsize != sizeof(Elf64_Phdr) || eh.e_phnum == 0)
    return truncated + "no program headers";
  if (!fits(eh.e_phoff, eh.e_phnum, eh.e_phentsize, size))
    return truncated + "its program headers end beyond the file";
  if (eh.e_shoff != 0 && !fits(eh.e_shoff, eh.e_shnum, eh.e_shentsize, size))
    return truncated + "its section headers end beyond the file";
  std::vector<Elf64_Phdr> ph(eh.e_phnum);
  in.seekg(static_cast<std::streamoff>(eh.e_phoff));
  if (!in.read(reinterpret_cast<char*>(ph.data()),
               static_cast<std::streamsize>(ph.size() * sizeof(Elf64_Phdr))))
    return truncated + "its program headers cannot be read";
  for (std::size_t i = 0; i < ph.size(); ++i)
    if (ph[i].p_type != PT_NULL && ph[i].p_type != PT_GNU_STACK &&
        !fits(ph[i].p_offset, 1, ph[i].p_filesz, size))
      return truncated + "segment " + std::to_string(i) + " (bytes " +
             std::to_string(ph[i].p_offset) + " to " +
             std::to_string(ph[i].p_offset + ph[i].p_filesz) + ") ends beyond the file";
  return "";
}

}  // namespace pinsim
