// A submission with a syntax error: the grader must report the compiler's message.
#include <pinsim/plugin.hpp>

class Spring {
 public:
  static pinsim::PluginInfo info() {
    return {}
  }  // missing semicolon
};
