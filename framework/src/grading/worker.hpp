// The untrusted side of the grader: `pinsim grade-worker`, run inside the sandbox. It loads
// the submission's libraries and answers the grader's requests on file descriptor 3 with raw
// numbers (forces, energies, Jacobian entries, states, events). It decides nothing: every
// verdict is computed by the grader from these numbers. Whatever the submission prints goes
// to stdout/stderr, which the grader captures separately and never parses.
#pragma once

#include <filesystem>

namespace pinsim::grading {

/// Serves requests on `fd` until Quit or end of file; plugins are looked up in `libraries`.
int serve_worker(int fd, const std::filesystem::path& libraries);

}  // namespace pinsim::grading
