// Each `pinsim` subcommand registers itself on the app; one file per command.
#pragma once

#include <CLI/CLI.hpp>

namespace pinsim::cli {

void add_run_command(CLI::App& app);
void add_validate_command(CLI::App& app);
void add_plugins_command(CLI::App& app);
void add_check_plugin_command(CLI::App& app);
void add_bench_command(CLI::App& app);
void add_merge_command(CLI::App& app);
void add_stress_command(CLI::App& app);
void add_crosscheck_command(CLI::App& app);
void add_render_command(CLI::App& app);
void add_replay_command(CLI::App& app);
void add_share_command(CLI::App& app);
void add_play_command(CLI::App& app);
void add_grade_command(CLI::App& app);
void add_gradescope_pack_command(CLI::App& app);
void add_grad_command(CLI::App& app);
void add_fit_command(CLI::App& app);

}  // namespace pinsim::cli
