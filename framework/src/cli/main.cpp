// pinsim: the command line program. Each subcommand lives in its own cmd_*.cpp.
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <csignal>
#include <iostream>

#include "commands.hpp"
#include "core/input_error.hpp"
#include "core/output_file.hpp"
#include "core/plugin_instance.hpp"
#include "core/plugin_loader.hpp"

int main(int argc, char** argv) {
  // Past a file-size limit a write fails with EFBIG (reported, naming the file) instead of
  // killing the process.
  std::signal(SIGXFSZ, SIG_IGN);
  auto logger = spdlog::stderr_color_mt("pinsim");
  logger->set_pattern("%^[%l]%$ %v");
  spdlog::set_default_logger(logger);

  CLI::App app{"pinsim: 2D particle simulation with plugin forces and collision backends"};
  app.set_version_flag("--version", std::string("pinsim ") + PINSIM_VERSION);
  int verbose = 0;
  bool quiet = false;
  app.add_flag("-v,--verbose", verbose, "More log output (-vv for trace)");
  app.add_flag("-q,--quiet", quiet, "Only errors");
  app.require_subcommand(1);
  // -q, -v after the subcommand too (`pinsim run SCENE -q`): its unknown options fall
  // through to these.
  app.fallthrough();
  app.parse_complete_callback([&] {
    spdlog::set_level(quiet          ? spdlog::level::err
                      : verbose >= 2 ? spdlog::level::trace
                      : verbose == 1 ? spdlog::level::debug
                                     : spdlog::level::info);
  });
  pinsim::cli::add_run_command(app);
  pinsim::cli::add_validate_command(app);
  pinsim::cli::add_plugins_command(app);
  pinsim::cli::add_check_plugin_command(app);
  pinsim::cli::add_bench_command(app);
  pinsim::cli::add_merge_command(app);
  pinsim::cli::add_stress_command(app);
  pinsim::cli::add_crosscheck_command(app);
  pinsim::cli::add_render_command(app);
  pinsim::cli::add_replay_command(app);
  pinsim::cli::add_share_command(app);
  pinsim::cli::add_play_command(app);
  pinsim::cli::add_grade_command(app);
  pinsim::cli::add_gradescope_pack_command(app);
#ifdef PINSIM_WITH_GRADIENTS
  pinsim::cli::add_grad_command(app);
  pinsim::cli::add_fit_command(app);
#endif

  try {
    app.parse(argc, argv);
  } catch (const CLI::RuntimeError& e) {
    return e.get_exit_code();  // a subcommand's own exit status
  } catch (const CLI::ParseError& e) {
    // --help and --version are "errors" with status 0; every command-line mistake is bad
    // input (exit 2, as documented), not CLI11's own codes 101-120.
    if (e.get_exit_code() == 0) return app.exit(e);
    spdlog::error("{} (pinsim --help, or pinsim COMMAND --help, lists the options)", e.what());
    return 2;
  } catch (const pinsim::InputError& e) {
    spdlog::error("{}", e.what());  // bad input: nothing ran
    return 2;
  } catch (const pinsim::OutputError& e) {
    spdlog::error("{}", e.what());
    return 1;  // something ran, or could have: its output could not be written
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());  // a plugin that cannot be loaded or created, or the system
    return 2;
  }
  return 0;
}
