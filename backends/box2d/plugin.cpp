// Registers the box2d backend (the only translation unit of the plugin module).
#include "box2d_backend.hpp"

PINSIM_PLUGIN(pinsim::box2d::Box2dBackend)
