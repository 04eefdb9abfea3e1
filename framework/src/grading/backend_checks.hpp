// The collision rubric's stage checks (configs/grading/collision_assignment.json): each runs
// the submission's backend on a scene beside the reference backend and grades it against a
// closed form (free flight, one bounce, rest, a flipper's hit, energy) or the reference's
// path, step by step. Each starts with a motion gate: a backend that does not move the balls
// the way free flight does before their first contact fails, whatever it reports.
#pragma once

#include <filesystem>
#include <memory>
#include <string>

#include "core/plugin_loader.hpp"
#include "grading/rubric.hpp"
#include "grading/verdicts.hpp"

namespace pinsim::grading {

/// True for the checks this file grades (backend_free_flight, backend_bounce, backend_rest,
/// backend_energy, backend_path).
bool is_stage_check(const std::string& check);

/// Runs stage check `t` on the submission's backend `sub`; scenes resolve against
/// `rubric_dir`. Throws InputError for a scene the check cannot grade (a rubric error).
Verdict run_stage_check(const RubricTest& t, const std::shared_ptr<const LoadedPlugin>& sub,
                        const std::filesystem::path& rubric_dir);

}  // namespace pinsim::grading
